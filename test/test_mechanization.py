"""Strapdown mechanization against simulator truth and closed-form error growth."""
import numpy as np
import pytest

from sins_align_ros.nav import earth
from sins_align_ros.nav.frames import attitude_error, euler_to_dcm, rotvec_to_dcm
from sins_align_ros.nav.mechanization import MechanizationOptions, Strapdown
from sins_align_ros.sim.imu import ImuSimulator, ImuSpec
from sins_align_ros.sim.presets import SEED000_SWAY, Segment, scenario
from sins_align_ros.sim.trajectory import Sway, Trajectory
from sins_align_ros.units import ARCSEC, DEG
from tolerance import roundoff

#: Round-off of one strapdown step run in another order (the compiled loop against
#: numpy's per-sample path; test/tolerance.py): two DCMs from rotation vectors (~20
#: operations each) and two 3x3 products (5 each). The products are orthonormal, so an
#: attitude error is passed on with gain 1 and the chain after N steps is N x STEP_OPS.
STEP_OPS = 50


def recurrence_bounds(n, dv, dt, v, h):
    """Round-off bounds on attitude, velocity, latitude/longitude and height after n steps.

    The velocity integrates ``C dv + g dt``: the attitude's error times the integrated
    size of both (``sum |dv| + g T``), plus its own ~10 operations a step on ``|v|``. The
    position integrates the velocity over ``T``: latitude and longitude through ``1 / R``
    (6.4e6 m), the height directly, plus 2 operations a step on its own size (``lat`` ~1 rad,
    ``h`` m).
    """
    T = float(np.sum(dt)) if np.ndim(dt) else n * dt
    att = roundoff(n * STEP_OPS)
    vel = roundoff(n * STEP_OPS, np.linalg.norm(dv, axis=1).sum() + 9.8 * T) \
        + roundoff(n * 10, np.abs(v).max())
    return att, vel, vel * T / 6.3e6 + roundoff(n * 2, np.pi), vel * T + roundoff(n * 2, h)


TRAJECTORIES = {
    'static': Trajectory(34.0, 108.0, 100.0, heading_deg=30.0, pitch_deg=1.0, roll_deg=-2.0),
    'sway': Trajectory(45.7796, 126.6705, 0.0, heading_deg=45.0,
                       sway=Sway(**{**SEED000_SWAY.__dict__, 'heave_amp': 1.0,
                                    'heave_period': 8.0, 'surge_amp': 0.5,
                                    'surge_period': 9.0})),
    'underway': scenario('ship_underway').trajectory,
    'flight': scenario('seed001_flight').trajectory,
}


def integrate(traj, seconds=600.0, rate=100.0, options=MechanizationOptions()):
    sim = ImuSimulator(traj, ImuSpec(), rate)
    e0, v0, p0 = sim.initial_truth()
    chunk = sim.next_chunk(int(seconds * rate))
    nav = Strapdown(euler_to_dcm(e0), v0, *p0, options=options)
    out = nav.run(chunk.dtheta, chunk.dv, 1.0 / rate)
    return chunk, out


@pytest.mark.slow
@pytest.mark.parametrize('name', list(TRAJECTORIES))
def test_error_free_imu_integrates_back_to_truth(name):
    """Issue 2: 600 s at 100 Hz, attitude < 2 arcsec, position < 1 m underway."""
    chunk, out = integrate(TRAJECTORIES[name])
    att = attitude_error(out['C_b_n'], euler_to_dcm(chunk.euler))
    assert np.abs(att).max() < 2 * ARCSEC
    pos_err = earth.local_offset_m(chunk.pos[:, 0], chunk.pos[:, 1], chunk.pos[:, 2],
                                   out['pos'][:, 0], out['pos'][:, 1], out['pos'][:, 2])
    assert np.abs(pos_err).max() < 1.0
    assert np.abs(out['v_n'] - chunk.v_n).max() < 1e-3


