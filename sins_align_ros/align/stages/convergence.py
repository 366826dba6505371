"""When the fine filter has converged: the heading sigma stopped shrinking.

The heading 1-sigma of the last ten seconds is kept; once a stage has run for
``min_duration`` seconds and the sigma has fallen by less than 2 % over at least
nine seconds, the stage has converged (the still-base stage then restages the
stationary filter where that helps; ``aligned`` is the settle test's,
:mod:`.aligned_gate`). Epochs at the same stamp count once, with the last sigma.
"""
from collections import deque

#: the window over which the sigma must keep falling, s
WINDOW_S = 10.0
#: the window must span at least this long, s
MIN_SPAN_S = 9.0
#: a sigma that fell below this fraction of the window's first is still converging
SHRINK = 0.98


class ConvergenceMonitor:
    """Heading-sigma history of the current stage; ``min_duration`` s before any verdict."""

    def __init__(self, min_duration):
        self.min_duration = float(min_duration)
        self.history = deque()
        self.t0 = None

    def start(self, t):
        """Start a stage at ``t``: forget the history."""
        self.t0 = t
        self.history.clear()

    def converged(self, t, sigma_heading):
        """Record the heading sigma (rad) at ``t``; tell whether the stage has converged."""
        h = self.history
        if h and h[-1][0] == t:
            # several epochs at one stamp (GNSS, then an external heading): the last counts,
            # else the window could start at the higher value of a pair for ever
            h.pop()
        h.append((t, sigma_heading))
        while h and h[0][0] < t - WINDOW_S:
            h.popleft()
        if t - self.t0 < self.min_duration:
            return False
        t_old, s_old = h[0]
        return not (t - t_old < MIN_SPAN_S or sigma_heading < SHRINK * s_old)
