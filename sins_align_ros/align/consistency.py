"""Consistency monitor: whether the filter's innovations agree with its own covariance.

A filter whose model is too optimistic (a MEMS IMU with navigation-grade defaults, a
wrong noise parameter, a manoeuvre the model lacks) makes innovations larger than its
innovation covariance predicts, and its published sigma is then too small. The
monitor keeps the normalised innovation squared (NIS) of the last ``window`` GNSS
epochs; their sum is chi-square with the summed measurement sizes as degrees of
freedom when the filter is consistent. When the sum exceeds the ``probability``
quantile the filter is inconsistent: the monitor asks for the covariance to be
inflated by the median ratio of the observed to the expected NIS over the window
(capped at :data:`MAX_INFLATION`; the median, so that one outlier does not set it), the
window restarts, and the fine stage leaves ``aligned`` with the reason until the test passes
again. Each NIS is winsorised at the 0.9999 quantile of its own size first, so that
single GNSS outliers (the innovation gate's and the robust filters' business) do not
trigger it; a lasting model error does.

Not in the seeds (their filters adapt R or Q, or fade, each in its own way); this is
the one check every GNSS-aided filter shares, so that a published sigma stays a claim.
"""
import math
from collections import deque

import numpy as np

from ..filters.kf import chi2_quantile

#: epochs in the window
WINDOW = 10
#: probability of the chi-square test on the window's NIS sum
PROBABILITY = 0.999
#: an epoch's NIS counts at most the chi-square quantile of this probability
WINSOR = 0.9999
#: largest covariance inflation at one time
MAX_INFLATION = 10.0


class ConsistencyMonitor:
    """Windowed NIS test; see the module docstring."""

    def __init__(self, window=WINDOW, probability=PROBABILITY):
        self.window = int(window)
        self.probability = float(probability)
        self._nis = deque(maxlen=self.window)
        self._dof = deque(maxlen=self.window)
        self._raw = deque(maxlen=self.window)
        #: the last test passed (True until the window has filled)
        self.consistent = True
        #: NIS sum over degrees of freedom, and the test's bound on it, of the last test
        self.ratio = float('nan')
        self.bound = float('nan')
        self.n_inconsistent = 0
        self.n_inflations = 0

    def add(self, nis, dof):
        """Record one epoch's NIS with ``dof`` measurements; return an inflation factor or None.

        The factor (> 1) is returned when the window's test fails; the window then
        restarts, so the next verdict uses innovations of the inflated filter.
        """
        if not (dof > 0 and math.isfinite(nis)):
            return None
        self._nis.append(min(nis, chi2_quantile(WINSOR, dof)))
        self._dof.append(dof)
        self._raw.append(nis / dof)
        if len(self._nis) < self.window:
            return None
        s, m = sum(self._nis), sum(self._dof)
        self.ratio = s / m
        self.bound = chi2_quantile(self.probability, m) / m
        self.consistent = self.ratio <= self.bound
        if self.consistent:
            return None
        self.n_inconsistent += 1
        self.n_inflations += 1
        factor = min(max(float(np.median(self._raw)), self.ratio), MAX_INFLATION)
        self._nis.clear()
        self._dof.clear()
        self._raw.clear()
        return factor

    def status(self):
        """Figures for diagnostics."""
        return {'consistency_ok': self.consistent, 'consistency_nis_ratio': self.ratio,
                'consistency_bound': self.bound, 'consistency_inflations': self.n_inflations}
