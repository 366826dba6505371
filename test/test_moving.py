"""Moving-base alignment (seed 000): model batch form, fast mechanization, ASCKF pieces,
the pipeline on the simulated ship against truth, and the fog_mems car recording."""
from types import SimpleNamespace

import numpy as np
import pytest

from conftest import shared_data
from sins_align_ros.align.engines.moving import MovingBaseAlignment, true_specific_force
from sins_align_ros.align.pipeline import AlignmentPipeline
from sins_align_ros.eval.feed import feed_arrays
from sins_align_ros.filters.adaptive import SageHusa
from sins_align_ros.filters.asckf import ASCKF
from sins_align_ros.filters.cubature import CubatureUpdate, batched
from sins_align_ros.models import large_azimuth as la
from sins_align_ros.nav.frames import attitude_error, euler_to_dcm, orthonormalize, quat_to_dcm
from sins_align_ros.nav.mechanization import Strapdown
from sins_align_ros.sim.presets import noise_window, scenario
from sins_align_ros.sim.scenario import ScenarioStream
from sins_align_ros.units import ARCMIN, DEG, DPH, DPSH, UG
from tolerance import assert_roundoff, roundoff

MARINE = {'gyro_bias_dph': 0.003, 'gyro_arw_dpsh': 0.0005, 'accel_bias_ug': 30.0,
          'accel_vrw_ug_rthz': 5.0, 'gnss_pos_sigma_m': 0.2}


def test_model_on_a_batch_of_states_equals_column_by_column():
    rng = np.random.default_rng(3)
    scale = np.r_[0.1, 0.1, 3, 3, 1e-3, 1e-3, 2.0, 1e-7, 1e-7, 1e-7]
    X = rng.normal(size=(10, 20)) * scale[:, None]
    f_n, v_n = np.array([0.3, -0.2, 9.8]), np.array([5.0, 3.0, 0.1])
    batch = la.propagate(X, f_n, v_n, 0.8, 10.0, 1.0)
    cols = np.column_stack([la.propagate(X[:, i], f_n, v_n, 0.8, 10.0, 1.0) for i in range(20)])
    # a 10-term dot product per entry (19 operations, numpy's matrix product against the
    # column's), on terms up to the model's largest coefficient (g = 9.8) x the state
    assert_roundoff(batch, cols, 20, 10.0 * np.abs(X).max())


def test_scalar_mechanization_step_equals_update():
    rng = np.random.default_rng(4)
    a = Strapdown(np.eye(3), np.array([5.0, 5.0, 0.2]), 0.8, 2.2, 10.0)
    b = Strapdown(np.eye(3), np.array([5.0, 5.0, 0.2]), 0.8, 2.2, 10.0)
    for _ in range(3000):
        dth = rng.normal(size=3) * 1e-3
        dv = np.array([0.001, 0.002, 0.098]) + rng.normal(size=3) * 1e-2
        a.update(dth, dv, 0.01)
        b.step(dth, dv, 0.01)
    np.testing.assert_allclose(b.C_b_n, a.C_b_n, atol=1e-10)
    np.testing.assert_allclose(b.v_n, a.v_n, atol=1e-6)
    np.testing.assert_allclose(b.dv_sf, a.dv_sf, atol=1e-9)
    assert abs(b.lat - a.lat) * 6.4e6 < 1e-3 and abs(b.h - a.h) < 1e-3


def test_sage_husa_updates_only_the_measured_block_and_respects_its_ceiling():
    R0 = np.diag([0.04, 0.04, 0.01, 0.01])
    sh = SageHusa(np.eye(2), R0, b=0.5, gate=False, adapt_q=False, r_ceiling=100.0)
    y = np.array([50.0, -50.0])
    upd = CubatureUpdate(y=y, z_pred=np.zeros(2), Pzz=np.eye(2), Pxz=np.zeros((2, 2)),
                         K=np.zeros((2, 2)), eta=np.zeros((2, 4)), chi=np.zeros((2, 4)))
    for _ in range(20):
        _, R = sh.update(upd, idx=np.array([0, 1]))
    np.testing.assert_array_equal(R[2:, 2:], R0[2:, 2:])
    # the ceiling's scaling (a few operations) and LAPACK's 2x2 eigenvalues (~20): met to
    # round-off of the ceiling's size
    ceiling = 100.0 * np.trace(R0) / 4
    assert np.linalg.eigvalsh(R[:2, :2]).max() <= ceiling + roundoff(25, ceiling)


