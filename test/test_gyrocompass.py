"""The still base's gyrocompass segments (align/engines/gyrocompass.py, issue 46)."""
import numpy as np
import pytest

from sins_align_ros.align.engines import gyrocompass
from sins_align_ros.align.engines.factory import noise_spec
from sins_align_ros.align.params import defaults
from sins_align_ros.nav import earth
from sins_align_ros.nav.frames import euler_to_dcm
from sins_align_ros.sim.presets import SENSOR_GRADES, alignment_params, scenario
from sins_align_ros.units import DEG


def _noise(grade):
    cfg = defaults()
    cfg.update(alignment_params(scenario('static_navigation', imu=SENSOR_GRADES[grade]),
                                'auto'))
    return noise_spec(cfg)


@pytest.mark.parametrize('grade, low, high', [('navigation', 55.0, 65.0),
                                              ('marine', 55.0, 65.0),
                                              ('tactical', 5.0, 7.0)])
def test_the_gyro_span_is_where_the_drift_route_keeps_a_fifth_of_the_gyro_information(
        grade, low, high):
    """sqrt(3) (VRW/g) / ARW from the grade's densities: navigation (10 ug/sqrt(Hz),
    0.001 deg/sqrt(h)) 59.5 s, marine (5, 0.0005: the same ratio) the same; tactical (50,
    0.05) 6.0 s, shorter than any window, so a tactical stage takes no gyrocompass
    heading. At the span, the drift route's accelerometer variance 12 (VRW/g)^2 / T^3 is 4
    times its gyro variance ARW^2 / T."""
    n = _noise(grade)
    span = gyrocompass.gyro_span(n, 35.0 * DEG)
    g = earth.gravity(35.0 * DEG, 0.0)
    assert 12.0 * (n.accel_vrw / g) ** 2 / span ** 3 == pytest.approx(
        4.0 * n.gyro_arw ** 2 / span, rel=1e-9)
    assert low <= span <= high


def test_segments_give_the_heading_of_a_still_body_and_drop_a_spoilt_one():
    """Exact increments of a still body (heading 30 deg, pitched 1 deg) at 100 Hz: after the
    skipped window, each 10-s segment gives the body's yaw (to round-off) with variance
    rate_var / 10 s; a spoilt segment gives nothing; segments stop at the span."""
    lat = 35.0 * DEG
    C = euler_to_dcm(np.radians([0.0, 1.0, 30.0]))
    w_b = C.T @ earth.w_ie_n(lat)
    f_b = C.T @ np.array([0.0, 0.0, earth.gravity(lat, 0.0)])
    dt, n = 0.01, 100
    dth, dv, dts = np.tile(w_b * dt, (n, 1)), np.tile(f_b * dt, (n, 1)), np.full(n, dt)
    seg = gyrocompass.GyroSegments(rate_var=2.0, lat=lat, span=25.0, skip=5.0)
    got = []
    for k in range(40):                       # 40 s of 1-s blocks
        seg.add(dth, dv, dts)
        if k == 16:
            seg.spoil()                       # inside the second segment (15-25 s)
        if not seg.done:
            got.append(seg.take())
    fixes = [f for f in got if f is not None]
    assert len(fixes) == 1 and seg.n_taken == 1 and seg.n_dropped == 1 and seg.done
    yaw, var = fixes[0]
    assert yaw == pytest.approx(np.radians(30.0), abs=1e-9)
    assert var == pytest.approx(2.0 / 10.0)
