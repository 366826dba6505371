"""Gyro scale factors as states of the kf/ukf engines (issue 44; align/engines/gyro_scale.py)."""
import math

import numpy as np
import pytest

from sins_align_ros.align.engines.gyro_scale import SCALE_STATE_FACTOR
from sins_align_ros.align.engines.navigation import IntegratedNavigation
from sins_align_ros.align.engines.registry import engine_class
from sins_align_ros.align.engines.rotation_error import COHERENCE_FACTOR
from sins_align_ros.eval.integrity import run_integrity
from sins_align_ros.eval.run import run_pipeline
from sins_align_ros.eval.scenarios import simulate
from sins_align_ros.models import loosely_coupled as lc
from sins_align_ros.nav.frames import euler_to_dcm
from sins_align_ros.sim.presets import SENSOR_GRADES, alignment_params, scenario
from sins_align_ros.units import DEG

#: issue 44's heading 1-sigma for the car with RTK at the end of a run, rad
RTK_CAR_HEADING_SIGMA = 0.5 * DEG


def test_the_nonlinear_drift_takes_the_scale_factor_as_the_linear_model_does():
    """derivative18 with a body rate: its Jacobian in the scale-factor states is -C diag(w_b)."""
    C = euler_to_dcm((0.02, -0.01, 1.1))
    f_n, v_n = np.array([0.3, -0.2, 9.8]), np.array([8.0, 3.0, 0.1])
    w_b = np.array([0.01, -0.02, 0.3])
    lat, h = math.radians(52.5), 40.0
    args = (f_n, v_n, C, lat, h, 300.0, 3600.0)
    J = np.zeros((21, 3))
    d = 1e-6                   # central differences of a function smooth at zero
    for j in range(3):
        x = np.zeros(21)
        x[18 + j] = d
        J[:, j] = (lc.derivative18(x, *args, w_b=w_b)
                   - lc.derivative18(-x, *args, w_b=w_b)) / (2 * d)
    F = np.zeros((21, 21))
    F[:18, :18] = lc.F_matrix(C, f_n, v_n, lat, h, 300.0, 3600.0, 18)
    F[0:3, 18:21] = -C * w_b
    # the derivative is linear in the scale factors at zero misalignment: the differences
    # are exact up to the rounding of terms of size |w_b| (~0.3) over 2d
    assert np.allclose(J, F[:, 18:21], rtol=0.0, atol=1e-9)
    # and without a rate the 21 states reduce to the 18 of seed 003
    x = np.r_[np.full(18, 1e-3), 0.02, 0.02, 0.02]
    assert np.array_equal(lc.derivative18(x, *args, w_b=np.zeros(3))[:18],
                          lc.derivative18(x[:18], *args))


def _engine():
    P0, Qc = np.eye(15) * 1e-4, np.zeros(15)
    return engine_class('kf')(np.eye(3), np.zeros(3), 0.9, 0.2, 40.0, P0, Qc, np.eye(6))


def test_a_scale_factor_goes_to_the_states_and_the_misalignment_stays_noise():
    eng = _engine()
    # no GNSS velocity measured yet: the turns cannot show the scale factor, noise keeps it
    eng.set_rotation_error(0.02, 0.005)
    assert eng.i_sf is None and eng._rot_sigma == (COHERENCE_FACTOR * 0.02,
                                                   COHERENCE_FACTOR * 0.005)
    # with velocity and the heading known (0.6 deg: P0), states at the interval's end
    eng.velocity_measured = True
    eng._interval_ended(1.0)
    assert eng.n == 18 and eng.i_sf == slice(15, 18) and len(eng.Qc) == 18
    assert np.allclose(np.diag(eng.kf.P)[15:], (SCALE_STATE_FACTOR * 0.02) ** 2, rtol=1e-12)
    assert eng._rot_sigma == (0.0, COHERENCE_FACTOR * 0.005)
    # a larger one later (the motion check seeing turns) widens the states, a smaller not
    eng.set_rotation_error(0.03, 0.005)
    assert np.allclose(np.diag(eng.kf.P)[15:], (SCALE_STATE_FACTOR * 0.03) ** 2, rtol=1e-12)
    eng.set_rotation_error(0.01, 0.005)
    assert np.allclose(np.diag(eng.kf.P)[15:], (SCALE_STATE_FACTOR * 0.03) ** 2, rtol=1e-12)
    # a turn of A about body z: the transition moves the heading by -A ds_z (level, C = I)
    A, T = math.radians(90.0), 1.0
    for _ in range(100):
        eng.step_imu(np.array([0.0, 0.0, A / 100]), np.array([0.0, 0.0, 9.8 * T / 100]),
                     T / 100)
    eng.predict()
    assert eng._F[2, 17] * T == pytest.approx(-A, rel=1e-9)
    # the estimate divides the increments: a 1 % scale factor fed back takes 1 % off
    x = np.zeros(18)
    x[17] = 0.01
    eng._feed_back_scale(x)
    d = eng._correct_imu(np.array([0.0, 0.0, 0.101]), np.zeros(3), 0.01)[0]
    assert d[2] == pytest.approx(0.1, rel=1e-12)