def test_sage_husa_takes_a_lent_variance_for_state_uncertainty_not_for_noise():
    """A variance lent for the epoch (a lever arm's share of the attitude uncertainty) is
    taken out of the innovation like H P H^T: the estimate stays the receiver's, and a row
    the loan dominates is not identifiable."""
    R0 = np.diag([1.0, 1.0])

    def update(y, lent, **kw):
        """One update of a fresh estimator weighing the epoch fully (d = 1)."""
        upd = CubatureUpdate(y=np.array(y), z_pred=np.zeros(2), Pzz=np.eye(2) * 4.0,
                             Pxz=np.zeros((2, 2)), K=np.zeros((2, 2)), eta=np.zeros((2, 2)),
                             chi=np.zeros((2, 4)))
        sh = SageHusa(np.eye(2), R0, b=0.5, gate=False, adapt_q=False, r_ceiling=100.0,
                      prior_epochs=0.0, **kw)
        return sh.update(upd, lent=np.array(lent))[1]

    R = update([2.0, 2.0], [0.0, 1.5], r_when_identifiable=True)
    assert R[0, 0] == pytest.approx(4.0)              # row 0: all of y^2 is the noise
    assert R[1, 1] == 1.0                             # row 1: the loan dominates, untouched
    R = update([2.0, 0.0], [1.5, 0.0])                # eq. 39 on the block
    assert R[0, 0] == pytest.approx(2.5) and R[0, 1] == 0.0


def test_asckf_subset_update_with_all_rows_equals_the_full_update():
    rng = np.random.default_rng(5)
    P0 = np.diag([1.0, 2.0, 0.5])
    Q, R = np.eye(3) * 0.01, np.diag([0.1, 0.2])
    H = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 1.0]])
    fx = batched(lambda X: X * 0.99)
    hx = batched(lambda X: H @ X)
    a = ASCKF(np.zeros(3), P0, Q, R)
    b = ASCKF(np.zeros(3), P0, Q, R)
    for _ in range(10):
        z = rng.normal(size=2)
        a.step(fx, z, hx)
        b.step(fx, z, hx, idx=np.array([0, 1]))
    # the same rows taken through the subset path: 10 square-root CKF steps of n = 3
    # (~100 operations each, test_filters.STEP_OPS), through the innovation solve
    cond = np.linalg.cond(a.last.Pzz)
    assert_roundoff(b.x, a.x, 10 * 100, np.abs(a.x).max(), cond)
    assert_roundoff(b.P, a.P, 10 * 100, np.abs(P0).max(), cond)


def _ship(seconds, seed=1):
    sc = scenario('seed000_case1', duration=seconds)
    return ScenarioStream(sc, seed=seed).next_block(int(seconds * sc.imu_rate_hz))


@pytest.mark.parametrize('fine_filter,ship_heading',
                         [('ckf', 45.0), ('asckf', 45.0), ('asckf', 225.0)])
def test_ship_pipeline_coarse_plus_fine_reaches_arcminutes_against_truth(fine_filter,
                                                                         ship_heading):
    """Seed 000 ship, 600 s: i0 + GNSS track coarse, large-azimuth fine filter.

    The ship heading 225 deg is 180 deg from the seed's: the pipeline starts from
    whatever the ship is doing.
    """
    sc = scenario('seed000_case1', duration=600.0)
    sc.trajectory.heading_deg = ship_heading
    b = ScenarioStream(sc, seed=1).next_block(int(600.0 * sc.imu_rate_hz))
    p = AlignmentPipeline({'fine_filter': fine_filter, **MARINE})
    p.start_clock(0.0)
    out = feed_arrays(p, b.imu, b.gnss, use_velocity=False)
    assert list(dict.fromkeys(out.phase))[:2] == ['coarse', 'fine']
    st = p.status()
    assert st['coarse_heading_source'] == 'gnss_track'
    assert st['gnss_used'] >= 530 and st['gnss_late'] == 0
    err = attitude_error(quat_to_dcm(out.q[-1]), euler_to_dcm(b.imu.euler[-1]))
    sig = np.sqrt(np.diag(out.P_phi[-1]))
    assert np.all(np.abs(err[:2]) < 1.0 * ARCMIN), err / ARCMIN
    assert abs(err[2]) < 3.0 * ARCMIN, err / ARCMIN
    assert np.all(np.abs(err) <= 3.0 * sig + 0.2 * ARCMIN), (err / ARCMIN, sig / ARCMIN)
    if fine_filter == 'asckf':
        assert len(st['fading_factors']) == p.engine.n and len(st['R_diag']) == 2
        assert 0 <= st['fading_epochs'] <= st['filter_updates']


