"""The sensor self-check: each rule against still data whose errors are known exactly."""
import math

import numpy as np
import pytest

from sins_align_ros.align import params as prm
from sins_align_ros.align.inputs.gnss_buffer import GnssBuffer
from sins_align_ros.align.stages.grade_check import GYRO_BIAS_PER_ARW_MOVING
from sins_align_ros.align.stages.noise_estimates import (coherent, difference_density,
                                                         robust_difference_sigma, white_density)
from sins_align_ros.align.stages.self_check import check
from sins_align_ros.nav import earth
from sins_align_ros.units import DEG, DPH, DPSH, UG

LAT = 34.0 * DEG
POS = np.array([LAT, 108.0 * DEG, 0.0])
DEFAULTS = prm.defaults()          # a navigation-grade IMU: 0.01 deg/h, 100 ug


def still(seconds=60.0, rate=100.0, gyro_bias=(0.0, 0.0, 0.0), accel_bias=(0.0, 0.0, 0.0),
          arw=0.001 * DPSH, vrw=10.0 * UG, seed=1, sway=0.0):
    """Coarse window (t, dtheta, dv, dt) of a level IMU facing north (FLU) at rest.

    ``sway``: amplitude (rad) of a 0.1 Hz roll oscillation (a ship at the quay).
    """
    rng = np.random.default_rng(seed)
    n = int(seconds * rate)
    dt = 1.0 / rate
    t = np.arange(1, n + 1) * dt
    # body FLU facing north: x = north, y = west, z = up
    w_ie = earth.OMEGA_IE * np.array([math.cos(LAT), 0.0, math.sin(LAT)])
    w = w_ie + np.asarray(gyro_bias, float) + rng.normal(size=(n, 3)) * arw / math.sqrt(dt)
    if sway:
        w[:, 0] += sway * 2 * math.pi * 0.1 * np.cos(2 * math.pi * 0.1 * t)
    f = (np.array([0.0, 0.0, earth.gravity(LAT, 0.0)]) + np.asarray(accel_bias, float)
         + rng.normal(size=(n, 3)) * vrw / math.sqrt(dt))
    return t, w * dt, f * dt, np.full(n, dt)


def test_a_model_that_fits_the_data_is_left_alone():
    c = check(still(), POS, DEFAULTS)
    assert c.widened == {} and c.still and c.heading_observable


def test_white_noise_above_the_model_widens_it_and_the_grade_biases():
    # a MEMS-like IMU (3 deg/sqrt(h), 300 ug/sqrt(Hz)) with the navigation-grade defaults
    c = check(still(arw=3.0 * DPSH, vrw=300.0 * UG), POS, DEFAULTS)
    assert c.widened['gyro_arw_dpsh'] == pytest.approx(3.0, rel=0.1)
    assert c.widened['accel_vrw_ug_rthz'] == pytest.approx(300.0, rel=0.1)
    # the grade the noise shows has larger biases: raised to the typical ratios
    assert c.widened['gyro_bias_dph'] == pytest.approx(30 * 3.0, rel=0.1)
    # the accelerometer bias: 14x its own noise (4200), or the consumer-MEMS class's 5000
    # the gyro noise shows, whichever is larger
    assert c.widened['accel_bias_ug'] == 5000.0
    assert not c.heading_observable          # 90 deg/h: no north at rest
    assert any('gyro_arw_dpsh widened' in s for s in c.findings)


def test_a_raw_industrial_ahrs_at_rest_gets_its_class_accelerometer_bias():
    """Gyro 0.42 deg/sqrt(h), accelerometers 120 ug/sqrt(Hz) (an industrial AHRS's raw
    triads, whose accelerometers have 6-8 mg of bias and 0.5 % misalignment): 14x the
    accelerometer noise says 1.7 mg; the gyro's class says 9 mg, and at rest that bias is
    tilt (a car still for 30 s published its north tilt 61' off under 5.8')."""
    c = check(still(arw=0.42 * DPSH, vrw=120.0 * UG), POS, DEFAULTS)
    assert c.widened['accel_bias_ug'] == 9000.0
    assert c.widened['gyro_bias_dph'] == pytest.approx(30 * 0.42, rel=0.1)


