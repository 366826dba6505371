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
