"""GNSS history and pending queue of the pipeline (after the input checks).

Every accepted fix is remembered (the last one, and the recent ones whose median
gives the stationary models their position), with a history of fixes and velocities
of the last :data:`KEEP_S` (the coarse stage's velocity, and whether the base moves);
while a GNSS-aided filter runs, epochs also wait in a queue for the IMU stream to pass
their stamps.
Rules, each counted by reason in :attr:`GnssBuffer.counts`:

* ``ahead_of_imu``: a fix stamped more than :data:`MAX_LEAD_S` after the last IMU
  sample (the clocks disagree): dropped;
* ``queue_full``: more than 100 epochs waiting: the oldest is dropped;
* ``before_start``: an epoch stamped before the fine filter started: history only;
* ``late``: an epoch applied more than :data:`MAX_LAG_S` after its stamp: dropped;
* ``used``: given to the filter (the measurement is moved back to the fix time with
  the current velocity by the engine).
"""
import math
from collections import deque

import numpy as np

from ...nav import earth
from ...units import DEG
from .gnss_fix import GnssFix, gnss_sigma
from .gnss_input import reported_variances

#: GNSS history kept for the moving-base coarse alignment, s
KEEP_S = 3600.0
#: a queued GNSS epoch older than this (against the IMU stamps) is dropped, s
MAX_LAG_S = 1.0
#: a GNSS epoch stamped this far ahead of the IMU clock is dropped (clocks disagree), s
MAX_LEAD_S = 10.0
#: fixes whose median gives the stationary models their position
MEDIAN_FIXES = 31
#: epochs that may wait for the IMU stream
QUEUE = 100
#: the fixes' track (:meth:`GnssBuffer.track_speed`) needs this many fixes, covering this
#: share of its span
TRACK_MIN_FIXES, TRACK_COVER = 8, 0.8


def _local_track(fixes):
    """Stamps (N,) and ENU offsets (N, 3) m from the first of ``fixes`` (history records)."""
    f = np.array([r[:4] for r in fixes], dtype=float)
    return f[:, 0], earth.local_offset_m(*f[0, 1:4], f[:, 1], f[:, 2], f[:, 3])