def test_a_navigation_class_gyro_told_too_good_gets_a_navigation_class_bias():
    """Gyro noise of the navigation class (0.001 deg/sqrt(h), told 0.0001): the bias is
    raised to 15x the noise (such gyros have 2-10x), not the 30x of lower grades, which
    made a heading sigma 3.3x its error; still a bias of the noise's class, not the
    0.001 deg/h told."""
    cfg = {**DEFAULTS, 'gyro_arw_dpsh': 0.0001, 'gyro_bias_dph': 0.001}
    c = check(still(arw=0.001 * DPSH), POS, cfg)
    assert c.widened['gyro_arw_dpsh'] == pytest.approx(0.001, rel=0.1)
    assert c.widened['gyro_bias_dph'] == pytest.approx(15 * 0.001, rel=0.1)
    assert c.heading_observable


def test_sway_and_quantization_are_not_taken_for_white_noise():
    dt = 0.01
    t, dth, dv, dts = still(sway=0.02)                  # 0.1 Hz roll of 1 deg
    assert math.isnan(white_density(dth / dt, dt))
    c = check((t, dth, dv, dts), POS, DEFAULTS)
    assert 'gyro_arw_dpsh' not in c.widened and not c.still
    # angle increments quantized to 1 arcsec (a laser gyro's counts)
    q = 1.0 * DEG / 3600.0
    dth_q = np.diff(np.round(np.cumsum(still()[1], axis=0) / q), axis=0, prepend=0.0) * q
    assert math.isnan(white_density(dth_q / dt, dt))


def test_specific_force_off_gravity_bounds_the_accelerometer_bias():
    c = check(still(accel_bias=(0.0, 0.0, 2000.0 * UG)), POS, DEFAULTS)
    assert c.widened['accel_bias_ug'] == pytest.approx(2000.0, rel=0.05)
    assert c.figures['accel_bias_bound_ug'] == pytest.approx(2000.0, rel=0.05)
    # within what the model and normal gravity explain: nothing
    assert 'accel_bias_ug' not in check(still(accel_bias=(0.0, 0.0, 300.0 * UG)), POS,
                                        DEFAULTS).widened


@pytest.mark.parametrize('axis', [0, 2])
def test_mean_rate_off_earth_rate_bounds_the_gyro_bias(axis):
    bias = np.zeros(3)
    bias[axis] = 5.0 * DPH                    # along north (horizontal) or up
    c = check(still(gyro_bias=bias), POS, DEFAULTS)
    assert c.widened['gyro_bias_dph'] == pytest.approx(5.0, rel=0.05)
    assert c.heading_observable               # 5 deg/h < half the horizontal Earth rate
    c = check(still(gyro_bias=bias * 40.0), POS, DEFAULTS)
    assert c.widened['gyro_bias_dph'] == pytest.approx(200.0, rel=0.05)
    assert not c.heading_observable


def test_a_moving_base_checks_the_noise_but_not_the_biases():
    # tactical-class gyro noise against the navigation-grade defaults: widened from the
    # third differences; the accelerometer bias (2000 ug, which the rest check would
    # bound) is raised only to the tactical class floor, no bias bound is drawn
    c = check(still(accel_bias=(0.0, 0.0, 2000.0 * UG), arw=0.1 * DPSH), POS, DEFAULTS,
              at_rest=False)
    assert not c.still and 'bias bounds skipped' in c.note
    assert c.widened['gyro_arw_dpsh'] == pytest.approx(0.1, rel=0.1)
    assert c.widened['gyro_bias_dph'] == pytest.approx(GYRO_BIAS_PER_ARW_MOVING * 0.1, rel=0.1)
    assert c.widened['accel_bias_ug'] == 500.0
    assert 'accel_bias_bound_ug' not in c.figures


def test_a_moving_base_at_the_configured_noise_widens_nothing():
    c = check(still(), POS, DEFAULTS, at_rest=False)
    assert c.widened == {} and c.findings == [] and not c.still


def test_difference_density_sees_white_noise_through_smooth_motion():
    rng = np.random.default_rng(5)
    dt, sigma = 0.01, 0.02
    t = np.arange(20000) * dt
    motion = np.column_stack([np.sin(2 * np.pi * 0.2 * t), np.cos(2 * np.pi * 0.5 * t),
                              0.3 * t]) * 5.0
    x = motion + sigma * rng.standard_normal((len(t), 3))
    assert difference_density(x, dt) == pytest.approx(sigma * np.sqrt(dt), rel=0.03)
    assert np.isnan(difference_density(x[:50], dt))


