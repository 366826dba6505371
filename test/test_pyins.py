"""Cross-check of our IMU simulator against an independent one: pyins (PyPI python-ins).

Issue 8: the same static and swaying trajectory through both simulators gives the
same increments after the frame conversion (NED/FRD -> ENU/FLU): to round-off
(1e-14 rad) for the gyros; for the accelerometers to the difference of the two
gravity models on a still base (a constant vertical 0.07 micro-g at 34 N) and to
pyins's piecewise-linear acceleration under sway (1e-10 m/s per sample); pyins's
last spline interval (its boundary condition) aside.
"""
import numpy as np
import pytest

from sins_align_ros.eval.pyins_sim import pyins_increments, simulate_with_pyins, truth_on_grid
from sins_align_ros.eval.run import run_pipeline
from sins_align_ros.eval.scenarios import simulate
from sins_align_ros.nav.frames import attitude_error, quat_to_dcm
from sins_align_ros.sim.imu import ideal_increments
from sins_align_ros.sim.presets import alignment_params, scenario
from sins_align_ros.sim.trajectory import PositionIntegrator
from sins_align_ros.units import ARCMIN
from tolerance import assert_roundoff

pytest.importorskip('pyins', reason='python-ins (requirements-test.txt) is not installed')

RATE = 100.0
#: pyins forms an angle increment by differencing attitudes (unit-size quaternion products,
#: a rotation vector: ~30 operations, with its cubic spline of rotation vectors ~20 and the
#: NED/FRD change 5); ours is a 4-point quadrature of rates (~30): ~100 operations whose
#: round-off is on the attitudes' unit size, not on the 1e-6 increment (tolerance.py)
N_INCREMENT = 100


def ours(traj, t):
    return ideal_increments(traj, t, PositionIntegrator(traj).advance(float(t[-1])))


def test_still_base_increments_agree_to_round_off():
    traj = scenario('static_navigation').trajectory
    t = np.arange(6001) / RATE
    dth, dv = ours(traj, t)
    dth_p, dv_p = pyins_increments(traj, t)
    assert_roundoff(dth_p, dth, N_INCREMENT, 1.0)               # rad, of 5e-7 per sample
    d = dv_p - dv
    # the two gravity models differ by a constant: 7e-7 m/s^2 (0.07 ug) here. pyins's
    # velocity increments come from its own integration over an ellipsoid (an independent
    # package's accuracy, not a round-off count of ours): 1e-12 m/s of 0.098
    assert np.max(np.abs(d[:, :2])) < 1e-12                     # of 0.098 m/s
    assert abs(np.mean(d[:, 2])) < 2e-8 and np.std(d[:, 2]) < 1e-12


@pytest.mark.parametrize('name', ['ship_sway', 'seed000_case1'])
def test_swaying_base_increments_agree_to_round_off_inside_the_spline(name):
    """Inside the grid the two agree to round-off; only pyins's last spline interval
    (its boundary condition) is off, and by less when its grid is denser."""
    traj = scenario(name).trajectory
    t = np.arange(3001) / RATE
    dth, dv = ours(traj, t)
    dth_p, dv_p = pyins_increments(traj, t)
    inner = slice(100, -100)
    assert_roundoff(dth_p[inner], dth[inner], N_INCREMENT, 1.0)  # rad, of 9e-4 per sample
    # pyins's acceleration is linear inside an interval (Hermite spline of position and
    # velocity); with the body turning inside the interval that leaves ~1e-10 m/s
    assert np.max(np.abs(dv_p - dv)[inner]) < 1e-9             # m/s, of 0.1 per sample
    end = np.max(np.abs(dth_p - dth))
    assert end < 1e-6 * np.max(np.abs(dth))
    t2 = np.arange(6001) / (2 * RATE)
    dth_2, _ = pyins_increments(traj, t2)
    assert np.max(np.abs(dth_2[0::2] + dth_2[1::2] - dth)) < end / 5.0


def test_filters_see_the_same_run_on_either_simulator():
    """Same seed, same error draws: only the ideal increments differ, so do the results."""
    sc = scenario('static_navigation', duration=200.0)
    ref = simulate(sc, seed=7)
    alt = simulate_with_pyins(sc, seed=7)
    assert np.array_equal(alt.gnss.t, ref.gnss.t)
    assert_roundoff(alt.imu.dtheta, ref.imu.dtheta, N_INCREMENT, 1.0)   # as above
    euler_true, _, _ = truth_on_grid(sc.trajectory, np.r_[0.0, ref.imu.t])
    # the same trajectory's angles two ways (~50 operations), yaw up to pi, pitch ~0
    assert_roundoff(euler_true[1:], ref.imu.euler, 50, np.pi)
    finals = []
    for data in (ref, alt):
        out = run_pipeline(alignment_params(sc, 'reduced7', coarse_duration=30.0), data).out
        finals.append(quat_to_dcm(out.q[-1]))
    assert np.max(np.abs(attitude_error(finals[0], finals[1]))) < 1e-3 * ARCMIN
