"""Simulator: physics of the ideal IMU, error models (Allan deviation), GNSS, presets."""
import numpy as np
import pytest

from sins_align_ros.nav import earth
from sins_align_ros.nav.frames import euler_to_dcm
from sins_align_ros.sim.allan import (adev_markov, adev_quantization, adev_white,
                                      allan_deviation)
from sins_align_ros.sim.gnss import GnssErrors, GnssSpec
from sins_align_ros.sim.imu import ImuErrors, ImuSimulator, ImuSpec, simulate
from sins_align_ros.sim.presets import SCENARIOS, SENSOR_GRADES, scenario
from sins_align_ros.sim.scenario import ScenarioStream
from sins_align_ros.nav.frames import wrap_pi
from sins_align_ros.sim.trajectory import PositionIntegrator, Segment, Sway, Trajectory
from sins_align_ros.units import ARCSEC, DEG, DPH, DPSH, G0, KNOT, UG
from tolerance import assert_roundoff, roundoff

LAT = 34.0


def test_static_level_imu_reads_gravity_up_and_earth_rate():
    traj = Trajectory(LAT, 108.0, 0.0, heading_deg=0.0)       # nose north
    c = simulate(traj, ImuSpec(), 100.0, 10.0)
    f = c.dv.mean(axis=0) / 0.01
    w = c.dtheta.mean(axis=0) / 0.01
    g = earth.gravity(LAT * DEG, 0.0)
    # the exact simulator to round-off (tolerance.py): each increment is a 4-point
    # quadrature of C^T f_n / C^T w_in (~30 operations), the mean sums 1000 of them
    n_ops = len(c.dv) + 30
    assert_roundoff(f, [0.0, 0.0, g], n_ops, g)                 # +g on z (FLU, REP-145)
    assert_roundoff(np.linalg.norm(w), earth.OMEGA_IE, n_ops + 5, earth.OMEGA_IE)
    # nose north: forward gyro sees the north component, up gyro the vertical one
    assert_roundoff(w, [earth.OMEGA_IE * np.cos(LAT * DEG), 0.0,
                        earth.OMEGA_IE * np.sin(LAT * DEG)], n_ops, earth.OMEGA_IE)


def test_tilted_static_imu_rotates_gravity_into_body():
    traj = Trajectory(LAT, 108.0, 0.0, heading_deg=70.0, pitch_deg=3.0, roll_deg=-4.0)
    c = simulate(traj, ImuSpec(), 100.0, 2.0)
    C = euler_to_dcm(c.euler[0])
    g = earth.gravity(LAT * DEG, 0.0)
    # as above: 200 increments of ~30 operations summed, on g's size
    assert_roundoff(c.dv.mean(axis=0) / 0.01, C.T @ [0, 0, g], len(c.dv) + 30, g)


def test_constant_biases_and_scale_factor_appear_in_the_increments():
    spec = ImuSpec(gyro_bias_dph=[1.0, -2.0, 3.0], accel_bias_ug=[100.0, 0.0, -50.0],
                   accel_scale_ppm=1000.0)
    traj = Trajectory(LAT, 108.0, 0.0)
    ideal = simulate(traj, ImuSpec(), 100.0, 5.0)
    real = simulate(traj, spec, 100.0, 5.0)
    dw = (real.dtheta - ideal.dtheta).mean(axis=0) / 0.01
    # the bias is the difference of two simulations: the operands are the increments (Earth
    # rate, 100 x the bias), the mean sums 500 of them (+30 a sample as above)
    n_ops = len(real.dv) + 30
    assert_roundoff(dw, np.array([1.0, -2.0, 3.0]) * DPH, n_ops,
                    np.abs(real.dtheta).max() / 0.01)
    df = (real.dv - ideal.dv).mean(axis=0) / 0.01
    g = earth.gravity(LAT * DEG, 0.0)
    assert_roundoff(df, np.array([100.0, 0.0, -50.0]) * UG + [0, 0, 1e-3 * g], n_ops,
                    np.abs(real.dv).max() / 0.01)


def _noise(spec, n, dt, seed=1):
    e = ImuErrors(spec, np.random.default_rng(seed))
    return e.apply(np.zeros((n, 3)), np.zeros((n, 3)), dt)