def test_robust_difference_sigma_ignores_a_few_manoeuvre_starts():
    rng = np.random.default_rng(6)
    x = 5.0 * rng.standard_normal((120, 2))
    x[40:, 0] += 3.0 * np.arange(80) ** 2 / 2.0         # a 3 m/s^2 acceleration starts
    assert robust_difference_sigma(x) == pytest.approx(5.0, rel=0.2)
    assert np.isnan(robust_difference_sigma(x[:5]))


def test_the_configured_model_is_never_narrowed():
    cfg = {**DEFAULTS, 'gyro_bias_dph': 50.0, 'gyro_arw_dpsh': 1.0, 'accel_bias_ug': 5000.0,
           'accel_vrw_ug_rthz': 500.0}
    c = check(still(), POS, cfg)
    assert c.widened == {}


def _gnss(sigma_m, reported_var=None, seconds=60, seed=3):
    """Return a GnssBuffer of 1-Hz fixes of a car driving and turning, noise ``sigma_m``."""
    rng = np.random.default_rng(seed)
    buf = GnssBuffer()
    R = earth.radii(LAT)
    for k in range(seconds + 1):
        e, n = 10.0 * k, 0.05 * k ** 2
        e, n = e + sigma_m * rng.standard_normal(), n + sigma_m * rng.standard_normal()
        lat = POS[0] + n / (R[0] + 0.0)
        lon = POS[1] + e / (R[1] * math.cos(POS[0]))
        pv = None if reported_var is None else (reported_var, reported_var)
        buf.position_fix(float(k), lat / DEG, lon / DEG, 0.5 * rng.standard_normal(), pv, None,
                         False)
    return buf


@pytest.mark.parametrize('ff, reported, widened', [('kf', None, True), ('ckf', 25.0, False),
                                                   ('kf', 25.0, False), ('ukf', 1.0, True),
                                                   ('mvbakf', 25.0, True), ('ckf', 1.0, True)])
def test_gnss_noise_above_the_model_widens_it(ff, reported, widened):
    # 5 m fixes: configured 1 m (kf, ckf without reports) or reported 5 m (used by ckf,
    # asckf without adaptation, kf and ukf; not by the VB filters, whose R is their own)
    # or reported 1 m (too small: widened and no longer used)
    cfg = {**DEFAULTS, 'fine_filter': ff}
    c = check(still(), POS, cfg, at_rest=False, gnss=_gnss(5.0, reported))
    assert c.figures['gnss_pos_noise_m'] == pytest.approx(5.0, rel=0.3)
    assert ('gnss_pos_sigma_m' in c.widened) == widened
    if widened:
        assert c.widened['gnss_pos_sigma_m'] == pytest.approx(5.0, rel=0.3)
        assert any('gnss_pos_sigma_m widened' in f for f in c.findings)
    assert c.widened.get('use_reported_gnss_covariance', True) == (reported != 1.0)
    assert 'gnss_height_sigma_m' not in c.widened          # 0.5 m against 2 m configured