@pytest.mark.parametrize('name', ['static_navigation', 'ship_sway'])
def test_coarse_on_a_base_that_does_not_translate_ignores_gnss_velocity_noise(name):
    """GNSS-aided filters on a still or moored base: the coarse heading comes from the
    IMU alone (velocity constant within its noise), not from noisy velocity changes:
    0.05 m/s on the first velocity used to turn it by ~6 deg under a 0.5 deg sigma."""
    from sins_align_ros.sim.presets import alignment_params
    sc = scenario(name, duration=62.0)
    b = ScenarioStream(sc, seed=1000).next_block(6200)
    p = AlignmentPipeline(alignment_params(sc, 'asckf'))
    p.start_clock(0.0)
    out = feed_arrays(p, b.imu, b.gnss)
    assert p.coarse_info['steady_velocity'] is True
    k = np.flatnonzero(out.phase != 'coarse')[0]           # fine, or aligned at once
    phi = attitude_error(quat_to_dcm(out.q[k]), euler_to_dcm(b.imu.euler[k]))
    assert abs(phi[2]) < 10 * ARCMIN                        # was 367' on static_navigation
    assert abs(phi[2]) < 3 * out.sigma[k, 2]


def test_coarse_weighs_gnss_velocity_with_the_covariance_the_filter_uses():
    """ckf takes R from the receiver's reported covariances (right here); configured
    GNSS sigmas ten times smaller made the coarse stage take the still base's noisy GNSS
    velocities for a velocity change and start 6 deg off in heading under a 1.2 deg
    sigma (integrity matrix, static navigation grade told optimistic)."""
    from sins_align_ros.sim.presets import alignment_params
    sc = scenario('static_navigation', duration=62.0)
    b = ScenarioStream(sc, seed=1000).next_block(6200)
    prm = alignment_params(sc, 'ckf')
    p = AlignmentPipeline({**prm, 'gnss_pos_sigma_m': 0.1, 'gnss_vel_sigma_mps': 0.005,
                           'sensor_self_check': False})
    p.start_clock(0.0)
    out = feed_arrays(p, b.imu, b.gnss)
    assert p.coarse_info['steady_velocity'] is True
    k = np.flatnonzero(out.phase != 'coarse')[0]           # fine, or aligned at once
    phi = attitude_error(quat_to_dcm(out.q[k]), euler_to_dcm(b.imu.euler[k]))
    assert abs(phi[2]) < 10 * ARCMIN, phi / ARCMIN


def test_seed000_engine_caps_a_wide_heading_prior_and_publishes_the_coarse_one():
    """A 60 deg coarse heading sigma: the cubature filter gets 45 deg (13 states: points
    within +-162 deg, inside the circle), the published heading variance is the coarse
    one until GNSS has told the filter something."""
    from sins_align_ros.align.engines.prior_shaping import HEADING_PRIOR_MAX
    P0 = np.diag(np.r_[[0.1 ** 2] * 2, [2.0 ** 2] * 2, [(0.5 * DEG) ** 2] * 2,
                       (60.0 * DEG) ** 2, [(1.0 * DPH) ** 2] * 3])
    eng = MovingBaseAlignment(np.eye(3), np.zeros(3), 0.5, 2.0, 0.0, P0, np.zeros(10),
                              np.eye(2), accel_bias=300 * UG)
    assert eng.n == 13 and eng.kf.P[6, 6] == pytest.approx(HEADING_PRIOR_MAX ** 2)
    assert eng.heading_prior_var == pytest.approx((60.0 * DEG) ** 2)
    assert eng.attitude_cov()[2, 2] == pytest.approx((60.0 * DEG) ** 2)
    assert eng.attitude_cov()[0, 0] == pytest.approx((0.5 * DEG) ** 2)


