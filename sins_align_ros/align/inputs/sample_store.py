"""The IMU samples of the last seconds, kept so that a restart reuses them (issue 46).

When GNSS shows a base that a still-base fine filter was aligning start to move, the
pipeline restarts from coarse alignment. Opening an empty window there threw the rest
before the motion away, and the new window, all motion, had no rest for the sensor
self-check and so waited out the whole ``coarse_duration`` (a car that stood 90 s, then
drove: ``aligned`` about 60 s after it started). The restart instead begins its window
with the stored samples from ``coarse_min_duration`` (plus a margin; at most
:data:`KEEP_S`) before the motion's onset, so that the window may end
``coarse_motion_s`` after the onset as on a first start (:class:`~.motion.Onset`). Their
rows were published already and are not
published again: the samples only fill the coarse window.

Bounded: at most :data:`KEEP_S` seconds (at 1 kHz about 1.7 MB).
"""
from collections import deque

import numpy as np

#: seconds of samples kept
KEEP_S = 40.0


class SampleStore:
    """Processed IMU samples (vehicle frame) of the last :data:`KEEP_S` seconds."""

    def __init__(self, keep_s=KEEP_S):
        self.keep_s = float(keep_s)
        self._parts = deque()

    def push(self, t, dtheta, dv):
        """Keep samples with stamps ``t`` (N,) and increments ``dtheta``, ``dv`` (N, 3)."""
        if not len(t):
            return
        self._parts.append((np.array(t, dtype=float), np.array(dtheta, dtype=float),
                            np.array(dv, dtype=float)))
        while self._parts and self._parts[0][0][-1] < t[-1] - self.keep_s:
            self._parts.popleft()

    def since(self, t0, t1=np.inf):
        """Return the kept samples stamped in ``(t0, t1]``: ``(t_before, t, dtheta, dv)`` or None.

        ``t_before``: the stamp the first returned sample's interval starts at (the sample
        before it; with none kept before, one interval like the next one earlier). ``t1``:
        the last sample processed (a block is kept whole before it is processed, and a stage
        may end inside it).
        """
        if not self._parts:
            return None
        t = np.concatenate([p[0] for p in self._parts])
        k = int(np.searchsorted(t, t0, side='right'))
        m = int(np.searchsorted(t, t1, side='right'))
        if k >= m:
            return None
        dth = np.concatenate([p[1] for p in self._parts])
        dv = np.concatenate([p[2] for p in self._parts])
        if k > 0:
            t_before = t[k - 1]
        else:                       # nothing kept before it: an interval like the next one
            t_before = t[0] - (t[1] - t[0] if len(t) > 1 else 0.0)
        return t_before, t[k:m], dth[k:m], dv[k:m]