@pytest.mark.parametrize('ff, widened', [('stationary12', True), ('reduced7', False)])
@pytest.mark.parametrize('told', [0.01, 0.0])
def test_heave_at_rest_widens_the_vertical_zero_velocity_noise(ff, widened, told):
    """A moored ship heaving 0.5 m over 6 s moves at 0.37 m/s RMS vertically: the 12-state
    filter, which measures the vertical velocity as zero, gets that noise on its vertical
    row only; the horizontal rows keep theirs (the ship does not move horizontally).

    Told 0.01 m/s, the vertical is widened; left to the data (0, the default), both are
    read: the vertical 1.5 x its RMS, the horizontal at the floor. The horizontal RMS is
    the accelerometers' random walk alone (5 ug/sqrt(Hz) less a quadratic over 10-s
    pieces: 0.032 mm/s expected) within 3x: against the window's mean vertical instead of
    each piece's own, the Earth's turn leaked 0.4 mm/s of the heave into it.
    """
    from sins_align_ros.align.stages.self_check import READ_MARGIN, ZERO_VELOCITY_FLOOR
    from sins_align_ros.eval.scenarios import named, simulate
    b = simulate(named('ship_sway', 60.0), 1)
    dts = np.diff(np.r_[0.0, b.imu.t])
    lat = 45.7796 * DEG
    c = check((b.imu.t, b.imu.dtheta, b.imu.dv, dts), np.array([lat, 2.2, 0.0]),
              {**DEFAULTS, 'fine_filter': ff, 'gyro_arw_dpsh': 0.0005,
               'accel_vrw_ug_rthz': 5.0, 'zero_velocity_sigma': told})
    assert c.figures['base_velocity_v_mps'] == pytest.approx(0.5 * 2 * np.pi / 6 / np.sqrt(2),
                                                             rel=0.1)
    assert c.figures['base_velocity_h_mps'] < 3 * 3.2e-5
    if told:
        assert ('zero_velocity_sigma_up' in c.widened) == widened
        if widened:
            assert c.widened['zero_velocity_sigma_up'] == pytest.approx(
                c.figures['base_velocity_v_mps'])
        assert not c.read
    else:
        assert not c.widened and not c.findings
        assert c.read['zero_velocity_sigma'] == ZERO_VELOCITY_FLOOR
        assert ('zero_velocity_sigma_up' in c.read) == widened
        if widened:
            assert c.read['zero_velocity_sigma_up'] == pytest.approx(
                READ_MARGIN * c.figures['base_velocity_v_mps'])
        assert 'zero-velocity sigma read' in c.note
    # the horizontal rows, which carry tilt and heading, keep their noise
    assert 'zero_velocity_sigma' not in c.widened


def test_a_disturbance_that_turns_and_accelerates_together_is_not_taken_for_noise():
    """Sensor noises are independent; a knock on the base turns and accelerates the IMU
    together. Independent noise: not coherent; a shared broadband disturbance: coherent,
    and at rest (sway spoiling the 1-s estimate) it widens nothing."""
    rng = np.random.default_rng(21)
    n = 6000
    noise_g, noise_a = rng.standard_normal((n, 3)), rng.standard_normal((n, 3))
    assert not coherent(noise_g, noise_a)
    knock = rng.standard_normal(n)
    assert coherent(noise_g + 0.5 * knock[:, None], noise_a + 0.5 * knock[:, None])
    t, dth, dv, dts = still(sway=0.05)
    kick = 2e-6 * rng.standard_normal(len(t))                  # rad and m/s per sample
    c = check((t, dth + kick[:, None], dv + 50.0 * kick[:, None], dts), POS, DEFAULTS)
    assert 'disturbance' in c.note and 'gyro_arw_dpsh' not in c.widened


@pytest.mark.parametrize('vel_sigma, widened', [(0.05, False), (0.25, True)])
def test_a_seaway_is_not_taken_for_gnss_velocity_noise(vel_sigma, widened):
    """Seed 004's USV in a severe sea at 1 Hz: the velocities' third differences hold the
    waves (0.045 m/s horizontal) and the 5 % outliers as well as the receiver's 0.05 m/s,
    and widened gnss_vel_sigma_mps 2.3x. The IMU sees the waves: with its view of the
    motion taken out, the right model stays; a receiver 5x noisier is still found."""
    import dataclasses
    from sins_align_ros.eval.scenarios import named, simulate
    sc = named('seed004_medium@navigation', 60.0)
    sc = dataclasses.replace(sc, gnss=dataclasses.replace(sc.gnss, vel_sigma=vel_sigma))
    b = simulate(sc, 1000)
    buf = GnssBuffer()
    for k, t in enumerate(b.gnss.t):
        buf.velocity_fix(float(t), b.gnss.v_n[k], None)
    dts = np.diff(np.r_[0.0, b.imu.t])
    cfg = {**DEFAULTS, 'fine_filter': 'vbch', 'gnss_vel_sigma_mps': 0.05}
    c = check((b.imu.t, b.imu.dtheta, b.imu.dv, dts), POS, cfg, at_rest=False, gnss=buf)
    assert ('gnss_vel_sigma_mps' in c.widened) == widened
    assert c.figures['gnss_vel_noise_mps'] == pytest.approx(vel_sigma, rel=0.4)