@pytest.mark.parametrize('tau_s', [0.1, 1.0, 10.0])
def test_allan_deviation_of_white_noise_matches_arw_and_vrw(tau_s):
    """Issue 2: Allan deviation within 10% of the configured ARW and VRW."""
    dt, n = 0.01, 360_000
    spec = ImuSpec(gyro_arw_dpsh=0.05, accel_vrw_ug_rthz=50.0)
    dth, dv = _noise(spec, n, dt)
    m = [int(round(tau_s / dt))]
    tau, ad_g = allan_deviation(dth / dt, dt, m)
    _, ad_a = allan_deviation(dv / dt, dt, m)
    assert ad_g[0] == pytest.approx(adev_white(0.05 * DPSH, tau[0]), rel=0.10)
    assert ad_a[0] == pytest.approx(adev_white(50.0 * UG, tau[0]), rel=0.10)
    # ARW read off at tau = 1 s in datasheet units
    if tau_s == 1.0:
        assert ad_g[0].mean() / DPSH == pytest.approx(0.05, rel=0.10)
        assert ad_a[0].mean() / UG == pytest.approx(50.0, rel=0.10)


def test_allan_deviation_of_markov_bias_matches_closed_form():
    dt, n = 0.1, 400_000                       # 40000 s = 4000 correlation times
    spec = ImuSpec(gyro_markov_dph=1.0, gyro_markov_tau_s=10.0,
                   accel_markov_ug=200.0, accel_markov_tau_s=10.0)
    dth, dv = _noise(spec, n, dt, seed=2)
    tau, ad_g = allan_deviation(dth / dt, dt, [10, 100, 1000])
    _, ad_a = allan_deviation(dv / dt, dt, [10, 100, 1000])
    assert ad_g.mean(axis=1) == pytest.approx(adev_markov(1.0 * DPH, 10.0, tau), rel=0.10)
    assert ad_a.mean(axis=1) == pytest.approx(adev_markov(200 * UG, 10.0, tau), rel=0.10)


def test_quantization_keeps_the_remainder_and_has_its_allan_signature():
    dt, n = 0.01, 200_000
    q = 1.0                                              # arcsec LSB
    arw = 0.08                                           # dithers the counter over LSBs
    spec = ImuSpec(gyro_quant_arcsec=q, gyro_arw_dpsh=arw)
    dth, _ = _noise(spec, n, dt, seed=3)
    lsb = q * ARCSEC
    assert np.allclose(dth / lsb, np.round(dth / lsb))   # integer counts
    tau, ad = allan_deviation(dth / dt, dt, [1, 2, 4])
    white = adev_white(arw * DPSH, tau)
    expected = np.sqrt(adev_quantization(lsb, tau) ** 2 + white ** 2)
    assert ad.mean(axis=1) == pytest.approx(expected, rel=0.05)
    assert ad[0].mean() > 1.3 * white[0]         # white noise alone would not explain it
    # the carried remainder keeps the integrated angle within one LSB of the true one
    e = ImuErrors(ImuSpec(gyro_quant_arcsec=q), np.random.default_rng(0))
    ideal = np.full((1000, 3), 0.37 * lsb)
    out, _ = e.apply(ideal, np.zeros((1000, 3)), dt)
    assert np.abs(out.sum(axis=0) - ideal.sum(axis=0)).max() <= lsb


def test_random_bias_draws_per_run_and_is_seeded():
    spec = ImuSpec(gyro_bias_dph=0.01, accel_bias_ug=100.0, random_bias=True)
    a = ImuErrors(spec, np.random.default_rng(5))
    b = ImuErrors(spec, np.random.default_rng(5))
    c = ImuErrors(spec, np.random.default_rng(6))
    assert np.array_equal(a.gyro_bias, b.gyro_bias)
    assert not np.array_equal(a.gyro_bias, c.gyro_bias)
    biases = np.array([ImuErrors(spec, np.random.default_rng(s)).accel_bias
                       for s in range(2000)])
    assert biases.std() / UG == pytest.approx(100.0, rel=0.05)


