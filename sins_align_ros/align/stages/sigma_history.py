"""The fine stage's variance history, the trend a moving-base forecast extrapolates.

Kept by :class:`~.fine_stage.FineStage`, read by :mod:`.expectation`; its own module so
that the fine stage does not import the forecast built on it.
"""
from collections import deque

import numpy as np

#: the moving-base trend is fitted over this much history, s
TREND_S = 12.0
#: spacing of the variance history, s
HISTORY_STEP_S = 1.0


class SigmaHistory:
    """The fine stage's misalignment variances (E, N, U), one per :data:`HISTORY_STEP_S`."""

    def __init__(self):
        self.t = deque()
        self.P = deque()

    def add(self, t, P_diag):
        """Record variances (3,) rad^2 at ``t`` (dropped when the last is too recent)."""
        if self.t and t - self.t[-1] < HISTORY_STEP_S:
            return
        self.t.append(float(t))
        self.P.append(np.array(P_diag, dtype=float))
        while self.t[0] < t - TREND_S:
            self.t.popleft()
            self.P.popleft()

    def arrays(self):
        """Return ``(t (M,), P (M, 3))``."""
        return np.array(self.t), np.array(self.P).reshape(-1, 3)
