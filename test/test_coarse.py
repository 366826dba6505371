"""Coarse alignment against simulator truth."""
import numpy as np
import pytest

from sins_align_ros.nav import coarse
from sins_align_ros.nav.frames import attitude_error, euler_to_dcm
from sins_align_ros.sim.imu import ImuSpec
from sins_align_ros.sim.presets import scenario
from sins_align_ros.sim.scenario import ScenarioStream
from sins_align_ros.units import ARCMIN, DEG, DPSH, UG
from tolerance import roundoff


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
    # 5000 products of rotations (a DCM from a rotation vector ~20 operations, the product
    # 5), passed on with gain 1: 5000 x 25 on unit entries (tolerance.py)
    np.testing.assert_allclose(body_attitude_increments(dtheta), ref, rtol=0,
                               atol=roundoff(len(dtheta) * 25))


def test_imu_velocity_change_at_the_true_attitude_follows_the_truth_in_severe_sea():
    """velocity_change_n inverts the inertial-frame relation: given the true end attitude,
    the IMU's velocity change over 60 s of seed 004's severe sea (1.3 m/s heave) matches
    the truth up to a slow trend (Coriolis and the fit's small-rotation form) of < 0.1 m/s,
    and to 5 mm/s once a quadratic trend is taken off (what the outlier screen relies on)."""
    sc, imu = block('seed004_high', 60.0, seed=3)
    n = len(imu.t)
    C = euler_to_dcm(imu.euler[-1])
    dv_n = coarse.velocity_change_n(imu.dtheta, imu.dv, 0.01, sc.trajectory.lat_deg * DEG,
                                    sc.trajectory.h, C)
    r = dv_n[1:] - (imu.v_n[1:] - imu.v_n[0])
    assert np.abs(r).max() < 0.1
    k = np.arange(99, n - 1, 100)
    A = np.vander(imu.t[k] - imu.t[k].mean(), 3)
    detrended = r[k] - A @ np.linalg.lstsq(A, r[k], rcond=None)[0]
    assert np.abs(detrended).max() < 0.005
    assert np.ptp(imu.v_n[:, 2]) > 2.0                  # the heave is there to follow


def test_attitude_at_start_turns_the_end_attitude_back_over_a_swaying_window():
    """Error-free IMU on the moored ship (sway of degrees, heave): the attitude at the end
    turned back by the gyros and the Earth is the truth at the window's start (issue 46's
    reprocessing starts the fine filter there), to the strapdown's own integration error."""
    sc, imu = block('ship_sway', 30.0, imu=ImuSpec())
    lat = sc.trajectory.lat_deg * DEG
    C0 = coarse.attitude_at_start(euler_to_dcm(imu.euler[-1]), imu.dtheta, 0.01, lat)
    truth0 = euler_to_dcm(sc.trajectory.kinematics(np.array([0.0])).euler[0])
    assert np.abs(attitude_error(C0, truth0)).max() < 0.01 * ARCMIN
    # the sway turned the body by degrees over the window: the end attitude is not it
    assert np.abs(attitude_error(euler_to_dcm(imu.euler[-1]), truth0)).max() > 30.0 * ARCMIN