@pytest.fixture(scope='module')
def rtk_car():
    """car_rtk (still 30 s, then town driving, RTK at 5 Hz) for 300 s with the raw AHRS
    triads at their 1-sigma: every gyro scale factor 2 %, misalignment 0.5 %."""
    sc = scenario('car_rtk', duration=300.0)
    sc.imu = SENSOR_GRADES['mems_ahrs'].with_(random_bias=False)
    return sc, simulate(sc, 3)


def _run(rtk_car, fine_filter='kf', **over):
    sc, data = rtk_car
    params = alignment_params(sc, fine_filter)
    params.update(over)
    run = run_pipeline(params, data)
    return run, run_integrity(run, sc.imu_rate_hz)


@pytest.mark.parametrize('fine_filter', ['kf', 'ukf'])
def test_a_turning_car_pins_its_scale_factor_and_its_heading_sigma_shrinks(
        rtk_car, fine_filter):
    sc, _ = rtk_car
    s_z = sc.imu.gyro_scale_ppm * 1e-6           # the simulated z scale factor (truth)
    run, r = _run(rtk_car, fine_filter)
    eng = run.pipeline.engine
    sd = np.sqrt(np.diag(eng.kf.P)[eng.i_sf])
    # the turns with RTK velocity observe the z scale factor: inside 3 sigma of the truth,
    # and its sigma down to a third of the prior's (a 90 deg turn then leaves 0.6 deg of
    # heading error (1 sigma), not the prior's 1.8 deg, and the next fixes narrow it)
    assert abs(eng.sf[2] - s_z) <= 3.0 * sd[2]
    assert sd[2] <= SCALE_STATE_FACTOR * s_z / 3.0
    # the heading error stays inside its sigma all along, and the sigma ends at the target
    assert not r['silent'], r['why']
    assert abs(r['end_err'][2]) <= 3.0 * r['end_sigma'][2]
    assert r['end_sigma'][2] <= RTK_CAR_HEADING_SIGMA
    assert r['phase'] == 'aligned'


def test_without_the_states_the_scale_factor_grows_the_heading_error_unseen(
        rtk_car, monkeypatch):
    # not told and not found (self-check off): the turns put the 2 % into the heading
    # and the filter claims it does not (the "unseen" growth issue 44 describes)
    _, r = _run(rtk_car, gyro_scale_factor_ppm=0.0, gyro_misalignment_ppm=0.0,
                sensor_self_check=False)
    assert r['silent']
    # as model-error noise only (the states refused), the heading sigma is held up by the
    # turns above the target at the end
    monkeypatch.setattr(IntegratedNavigation, '_take_scale_states', lambda self, s: False)
    _, r = _run(rtk_car)
    assert not r['silent'] and r['end_sigma'][2] > RTK_CAR_HEADING_SIGMA


def test_the_published_heading_is_never_sharper_than_the_accelerometer_misalignment():
    eng = _engine()
    eng.velocity_measured = True
    eng.set_rotation_error(0.02, 0.005)
    eng.set_force_error(0.004, 0.005)
    P = eng.kf.P.copy()
    P[2, 2] = 1e-6                                     # heading 3.4'
    P[0, 2] = P[2, 0] = 5e-7                           # correlated with the tilt
    eng.kf.P = P
    C = eng.attitude_cov()
    # the misalignment's 0.5 % (17') of heading: row and column scaled together
    assert C[2, 2] == pytest.approx(0.005 ** 2, rel=1e-12)
    assert C[0, 2] == pytest.approx(5e-7 * 0.005 / 1e-3, rel=1e-12)
    assert C[0, 0] == P[0, 0]
    # a heading already wider keeps its own
    P[2, 2] = 0.01 ** 2
    eng.kf.P = P
    assert eng.attitude_cov()[2, 2] == P[2, 2]
