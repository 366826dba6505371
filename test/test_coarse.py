"""Coarse alignment against simulator truth."""
import numpy as np
import pytest

from sins_align_ros.nav import coarse
from sins_align_ros.nav.frames import attitude_error, euler_to_dcm
from sins_align_ros.sim.imu import ImuSpec
from sins_align_ros.sim.presets import scenario
from sins_align_ros.sim.scenario import ScenarioStream
from sins_align_ros.units import ARCMIN, DEG, DPSH, UG


def block(name, seconds, seed=1, **overrides):
    sc = scenario(name, **overrides)
    st = ScenarioStream(sc, seed=seed)
    b = st.next_block(int(seconds * sc.imu_rate_hz))
    return sc, b.imu


@pytest.mark.parametrize('method', [coarse.analytic, coarse.inertial_frame])
def test_error_free_still_imu_gives_the_truth(method):
    sc, imu = block('static_navigation', 60.0, imu=ImuSpec())
    C = method(imu.dtheta, imu.dv, 0.01, sc.trajectory.lat_deg * DEG)
    err = attitude_error(C, euler_to_dcm(imu.euler[-1]))
    assert np.abs(err).max() < 0.01 * ARCMIN


def test_analytic_on_navigation_grade_is_near_the_sensor_limit():
    sc, imu = block('static_navigation', 60.0)
    C = coarse.analytic(imu.dtheta, imu.dv, 0.01, 34.0 * DEG)
    err = attitude_error(C, euler_to_dcm(imu.euler[-1])) / ARCMIN
    assert np.abs(err[:2]).max() < 1.0          # 100 ug -> 0.34'
    assert abs(err[2]) < 15.0                     # bias 2.8' + 60 s of ARW


def test_inertial_frame_tolerates_sway_where_analytic_fails():
    sc, imu = block('ship_sway', 120.0)
    lat = sc.trajectory.lat_deg * DEG
    C_true = euler_to_dcm(imu.euler[-1])
    err_i0 = attitude_error(coarse.inertial_frame(imu.dtheta, imu.dv, 0.01, lat), C_true)
    err_an = attitude_error(coarse.analytic(imu.dtheta, imu.dv, 0.01, lat), C_true)
    assert np.abs(err_i0[:2]).max() < 2.0 * ARCMIN
    assert abs(err_i0[2]) < 20.0 * ARCMIN
    assert np.abs(err_an).max() > 1.0 * DEG       # the mean is meaningless on a swaying deck


def test_detect_motion():
    sc, imu = block('static_navigation', 30.0)
    args = (imu.dtheta, imu.dv, 0.01, sc.imu.gyro_arw_dpsh * DPSH, sc.imu.accel_vrw_ug_rthz * UG)
    assert coarse.detect_motion(*args)[0] is False
    sc, imu = block('ship_sway', 30.0)
    assert coarse.detect_motion(imu.dtheta, imu.dv, 0.01, sc.imu.gyro_arw_dpsh * DPSH,
                                sc.imu.accel_vrw_ug_rthz * UG)[0] is True
    sc, imu = block('static_mems', 30.0)           # noisy but still: not "moving"
    assert coarse.detect_motion(imu.dtheta, imu.dv, 0.01, sc.imu.gyro_arw_dpsh * DPSH,
                                sc.imu.accel_vrw_ug_rthz * UG)[0] is False


def test_compiled_body_attitude_increments_equal_the_rotation_products():
    """``body_attitude_increments`` (compiled, issue 22) against the products of scipy's
    rotation of each coning-corrected increment, over 5000 samples of sway."""
    from sins_align_ros.nav.coarse import body_attitude_increments
    from sins_align_ros.nav.frames import rotvec_to_dcm
    rng = np.random.default_rng(5)
    dtheta = 0.01 * np.sin(np.arange(5000)[:, None] * [0.013, 0.021, 0.008]) \
        + 1e-5 * rng.standard_normal((5000, 3))
    C, prev, ref = np.eye(3), np.zeros(3), []
    for d in dtheta:
        C = C @ rotvec_to_dcm(d + np.cross(prev, d) / 12.0)
        ref.append(C)
        prev = d
    np.testing.assert_allclose(body_attitude_increments(dtheta), ref, rtol=0, atol=1e-13)
