"""From stamped IMU rate samples to increments, with the input checks.

Shared by the node and the replay tool so both treat bad input the same way.
A sample ``(t, w_b, f_b)`` (s, rad/s, m/s^2; the mean rate and specific force
over the interval ending at ``t``) becomes ``dtheta = w_b dt``, ``dv = f_b dt``
with ``dt = t - t_previous``. Rules, each counted by reason (the keys of
:attr:`ImuInput.counts`):

* ``nan``: a non-finite value: the sample is skipped;
* ``saturated``: a component at or beyond the sensor range (``gyro_range``,
  ``accel_range``): skipped (the next good sample's interval covers it, so the
  rate is held over the saturated stretch; a stretch longer than ``max_gap``
  becomes a gap);
* ``field_missing``, ``wrong_frame``: counted by the caller through
  :meth:`ImuInput.reject_missing_field` (a message whose angular velocity or
  acceleration covariance[0] is -1, i.e. the field is not provided) or
  :meth:`ImuInput.reject` (a frame other than the configured one): skipped;
* ``stamp_not_increasing``: a stamp equal to or before the previous one
  (zero or negative dt, repeated or out-of-order messages): skipped, unless it
  is more than ``max_gap`` earlier: ``clock_jump_back`` (a looping bag, a
  restarted simulator, a ``use_sim_time`` reset) and the caller must reset;
* ``gap``: a stamp more than ``max_gap`` after the previous one (a dropped
  stretch or a forward clock jump): the caller restarts the alignment from this
  sample's stamp;
* ``bridged``: an interval longer than 1.5 nominal intervals but within
  ``max_gap`` (dropped or skipped samples): accepted, with the mean of the
  rates before and after the interval (trapezoid) over it; :attr:`ImuInput.bridge`
  then holds ``(var_phi, var_v)``, the variance (rad^2, (m/s)^2) of the attitude
  and velocity error the bridge may leave, ``(|w_after - w_before| dt / 2)^2``
  and likewise for the specific force, which the caller adds to the filter's
  covariance (:meth:`~sins_align_ros.align.pipeline.AlignmentPipeline.widen`) so
  that a bridge on a swaying base cannot leave a silently wrong attitude
  (after a rate drop, samples are bridged until the nominal interval has caught up);
* ``rate_change``: the nominal interval (median of the last
  :data:`RATE_WINDOW` intervals) moved by more than 20 %: accepted (the
  increments use each sample's own interval), reported once per change;
* the very first sample starts the clock (its interval is unknown).

Reasons that the caller should report are queued in :attr:`ImuInput.notices`
as ``(key, text)``; :meth:`ImuInput.pop_notices` drains them.
"""
import math
import statistics
from collections import Counter, deque

import numpy as np

OK, SKIP, RESET, START = 0, 1, 2, 3
#: samples over which the nominal interval is the median
RATE_WINDOW = 50
#: reasons for which a sample is skipped
SKIP_REASONS = ('nan', 'saturated', 'field_missing', 'wrong_frame', 'stamp_not_increasing',
                'undecodable')


def intervals(t, t_prev):
    """Sample intervals ``dt`` (N,) of stamps ``t`` (N,) after ``t_prev``, s.

    ``dt[0] = t[0] - t_prev``, ``dt[k] = t[k] - t[k-1]``: ``np.diff(t, prepend=t_prev)``,
    the same numbers without its concatenation (a block of samples at every GNSS epoch).
    """
    dt = np.empty(len(t))
    if len(t):
        dt[0] = t[0] - t_prev
        np.subtract(t[1:], t[:-1], out=dt[1:])
    return dt


