"""The slow-error monitor: the published heading against the GNSS course on straight legs.

A model error the filter absorbs (a gyro scale factor or axis misalignment it is not told,
a bias larger than its prior) leaves the innovations small: on a straight leg at constant
speed the GNSS position and velocity say nothing about the heading, so a heading a few
degrees off under a sigma of a quarter of a degree passes every innovation test, the
10-epoch NIS window of :mod:`.consistency` included (issue 44: a car with uncalibrated
MEMS triads ended ``aligned`` 4.0 deg off under 0.25 deg). The GNSS course does say it: a
ground vehicle moves along its forward axis on a straight leg, give or take a sideslip
(a car slips little, a skid-steer robot a little more, a boat crabs), so the course minus
the published heading is the heading error plus the sideslip plus the course's noise.

At each accepted GNSS epoch of a GNSS-aided fine stage with a known heading, the epoch
joins the current **leg** while the vehicle goes straight: horizontal speed (the filter's)
at least :data:`MIN_SPEED`, yaw rate at most :data:`MAX_YAW_RATE` and the published
heading within :data:`STRAIGHT` of the leg's first one (a ship whose heading sways by
more, a USV in a seaway, makes no legs and is not judged). The yaw rate is the published
yaw's change over at least :data:`RATE_SPAN` (:class:`YawRate`, shared with
:mod:`.course_heading`): a vibrating skid-steer robot's yaw shakes by more than
:data:`MAX_YAW_RATE` over one 0.2-0.4 s epoch interval (bench/integrity.py robot:consumer,
MEMS, ``kf``, told the defaults, seeds 1000-1002: 6, 9 and 4 legs judged in 400 s from the
per-epoch rate, 17, 21 and 19 from the rate over 1 s). A window that long sees a turn late: the
first epochs of a turn (at 15 deg/s and 5 Hz, 3 deg in the last 0.2 s of a 1-s window)
still read under :data:`MAX_YAW_RATE`. So a leg that ends on a rate above it is **trimmed**
to its epochs up to the start of the window that saw the turn (:meth:`YawRate.since`):
the turn began inside that window, and the epochs before it were admitted over windows
that did not show it. A leg ends at the first epoch that does not qualify or after
:data:`MAX_LEG_S` seconds; one of at least :data:`MIN_LEG_S` seconds and
:data:`MIN_EPOCHS` epochs (after the trim) is **judged**:

- the course: with GNSS velocity, each epoch's ``atan2(v_N, v_E)`` (REP-103 yaw) less the
  published yaw, folded by 180 deg when reversing, averaged over the leg (``D``); its
  1-sigma the velocity sigma over the speed, root mean square over the epochs, divided by
  the square root of the leg's seconds (at most one independent Doppler error a second);
  positions only: the direction of the displacement from the mean of the leg's first
  third of fixes to that of its last third, less the mean yaw; its 1-sigma
  ``sqrt(2) sigma_p / |displacement|`` (no credit for the averaging: consumer receivers'
  errors are correlated over tens of seconds); a leg whose course sigma exceeds
  :data:`MAX_COURSE_SIGMA` is too short to tell anything and is not judged;
- ``z = D / sqrt(sigma_h^2 + sigma_c^2 + sigma_s^2)``: ``sigma_h`` the published heading
  1-sigma (root mean of its variance over the leg), ``sigma_c`` the course's,
  ``sigma_s`` the sideslip the vehicle may have on a straight leg
  (``slow_monitor_sideslip_deg``: 1 deg, a car; a skid-steer robot a few, a boat in a
  current 20-30).

A leg **disagrees** when ``|z| > slow_monitor_sigmas`` (3). ``slow_monitor_legs``
consecutive disagreeing legs (3) are a persistent excess, the **failure**: the heading is
further from the course than the filter claims on leg after leg, while a consistent filter
shows ``|z| > 3`` on 0.3 % of its legs (a lasting error of about 3 sigma only a few times
as long as its heading error stays that large). Then the fine stage leaves ``aligned``
with the reason (:attr:`SlowErrorMonitor.reason`) and the engine's covariance is opened
(:meth:`remedy`): every misalignment variance gets ``D^2`` (``engine.widen``: the heading
then holds the difference seen; the tilt, which the same unmodelled turn errors disturb
through the axis misalignment, gets as much, and GNSS-aided motion soon narrows it again),
and the whole state, biases included, is inflated by the legs' mean ``z^2`` up to
:data:`MAX_INFLATION` (``engine.inflate``: covariance by its root, process noise by it,
as for a failed consistency test). Those raised process noises are halved back by the
consistency monitor's relaxation within seconds, while the error that built up unseen is a
drift the model lacks: the heading went ``|D|`` off within the failing legs' span ``T``,
so the gyro-drift states get, for good, the rate random walk ``q = D^2 / T^3`` that
reaches a drift of ``|D| / T`` within ``T``
(:meth:`~.process_noise.ProcessNoise.raise_drift_noise`; a car whose up gyro has a
300 deg/h bias it is told as 1 deg/h: 76 % of its 1-s heading rows outside 3 sigma with
the inflation alone, 18 % with this, all of them before the first failure;
test_slow_monitor.py). While failing, each further disagreeing leg applies the
remedy again; ``slow_monitor_legs`` consecutive agreeing legs end the failure (the
inflated filter agrees with the course again) and the stage may be ``aligned`` again.

Only the heading is judged: the course says nothing about the tilt. Not in the seeds
(their vehicles are calibrated and their filters' heading is observed by the GNSS in
their manoeuvres); the sideslip check of :mod:`.sideslip` uses the same course for a
different question (a mounting turned by tens of degrees).
"""
import math
from collections import deque

