"""Per-cell integrity statistics (``sins_align_ros.eval.integrity``) on hand-made arrays.

The rules of issue 21: a run is silently wrong with more than 5 % of its samples
outside 3 sigma on some published axis or any sample beyond 5 sigma; a heading
declared unknown (variance pi^2/3) is not a published sigma; a cell passes when no
run is silently wrong and at least 95 % of the runs end inside 3 sigma.
"""
import math

import numpy as np

from sins_align_ros.eval.integrity import (cell_stats, inside_at_end, judged_sharpness,
                                           outside_shares, published_sigma, silent_wrong,
                                           verdict)

UNKNOWN = math.pi ** 2 / 3.0


def _samples(n=100, outside=0, axis=0, value=3.5, sigma=1.0):
    """``n`` samples of error 1 sigma, ``outside`` of them at ``value`` sigma on ``axis``."""
    err = np.full((n, 3), sigma)
    err[:outside, axis] = value * sigma
    return err, np.full((n, 3), sigma)


def test_silent_wrong_rule_counts_the_share_outside_3_sigma_and_any_sample_beyond_5():
    # 5 of 100 samples outside 3 sigma is exactly 5 %: allowed; 6 is not
    assert silent_wrong(*_samples(outside=5)) == (False, '')
    wrong, why = silent_wrong(*_samples(outside=6, axis=1))
    assert wrong and why.startswith('N: 6%')
    # one sample beyond 5 sigma is enough, though it is 1 % of the samples
    wrong, why = silent_wrong(*_samples(outside=1, axis=2, value=5.01))
    assert wrong and why == 'U: a sample beyond 5 sigma'
    # exactly 3 sigma is inside
    assert outside_shares(*_samples(outside=50, value=3.0))[0] == 0.0
    assert outside_shares(*_samples(outside=50, value=3.01))[0] == 0.5


def test_an_unknown_heading_is_not_a_published_sigma_and_no_attitude_is_not_a_sample():
    P = np.tile(np.diag([1e-6, 4e-6, UNKNOWN]), (4, 1, 1))
    sig = published_sigma(P)
    assert np.allclose(sig[:, :2], [1e-3, 2e-3]) and np.all(np.isnan(sig[:, 2]))
    # a 100-rad "heading error" under an unknown heading claims nothing
    err = np.array([[1e-3, 1e-3, 100.0]] * 4)
    err[3] = np.nan                               # a row without attitude (a restart)
    assert silent_wrong(err, sig) == (False, '')
    assert np.array_equal(outside_shares(err, sig)[:2], [0.0, 0.0])
    assert np.isnan(outside_shares(err, sig)[2])
    assert inside_at_end(err[0], sig[0]) is True
    assert inside_at_end([4e-3, 0.0, 0.0], sig[0]) is False
    assert inside_at_end([np.nan] * 3, sig[0]) is None


def _run(err, sigma, silent=False, phase='fine', refused=False):
    e, s = np.asarray(err, float), np.asarray(sigma, float)
    return {'end_err': e, 'end_sigma': s, 'end_inside': inside_at_end(e, s),
            'silent': silent, 'why': 'E: test' if silent else '', 'phase': phase,
            'heading_unknown': bool(np.isfinite(e[2]) and np.isnan(s[2])),
            'refused': refused}


def test_cell_share_inside_rms_sharpness_and_verdict_on_known_runs():
    # 20 runs: 19 inside 3 sigma (95 %: passes), one at 4 sigma on east
    runs = [_run([1.0, -1.0, 2.0], [1.0, 1.0, 2.0], phase='aligned') for _ in range(19)]
    runs.append(_run([4.0, 1.0, 2.0], [1.0, 1.0, 2.0]))
    c = cell_stats(runs, limit=[1.0, 1.0, 2.0], spec=[1.0, 1.0, 2.0])
    assert c.runs == 20 and c.with_attitude == 20 and c.ended_inside == 0.95
    assert np.allclose(c.rms, [math.sqrt((19 + 16) / 20), 1.0, 2.0])
    assert np.allclose(c.sharpness, [1.0 / c.rms[0], 1.0, 1.0]) and c.aligned == 0.95
    assert verdict(c) == (True, 'ok')
    # one more outside: 19/21 = 90 %, and a silent-wrong run: both said
    runs.append(_run([0.0, 5.0, 0.0], [1.0, 1.0, 2.0], silent=True))
    ok, text = verdict(cell_stats(runs, [1.0, 1.0, 2.0], [1.0, 1.0, 2.0]))
    assert not ok and text == 'FAIL: 1 silent-wrong; ended inside 3 sigma 90%'


def test_sigma_too_wide_only_where_the_error_is_at_the_limit():
    # heading sigma 10 with an error of 1 at a limit of 1: 10x too wide
    runs = [_run([1.0, 1.0, s], [1.0, 1.0, 10.0]) for s in (1.0, -1.0)]
    c = cell_stats(runs, limit=[1.0, 1.0, 1.0], spec=[1.0, 1.0, 1.0])
    assert np.allclose(judged_sharpness(c), [1.0, 1.0, 10.0])
    assert verdict(c) == (False, 'FAIL: sigma too wide: U 10.0x')
    # a tilt bias that cancels by projection (limit 0.01, error 0.01): judged against the
    # spec limit 1, so a sigma of 1 is not too wide
    runs = [_run([1.0, 0.01, 1.0], [1.0, 1.0, 1.0]) for _ in range(2)]
    c = cell_stats(runs, limit=[1.0, 0.01, 1.0], spec=[1.0, 1.0, 1.0])
    assert c.sharpness[1] == 100.0 and judged_sharpness(c)[1] == 1.0 and verdict(c)[0]
    # an error far above the limit (not converged) is not judged for sharpness; no
    # finite limit (the gyro cannot find north): not judged either
    runs = [_run([10.0, 1.0, 1.0], [40.0, 1.0, 1.0]) for _ in range(2)]
    c = cell_stats(runs, limit=[1.0, 1.0, np.nan], spec=[1.0, 1.0, 1.0])
    assert np.isnan(judged_sharpness(c)[0]) and np.isnan(judged_sharpness(c)[2])
    assert verdict(c) == (True, 'ok (RMS > 1.5x limit: E)')


def test_refusals_unknown_headings_and_missing_attitudes_are_said_not_failed():
    nan3 = [np.nan] * 3
    c = cell_stats([_run(nan3, nan3, refused=True) for _ in range(3)], [1.0, 1.0, 1.0])
    assert c.refused == 3 and math.isnan(c.ended_inside)
    assert verdict(c) == (True, 'refused (correctly: stationary model on a moving base)')
    runs = [_run([0.5, 0.5, 3.0], [1.0, 1.0, np.nan]) for _ in range(2)] + [_run(nan3, nan3)]
    c = cell_stats(runs, [1.0, 1.0, np.nan])
    assert c.heading_unknown == 2 and c.ended_inside == 1.0 and np.isnan(c.sigma[2])
    assert verdict(c) == (True, 'ok (1 without attitude at the end; heading declared '
                                'unknown)')
