"""The innovation-consistency monitor: its test, its remedy and the phase it leaves."""
import numpy as np
import pytest

from sins_align_ros.align.consistency import MAX_INFLATION, WINDOW, ConsistencyMonitor
from sins_align_ros.align.moving import MovingBaseAlignment


def _feed(mon, nis, dof=4):
    return [mon.add(float(v), dof) for v in nis]


def test_consistent_innovations_never_inflate():
    rng = np.random.default_rng(7)
    mon = ConsistencyMonitor()
    out = _feed(mon, rng.chisquare(4, size=50 * WINDOW))
    assert all(f is None for f in out) and mon.consistent
    assert 0.7 < mon.ratio < 1.3 and mon.n_inflations == 0


def test_a_too_optimistic_filter_is_inflated_by_its_nis_ratio_and_recovers():
    rng = np.random.default_rng(8)
    mon = ConsistencyMonitor()
    out = _feed(mon, 10.0 * rng.chisquare(4, size=WINDOW))      # innovations 10x too large
    assert out[:-1] == [None] * (WINDOW - 1)
    assert out[-1] == pytest.approx(10.0, rel=0.4) and not mon.consistent
    assert not mon.consistent                                    # until a window passes
    _feed(mon, rng.chisquare(4, size=WINDOW - 1))
    assert not mon.consistent
    _feed(mon, rng.chisquare(4, size=1))
    assert mon.consistent and mon.n_inflations == 1
    assert _feed(ConsistencyMonitor(), [1e9] * WINDOW)[-1] == MAX_INFLATION    # capped


def test_one_gnss_outlier_does_not_inflate():
    rng = np.random.default_rng(9)
    nis = rng.chisquare(4, size=WINDOW)
    nis[3] = 1e4
    assert _feed(ConsistencyMonitor(), nis) == [None] * WINDOW


def test_inflation_scales_the_covariance_and_the_process_noise():
    eng = MovingBaseAlignment(np.eye(3), np.zeros(3), 0.5, 2.0, 0.0, np.eye(10) * 1e-4,
                              np.full(10, 1e-8), np.eye(2), square_root=False)
    P, Qc = eng.kf.P.copy(), eng.Qc.copy()
    eng.inflate(5.0)
    np.testing.assert_allclose(eng.kf.P, 5.0 * P)
    np.testing.assert_allclose(eng.Qc, 5.0 * Qc)
    for _ in range(10):
        eng.inflate(100.0)
    np.testing.assert_allclose(eng.Qc, 1e4 * Qc)                 # process noise capped


def test_inflation_never_makes_an_angle_less_known_than_a_full_circle():
    eng = MovingBaseAlignment(np.eye(3), np.zeros(3), 0.5, 2.0, 0.0, np.eye(10) * 0.5,
                              np.full(10, 1e-8), np.eye(2), square_root=False)
    eng.inflate(10.0)
    P = eng.kf.P
    np.testing.assert_allclose(np.diag(P)[4:7], np.pi ** 2 / 3.0)   # capped misalignment
    np.testing.assert_allclose(np.diag(P)[:4], 5.0)                 # other states inflated
    assert np.all(np.linalg.eigvalsh(P) > 0.0)