import numpy as np

from ...nav import earth
from ..engines.base import AidedEngine, Engine
from ..inputs.gnss_fix import epoch_var, uses_reported_covariance

#: horizontal speed (m/s) below which an epoch joins no leg
MIN_SPEED = 0.5
#: yaw rate (rad/s) above which the vehicle is turning
MAX_YAW_RATE = math.radians(3.0)
#: the published heading stays within this of the leg's first epoch's on a straight leg, rad
STRAIGHT = math.radians(5.0)
#: shortest leg judged, s, and its fewest epochs
MIN_LEG_S = 5.0
MIN_EPOCHS = 5
#: a leg is judged and a new one started after this long, s
MAX_LEG_S = 30.0
#: a course less certain than this (1-sigma, rad) judges nothing
MAX_COURSE_SIGMA = math.radians(15.0)
#: largest inflation at one failure (the consistency monitor's)
MAX_INFLATION = 10.0
#: judged legs kept for the figures
HISTORY = 50
#: the yaw rate of the straightness test is taken over at least this long, s
RATE_SPAN = 1.0


def wrap(a):
    """Return angle ``a`` (rad) in (-pi, pi]."""
    return math.atan2(math.sin(a), math.cos(a))


def fold(d):
    """Return difference ``d`` (rad, wrapped) folded into [-pi/2, pi/2]: reversing is along."""
    if abs(d) > 0.5 * math.pi:
        d -= math.copysign(math.pi, d)
    return d


class YawRate:
    """The yaw rate over the shortest span of past epochs of at least ``span`` seconds.

    :meth:`add` takes an epoch's yaw and returns ``|yaw - yaw_0| / (t - t_0)`` (rad/s),
    ``(t_0, yaw_0)`` the latest epoch at least ``span`` before ``t``; infinite until the
    epochs cover ``span`` (no rate known yet: no leg).
    """

    def __init__(self, span=RATE_SPAN):
        self.span = float(span)
        self._recent = deque()

    def add(self, t, yaw):
        """Take the yaw ``yaw`` (rad) at ``t`` (s); return the rate over the span (rad/s)."""
        recent = self._recent
        recent.append((t, yaw))
        while len(recent) > 2 and t - recent[1][0] >= self.span:
            recent.popleft()
        t0, y0 = recent[0]
        if not t - t0 >= self.span or not t > t0:
            return math.inf
        return abs(wrap(yaw - y0)) / (t - t0)

    def since(self):
        """Return the stamp of the window's first epoch (s): the rate is over what follows it."""
        return self._recent[0][0]