def test_streaming_in_chunks_equals_one_block_and_is_deterministic():
    sc = scenario('ship_underway')
    one = ImuSimulator(sc.trajectory, sc.imu, 100.0, seed=9).next_chunk(3000)
    sim = ImuSimulator(sc.trajectory, sc.imu, 100.0, seed=9)
    parts = [sim.next_chunk(n) for n in (700, 1300, 1000)]
    ideal_one = ImuSimulator(sc.trajectory, ImuSpec(), 100.0).next_chunk(3000)
    sim_i = ImuSimulator(sc.trajectory, ImuSpec(), 100.0)
    ideal_parts = np.vstack([sim_i.next_chunk(n).dtheta for n in (700, 1300, 1000)])
    # the same quadrature (~50 operations) on each sample's own stamps; the chunks' ODE
    # positions (below) move Earth and transport rates by 1e-17 rad/s at most
    assert_roundoff(ideal_parts, ideal_one.dtheta, 50, np.abs(ideal_one.dtheta).max())
    assert np.array_equal(np.concatenate([p.t for p in parts]), one.t)
    # positions: DOP853 per chunk at rtol 1e-12 (trajectory.py), a solver bound, not round-off
    assert np.abs(np.vstack([p.pos for p in parts]) - one.pos).max() < 1e-12
    # noise draws differ in order between chunkings, but the statistics and seed do not
    again = ImuSimulator(sc.trajectory, sc.imu, 100.0, seed=9).next_chunk(3000)
    assert np.array_equal(again.dtheta, one.dtheta)


def test_gnss_white_and_markov_errors_have_configured_sigma():
    spec = GnssSpec(pos_sigma_h=2.0, pos_sigma_v=3.0, vel_sigma=0.1,
                    pos_markov_sigma=1.0, pos_markov_tau_s=50.0)
    g = GnssErrors(spec, np.random.default_rng(1))
    n = 20000
    t = np.arange(n, dtype=float)
    pos = np.tile([LAT * DEG, 2.0, 10.0], (n, 1))
    ep = g.measure(t, pos, np.zeros((n, 3)))
    assert ep.pos_err_m.std(axis=0) == pytest.approx(spec.pos_sigma, rel=0.08)
    assert ep.v_n.std(axis=0) == pytest.approx([0.1] * 3, rel=0.05)
    # the Markov part is correlated: lag-1 autocorrelation of E error ~ 1/(4+1) * e^{-1/50}
    e = ep.pos_err_m[:, 0]
    r1 = np.corrcoef(e[:-1], e[1:])[0, 1]
    assert r1 == pytest.approx(np.exp(-1 / 50) * 1.0 / 5.0, abs=0.03)
    # reported covariance is the total variance; measured lat/lon carry the error
    R_M, _ = earth.radii(LAT * DEG)
    assert (ep.lat - pos[:, 0]) * (R_M + 10.0) == pytest.approx(ep.pos_err_m[:, 1], abs=1e-6)


def test_gnss_outages_and_bernoulli_outliers():
    spec = GnssSpec(pos_sigma_h=1.0, outages=((100.0, 200.0),), outlier_prob=0.05,
                    outlier_scale=20.0)
    g = GnssErrors(spec, np.random.default_rng(2))
    n = 10000
    t = np.arange(n, dtype=float)
    ep = g.measure(t, np.tile([0.5, 0.5, 0.0], (n, 1)), np.zeros((n, 3)))
    assert not ep.fix[(t >= 100) & (t < 200)].any()
    assert ep.fix[(t < 100) | (t >= 200)].all()
    assert ep.outlier.mean() == pytest.approx(0.05, abs=0.01)
    big = np.abs(ep.pos_err_m[:, 0]) > 5.0
    assert big[~ep.outlier].mean() < 1e-3
    assert ep.pos_err_m[ep.outlier, 0].std() == pytest.approx(20.0, rel=0.1)


@pytest.mark.parametrize('name', SCENARIOS)
def test_every_scenario_preset_runs(name):
    sc = scenario(name)
    st = ScenarioStream(sc, seed=1)
    b = st.next_block(int(2 * sc.imu_rate_hz))
    assert np.all(np.isfinite(b.imu.dtheta)) and np.all(np.isfinite(b.imu.dv))
    assert (b.gnss is None) == (sc.gnss is None)
    if b.gnss is not None:                  # the epochs of 2 s at the receiver's rate
        assert len(b.gnss.t) == int(np.floor(2 * sc.gnss.rate_hz + 1e-9))
    assert sc.description