def test_the_lever_arm_grid_scores_equal_the_fit_at_each_heading():
    """The vectorised heading grid of the lever-arm fit (``arm_check._grid_scores``, in
    chunks) scores every heading as the one-by-one clipped fit does, to round-off, with
    outliers among the velocities."""
    from sins_align_ros.align.stages import arm_check as ac
    rng = np.random.default_rng(7)
    n = 40
    U_l = np.cumsum(rng.normal(size=(n, 3)), axis=0)
    B0 = rng.normal(size=(n, 3, 3))
    V = U_l @ np.diag([0.8, -1.1, 1.0]) + rng.normal(scale=0.05, size=(n, 3))
    V[[5, 17]] += 3.0                                    # GNSS outliers
    grid = np.radians(np.arange(0.0, 360.0, 7.0))
    exact = []
    for psi in grid:
        R3 = np.eye(3)
        R3[:2, :2] = ac._rotation(psi)
        e, B = V - U_l @ R3, np.einsum('nak,ab->nbk', B0, R3)
        exact.append(ac._clipped_fit(*ac._design(e, B))[1])
    for rows in (100_000, 500):                          # one chunk, several chunks
        np.testing.assert_allclose(ac._grid_scores(V, U_l, B0, grid, rows=rows), exact,
                                   rtol=1e-10)


def test_latitude_not_set_is_estimated_from_the_earth_rate_and_used():
    """No fix, initial_latitude_deg not set: sin L from the mean rate and specific force."""
    pos = np.array([0.0, 108.0 * DEG, 0.0])           # what GnssBuffer.position gives
    gnss = GnssBuffer()
    assert not gnss.latitude_known(DEFAULTS)
    c = check(still(seconds=120.0), pos, DEFAULTS, gnss=gnss)
    lat, sigma = c.latitude
    assert abs(lat - LAT) < 3.0 * sigma and sigma < 0.1 * DEG
    assert pos[0] == lat and not c.latitude_unknown     # the stages after use it
    assert c.widened == {} and c.heading_observable
    assert any('estimated from the angle' in s for s in c.findings)


def test_latitude_not_set_with_a_tactical_gyro_is_unknown_and_so_is_the_heading():
    """1 deg/h gyro bias: the latitude to 4 deg only; not used, no gyro blame, heading
    unknown for the latitude's sake (the gyro alone would find north)."""
    from sins_align_ros.align.stages.self_check import heading_warning
    cfg = {**DEFAULTS, 'gyro_bias_dph': 1.0, 'gyro_arw_dpsh': 0.05}
    pos = np.array([0.0, 108.0 * DEG, 0.0])
    c = check(still(gyro_bias=(0.0, 0.5 * DPH, 0.0), arw=0.05 * DPSH), pos, cfg,
              gnss=GnssBuffer())
    assert c.latitude is None and c.latitude_unknown and pos[0] == 0.0
    # hypot(1 deg/h, 0.05 deg/sqrt(h) / sqrt(60 s)) over the 15.04 deg/h Earth rate
    want = math.degrees(math.hypot(1.0, 0.05 * math.sqrt(3600.0 / 60.0)) / (earth.OMEGA_IE / DPH))
    assert c.figures["latitude_sigma_deg"] == pytest.approx(want, rel=1e-5)   # + accel tilt
    assert 'gyro_bias_dph' not in c.widened and 'accel_bias_ug' not in c.widened
    assert c.gyro_finds_north and not c.heading_observable
    assert heading_warning(c, True, False).startswith('heading unobservable: the latitude is '
                                                      'unknown')
    assert any(s.startswith('latitude unknown') for s in c.findings)
    # told the latitude, the same data find north
    told = check(still(gyro_bias=(0.0, 0.5 * DPH, 0.0), arw=0.05 * DPSH), POS.copy(),
                 {**cfg, 'initial_latitude_deg': 34.0}, gnss=GnssBuffer())
    assert told.heading_observable and told.latitude is None and not told.latitude_unknown