class GnssBuffer:
    """See the module docstring."""

    def __init__(self):
        #: the last valid GNSS fix (t, lat_deg, lon_deg, h), kept across resets
        self.last_fix = None
        #: recent fixes (lat_deg, lon_deg, h): their median is the stationary position
        self.recent_fixes = deque(maxlen=MEDIAN_FIXES)
        self.fixes = deque()        # (t, lat, lon, h, pos_var) in rad, rad, m, m^2
        self.vels = deque()         # (t, v_n (3,), vel_var)
        self.reset()

    def reset(self, keep_history=False):
        """Empty the queue and the counts (and the history unless ``keep_history``)."""
        if not keep_history:
            self.fixes = deque()
            self.vels = deque()
        self.pending = deque(maxlen=QUEUE)
        self.counts = {'used': 0, 'late': 0, 'before_start': 0, 'ahead_of_imu': 0,
                       'queue_full': 0}
        #: stamp of the last epoch given to the filter
        self.t_used = None

    def inherit(self, other):
        """Take over the position history of ``other`` (a buffer being replaced)."""
        self.last_fix = other.last_fix
        self.recent_fixes.extend(other.recent_fixes)

    @property
    def seen(self):
        """Tell whether a fix or a velocity has come (since the history began)."""
        return self.last_fix is not None or bool(self.vels)

    # -- input ---------------------------------------------------------------------------
    def position_fix(self, t, lat_deg, lon_deg, h, pos_var, t_imu, queue):
        """Record a fix (deg, deg, m); ``queue``: the filter runs, so it waits to be applied.

        ``t_imu`` is the last IMU stamp (None before the first); ``pos_var`` (2,) east/north
        m^2 as reported, used only if both are finite and positive.
        """
        t = float(t)
        if t_imu is not None and t > t_imu + MAX_LEAD_S:
            self.counts['ahead_of_imu'] += 1
            return
        self.last_fix = (t, float(lat_deg), float(lon_deg), float(h))
        self.recent_fixes.append(self.last_fix[1:])
        rec = (t, lat_deg * DEG, lon_deg * DEG, float(h), reported_variances(pos_var))
        self.fixes.append(rec)
        while self.fixes and self.fixes[0][0] < t - KEEP_S:
            self.fixes.popleft()
        if queue:
            if len(self.pending) == self.pending.maxlen:
                self.counts['queue_full'] += 1     # the oldest is dropped
            self.pending.append(rec)

    def velocity_fix(self, t, v_n, vel_var):
        """Record an ENU velocity (3,) m/s with ``vel_var`` (2,) or None."""
        t = float(t)
        self.vels.append((t, np.asarray(v_n, dtype=float).copy(), reported_variances(vel_var)))
        while self.vels and self.vels[0][0] < t - KEEP_S:
            self.vels.popleft()

    # -- the fine filter's epochs -----------------------------------------------------------
    def drop_pending(self, t):
        """Forget the queued epochs stamped at or before ``t`` (coarse alignment's history)."""
        while self.pending and self.pending[0][0] <= t + 1e-9:
            self.pending.popleft()

    def requeue(self, t0, t1):
        """Queue again the fixes of the history stamped in ``(t0, t1]``, ahead of the queue.

        A GNSS-aided stage that starts at the coarse window's first sample (``t0``) runs
        over the window's fixes (:mod:`~..stages.reprocess`); they were history while the
        window filled. The queue grows to hold them and what already waits, and shrinks
        back to :data:`QUEUE` as they are taken (:meth:`pop_due`). Returns the number
        queued.
        """
        old = [f for f in self.pending if f[0] > t1 + 1e-9]
        back = [f for f in self.fixes if t0 + 1e-9 < f[0] <= t1 + 1e-9]
        self.pending = deque(back + old, maxlen=QUEUE + len(back))
        return len(back)

    def fix_nearest(self, t):
        """Return the history's fix stamped nearest ``t``: ``(t, lat, lon, h)`` rad, rad, m."""
        if not self.fixes:
            return None
        f = min(self.fixes, key=lambda f: abs(f[0] - t))
        return f[:4]

    def due(self, t):
        """Tell whether a queued epoch is stamped at or before ``t``."""
        return bool(self.pending) and self.pending[0][0] <= t + 1e-9

    def next_due_index(self, t, k):
        """Index of the first stamp of ``t`` (from ``k``) a queued epoch is due at, or None."""
        if not self.pending:
            return None
        i = k + int(np.searchsorted(t[k:], self.pending[0][0] - 1e-9, side='left'))
        return i if i < len(t) else None

    def pop_due(self, t_now, t_start):
        """Return the next usable queued epoch up to ``t_now`` as a :class:`GnssFix`, or None.

        Epochs before ``t_start`` (the filter's start) or more than :data:`MAX_LAG_S`
        old are dropped and counted.
        """
        while self.due(t_now):
            t_f, lat, lon, h, pv = self.pending.popleft()
            if self.pending.maxlen > QUEUE >= len(self.pending):   # the requeued are taken
                self.pending = deque(self.pending, maxlen=QUEUE)
            if t_f <= t_start:
                self.counts['before_start'] += 1
                continue
            if t_now - t_f > MAX_LAG_S:
                self.counts['late'] += 1
                continue
            v, vv = self.velocity_at_stamp(t_f)
            return GnssFix(t_f, lat, lon, h, v, pv, vv)
        return None

    def used(self, fix):
        """Count ``fix`` as given to the filter."""
        self.t_used = fix.t
        self.counts['used'] += 1

    def velocity_at_stamp(self, t_f):
        """GNSS velocity with the fix's stamp (within 20 ms), or (None, None)."""
        for t_v, v, vv in reversed(self.vels):
            if abs(t_v - t_f) <= 0.02:
                return v, vv
            if t_v < t_f - 0.02:
                break
        return None, None

    # -- the coarse stage ---------------------------------------------------------------------
    def last_fix_until(self, t):
        """Return the last fix stamped at or before ``t`` as ``last_fix`` has it, or None.

        (A replay's block may have brought fixes past the coarse window's last sample.)
        """
        if t is None or self.last_fix is None or self.last_fix[0] <= t + 1e-9:
            return self.last_fix
        for t_f, lat, lon, h, _ in reversed(self.fixes):
            if t_f <= t + 1e-9:
                return (t_f, lat / DEG, lon / DEG, h)
        return None

    def position(self, cfg, aided, t=None):
        """Latitude, longitude (rad), height (m) for the fine filter, and the source name.

        Stationary models: the median of the recent fixes, so that an outlier or a
        short jump does not set their latitude. Aided filters: the last fix at or before
        ``t`` (the filter's innovation gate judges the fixes that follow; ``aided``).
        Without a fix (or with ``use_gnss_position`` off): the ``initial_*`` parameters; with
        ``initial_latitude_deg`` not set (NaN) the latitude is 0 and the source
        ``latitude_not_set``: the sensor self-check then estimates it from the gyros in
        place (the hand-over then names the source ``gyro_latitude``), or says it is
        unknown (:mod:`.self_check`).
        """
        last = self.last_fix_until(t)
        if cfg['use_gnss_position'] and self.recent_fixes and (last is not None or not aided):
            if aided:
                la, lo, h = last[1:]
            else:
                la, lo, h = np.median(np.array(self.recent_fixes), axis=0)
            src = 'gnss'
        else:
            la, lo, h = (cfg['initial_latitude_deg'], cfg['initial_longitude_deg'],
                         cfg['initial_height_m'])
            src = 'parameters'
            if not math.isfinite(la):
                la, src = 0.0, 'latitude_not_set'
        return np.array([la * DEG, lo * DEG, h]), src

    def latitude_known(self, cfg):
        """Tell whether :meth:`position`'s latitude is known: a fix, or the parameter set."""
        return bool(cfg['use_gnss_position'] and self.recent_fixes) or math.isfinite(
            cfg['initial_latitude_deg'])

    def reported_over(self, t0, t1):
        """Return the reported east/north variances of the fixes and velocities in ``[t0, t1]``.

        Returns ``(positions, velocities)``, lists of (2,) arrays (messages that
        reported none are left out).
        """
        pos = [f[4] for f in self.fixes if t0 <= f[0] <= t1 and f[4] is not None]
        vel = [v[2] for v in self.vels if t0 <= v[0] <= t1 and v[2] is not None]
        return pos, vel

    def sigmas_over(self, tt, cfg):
        """GNSS velocity and position 1-sigma (m/s, m) the engine of ``cfg`` uses over ``tt``.

        :func:`~.gnss_fix.gnss_sigma` with the variances reported around stamps ``tt``.
        """
        pos, vel = self.reported_over(tt[0] - 2.0, tt[-1] + 2.0)
        return gnss_sigma(cfg, 'gnss_vel_sigma_mps', vel), gnss_sigma(cfg, 'gnss_pos_sigma_m', pos)

    def velocity_over(self, tt, vel_sigma, pos_sigma, correct=None, drop=()):
        """GNSS velocity at stamps ``tt`` (N, 3), its 1-sigma (m/s) and source; or (None, ...).

        From gnss/vel when at least two messages cover the window (sigma
        ``vel_sigma``), else from the fixes by a least-squares slope over +-3 epochs
        (sigma from ``pos_sigma``). ``correct(t, V) -> V``, if given, is applied to the
        velocities at their own stamps before they are interpolated to ``tt`` (the
        lever arm's velocity: it sways faster than the GNSS rate samples it well).
        ``drop``: stamps of gnss/vel messages to leave out (outliers).
        """
        lo, hi = tt[0] - 2.0, tt[-1] + 2.0
        vels = [(tv, v) for tv, v, _ in self.vels if lo <= tv <= hi and tv not in drop]
        if len(vels) >= 2 and vels[0][0] <= tt[0] + 2.0 and vels[-1][0] >= tt[-1] - 2.0:
            tv = np.array([a for a, _ in vels])
            V = np.array([b for _, b in vels])
            if correct is not None:
                V = correct(tv, V)
            out = np.column_stack([np.interp(tt, tv, V[:, i]) for i in range(3)])
            return out, vel_sigma, 'gnss_velocity'
        fixes = [f for f in self.fixes if lo <= f[0] <= hi]
        if len(fixes) < 7 or fixes[0][0] > tt[0] + 2.0 or fixes[-1][0] < tt[-1] - 2.0:
            return None, None, 'none'
        tf, enu = _local_track(fixes)
        w = 3
        vt, vv = [], []
        for i in range(w, len(tf) - w):
            sl = slice(i - w, i + w + 1)
            tc = tf[sl] - tf[i]
            vv.append((tc @ (enu[sl] - enu[sl].mean(axis=0))) / (tc @ tc))
            vt.append(tf[i])
        vt, vv = np.array(vt), np.array(vv)
        if correct is not None:
            vv = correct(vt, vv)
        out = np.column_stack([np.interp(tt, vt, vv[:, i]) for i in range(3)])
        dt_fix = float(np.median(np.diff(tf)))
        sig = pos_sigma * math.sqrt(12.0 / (2 * w + 1) / ((2 * w + 1) ** 2 - 1)) / dt_fix
        return out, sig, 'gnss_positions'

    def velocity_epochs(self, tt):
        """Return the gnss/vel messages in ``tt``'s span: stamps (M,) and velocities (M, 3)."""
        vels = [(tv, v) for tv, v, _ in self.vels if tt[0] <= tv <= tt[-1]]
        return (np.array([a for a, _ in vels]),
                np.array([b for _, b in vels], dtype=float).reshape(-1, 3))

    def velocity_stamps(self, tt, drop=()):
        """Stamps (M,) in ``tt``'s span of what :meth:`velocity_over` reads: gnss/vel or fixes."""
        vels = [v[0] for v in self.vels if tt[0] <= v[0] <= tt[-1] and v[0] not in drop]
        if len(vels) >= 2:
            return np.array(vels)
        return np.array([f[0] for f in self.fixes if tt[0] <= f[0] <= tt[-1]])

    def track_speed(self, t_end, span, pos_sigma, markov_sigma, markov_tau):
        """Horizontal speed of the fixes' track over ``(t_end - span, t_end]``, its noise, a bound.

        The least-squares slope of east and north against time over the fixes of the span
        (m/s). Its 1-sigma per axis: the white position noise through the slope, and a
        time-correlated error of ``markov_sigma`` (m; correlation time ``markov_tau`` s;
        0: the white sigma's) through the span's ends (a consumer receiver's position
        wanders by metres over a minute). The white noise is ``pos_sigma`` (m), or the
        scatter of the fixes about their line where that is larger (a receiver noisier
        than configured: seed 003's 10-m fixes told the default 1 m looked like a car at
        3 m/s over 5 s). Returns ``(speed, sigma, k)``: motion is a speed beyond ``k``
        sigma, ``k`` 4 with the configured noise (a Rayleigh tail of e^-8), and with the
        scatter the bound of the same tail for a noise estimated with ``2 (n - 2)``
        degrees of freedom (an F law: ``sqrt(nu (e^(16 / nu) - 1))``, 5.8 for 8 fixes, 4.3
        for 30). ``(None, None, None)`` with fewer than :data:`TRACK_MIN_FIXES` fixes or
        fixes covering less than :data:`TRACK_COVER` of the span.
        """
        fixes = []
        for f in reversed(self.fixes):
            if f[0] <= t_end - span:
                break
            if f[0] <= t_end + 1e-9:
                fixes.append(f)
        if len(fixes) < TRACK_MIN_FIXES or fixes[0][0] - fixes[-1][0] < TRACK_COVER * span:
            return None, None, None
        tf, enu = _local_track(fixes)
        tc = tf - tf.mean()
        d = enu[:, :2] - enu[:, :2].mean(axis=0)
        v = (tc @ d) / (tc @ tc)
        nu = 2 * (len(fixes) - 2)
        scatter = math.sqrt(float(np.sum((d - np.outer(tc, v)) ** 2)) / nu)
        k = 4.0
        if scatter > pos_sigma:
            pos_sigma, k = scatter, math.sqrt(nu * (math.exp(16.0 / nu) - 1.0))
        white = pos_sigma / math.sqrt(tc @ tc)
        ends = tf[0] - tf[-1]
        walk = (markov_sigma or pos_sigma) * math.sqrt(
            2.0 * (1.0 - math.exp(-ends / markov_tau))) / ends
        return float(np.hypot(v[0], v[1])), math.hypot(white, walk), k

    def speed_over(self, tt, vel_sigma, pos_sigma):
        """Largest horizontal GNSS speed (m/s) over stamps ``tt`` and its noise; or None, None."""
        V, sig, _ = self.velocity_over(tt, vel_sigma, pos_sigma)
        if V is None:
            return None, None
        return float(np.max(np.hypot(V[:, 0], V[:, 1]))), sig