def test_underway_truth_really_moves():
    chunk, _ = integrate(TRAJECTORIES['underway'], seconds=600.0, rate=50.0)
    d = earth.local_offset_m(*chunk.pos[0], *chunk.pos[-1].T)
    assert np.hypot(d[0], d[1]) > 2000.0     # several km: the position check is meaningful


def test_stationary_mode_tilt_error_grows_velocity_as_seed002_eq16():
    """A tilt error gives dV_E' = -g phi_N, dV_N' = g phi_E (seed 002 eq. 16).

    The heading error couples in through phi_E' = -w_N phi_U (eq. 16 row 3), so
    v_N(T) = g (phi_E T - w_N phi_U T^2 / 2) to first order.
    """
    traj = Trajectory(34.0, 75.0, 100.0, heading_deg=0.0)
    sim = ImuSimulator(traj, ImuSpec(), 100.0)
    e0, v0, p0 = sim.initial_truth()
    chunk = sim.next_chunk(1000)
    phi = np.array([2e-4, -1e-4, 3e-3])
    C0 = rotvec_to_dcm(-phi) @ euler_to_dcm(e0)
    nav = Strapdown(C0, v0, *p0, options=MechanizationOptions.stationary())
    out = nav.run(chunk.dtheta, chunk.dv, 0.01)
    g = earth.gravity(p0[0], p0[2])
    t = chunk.t[-1]
    # exact initial specific-force error of the tilted DCM, then eq. 16 to first order
    f_err = (rotvec_to_dcm(-phi) - np.eye(3)) @ np.array([0.0, 0.0, g])
    assert f_err[0] == pytest.approx(-g * phi[1], rel=0.02)
    assert f_err[1] == pytest.approx(g * phi[0], rel=0.02)
    w_N = earth.w_ie_n(p0[0])[1]
    assert out['v_n'][-1, 0] == pytest.approx(f_err[0] * t, rel=1e-3)
    assert out['v_n'][-1, 1] == pytest.approx(f_err[1] * t - 0.5 * g * w_N * phi[2] * t * t,
                                              rel=1e-3)
    assert np.all(out['v_n'][:, 2] == 0.0)                # vertical held (sec. 3)
    assert np.all(out['pos'] == p0)                       # position fixed (Table 1)


def test_stationary_mode_without_coriolis_matches_full_mode_on_still_base():
    traj = Trajectory(34.0, 75.0, 100.0, heading_deg=10.0)
    _, full = integrate(traj, seconds=60.0)
    _, stat = integrate(traj, seconds=60.0, options=MechanizationOptions.stationary())
    assert np.abs(stat['v_n']).max() < 1e-6
    err = attitude_error(stat['C_b_n'][-1], full['C_b_n'][-1])
    assert np.abs(err).max() < 0.01 * ARCSEC


def test_coning_correction_matters_under_coning_motion():
    """Pure coning: without the (1/12) dtheta_prev x dtheta term the drift is far larger."""
    traj = Trajectory(0.0, 0.0, 0.0, sway=Sway(roll_amp=5.0, roll_period=0.5,
                                               pitch_amp=5.0, pitch_period=0.5,
                                               pitch_phase=np.pi / 2))
    chunk, out = integrate(traj, seconds=60.0, rate=100.0)
    err_full = np.abs(attitude_error(out['C_b_n'][-1], euler_to_dcm(chunk.euler[-1]))).max()
    sim = ImuSimulator(traj, ImuSpec(), 100.0)
    e0, v0, p0 = sim.initial_truth()
    chunk = sim.next_chunk(6000)
    C = euler_to_dcm(e0)
    for k in range(len(chunk.t)):       # attitude from plain increments, no coning term
        w = earth.w_ie_n(p0[0]) * 0.01
        C = rotvec_to_dcm(-w) @ C @ rotvec_to_dcm(chunk.dtheta[k])
    err_plain = np.abs(attitude_error(C, euler_to_dcm(chunk.euler[-1]))).max()
    assert err_plain > 20 * err_full
    assert err_full < 10 * ARCSEC      # 2 Hz, 5 deg coning: far harsher than any ship