def test_scenario_overrides_and_errors():
    assert scenario('static_navigation', duration=5.0).duration == 5.0
    with pytest.raises(ValueError, match='unknown scenario'):
        scenario('nope')
    with pytest.raises(ValueError, match='no field'):
        scenario('static_navigation', bogus=1)


def test_seed002_grade_matches_paper():
    s = SENSOR_GRADES['navigation']
    assert (s.gyro_bias_dph, s.gyro_arw_dpsh, s.accel_bias_ug, s.accel_vrw_ug_rthz) == (
        0.01, 0.001, 100.0, 10.0)
    sc = scenario('seed002_5deg')
    assert sc.trajectory.lat_deg == 34.0 and sc.duration == 600.0
    assert sc.misalignment_deg == (5, 5, 5)


def test_seed000_profile_reaches_plausible_ship_speed():
    sc = scenario('seed000_case1')
    kin = sc.trajectory.kinematics(np.arange(0.0, sc.duration, 0.05))
    speed = np.hypot(kin.v_n[:, 0], kin.v_n[:, 1])
    assert speed[0] == pytest.approx(5 * KNOT, rel=1e-6)
    assert 8.0 < speed.max() < 15.0                     # about 16-29 kn, not 1400 m/s
    assert np.linalg.norm(kin.a_n, axis=1).max() == pytest.approx(0.1 * G0, rel=0.01)


def _ramp_profile_reference(tau, D, r):
    """s, S, s' of one segment at times ``tau`` (N,), as trajectory.py first wrote it."""
    s, S, ds = np.zeros_like(tau), np.zeros_like(tau), np.zeros_like(tau)
    k = np.pi / r
    up = (tau >= 0.0) & (tau < r)
    mid = (tau >= r) & (tau <= D - r)
    down = (tau > D - r) & (tau <= D)
    s[up] = 0.5 * (1.0 - np.cos(k * tau[up]))
    S[up] = 0.5 * (tau[up] - np.sin(k * tau[up]) / k)
    ds[up] = 0.5 * k * np.sin(k * tau[up])
    s[mid] = 1.0
    S[mid] = 0.5 * r + (tau[mid] - r)
    u = D - tau[down]
    s[down] = 0.5 * (1.0 - np.cos(k * u))
    S[down] = (D - r) - 0.5 * (u - np.sin(k * u) / k)
    ds[down] = -0.5 * k * np.sin(k * u)
    S[tau > D] = D - r
    return s, S, ds


class _LoopTrajectory(Trajectory):
    """The straightforward form: every segment's profile added in turn, at every time.

    (trajectory.py's own until the 80-segment ground scenarios took 16-27 s to simulate.)
    """

    def _base(self, t):
        V, chi = np.full_like(t, self.speed), np.full_like(t, self.heading_deg * DEG)
        dV, dchi, ddchi, gam, dgam = (np.zeros_like(t) for _ in range(5))
        starts = np.concatenate([[0.0], np.cumsum([s.duration for s in self.segments])])
        for seg, t0 in zip(self.segments, starts):
            if not (seg.accel or seg.turn_rate or seg.climb_rate):
                continue
            s, S, ds = _ramp_profile_reference(t - t0, seg.duration, seg.ramp_s)
            w, c = seg.turn_rate * DEG, seg.climb_rate * DEG
            V += seg.accel * S
            dV += seg.accel * s
            chi += w * S
            dchi += w * s
            ddchi += w * ds
            gam += c * S
            dgam += c * s
        return V, dV, chi, dchi, ddchi, gam, dgam

    def velocity(self, t):
        return self.kinematics(t).v_n[0]