@pytest.mark.parametrize('heading_err_deg, tol_arcmin', [(30.0, 10.0), (180.0, 15.0)])
def test_fine_filter_recovers_a_large_heading_error(heading_err_deg, tol_arcmin):
    """Seed 000 ship, fine filter alone started 30/180 deg off in heading: arcminutes at 600 s.

    (From 90 deg with a 90 deg sigma it fails in some seeds, bench/moving_base.py
    section 3a: the cubature points spread over +-5 rad of heading.) The filter is given
    at most a 45 deg heading sigma (``prior_shaping.capped_heading_prior``), which slows the
    recovery from 180 deg (2.4' -> 10.2' at 600 s) but keeps the points inside the circle.
    """
    b = _ship(600.0, seed=2)
    phi0 = np.array([0.03, 0.03, heading_err_deg]) * DEG
    P0 = np.diag(np.r_[[0.1 ** 2] * 2, [2.0 ** 2] * 2, [(0.06 * DEG) ** 2] * 2,
                       (heading_err_deg * DEG) ** 2, [(0.003 * DPH) ** 2] * 3])
    Qc = np.r_[[(5e-6 * 9.8) ** 2] * 2, 0, 0, [(0.0005 * DPSH) ** 2] * 3, 0, 0, 0]
    eng = MovingBaseAlignment(la.C_n_nprime(phi0) @ euler_to_dcm(b.imu.euler[0]),
                              b.imu.v_n[0], *b.imu.pos[0], P0, Qc, np.eye(2) * 0.04)
    eng.feed(b.imu, b.gnss, b.imu.t[0])
    phi = la.misalignment_of(eng.mech.C_b_n, euler_to_dcm(b.imu.euler[-1]))
    assert abs(phi[2]) < tol_arcmin * ARCMIN, phi / ARCMIN
    assert np.all(np.abs(phi[:2]) < 1.0 * ARCMIN), phi / ARCMIN


def test_asckf_learns_a_gnss_noise_rise_over_the_manoeuvre_where_the_ckf_is_misled():
    """Issue 4 target 2 in small: Q 9x the truth, GNSS noise 10x from 30 to 330 s, over the
    0.1 g burst at 60 s that makes the heading observable (bench/moving_base.py 2b).

    The CKF trusts its nominal R, takes the noise as heading information and ends far
    outside its own sigma; the ASCKF learns R and keeps the heading within its sigma and
    under half the CKF's error (seed 1: CKF -20.8', ASCKF -0.7').
    """
    seconds = 400.0
    sc = scenario('seed000_case1', duration=seconds)
    sc.extra['gnss_noise_profile'] = noise_window(30.0, 330.0, 10.0, seconds)
    b = ScenarioStream(sc, seed=1).next_block(int(seconds * sc.imu_rate_hz))
    phi0 = np.array([0.03, 0.03, 0.35]) * DEG
    sig0 = np.array([0.06, 0.06, 1.0]) * DEG                 # consistent with phi0
    P0 = np.diag(np.r_[[0.1 ** 2] * 2, [2.0 ** 2] * 2, sig0 ** 2, [(0.003 * DPH) ** 2] * 3])
    Qc = 9.0 * np.r_[[(5 * UG) ** 2] * 2, 0, 0, [(0.0005 * DPSH) ** 2] * 3, 0, 0, 0]
    R = np.eye(2) * 0.2 ** 2
    err, sig = {}, {}
    for name, improved in (('ckf', False), ('asckf', True)):
        eng = MovingBaseAlignment(la.C_n_nprime(phi0) @ euler_to_dcm(b.imu.euler[0]),
                                  b.imu.v_n[0], *b.imu.pos[0], P0, Qc, R, square_root=improved,
                                  fading=improved, adaptive=improved)
        eng.feed(b.imu, b.gnss, b.imu.t[0])
        err[name] = la.misalignment_of(eng.mech.C_b_n, euler_to_dcm(b.imu.euler[-1]))[2]
        sig[name] = np.sqrt(eng.attitude_cov()[2, 2])
        if improved:
            assert eng.kf.R[0, 0] > 4.0 * R[0, 0]              # learned the larger noise
    assert abs(err['ckf']) > 3.0 * sig['ckf'], err            # misled, and over-confident
    assert abs(err['asckf']) < 0.5 * abs(err['ckf']), err
    assert abs(err['asckf']) < 3.0 * sig['asckf'], (err, sig)