class Leg:
    """The epochs of one straight leg: stamps, yaw, heading variance, velocity, position."""

    def __init__(self, t, yaw):
        self.t0 = t
        self.yaw0 = yaw
        self.t, self.yaw, self.var_h = [], [], []
        self.course, self.var_c = [], []      # per epoch with a GNSS velocity
        self.pos = []                         # (lat, lon, h)
        self.pos_var = []
        #: displacement between the first and last thirds' means (positions only), m
        self.length = math.nan

    @property
    def duration(self):
        return self.t[-1] - self.t0 if self.t else 0.0

    def add(self, t, yaw, var_h, fix, pos_var):
        """Append an epoch: stamp, yaw, heading variance, ``fix``'s position and its variance."""
        self.t.append(t)
        self.yaw.append(yaw)
        self.var_h.append(var_h)
        self.pos.append((fix.lat, fix.lon, fix.h))
        self.pos_var.append(pos_var)

    def trim(self, t_end):
        """Drop the epochs stamped after ``t_end`` (s): a turn's first ones (module docstring)."""
        n = int(np.searchsorted(self.t, t_end, side='right'))
        # a course at every epoch or the positions only (difference()): keep it so
        n_c = n if len(self.course) == len(self.t) else 0
        del self.t[n:], self.yaw[n:], self.var_h[n:], self.pos[n:], self.pos_var[n:]
        del self.course[n_c:], self.var_c[n_c:]

    def difference(self, fold_reverse=True):
        """Return ``(D, sigma_c)`` of the leg, rad (module docstring), or None if too uncertain.

        ``fold_reverse`` False: the leg is taken as driven forward, ``D`` is not folded by
        180 deg (:mod:`.course_heading`: the course as a heading, the heading unknown).
        Sets :attr:`length` (m) of a positions-only leg.
        """
        n = len(self.t)
        f = fold if fold_reverse else (lambda a: a)
        if len(self.course) == n:              # a velocity at every epoch
            d = np.array([f(wrap(c - y)) for c, y in zip(self.course, self.yaw)])
            sig_c = math.sqrt(float(np.mean(self.var_c)) / max(1.0, min(n, self.duration)))
            D = (float(np.mean(d)) if fold_reverse
                 else math.atan2(np.mean(np.sin(d)), np.mean(np.cos(d))))
        else:                                  # positions only: the leg's displacement
            k = max(1, n // 3)
            lat, lon, h = (np.array([p[i] for p in self.pos]) for i in range(3))
            enu = earth.local_offset_m(lat[0], lon[0], h[0], lat, lon, h)
            delta = enu[-k:, :2].mean(axis=0) - enu[:k, :2].mean(axis=0)
            length = self.length = float(np.hypot(*delta))
            if not length > 0.0:
                return None
            sig_c = math.sqrt(2.0 * float(np.mean(self.pos_var))) / length
            yaw = math.atan2(np.mean(np.sin(self.yaw)), np.mean(np.cos(self.yaw)))
            D = f(wrap(math.atan2(delta[1], delta[0]) - yaw))
        if not sig_c <= MAX_COURSE_SIGMA:
            return None
        return D, sig_c


class SlowErrorMonitor:
    """Heading against the GNSS course on straight legs (module docstring).

    ``legs``: consecutive legs for a failure and for its end (0: off); ``sigmas``: the
    bound on ``|z|``; ``sideslip_deg``: the sideslip 1-sigma allowed; ``pos_sigma``,
    ``vel_sigma``: the configured GNSS sigmas (m, m/s); ``use_reported``: a fix's reported
    variances replace them, as in the engine (:func:`~..inputs.gnss_fix.epoch_var`).
    """

    def __init__(self, legs=3, sigmas=3.0, sideslip_deg=1.0, pos_sigma=1.0, vel_sigma=0.1,
                 use_reported=False):
        self.use_reported = bool(use_reported)
        self.n_legs = int(legs)
        self.sigmas = float(sigmas)
        self.var_s = math.radians(sideslip_deg) ** 2
        self.pos_var = float(pos_sigma) ** 2
        self.vel_var = float(vel_sigma) ** 2
        self.leg = None
        #: the heading disagrees with the course persistently (the stage is not aligned)
        self.failing = False
        self._run = 0                 # consecutive legs against the current state
        self._pending = []            # (D, z) of the disagreeing legs of that run
        #: (end, D, sigma, z, start) of the last judged legs (s, rad, rad, -, s)
        self.judged = deque(maxlen=HISTORY)
        self.n_judged = 0
        self.n_disagree = 0
        self.n_failures = 0
        #: stamps of the epochs at which the failures were found
        self.failed_at = []
        #: what the last failure found (its reason while failing)
        self.finding = ''
        #: ``(var_phi, factor, q_drift)`` the fine stage is to apply now (:meth:`remedy`), or None
        self.due = None
        self._reported = 0
        self._rate = YawRate()

    @property
    def reason(self):
        """Why the stage may not be ``aligned`` ('' while the heading agrees)."""
        return self.finding if self.failing else ''

    def add(self, t, C_b_n, v_n_filter, var_h, fix):
        """Take an accepted GNSS epoch at ``t``; return True when a remedy is due (:attr:`due`).

        ``C_b_n`` (3, 3) the attitude after the update; ``v_n_filter`` (3,) the filter's
        ENU velocity (m/s); ``var_h`` the published heading variance (rad^2); ``fix`` the
        :class:`~.gnss_fix.GnssFix` applied (moved to the IMU). The yaw rate is the published
        yaw's over :data:`RATE_SPAN` (:class:`YawRate`; a vibrating chassis's sample rates
        are no guide).
        """
        if self.n_legs <= 0:
            return False
        yaw = math.atan2(C_b_n[1, 0], C_b_n[0, 0])
        rate = self._rate.add(t, yaw)
        speed = math.hypot(v_n_filter[0], v_n_filter[1])
        straight = (speed >= MIN_SPEED and rate <= MAX_YAW_RATE
                    and math.isfinite(var_h) and var_h < math.pi ** 2 / 3.0)
        leg = self.leg
        if leg is not None and (not straight or abs(wrap(yaw - leg.yaw0)) > STRAIGHT
                                or t - leg.t0 > MAX_LEG_S):
            self.leg = None
            if math.isfinite(rate) and rate > MAX_YAW_RATE:   # ends on a turn: its first epochs
                leg.trim(self._rate.since())
            due = self._judge(leg, t)
            if straight:
                self._join(t, yaw, var_h, fix)
            return due
        if straight:
            self._join(t, yaw, var_h, fix)
        return False

    def _join(self, t, yaw, var_h, fix):
        if self.leg is None:
            self.leg = Leg(t, yaw)
        leg = self.leg
        leg.add(t, yaw, var_h, fix, epoch_var(self.pos_var, fix.pos_var, self.use_reported))
        if fix.v_n is not None:
            v = np.asarray(fix.v_n, dtype=float)
            sp = math.hypot(v[0], v[1])
            if sp >= MIN_SPEED:
                vv = epoch_var(self.vel_var, fix.vel_var, self.use_reported)
                leg.course.append(math.atan2(v[1], v[0]))
                leg.var_c.append(vv / (sp * sp))

    def _judge(self, leg, t):
        """Judge a finished leg at the epoch ``t`` that ended it; True: a remedy is due."""
        if len(leg.t) < MIN_EPOCHS or leg.duration < MIN_LEG_S:
            return False
        res = leg.difference()
        if res is None:
            return False
        D, sig_c = res
        sigma = math.sqrt(float(np.mean(leg.var_h)) + sig_c ** 2 + self.var_s)
        z = D / sigma
        self.judged.append((leg.t[-1], D, sigma, z, leg.t0))
        self.n_judged += 1
        disagrees = abs(z) > self.sigmas
        self.n_disagree += disagrees
        if disagrees == self.failing:           # the state holds: the run restarts
            self._run, self._pending = 0, []
            if disagrees:                       # still failing: inflate again
                return self._due([(D, z, leg.t0, leg.t[-1])])
            return False
        self._run += 1
        if disagrees:
            self._pending.append((D, z, leg.t0, leg.t[-1]))
        if self._run < self.n_legs:
            return False
        self._run = 0
        self.failing = disagrees
        if not disagrees:
            return False
        self.n_failures += 1
        self.failed_at.append(t)
        zs = [p[1] for p in self._pending]
        self.finding = (f'heading {math.degrees(D):+.1f} deg from the GNSS course on '
                        f'{len(zs)} straight legs running ({min(map(abs, zs)):.1f}-'
                        f'{max(map(abs, zs)):.1f} sigma, sideslip allowed '
                        f'{math.degrees(math.sqrt(self.var_s)):g} deg): a slow model error '
                        '(gyro scale factor, misalignment, bias?), or an IMU mounted turned '
                        'about the vertical and untold (imu_mounting_rpy_deg: the two look '
                        'alike on straight legs); heading, tilt and bias covariance inflated')
        pending, self._pending = self._pending, []
        return self._due(pending)

    def _due(self, legs):
        """Set :attr:`due` from the disagreeing legs ``[(D, z, t_start, t_end)]``; return True."""
        var_phi = max(p[0] ** 2 for p in legs)
        factor = min(max(float(np.mean([p[1] ** 2 for p in legs])) / self.sigmas ** 2, 1.0),
                     MAX_INFLATION)
        # the heading went |D| off within the legs' span T unseen: a drift of at least |D| / T
        # the model lacked; its rate random walk q = (|D| / T)^2 / T lets the drift states
        # reach it within T
        T = max(legs[-1][3] - legs[0][2], MIN_LEG_S)
        q_drift = var_phi / T ** 3
        self.due = (var_phi, factor, q_drift)
        return True

    def remedy(self, engine: AidedEngine):
        """Apply the due remedy to ``engine`` (``widen`` then ``inflate``; module docstring)."""
        if self.due is None:
            return
        var_phi, factor, q_drift = self.due
        self.due = None
        engine.widen(var_phi, 0.0)
        if factor > 1.0:
            engine.inflate(factor)
        engine.raise_drift_noise(q_drift)

    def take_findings(self):
        """Return the failures not reported yet (a WARN each; and forget them)."""
        if self.n_failures == self._reported:
            return []
        self._reported = self.n_failures
        return [self.finding]

    def status(self):
        """Figures for diagnostics."""
        s = {'slow_monitor_ok': not self.failing, 'slow_monitor_legs_judged': self.n_judged,
             'slow_monitor_legs_disagreeing': self.n_disagree,
             'slow_monitor_failures': self.n_failures}
        if self.judged:
            _, D, sigma, z, _ = self.judged[-1]
            zs = np.array([j[3] for j in self.judged])
            s.update(slow_monitor_last_diff_deg=math.degrees(D),
                     slow_monitor_last_sigma_deg=math.degrees(sigma),
                     slow_monitor_last_z=z,
                     slow_monitor_rms_z=float(np.sqrt(np.mean(zs * zs))))
        return s


def for_stage(engine: Engine, cfg):
    """Return the monitor of a fine stage running ``engine`` with parameters ``cfg``, or None.

    None for the still-base engines (no legs) and with ``slow_monitor_legs`` 0.
    """
    if engine.restages or cfg['slow_monitor_legs'] <= 0:
        return None
    return SlowErrorMonitor(cfg['slow_monitor_legs'], cfg['slow_monitor_sigmas'],
                            cfg['slow_monitor_sideslip_deg'], cfg['gnss_pos_sigma_m'],
                            cfg['gnss_vel_sigma_mps'], uses_reported_covariance(cfg))