def test_segment_rejects_bad_ramp():
    with pytest.raises(ValueError):
        Segment(10.0, ramp=6.0).ramp_s
    assert Segment(10.0).ramp_s == 2.0
    assert DEG > 0


@pytest.mark.parametrize('options', [MechanizationOptions(), MechanizationOptions.stationary(),
                                     MechanizationOptions.stationary(coriolis=True),
                                     MechanizationOptions(transport_rate=False)],
                         ids=['full', 'stationary', 'stationary-coriolis', 'no-transport'])
def test_compiled_run_equals_the_per_sample_reference(options):
    """``Strapdown.run`` (compiled kernel, issue 22) against ``update`` sample by sample.

    2500 samples of a swaying, heaving ship underway with biased, noisy sensors, across a
    re-orthonormalisation (every 1000 steps) and a varying ``dt``; the state left behind
    must continue identically, and the input arrays must not be written.
    """
    traj = Trajectory(45.7796, 126.6705, 10.0, heading_deg=45.0, speed=8.0,
                      sway=TRAJECTORIES['sway'].sway)
    spec = ImuSpec(gyro_bias_dph=5.0, gyro_arw_dpsh=0.1, accel_bias_ug=500.0,
                   accel_vrw_ug_rthz=50.0)
    sim = ImuSimulator(traj, spec, 100.0, seed=7)
    e0, v0, p0 = sim.initial_truth()
    c = sim.next_chunk(2500)
    dt = 0.01 * (1.0 + 0.1 * np.sin(np.arange(2500)))
    dtheta, dv = c.dtheta.copy(), c.dv.copy()
    C0 = rotvec_to_dcm(np.array([0.01, -0.02, 0.3])) @ euler_to_dcm(e0)
    ref = Strapdown(C0, v0, *p0, options=options)
    C_ref = np.empty((2500, 3, 3))
    V_ref, P_ref = np.empty((2500, 3)), np.empty((2500, 3))
    for k in range(2500):
        ref.update(dtheta[k], dv[k], dt[k])
        C_ref[k], V_ref[k], P_ref[k] = ref.C_b_n, ref.v_n, ref.position
    fast = Strapdown(C0, v0, *p0, options=options)
    out = fast.run(dtheta[:1500], dv[:1500], dt[:1500])
    rest = fast.run(dtheta[1500:], dv[1500:], dt[1500:])
    C = np.concatenate([out['C_b_n'], rest['C_b_n']])
    V = np.concatenate([out['v_n'], rest['v_n']])
    P = np.concatenate([out['pos'], rest['pos']])
    att, vel, latlon, height = recurrence_bounds(2500, dv, dt, V_ref, np.abs(P_ref[:, 2]).max())
    np.testing.assert_allclose(C, C_ref, rtol=0, atol=att)
    np.testing.assert_allclose(V, V_ref, rtol=0, atol=vel)
    np.testing.assert_allclose(P[:, :2], P_ref[:, :2], rtol=0, atol=latlon)
    np.testing.assert_allclose(P[:, 2], P_ref[:, 2], rtol=0, atol=height)
    # the last step's specific-force increment: one DCM (20) times dv (5)
    np.testing.assert_allclose(fast.dv_sf, ref.dv_sf, rtol=0,
                               atol=roundoff(25, np.abs(dv).max()) + att * np.abs(dv).max())
    assert fast._steps == ref._steps == 2500
    np.testing.assert_array_equal(dtheta, c.dtheta)      # inputs untouched
    np.testing.assert_array_equal(dv, c.dv)
    assert np.abs(V_ref[-1] - V_ref[0]).max() > 0.1      # the state really moved