def test_fog_mems_car_recording_heading_against_the_fog_reference():
    """Real car data: MEMS IMU aided by the FOG-INS position/velocity, 100 s."""
    from sins_align_ros.io.fog import read_fog_mems
    imu_path, ref_path = shared_data('fog_mems_imu.csv'), shared_data('fog_mems_reference.csv')
    rec = read_fog_mems(imu_path, ref_path)
    p = AlignmentPipeline({'fine_filter': 'asckf', 'gyro_bias_dph': 200.0,
                           'gyro_arw_dpsh': 1.0, 'accel_bias_ug': 2000.0,
                           'accel_vrw_ug_rthz': 200.0, 'coarse_duration': 10.0,
                           'gnss_pos_sigma_m': 0.5, 'gnss_vel_sigma_mps': 0.05})
    p.start_clock(rec.t[0] - 0.01)
    out = feed_arrays(p, rec.imu_like(), rec.gnss_like())
    e = rec.errors(out)
    assert e['t'] == pytest.approx(100.0, abs=0.02)
    # measured 2026-11-22: heading +1.70 deg (sigma 2.05), roll -0.10, pitch -0.37 deg
    assert abs(e['heading']) < 2.5 and abs(e['heading']) < 3.0 * e['sigma_yaw']
    assert abs(e['roll']) < 0.4 and abs(e['pitch']) < 0.6
    assert p.status()['coarse_velocity_source'] == 'gnss_velocity'


def test_moving_filter_without_gnss_runs_unaided_and_says_so():
    b = _ship(120.0)
    p = AlignmentPipeline({'fine_filter': 'asckf', **MARINE})
    p.start_clock(0.0)
    out = feed_arrays(p, b.imu, None)
    assert np.all(np.isfinite(out.q[-1]))
    st = p.status()
    assert st['gnss_used'] == 0 and st['predict_only_epochs'] >= 25
    assert any('no GNSS velocity' in w for w in p.warnings)
    # the published covariance follows every epoch without GNSS (it was held at its value
    # of the last GNSS epoch, i.e. frozen through an outage)
    k = int(np.argmax(out.phase == 'fine'))
    tr = np.trace(out.P_phi[k:], axis1=1, axis2=2)
    assert len(np.unique(tr)) >= 25


def test_a_diverged_filter_restarts_alignment_and_says_so():
    """Wrong noise statistics can break the ASCKF: never a crash or a NaN attitude."""
    b = _ship(200.0)
    p = AlignmentPipeline({'fine_filter': 'asckf', **MARINE})
    p.start_clock(0.0)
    feed_arrays(p, _imu_slice(b.imu, 0, 6100), b.gnss)
    assert p.engine is not None
    p.restart_from_coarse('filter diverged at t=61.000 s (test)')
    assert p.phase == 'waiting' and p.engine is None
    out = feed_arrays(p, _imu_slice(b.imu, 6100, 20000), None)
    assert list(dict.fromkeys(out.phase))[:2] == ['coarse', 'fine']
    assert np.all(np.isfinite(out.q[-1]))
    assert any('alignment restarted from coarse' in w for w in p.warnings)


def _imu_slice(imu, a, b):
    return SimpleNamespace(t=imu.t[a:b], dtheta=imu.dtheta[a:b], dv=imu.dv[a:b])


def test_reported_gnss_variances_are_used_only_when_finite_and_positive():
    p = AlignmentPipeline({'fine_filter': 'asckf', **MARINE})
    for bad in [(0.0, 0.04), (np.nan, 0.04), (-1.0, 0.04), (np.inf, 0.04), None]:
        p.position_fix(1.0, 45.0, 126.0, 0.0, pos_var=bad)
        p.velocity_fix(1.0, [1.0, 0.0, 0.0], vel_var=bad)
        assert p.gnss.fixes[-1][4] is None and p.gnss.vels[-1][2] is None
    p.position_fix(2.0, 45.0, 126.0, 0.0, pos_var=(0.04, 0.09))
    p.velocity_fix(2.0, [1.0, 0.0, 0.0], vel_var=(0.01, 0.02))
    np.testing.assert_array_equal(p.gnss.fixes[-1][4], [0.04, 0.09])
    np.testing.assert_array_equal(p.gnss.vels[-1][2], [0.01, 0.02])