def _manoeuvres(cls):
    """40 segments of random ramps, turns, climbs and pauses; sway; coordinated bank."""
    rng = np.random.default_rng(44)
    segs = []
    for _ in range(40):
        D = float(rng.choice([0.3, 0.7, 1.1, 2.9, 5.3, 13.7]))   # starts that round
        on = rng.random(3) < 0.6                                 # none of them: a pause
        segs.append(Segment(D, accel=on[0] * rng.uniform(-0.2, 0.2),
                            turn_rate=on[1] * rng.uniform(-15.0, 15.0),
                            climb_rate=on[2] * rng.uniform(-0.5, 0.5),
                            ramp=None if rng.random() < 0.7 else D * rng.uniform(0.05, 0.5)))
    sway = Sway(roll_amp=2.0, roll_period=7.3, roll_phase=0.4, pitch_amp=1.0,
                pitch_period=5.1, yaw_amp=0.5, yaw_period=11.0, surge_amp=0.3,
                surge_period=9.0, sway_amp=0.2, sway_period=6.5, heave_amp=0.5,
                heave_period=8.0)
    return cls(LAT, 108.0, 30.0, heading_deg=355.0, speed=6.0, segments=segs, sway=sway,
               coordinated_bank=True, name='manoeuvres')


def test_trajectory_sums_only_the_segment_under_way_and_equals_every_segment_added():
    """Trajectory._base adds the finished segments' whole integrals (summed once) and the
    profiles of the segment under way and the one before; velocity() is the scalar twin of
    kinematics(t).v_n for the position ODE. Both equal the straightforward loop to round-off.
    """
    traj, ref = _manoeuvres(Trajectory), _manoeuvres(_LoopTrajectory)
    ends = np.cumsum([s.duration for s in traj.segments])
    t = np.concatenate([np.arange(-1.0, ends[-1] + 2.0, 0.01), ends,
                        np.nextafter(ends, -np.inf), np.nextafter(ends, np.inf)])
    base, base_ref = traj._base(t), ref._base(t)
    # Bound (tolerance.py): each side sums n_seg terms rate_j * S_j(t) in turn onto the
    # initial value; a term is ~8 rounded operations (S: pi/r, k tau, sin = 2, /k, -, and
    # the rate's product), so a partial sum is off by at most (n_seg + 8) u times the sum of
    # the operands' sizes: |x0| + sum_j |rate_j| max S_j = (D_j - r_j); the derivatives sum
    # rate_j s_j (s <= 1) and w_j s'_j (|s'| <= pi / (2 r_j)).
    moving = [s for s in traj.segments if s.accel or s.turn_rate or s.climb_rate]
    n_ops = len(moving) + 8
    rho = roundoff(n_ops)                                # relative to each operand scale
    a = np.array([s.accel for s in moving])
    w = np.array([s.turn_rate for s in moving]) * DEG
    c = np.array([s.climb_rate for s in moving]) * DEG
    D = np.array([s.duration for s in moving])
    r = np.array([s.ramp_s for s in moving])
    Vs = traj.speed + np.abs(a) @ (D - r)
    As = abs(traj.heading_deg * DEG) + (np.abs(w) + np.abs(c)) @ (D - r)
    dVs, Rs, RRs = np.abs(a).sum(), (np.abs(w) + np.abs(c)).sum(), np.abs(w) @ (np.pi / (2 * r))
    for name, x, x_ref, scale in zip(('V', 'dV', 'chi', 'dchi', 'ddchi', 'gam', 'dgam'),
                                     base, base_ref, (Vs, dVs, As, Rs, RRs, As, Rs)):
        assert_roundoff(x, x_ref, n_ops, scale, what=name)

    # kinematics: the same code on both sides, on base values within the bounds above,
    # propagated to first order (v = V u(chi, gam); a = V' u + V u'; roll = atan(V chi'/g0))
    # plus ~10-20 rounded operations of its own on the size of each output
    V, dV, chi, dchi, ddchi, gam, dgam = base_ref
    Vm, dVm, Rm, RRm = np.abs(V).max(), np.abs(dV).max(), (np.abs(dchi) + np.abs(dgam)).max(), \
        np.abs(ddchi).max()
    sw = traj.sway
    osc = [(sw.surge_amp, sw.surge_period), (sw.sway_amp, sw.sway_period),
           (sw.heave_amp, sw.heave_period)]
    osc_v = sum(amp * 2 * np.pi / per for amp, per in osc)
    osc_a = sum(amp * (2 * np.pi / per) ** 2 for amp, per in osc)
    kin, kin_ref = traj.kinematics(t), ref.kinematics(t)
    v_bound = rho * (Vs + Vm * As) + roundoff(10, Vm + osc_v)
    assert np.abs(kin.v_n - kin_ref.v_n).max() <= v_bound
    a_bound = (rho * (dVs + dVm * As + Vs * Rm + Vm * Rs + Vm * Rm * As)
               + roundoff(20, dVm + Vm * Rm + osc_a))
    assert np.abs(kin.a_n - kin_ref.a_n).max() <= a_bound
    dq = rho * (Vs * Rm + Vm * Rs) / G0                  # q = V chi' / g0, roll = atan(q)
    angle_bound = rho * As + dq + roundoff(10, 2 * np.pi)
    assert np.abs(wrap_pi(kin.euler - kin_ref.euler)).max() <= angle_bound
    q_max, dq_max = Vm * Rm / G0, (dVm * Rm + Vm * RRm) / G0
    d_dq = rho * (dVs * Rm + dVm * Rs + Vs * RRm + Vm * RRs) / G0
    rate_bound = rho * Rs + d_dq + 2 * q_max * dq_max * dq + roundoff(20, dq_max + Rm + 1.0)
    assert np.abs(kin.euler_rate - kin_ref.euler_rate).max() <= rate_bound
    # the position ODE's scalar velocity: the v_n formulas again, in math's libm
    v_scalar = np.array([traj.velocity(x) for x in t[::7]])
    assert np.abs(v_scalar - kin_ref.v_n[::7]).max() <= v_bound

    # positions: DOP853 on right-hand sides that differ by round-off. Each accepted step's
    # estimated local error is <= sqrt(3) (atol + rtol |y|) per component (scipy's RMS norm
    # over 3 components <= 1) and the position ODE hardly amplifies (d(rate)/d(position)
    # ~ V / R ~ 1e-6 /s), so each solution is within (steps + 1) such errors of the exact one
    # (+1: the dense output between steps), and the two within the sum: a solver bound.
    # 25 s in two chunks (the loop's ODE takes 6 ms a call: the whole run would take 18 s)
    pos, pos_ref = PositionIntegrator(traj), PositionIntegrator(ref)
    tg = np.arange(0.0, 25.0, 0.05)
    y, y_ref = [], []
    for t_lo, t_hi in ((0.0, 10.0), (10.0, 25.0)):
        f, f_ref = pos.advance(t_hi), pos_ref.advance(t_hi)
        inside = (tg >= t_lo) & (tg <= t_hi)
        y.append(f(tg[inside]))
        y_ref.append(f_ref(tg[inside]))
    y, y_ref = np.vstack(y), np.vstack(y_ref)
    tol = (np.asarray(PositionIntegrator.ATOL)
           + PositionIntegrator.RTOL * np.abs(np.vstack([y, y_ref])).max(axis=0))
    bound = np.sqrt(3.0) * (pos.steps + pos_ref.steps + 2) * tol
    assert np.all(np.abs(y - y_ref).max(axis=0) <= bound)
    assert np.all(np.abs(pos.y - pos_ref.y) <= bound)


def test_trajectory_set_after_use_moves_as_one_built_so_and_pickles_as_its_fields():
    """Benches and tests set ``heading_deg`` on a scenario's trajectory after building it;
    the tables derived on first use must follow, and the simulation cache's key (a pickle)
    must not depend on whether the trajectory was used."""
    import pickle
    from dataclasses import replace
    traj = _manoeuvres(Trajectory)
    before = pickle.dumps(traj)
    t = np.arange(0.0, 60.0, 0.1)
    traj.kinematics(t), traj.velocity(3.0)
    assert pickle.dumps(traj) == before
    traj.heading_deg = 100.0
    fresh = replace(_manoeuvres(Trajectory), heading_deg=100.0)
    assert np.array_equal(traj.kinematics(t).v_n, fresh.kinematics(t).v_n)
    assert np.array_equal(traj.velocity(33.3), fresh.velocity(33.3))