def test_compiled_run_as_step_equals_scalar_steps_and_mixes_with_them():
    """``run(as_step=True)`` is ``step``'s arithmetic (its Earth-term cache): a block, some
    single steps and another block give what 3000 single steps give, to round-off (the
    filters run blocks in the replay and single steps in the live node)."""
    traj = Trajectory(45.7796, 126.6705, 10.0, heading_deg=45.0, speed=30.0,
                      sway=TRAJECTORIES['sway'].sway)
    sim = ImuSimulator(traj, ImuSpec(gyro_bias_dph=5.0, accel_bias_ug=500.0), 100.0, seed=3)
    e0, v0, p0 = sim.initial_truth()
    c = sim.next_chunk(3000)
    ref = Strapdown(euler_to_dcm(e0), v0, *p0)
    C_ref = np.array([ref.step(c.dtheta[k], c.dv[k], 0.01).copy() for k in range(3000)])
    mix = Strapdown(euler_to_dcm(e0), v0, *p0)
    a = mix.run(c.dtheta[:1200], c.dv[:1200], 0.01, as_step=True)
    single = [mix.step(c.dtheta[k], c.dv[k], 0.01).copy() for k in range(1200, 1300)]
    b = mix.run(c.dtheta[1300:], c.dv[1300:], 0.01, as_step=True)
    C = np.concatenate([a['C_b_n'], single, b['C_b_n']])
    att, vel, latlon, height = recurrence_bounds(3000, c.dv, 0.01, c.v_n, abs(ref.position[2]))
    np.testing.assert_allclose(C, C_ref, rtol=0, atol=att)
    np.testing.assert_allclose(mix.v_n, ref.v_n, rtol=0, atol=vel)
    np.testing.assert_allclose(mix.position[:2], ref.position[:2], rtol=0, atol=latlon)
    np.testing.assert_allclose(mix.position[2], ref.position[2], rtol=0, atol=height)
    dv_sf = roundoff(25, np.abs(c.dv).max()) + att * np.abs(c.dv).max()   # as above
    np.testing.assert_allclose(mix.dv_sf, ref.dv_sf, rtol=0, atol=dv_sf)
    np.testing.assert_allclose(b['dv_sf'][-1], ref.dv_sf, rtol=0, atol=dv_sf)


def test_stationary_compiled_run_equals_the_vectorised_one():
    """``StationaryStrapdown.run`` (compiled loop) and ``run_vectorised`` (numpy prefix
    products, the path without numba) on a swaying still base, in filter-sized blocks."""
    from sins_align_ros.nav.mechanization import StationaryStrapdown
    sim = ImuSimulator(TRAJECTORIES['sway'], ImuSpec(gyro_bias_dph=0.5, accel_bias_ug=100.0,
                                                     accel_vrw_ug_rthz=20.0), 100.0, seed=2)
    e0, _, p0 = sim.initial_truth()
    c = sim.next_chunk(3000)
    for coriolis in (False, True):
        a = StationaryStrapdown(euler_to_dcm(e0), *p0, coriolis=coriolis)
        b = StationaryStrapdown(euler_to_dcm(e0), *p0, coriolis=coriolis)
        for i in range(0, 3000, 10):
            ra = a.run(c.dtheta[i:i + 10], c.dv[i:i + 10], 0.01)
            rb = b.run_vectorised(c.dtheta[i:i + 10], c.dv[i:i + 10], 0.01)
            # numpy's prefix products (a tree of up to log2(10) + 1 products) against the
            # loop: both carry i + 10 steps from the start
            att, vel, _, _ = recurrence_bounds(i + 10, c.dv[:i + 10], 0.01, rb['v_n'], 0.0)
            np.testing.assert_allclose(ra['C_b_n'], rb['C_b_n'], rtol=0, atol=att)
            np.testing.assert_allclose(ra['v_n'], rb['v_n'], rtol=0, atol=vel)
        assert a._steps == b._steps == 3000