def test_gyro_bias_instability_lets_the_drift_states_follow_a_markov_bias():
    """The drift states get the random walk 2 sigma^2 / tau of the configured Gauss-Markov
    gyro bias; the total 1-sigma bias (constant and varying) sets their P0."""
    from sins_align_ros.sim.presets import alignment_params
    sc = scenario('seed003_car', duration=70.0)
    cfg = alignment_params(sc, 'ckf')
    assert (cfg['gyro_bias_dph'], cfg['gyro_bias_instability_dph'],
            cfg['gyro_bias_tau_s']) == (200.0, 50.0, 300.0)
    b = ScenarioStream(sc, seed=1).next_block(7000)
    p = AlignmentPipeline(cfg)
    p.start_clock(0.0)
    feed_arrays(p, b.imu, b.gnss)
    # 2 sigma^2 / tau from the degrees-per-hour figures: ~6 operations, relative
    assert_roundoff(p.engine.Qc[7:10], 2.0 * (50.0 * DPH) ** 2 / 300.0, 6)
    assert p.noise.gyro_bias == pytest.approx(np.hypot(200.0, 50.0) * DPH)


def _turning_ship(nab):
    """60 s at 100 Hz of a swaying ship turning at 1.5 deg/s, accelerometer bias ``nab``.

    Returns ``(trajectory, samples, initial truth (euler, v_n, position), phi0)`` with
    ``phi0`` a 30 deg heading error and 0.03 deg tilts.
    """
    from sins_align_ros.sim.imu import ImuSimulator, ImuSpec
    from sins_align_ros.sim.presets import SEED000_SWAY
    from sins_align_ros.sim.trajectory import Segment, Trajectory
    traj = Trajectory(45.78, 126.67, 0.0, heading_deg=45.0, speed=8.0,
                      segments=[Segment(60.0, turn_rate=1.5, ramp=5.0)], sway=SEED000_SWAY)
    sim = ImuSimulator(traj, ImuSpec(accel_bias_ug=nab / UG), 100.0)
    truth = sim.initial_truth()
    return traj, sim.next_chunk(6000), truth, np.array([0.03, 0.03, 30.0]) * DEG


def test_accel_bias_states_predict_the_mechanization_errors_in_a_turn():
    """13-state model: a body-axis accelerometer bias turns with the vehicle in ENU.

    60 s of a swaying ship turning at 1.5 deg/s with a 30 deg heading error, an
    accelerometer bias alone: the 13-state model (``C~_b_n nab`` in the velocity error)
    follows the full mechanization; seed 000's 10 states miss the bias's velocity error.
    """
    from sins_align_ros.nav import earth
    from sins_align_ros.sim.imu import specific_force_n
    nab = np.array([100.0, -80.0, 60.0]) * UG
    traj, c, (e0, v0, p0), phi0 = _turning_ship(nab)
    out = Strapdown(la.C_n_nprime(phi0) @ euler_to_dcm(e0), v0, *p0).run(c.dtheta, c.dv, 0.01)
    x10, x13 = np.r_[0, 0, 0, 0, phi0, 0, 0, 0], np.r_[0, 0, 0, 0, phi0, 0, 0, 0, nab]
    for k in range(9, 6000, 10):                       # 10 Hz model steps, truth at mid-step
        km = traj.kinematics(c.t[k] - 0.05)
        lat, h, v = c.pos[k, 0], c.pos[k, 2], km.v_n[0]
        f_n = specific_force_n(km, lat, h)[0]
        x10 = la.propagate(x10, f_n, v, lat, h, 0.1)
        x13 = la.propagate(x13, f_n, v, lat, h, 0.1, C_b_n=out['C_b_n'][k - 5])
    dv = out['v_n'][-1, :2] - c.v_n[-1, :2]
    dp = earth.local_offset_m(*c.pos[-1], *out['pos'][-1])[:2]
    phi = la.misalignment_of(out['C_b_n'][-1], euler_to_dcm(c.euler[-1]))
    assert x13[0:2] == pytest.approx(dv, abs=2e-3)     # measured: 1e-4 m/s
    assert x13[2:4] == pytest.approx(dp, abs=0.05)
    assert x13[4:7] == pytest.approx(phi, abs=2e-5)
    np.testing.assert_array_equal(x13[10:], nab)       # a random constant
    assert np.abs(x10[0:2] - dv).max() > 0.02          # the bias's share: 0.03-0.06 m/s