def test_a_moving_mems_triad_gets_its_class_biases_and_scale_factors_never_narrowed():
    """Raw MEMS AHRS triads' gyro noise (0.42 deg/sqrt(h)) on a moving base against the
    defaults: the gyro bias is raised to the class floor (500 deg/h, not 67 x 0.42 = 28),
    the accelerometer bias to the industrial class's 9000 ug, and the gyro and
    accelerometer scale factors and misalignment to the class's (issue 44); a model told
    more keeps it."""
    from sins_align_ros.align.stages.grade_check import (ACCEL_SCALE_BY_GYRO_NOISE,
                                                         GYRO_BIAS_BY_GYRO_NOISE_MOVING)
    c = check(still(arw=0.42 * DPSH, vrw=120.0 * UG), POS, DEFAULTS, at_rest=False)
    assert c.widened['gyro_bias_dph'] == GYRO_BIAS_BY_GYRO_NOISE_MOVING[2][1] == 500.0
    assert c.widened['accel_bias_ug'] == 9000.0
    scale, mis = ACCEL_SCALE_BY_GYRO_NOISE[2][1]
    assert c.widened['accel_scale_factor_ppm'] == scale >= 3000.0
    assert c.widened['accel_misalignment_ppm'] == mis >= 5000.0
    assert any('accel_misalignment_ppm raised' in s and 'velocity error' in s
               for s in c.findings)
    told = dict(DEFAULTS, accel_scale_factor_ppm=9000.0, accel_misalignment_ppm=9000.0,
                gyro_bias_dph=900.0)
    c = check(still(arw=0.42 * DPSH, vrw=120.0 * UG), POS, told, at_rest=False)
    assert not {'accel_scale_factor_ppm', 'accel_misalignment_ppm',
                'gyro_bias_dph'} & set(c.widened)


def test_a_vibrating_chassis_raises_the_bias_instability_only_to_the_consumer_class():
    """Under way, 37 deg/sqrt(h) of third-difference noise (a skid-steer chassis's vibration
    on a 0.42 deg/sqrt(h) gyro): the white noise and the bias are raised by all of it
    (67 x 37 deg/h), the bias instability by at most the consumer class's 3 deg/sqrt(h)
    (15 x 3 = 45 deg/h, not 15 x 37 = 555); at rest the noise counts whole, as before."""
    from sins_align_ros.align.stages.grade_check import (GYRO_INSTABILITY_PER_ARW,
                                                         GYRO_NOISE_FOR_INSTABILITY_MOVING)
    window = still(arw=37.0 * DPSH, vrw=120.0 * UG)
    c = check(window, POS, DEFAULTS, at_rest=False)
    arw = c.widened['gyro_arw_dpsh']
    assert arw == pytest.approx(37.0, rel=0.1)
    assert c.widened['gyro_bias_dph'] == pytest.approx(GYRO_BIAS_PER_ARW_MOVING * arw)
    assert GYRO_NOISE_FOR_INSTABILITY_MOVING == 3.0
    assert c.widened['gyro_bias_instability_dph'] == pytest.approx(
        GYRO_INSTABILITY_PER_ARW * GYRO_NOISE_FOR_INSTABILITY_MOVING)
    c = check(window, POS, DEFAULTS, at_rest=True)
    assert c.widened['gyro_bias_instability_dph'] == pytest.approx(
        GYRO_INSTABILITY_PER_ARW * c.widened['gyro_arw_dpsh'])


def test_the_navigation_and_tactical_classes_are_as_before():
    from sins_align_ros.align.stages.grade_check import (ACCEL_BIAS_BY_GYRO_NOISE,
                                                         ACCEL_SCALE_BY_GYRO_NOISE,
                                                         GYRO_BIAS_BY_GYRO_NOISE_MOVING)
    assert ACCEL_BIAS_BY_GYRO_NOISE[:2] == ((0.003, 100.0), (0.15, 500.0))
    assert [v for _, v in ACCEL_SCALE_BY_GYRO_NOISE[:2]] == [(0.0, 0.0)] * 2
    assert [v for _, v in GYRO_BIAS_BY_GYRO_NOISE_MOVING[:2]] == [0.0, 0.0]
    # the consumer class keeps 67 x its noise: our MEMS preset's 200 deg/h at 3 deg/sqrt(h)
    assert GYRO_BIAS_BY_GYRO_NOISE_MOVING[3][1] == 0.0