class ImuInput:
    """Stateful converter; see the module docstring.

    Parameters
    ----------
    max_gap : float
        Largest accepted stamp interval, s.
    gyro_range, accel_range : float
        Sensor range, rad/s and m/s^2 (``inf``: not checked); a component whose
        magnitude reaches 0.999 of it is taken as saturated.
    """

    def __init__(self, max_gap=0.5, gyro_range=np.inf, accel_range=np.inf):
        self.max_gap = float(max_gap)
        self.gyro_range = float(gyro_range)
        self.accel_range = float(accel_range)
        self.t_last = None
        self.counts = Counter()
        self.last_reason = ''
        self.notices = deque(maxlen=100)
        self.dt_nominal = None
        self._dts = deque(maxlen=RATE_WINDOW)
        self._wf_prev = None
        #: (var_phi, var_v) of the last accepted sample if it bridged an interval, else None
        self.bridge = None

    @classmethod
    def from_params(cls, p):
        """Checker for alignment parameter values ``p`` (``max_gap``, the sensor ranges)."""
        conv = cls()
        conv.set_params(p)
        return conv

    def set_params(self, p):
        """Take ``max_gap`` and the sensor ranges from alignment parameter values ``p``."""
        self.max_gap = float(p['max_gap'])
        self.gyro_range = math.radians(p['gyro_range_dps'])
        self.accel_range = float(p['accel_range_mps2'])

    def reject_missing_field(self):
        """Count a message that marks its rates or accelerations as not provided."""
        return self.reject('field_missing', 'angular velocity or linear acceleration not '
                                            'provided (covariance[0] = -1): sample skipped')

    def restart(self):
        """Forget the clock (the next sample starts it again)."""
        self.t_last = None
        self._wf_prev = None

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
            return self.reject('nan', 'non-finite value in IMU sample')
        if (np.max(np.abs(w_b)) >= 0.999 * self.gyro_range
                or np.max(np.abs(f_b)) >= 0.999 * self.accel_range):
            return self.reject('saturated', 'IMU sample at the sensor range (saturated)')
        self.bridge = None
        if self.t_last is None:
            self.t_last = t
            self._wf_prev = (w_b, f_b)
            self.counts['clock_start'] += 1
            return START, None, None
        dt = t - self.t_last
        if dt <= 0.0:
            if dt < -self.max_gap:
                self.t_last = t
                self._wf_prev = (w_b, f_b)
                self._restart_rate()
                return self._reset('clock_jump_back',
                                   f'IMU stamp jumped back by {-dt:.3f} s: restarting')
            return self.reject('stamp_not_increasing',
                               f'IMU stamp not increasing (dt = {dt * 1e3:.3f} ms)')
        if dt > self.max_gap:
            self.t_last = t
            self._wf_prev = (w_b, f_b)
            self._restart_rate()
            return self._reset('gap', f'gap of {dt:.3f} s in IMU data (max_gap '
                                      f'{self.max_gap} s)')
        self.t_last = t
        self.counts['accepted'] += 1
        w_prev, f_prev = self._wf_prev
        self._wf_prev = (w_b, f_b)
        if self._track_rate(dt):
            self.bridge = (float(np.sum((w_b - w_prev) ** 2)) * dt * dt / 4.0,
                           float(np.sum((f_b - f_prev) ** 2)) * dt * dt / 4.0)
            return OK, 0.5 * (w_b + w_prev) * dt, 0.5 * (f_b + f_prev) * dt
        return OK, w_b * dt, f_b * dt

    def push_run(self, t, w_b, f_b):
        """Accept the longest leading run of samples :meth:`push` would take as plain OK.

        ``t`` (N,), ``w_b``, ``f_b`` (N, 3). A sample ends the run when :meth:`push`
        would do anything else with it (the first sample of a clock, a bad value, a
        saturated component, a stamp not increasing, a gap, a bridge); the caller gives
        that sample to :meth:`push`. The nominal rate is re-estimated inside the run
        where :meth:`push` would (every :data:`RATE_WINDOW` accepted samples), so the
        state afterwards is exactly as if :meth:`push` had taken each sample of the run.

        Returns ``(n, dtheta, dv)``: the run's length (0: give ``t[0]`` to
        :meth:`push`) and its increments ((n, 3) each).
        """
        if self.t_last is None or self.dt_nominal is None or len(t) == 0:
            return 0, None, None
        t = np.asarray(t, dtype=float)
        w_b = np.asarray(w_b, dtype=float)
        f_b = np.asarray(f_b, dtype=float)
        dt = intervals(t, self.t_last)
        # (a NaN or infinite component fails its range test: no separate finiteness test;
        # the stamps are finite where every interval is, from a finite t_last)
        g_max, a_max = 0.999 * self.gyro_range, 0.999 * self.accel_range
        dt_max = dt.max()
        if (np.abs(w_b).max() < g_max and np.abs(f_b).max() < a_max
                and dt.min() > 0.0 and dt_max <= self.max_gap and dt_max < math.inf):
            n = len(t)                     # the usual block: every sample plain
        else:
            dt_max = math.inf
            plain = (np.isfinite(t) & (np.abs(w_b).max(axis=1) < g_max)
                     & (np.abs(f_b).max(axis=1) < a_max) & (dt > 0.0) & (dt <= self.max_gap))
            n = len(t) if plain.all() else int(np.argmin(plain))
        dts = dt[:n].tolist()
        k, bridge, nominal = 0, n, None
        while k < n:               # one stretch per rate window: the bridge test's nominal
            if self.dt_nominal != nominal:          # the first bridge under this nominal
                nominal = self.dt_nominal
                bridges = (() if dt_max <= 1.5 * nominal       # (dt_max: of dt[:n], or inf)
                           else np.flatnonzero(dt[k:n] > 1.5 * nominal))
                bridge = k + int(bridges[0]) if len(bridges) else n
            end = min(n, k + RATE_WINDOW - self.counts['accepted'] % RATE_WINDOW)
            stop = min(bridge, end)
            self.counts['accepted'] += stop - k
            self._dts.extend(dts[k:stop])
            k = stop
            if stop < end:
                break
            self._renew_rate()
        if k == 0:
            return 0, None, None
        self.t_last = float(t[k - 1])
        self._wf_prev = (w_b[k - 1].copy(), f_b[k - 1].copy())
        self.bridge = None
        return k, w_b[:k] * dt[:k, None], f_b[:k] * dt[:k, None]

    def _reset(self, key, reason):
        self.counts[key] += 1
        self.last_reason = reason
        self.notices.append((key, reason))
        return RESET, None, None

    def reject(self, key, reason):
        """Count a skipped sample under ``key`` with ``reason``; returns ``(SKIP, None, None)``."""
        self.counts[key] += 1
        self.last_reason = reason
        self.notices.append((key, reason))
        return SKIP, None, None

    def pop_notices(self):
        """Return and clear the queued ``(key, text)`` notices."""
        out = list(self.notices)
        self.notices.clear()
        return out

    def _restart_rate(self):
        self._dts.clear()

    def _track_rate(self, dt):
        """Update the nominal interval; return True if ``dt`` bridges missing samples."""
        nom = self.dt_nominal
        bridged = nom is not None and dt > 1.5 * nom
        if bridged:
            self.counts['bridged'] += 1
            self.notices.append(('bridged', f'{dt / nom - 1.0:.0f} IMU sample(s) missing before '
                                            f't={self.t_last:.3f}: interval of {dt * 1e3:.1f} ms '
                                            'bridged'))
        self._dts.append(dt)
        self._renew_rate()
        return bridged

    def _renew_rate(self):
        """Re-estimate the nominal interval when a rate window has just filled."""
        if len(self._dts) < RATE_WINDOW or self.counts['accepted'] % RATE_WINDOW:
            return
        nom, med = self.dt_nominal, statistics.median(self._dts)   # 50 floats: no numpy
        if nom is None:
            self.dt_nominal = med
        elif abs(med / nom - 1.0) > 0.2:
            self.counts['rate_change'] += 1
            self.notices.append(('rate_change', f'IMU rate changed from {1.0 / nom:.1f} to '
                                                f'{1.0 / med:.1f} Hz'))
            self.dt_nominal = med

    @property
    def rejected(self):
        """Number of samples skipped for bad values, stamps, frames or missing fields."""
        return sum(self.counts[k] for k in SKIP_REASONS)

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
        self.notices.clear()
        if cur is not None and cur[1]:
            segments.append(cur)
        return [(t0, np.array(tt), np.array(a), np.array(b)) for t0, tt, a, b in segments]