def test_the_model_takes_the_mechanizations_specific_force_as_the_engine_gives_it():
    """13 states fed the computed specific force (the engine's ``dv_sum / T``).

    A MEMS-size bias (5 mg) and a 30 deg heading error on a turning, swaying ship: through
    ``moving.true_specific_force`` the model follows the full mechanization; reading the
    computed force as the true one adds heading error x bias to the velocity error, which
    the mechanization does not have.
    """
    nab = np.array([5000.0, -4000.0, 3000.0]) * UG
    _, c, (e0, v0, p0), phi0 = _turning_ship(nab)
    m = Strapdown(la.C_n_nprime(phi0) @ euler_to_dcm(e0), v0, *p0)
    x_c = x_t = np.r_[0, 0, 0, 0, phi0, 0, 0, 0, nab]
    for k0 in range(0, 6000, 10):                      # 10 Hz model steps
        dv_sum, C_sum = np.zeros(3), np.zeros((3, 3))
        for k in range(k0, k0 + 10):
            C_sum += m.step(c.dtheta[k], c.dv[k], 0.01)
            dv_sum += m.dv_sf
        f_c, C = dv_sum / 0.1, orthonormalize(C_sum / 10)
        lat, h, v = m.lat, m.h, m.v_n
        x_c = la.propagate(x_c, true_specific_force(f_c, C, x_c), v, lat, h, 0.1, C_b_n=C)
        x_t = la.propagate(x_t, f_c, v, lat, h, 0.1, C_b_n=C)
    dv = m.v_n[:2] - c.v_n[-1, :2]
    phi = la.misalignment_of(m.C_b_n, euler_to_dcm(c.euler[-1]))
    assert x_c[0:2] == pytest.approx(dv, abs=0.01)     # measured: 3e-3 m/s
    assert x_c[4:7] == pytest.approx(phi, abs=2e-5)
    assert np.abs(x_t[0:2] - dv).max() > 0.5           # heading error x bias: 2.45 m/s


def _underway_run(seed, accel_bias):
    """Seed 000 engine (ASCKF, GNSS position) on ship_underway, 600 s, 50 Hz IMU.

    Starts from a coarse-like error (0.1, 0.1, 1 deg; sigma twice that); returns the
    engine and, every second, the misalignment and its 1-sigma (rad, (600, 3) each).
    """
    from sins_align_ros.align.engines.moving import model_noise
    from sins_align_ros.models.stationary import NoiseSpec
    sc = scenario('ship_underway')
    b = ScenarioStream(sc, seed=seed, imu_rate_hz=50.0).next_block(int(sc.duration * 50))
    noise = NoiseSpec(gyro_bias=0.003 * DPH, gyro_arw=0.0005 * DPSH, accel_bias=30.0 * UG,
                      accel_vrw=5.0 * UG)                       # the marine grade, as set
    phi0 = np.array([0.1, 0.1, 1.0]) * DEG
    P0, Qc = model_noise(2.0 * phi0, 0.1, 0.5, noise, 0.0, accel_bias=accel_bias)
    eng = MovingBaseAlignment(la.C_n_nprime(phi0) @ euler_to_dcm(b.imu.euler[0]),
                              b.imu.v_n[0], *b.imu.pos[0], P0, Qc, np.eye(2) * 0.5 ** 2)
    phi, sig = [], []
    ends = np.r_[0, np.arange(25, len(b.imu.t), 50)]   # half-way between fixes
    for k0, k1 in zip(ends[:-1], ends[1:]):
        sl = slice(k0, k1 + 1)
        eng.feed(SimpleNamespace(t=b.imu.t[sl], dtheta=b.imu.dtheta[sl], dv=b.imu.dv[sl]),
                 b.gnss, b.imu.t[k0])
        phi.append(la.misalignment_of(eng.mech.C_b_n, euler_to_dcm(b.imu.euler[k1])))
        sig.append(np.sqrt(np.diag(eng.attitude_cov())))
    return eng, np.array(phi[1:]), np.array(sig[1:])


