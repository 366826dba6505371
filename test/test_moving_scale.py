"""Gyro scale factors as states of the seed 000 engine (ASCKF; issue 44, engines/gyro_scale.py).

The square-root filter appends the states to its factor ``S`` (``ASCKF.append_states``), the
nonlinear transition takes ``C~ diag(w_b) ds`` into its drift, and a turning car's heading
no longer pays the told scale factor again at each turn.
"""
import math

import numpy as np
import pytest

from sins_align_ros.align.engines.moving import I_EPS, MovingBaseAlignment
from sins_align_ros.eval.integrity import run_integrity
from sins_align_ros.eval.run import run_pipeline
from sins_align_ros.eval.scenarios import simulate
from sins_align_ros.nav import earth
from sins_align_ros.sim.presets import SENSOR_GRADES, alignment_params, scenario
from sins_align_ros.units import DEG, DPH
from tolerance import assert_roundoff

LAT = 0.6
RATE = 100.0
#: the told gyro scale factor and misalignment (a MEMS triad's class, the self-check's)
SCALE, MISALIGNMENT = 0.02, 0.005


def _engine(square_root=True):
    """A 13-state ASCKF (CKF) engine at rest, heading known to 0.5 deg, no process noise."""
    P0 = np.diag(np.r_[[0.1 ** 2] * 2, [1.0] * 2, [(0.1 * DEG) ** 2] * 2, (0.5 * DEG) ** 2,
                       [(10.0 * DPH) ** 2] * 3])
    P0[4, 6] = P0[6, 4] = 0.5 * 0.1 * 0.5 * DEG ** 2          # a tilt-heading correlation
    return MovingBaseAlignment(np.eye(3), np.zeros(3), LAT, 2.0, 0.0, P0, np.zeros(10),
                               np.eye(2), square_root=square_root, fading=False,
                               adaptive=False, accel_bias=0.01)


def test_the_states_are_appended_to_the_factor_and_a_turn_moves_the_heading_by_them():
    eng = _engine()
    # no GNSS velocity measured yet: the noise keeps the scale factors
    eng.set_rotation_error(SCALE, MISALIGNMENT)
    assert eng.i_sf is None and eng._rot_sigma[0] > 0.0
    S_old, P_old = eng.kf.S.copy(), eng.kf.P
    eng.velocity_measured = True
    eng._interval_ended(0.0)
    assert eng.n == 16 and eng.i_sf == slice(13, 16) and eng._rot_sigma[0] == 0.0
    S = eng.kf.S
    # the old factor is kept as it was, the new block is diagonal: S stays lower triangular
    assert np.array_equal(S[:13, :13], S_old) and np.array_equal(S, np.tril(S))
    assert not S[13:, :13].any() and len(eng.kf.x) == len(eng.kf.Q) == len(eng.Qc) == 16
    P = eng.kf.P
    # P's old block: dot products of 13 terms, the same terms plus zeros
    assert_roundoff(P[:13, :13], P_old, 13, what='P old block')
    assert not P[:13, 13:].any()
    # the new variances: a square root squared (two roundings)
    assert_roundoff(np.diag(P)[13:], SCALE ** 2, 2, what='scale-factor variances')
    assert eng.kf.var_max[13:].tolist() == np.diag(P)[13:].tolist()

    # a 90 deg turn about body z in 1 s: the transition moves the heading by -A ds_z and
    # leaves the drift and the scale factors as they were
    A, T = math.radians(90.0), 1.0
    g = earth.gravity(LAT, 0.0)
    for _ in range(int(RATE * T)):
        eng.step_imu(np.array([0.0, 0.0, A / RATE / T]), np.array([0.0, 0.0, g / RATE]),
                     1.0 / RATE)
    fx = eng._transition()
    d = 1e-4
    X = np.zeros((16, 2))
    X[15, 1] = d
    Y = fx(X)
    # the rest of the model couples the heading to the tilts by the earth rate over T
    # (w_ie T = 7e-5 of it), nothing else
    assert Y[6, 1] - Y[6, 0] == pytest.approx(-A * d, rel=1e-3)
    assert np.array_equal(Y[I_EPS], X[I_EPS]) and np.array_equal(Y[13:], X[13:])
    # the feedback moves the estimate into the compensation and zeroes it in the filter
    eng.kf.x[15] = 0.01
    eng._feedback(None)
    assert eng.sf[2] == 0.01 and eng.kf.x[15] == 0.0
    assert eng._correct_imu(np.array([0.0, 0.0, 0.101]), np.zeros(3), 0.01)[0][2] \
        == pytest.approx(0.1, rel=1e-12)
    assert 'gyro_scale_factor_ppm' in eng.status()


@pytest.mark.parametrize('square_root', [False, True], ids=['ckf', 'asckf'])
def test_the_append_keeps_the_drift_and_the_bias_the_filter_holds(square_root):
    # the seed 000 engine keeps its drift and accelerometer bias in the filter between
    # epochs: the states come in at an interval's end and must not reset them
    eng = _engine(square_root)
    x = np.r_[np.zeros(7), np.array([3.0, -2.0, 1.0]) * DPH, 0.01, -0.02, 0.03]
    eng.kf.x = x.copy()
    eng.velocity_measured = True
    eng.set_rotation_error(SCALE, MISALIGNMENT)
    assert eng.i_sf == slice(13, 16)
    assert np.array_equal(eng.kf.x, np.r_[x, np.zeros(3)])


@pytest.fixture(scope='module')
def mems_car():
    """car_rtk (still 30 s, then town driving with 90 deg junction turns, RTK at 5 Hz) with
    the plain MEMS grade: no gyro scale factor at all, which the self-check still models at
    its MEMS class's 2 %."""
    sc = scenario('car_rtk', duration=510.0)
    sc.imu = SENSOR_GRADES['mems'].with_(random_bias=False)
    assert sc.imu.gyro_scale_ppm == 0.0
    return sc, simulate(sc, 2)


def _run(mems_car):
    sc, data = mems_car
    run = run_pipeline(alignment_params(sc, 'asckf'), data)
    out = run.out
    late = out.t >= 300.0                   # after the first minutes of turns with RTK
    peak = float(np.sqrt(out.P_phi[late, 2, 2].max()))
    return run, run_integrity(run, sc.imu_rate_hz), peak


def test_a_turning_car_does_not_pay_the_told_scale_factor_again_at_each_turn(
        mems_car, monkeypatch):
    run, r, peak = _run(mems_car)
    eng = run.pipeline.engine
    told = eng.sf_wanted
    assert told >= SCALE and eng.i_sf is not None
    # a 90-deg junction turn with the scale factor as noise adds (told x 90 deg)^2 to the
    # heading variance; as states, the turns have pinned it and later turns add less
    turn = told * math.pi / 2
    assert peak < turn
    sd = np.sqrt(np.diag(eng.kf.P)[eng.i_sf])
    assert abs(eng.sf[2]) <= 3.0 * sd[2]            # the truth is 0
    assert not r['silent'], r['why']
    assert abs(r['end_err'][2]) <= 3.0 * r['end_sigma'][2]
    # the same run with the states refused: every junction turn pays the whole of it
    monkeypatch.setattr(MovingBaseAlignment, '_take_scale_states', lambda self, s: False)
    run, r, peak = _run(mems_car)
    assert run.pipeline.engine.i_sf is None and peak >= turn
