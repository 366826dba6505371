"""The sensor self-check: each rule against still data whose errors are known exactly."""
import math

import numpy as np
import pytest

from sins_align_ros.align import params as prm
from sins_align_ros.align.self_check import check, white_density
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
    assert c.widened['accel_bias_ug'] == pytest.approx(14 * 300.0, rel=0.1)
    assert not c.heading_observable          # 90 deg/h: no north at rest
    assert any('gyro_arw_dpsh widened' in s for s in c.findings)


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


def test_a_moving_base_skips_the_check():
    c = check(still(accel_bias=(0.0, 0.0, 2000.0 * UG), arw=3.0 * DPSH), POS, DEFAULTS,
              at_rest=False)
    assert c.widened == {} and not c.still
    assert 'skipped' in c.note and c.findings == []


def test_the_configured_model_is_never_narrowed():
    cfg = {**DEFAULTS, 'gyro_bias_dph': 50.0, 'gyro_arw_dpsh': 1.0, 'accel_bias_ug': 5000.0,
           'accel_vrw_ug_rthz': 500.0}
    c = check(still(), POS, cfg)
    assert c.widened == {}