def test_turning_ship_asckf_with_accel_bias_states_stays_inside_its_sigma():
    """Issue 21: the ship turns 90 deg and back (ship_underway); the ASCKF with the 13-state
    model (accelerometer bias) ends inside 3 sigma with the heading within 2.5', every 1-s
    sample inside 3 sigma, and a sigma that is not uselessly wide; it finds the bias.

    Seed 000's 10 states on the same data take the bias, turning with the ship, for tilt
    and heading: the north tilt leaves its sigma (bench/results/moving_base_integrity.md).
    """
    eng, phi, sig = _underway_run(1, accel_bias=True)
    assert eng.has_accel_bias and eng.n == 13 and eng.sums.attitude
    r = np.abs(phi) / sig
    assert abs(phi[-1, 2]) < 2.5 * ARCMIN, phi[-1] / ARCMIN
    assert np.all(r[-1] <= 3.0), (phi[-1] / ARCMIN, sig[-1] / ARCMIN)
    assert np.all((r <= 3.0).mean(axis=0) >= 0.95) and r.max() < 5.0, r.max(axis=0)
    assert sig[-1, 2] < 1.0 * ARCMIN                   # measured 0.48'
    # the horizontal-axis biases are found (30 ug each, the marine grade's constant bias)
    nab, s_nab = eng.kf.x[10:12], np.sqrt(np.diag(eng.kf.P)[10:12])
    assert np.all(np.abs(nab - 30.0 * UG) <= 3.0 * s_nab) and np.all(s_nab < 5.0 * UG)
    assert eng.status()['accel_bias_ug'][0] == pytest.approx(nab[0] / UG)

    eng10, phi10, sig10 = _underway_run(1, accel_bias=False)
    assert not eng10.has_accel_bias and eng10.n == 10
    r10 = np.abs(phi10) / sig10
    assert (r10[:, 1] <= 3.0).mean() < 0.9 and r10.max() > 5.0, r10.max(axis=0)


def test_turning_ship_through_the_pipeline_asckf_stays_inside_its_sigma():
    """Issue 21 must-show through the pipeline: ship_underway (90 deg turn and back, 600 s,
    seed 1), ASCKF with the scenario's sensor parameters: the 13-state engine, final heading
    within 2.5' and inside 3 sigma, every 1-s sample after coarse inside 3 sigma."""
    from sins_align_ros.eval.run import run_scenario
    from sins_align_ros.nav.frames import euler_error
    run = run_scenario('ship_underway', 1, 'asckf', use_velocity=True)
    assert run.pipeline.engine.has_accel_bias
    out = run.out
    k = np.arange(99, len(out.t), 100)
    k = k[np.isin(out.phase[k], ('fine', 'aligned'))]
    r = np.abs(euler_error(out.euler[k], run.truth_euler[k])) / out.sigma[k]
    fe = run.final
    assert abs(fe.euler[2]) < 2.5 * ARCMIN and np.all(np.abs(fe.euler) <= 3.0 * fe.sigma)
    assert np.all((r <= 3.0).mean(axis=0) >= 0.95) and r.max() < 5.0, r.max(axis=0)
    assert fe.sigma[2] < 1.0 * ARCMIN and out.phase[-1] == 'aligned'


@pytest.mark.parametrize('seed', [1001, 1004])
def test_mems_ship_heading_sigma_covers_a_heading_the_data_cannot_find(seed):
    """Seed 000's ship with a MEMS IMU, CKF told the right model (integrity matrix runs).

    The ship runs straight with 0.01 m/s^2 of acceleration after a short burst: with a
    200 deg/h gyro the heading is not observable after the burst. Before session 23 the
    feedback's tilt-heading mixing and the force read from the filter's own errors made
    the sigma about half the error (run 1001: 30 deg off under 6 deg, 18 % of 1-s
    samples outside 3 sigma; run 1004 went the same way, 28 deg under 7 deg, with the
    force rule alone). Now: no silent-wrong run and a sigma that says the heading is
    poor (above 5 deg at the end).
    """
    from sins_align_ros.eval.integrity import run_integrity
    from sins_align_ros.eval.run import run_scenario
    run = run_scenario('seed000_case1@mems', seed, 'ckf', duration=400.0)
    r = run_integrity(run, 1.0)
    assert not r['silent'], r['why']
    assert r['end_inside']
    assert np.degrees(r['end_sigma'][2]) > 5.0
