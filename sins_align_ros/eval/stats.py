"""Statistics over Monte Carlo runs: accuracy, sharpness and consistency of a filter.

Accuracy: mean and RMS of the final errors; sharpness: the mean reported 1-sigma;
consistency: the share of runs whose error is inside ``k`` reported sigma and the
mean NEES (:func:`~.errors.nees`; 3 for a consistent filter on 3 axes).
"""
from types import SimpleNamespace

import numpy as np


def rms(x, axis=0):
    """Root mean square along ``axis``."""
    x = np.asarray(x, dtype=float)
    return np.sqrt((x ** 2).mean(axis=axis))


def error_summary(err, sigma, k=3.0):
    """Per-axis statistics of final errors ``err`` (n, 3) with their reported ``sigma`` (n, 3).

    Returns ``n``, ``mean``, ``rms``, ``sigma`` (mean reported sigma) and ``inside``
    (share of runs with ``|err| <= k sigma``), each (3,); NaN without runs.
    """
    e = np.asarray(err, dtype=float)
    s = np.asarray(sigma, dtype=float)
    if len(e) == 0:
        nan = np.full(3, np.nan)
        return SimpleNamespace(n=0, mean=nan, rms=nan.copy(), sigma=nan.copy(),
                               inside=nan.copy())
    return SimpleNamespace(n=len(e), mean=e.mean(axis=0), rms=rms(e), sigma=s.mean(axis=0),
                           inside=(np.abs(e) <= k * s).mean(axis=0))


def mean_nees(values):
    """Mean of the finite NEES values (NaN if none)."""
    return float(np.mean([v for v in values if np.isfinite(v)] or [np.nan]))
