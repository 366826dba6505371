"""From stamped IMU rate samples to increments, with the input checks.

Shared by the node and the replay tool so both treat bad input the same way.
A sample ``(t, w_b, f_b)`` (s, rad/s, m/s^2; the mean rate and specific force
over the interval ending at ``t``) becomes ``dtheta = w_b dt``, ``dv = f_b dt``
with ``dt = t - t_previous``. Rules, each counted by reason:

* non-finite values: the sample is skipped (``nan``);
* a stamp equal to or before the previous one: skipped (``stamp_not_increasing``),
  unless it is more than ``max_gap`` earlier: the clock jumped back (a looping
  bag, a restarted simulator) and the caller must reset (``clock_jump_back``);
* a stamp more than ``max_gap`` after the previous one: a gap (``gap``); the
  caller restarts the alignment from this sample's stamp;
* the very first sample starts the clock (its interval is unknown).
"""
from collections import Counter

import numpy as np

OK, SKIP, RESET, START = 0, 1, 2, 3


class ImuInput:
    """Stateful converter; see the module docstring.

    Parameters
    ----------
    max_gap : float
        Largest accepted stamp interval, s.
    """

    def __init__(self, max_gap=0.5):
        self.max_gap = float(max_gap)
        self.t_last = None
        self.counts = Counter()
        self.last_reason = ''

    def restart(self):
        """Forget the clock (the next sample starts it again)."""
        self.t_last = None

    def push(self, t, w_b, f_b):
        """Check one sample.

        Returns
        -------
        action : int
            OK (``dtheta``, ``dv`` valid), SKIP (drop the sample), START (the first
            sample: its stamp starts the clock) or RESET (the caller must reset its
            pipeline; the clock restarts at this sample's stamp).
        dtheta, dv : ndarray (3,) or None
        """
        w_b = np.asarray(w_b, dtype=float)
        f_b = np.asarray(f_b, dtype=float)
        if not (np.isfinite(t) and np.all(np.isfinite(w_b)) and np.all(np.isfinite(f_b))):
            return self._reject('nan', 'non-finite value in IMU sample')
        if self.t_last is None:
            self.t_last = t
            self.counts['clock_start'] += 1
            return START, None, None
        dt = t - self.t_last
        if dt <= 0.0:
            if dt < -self.max_gap:
                self.t_last = t
                self.counts['clock_jump_back'] += 1
                self.last_reason = f'IMU stamp jumped back by {-dt:.3f} s: restarting'
                return RESET, None, None
            return self._reject('stamp_not_increasing',
                                f'IMU stamp not increasing (dt = {dt * 1e3:.3f} ms)')
        if dt > self.max_gap:
            self.t_last = t
            self.counts['gap'] += 1
            self.last_reason = f'gap of {dt:.3f} s in IMU data (max_gap {self.max_gap} s)'
            return RESET, None, None
        self.t_last = t
        self.counts['accepted'] += 1
        return OK, w_b * dt, f_b * dt

    def _reject(self, key, reason):
        self.counts[key] += 1
        self.last_reason = reason
        return SKIP, None, None

    @property
    def rejected(self):
        """Number of samples rejected for bad values or stamps."""
        return self.counts['nan'] + self.counts['stamp_not_increasing']

    def convert(self, t, w_b, f_b):
        """Vectorised conversion of a whole recording (N,), (N, 3), (N, 3).

        Returns a list of segments ``(t0, t (M,), dtheta (M, 3), dv (M, 3))``: each
        segment starts its clock at ``t0``; a new segment follows every gap or
        backward clock jump. Rejected samples are dropped and counted.
        """
        t = np.asarray(t, dtype=float)
        segments, cur = [], None
        for k in range(len(t)):
            action, dth, dv = self.push(t[k], w_b[k], f_b[k])
            if action in (RESET, START):
                if cur is not None and cur[1]:
                    segments.append(cur)
                cur = (t[k], [], [], [])
            elif action == OK:
                cur[1].append(t[k])
                cur[2].append(dth)
                cur[3].append(dv)
        if cur is not None and cur[1]:
            segments.append(cur)
        return [(t0, np.array(tt), np.array(a), np.array(b)) for t0, tt, a, b in segments]
