"""The GNSS course of a straight leg as a heading fix, while the filter's heading is unknown.

A skid-steer robot with positions-only consumer GNSS (issue 44: 1 m/s, 2.5 Hz, 0.9 m
reported, turning every few seconds) never shows the filter its heading: at constant
speed on a straight leg the positions say nothing about it, the turns are too slow and
short for the position-only fixes to resolve the centripetal force's direction, and the
GNSS track (``track_min_speed_mps``, 2 m/s) is never fast enough. The linear filter then
holds its heading variance at its linear range for the whole run and the heading ends
declared unknown (55-120 deg RMS). Yet a ground vehicle moves along its forward axis,
give or take a sideslip: the course over a straight leg *is* a heading measurement.

This aid forms the straight legs the slow-error monitor forms (:mod:`.slow_monitor`: yaw
rate, yaw change, speed, 5-30 s; its :class:`~.slow_monitor.Leg` and its course with its
1-sigma ``sigma_c``; positions only: the displacement between the mean of the leg's first
and last thirds, ``sqrt(2) sigma_p / |d|``, no credit for averaging), but not from the
published heading (the filter's yaw over the leg is only differenced, so its error
cancels and an unknown heading is fine) and without folding by 180 deg (a leg is taken
as driven forward: the course is the heading, not its axis). At the epoch that ends a
judged leg the engine gets the yaw ``yaw_now + D`` (``D``: the leg's course minus the
filter's yaw over it) as an external heading
(:meth:`~.heading_update.ExternalHeading.update_heading`) with the variance

    ``sigma^2 = sigma_c^2 + sigma_gm^2 + sigma_s^2``

``sigma_s`` the sideslip a straight leg may have (``course_heading_sideslip_deg``);
``sigma_gm`` the configured Gauss-Markov position error's share
(``gnss_position_markov_sigma_m``, ``tau``): the difference of that error between the two
thirds, ``sqrt(2 (1 - exp(-dt / tau))) sigma_m / |d|`` with ``dt`` their spacing (with
the defaults 0: ``sigma_c`` already takes the whole configured position sigma without
averaging credit, the bound for any non-negative correlation of the errors).

**Only as a bootstrap.** The aid starts on a heading the filter has not found: published
as unknown or with a 1-sigma beyond :data:`LINEAR_MAX` (a heading the filter found itself
is the slow-error monitor's to judge: a marine-grade ship in a 1 m/s current, its heading
known to 7.6 deg from the coarse stage, had its north tilt pulled outside 3 sigma on 7-12
% of its rows by one crabbed leg). Once the aid has set the heading, a leg is given while
the published heading 1-sigma is above half the leg's (:data:`BETTER`). The Gauss-Markov
position error is common to the course and the filter's own position updates; its share
in the filter's heading is small while the filter knows less than one leg (on a straight
leg the positions do not reach the heading at all), which is when the course is used;
once the filter knows the heading better than a leg, the course is left to the slow-error
monitor to judge, not fed back as information it already has.
A filter whose heading is beyond its linear range (``kf``'s held heading, a cubature
prior) takes it directly (:func:`~.heading.take_heading`); otherwise it is a linear yaw
update up to :data:`LINEAR_MAX` (a rotation about up is exactly linear in the up
misalignment) through the heading innovation gate.

**Not where the GNSS track speaks.** A leg whose receiver reports velocity at every epoch
with a median speed of at least ``track_min_speed_mps`` is not the aid's: there the
coarse stage takes the track heading, and the under-way mounting check
(:mod:`.sideslip`) needs the filter's heading to come from the IMU, not from the course
(a car with its IMU turned 90 deg and untold, seed 003's at 5-10 m/s: with the aid
feeding, the course held the heading where the vehicle goes, the mounting was never
named and the tilt ended 2.2 sigma off; without it the check names it). The aid fills
what the track leaves: positions only, and speeds below the track's.

**Safety.** A boat crabs 20-30 deg in a current, a holonomic robot moves sideways. A crab
fixed to the earth (a current) changes with the course: legs in different directions
give courses that disagree with the gyro-carried heading far beyond their sigmas, so the
gate rejects them. :data:`MAX_DISAGREE` such legs (rejected, or beyond
``course_heading_sigmas`` from the filter's heading once it stands on a course) turn the
aid off for the stage, widen the heading by the largest difference seen and say so (a
WARN). A crab equal on every leg (an IMU mounted turned, a steady cross wind) cannot be
told from the heading by the course: set ``course_heading_sideslip_deg`` to the crab
the vehicle may have, or 0 to turn the aid off (every vehicle that may move off its nose
by more than a few degrees on a straight leg). Not in the seeds (their filters observe
the heading from their manoeuvres or their gyros).
"""
import math

import numpy as np

from ...nav import earth
from ..engines.base import Engine
from ..inputs.gnss_fix import epoch_var, uses_reported_covariance
from ..inputs.heading import HeadingFix, wrap
from .finding import OnceFinding
from .slow_monitor import (MAX_COURSE_SIGMA, MAX_LEG_S, MAX_YAW_RATE, MIN_EPOCHS, MIN_LEG_S,
                           MIN_SPEED, RATE_SPAN, STRAIGHT, Leg, YawRate)

#: a linear yaw update of a course fix up to this filter heading 1-sigma, rad; beyond, taken
#: directly; the aid starts only on a published heading beyond it (or unknown)
LINEAR_MAX = math.radians(25.0)
#: the aid feeds a leg while the published heading 1-sigma is above the leg's over this
BETTER = 2.0
#: disagreeing legs that turn the aid off for the stage
MAX_DISAGREE = 2


class CourseHeading(OnceFinding):
    """Straight legs' GNSS courses as heading fixes while the heading is unknown (module doc).

    ``sideslip_deg``: the sideslip 1-sigma of a straight leg; ``sigmas``: a leg disagrees
    beyond this many combined sigmas; ``pos_sigma``, ``vel_sigma``: the configured GNSS
    sigmas (m, m/s); ``use_reported``: a fix's reported variances replace them, as in the
    engine (:func:`~..inputs.gnss_fix.epoch_var`); ``markov_sigma`` (m), ``markov_tau``
    (s): the configured Gauss-Markov position error.
    """

    def __init__(self, sideslip_deg=5.0, sigmas=3.0, pos_sigma=1.0, vel_sigma=0.1,
                 markov_sigma=0.0, markov_tau=60.0, track_speed=math.inf, use_reported=False):
        self.use_reported = bool(use_reported)
        self.var_s = math.radians(sideslip_deg) ** 2
        self.track_speed = float(track_speed)
        self._speeds = []             # the current leg's GNSS speeds (m/s), with velocity
        self.sigmas = float(sigmas)
        self.pos_var = float(pos_sigma) ** 2
        self.vel_var = float(vel_sigma) ** 2
        self.markov_var = float(markov_sigma) ** 2
        self.markov_tau = float(markov_tau)
        self.leg = None
        self._rate = YawRate(RATE_SPAN)
        #: the aid is off for good (legs disagreed: a crab or a sideways motion)
        self.off = False
        self.n_judged = self.n_used = self.n_taken = self.n_disagree = 0
        self._run = 0
        self._worst = 0.0             # largest D^2 (rad^2) of the disagreeing run
        #: (t, D, sigma, result) of the last judged leg (s, rad, rad, str)
        self.last = None

    def add(self, t, C_b_n, v_n_filter, fix):
        """Take an accepted GNSS epoch; return the judged leg ``(D, var)`` (rad, rad^2) or None.

        ``C_b_n`` (3, 3) the attitude after the update, ``v_n_filter`` (3,) the filter's ENU
        velocity (m/s), ``fix`` the :class:`~.gnss_fix.GnssFix` applied.
        """
        if self.off:
            return None
        yaw = math.atan2(C_b_n[1, 0], C_b_n[0, 0])
        # the yaw rate over at least RATE_SPAN s: a vibrating chassis's yaw shakes by
        # degrees per second over one 0.4-s epoch interval
        rate = self._rate.add(t, yaw)
        # no speed test per epoch: a position-only filter's speed scatters by half a metre
        # a second at 1 m/s; a leg that did not move far enough has too vague a course
        straight = rate <= MAX_YAW_RATE
        leg, out = self.leg, None
        if leg is not None and (not straight or abs(wrap(yaw - leg.yaw0)) > STRAIGHT
                                or t - leg.t0 > MAX_LEG_S):
            self.leg = None
            out = self._judge(leg)
        if straight:
            self._join(t, yaw, fix)
        return out

    def _join(self, t, yaw, fix):
        if self.leg is None:
            self.leg = Leg(t, yaw)
            self._speeds = []
        leg = self.leg
        leg.add(t, yaw, 0.0, fix, epoch_var(self.pos_var, fix.pos_var, self.use_reported))
        if fix.v_n is not None:
            v = np.asarray(fix.v_n, dtype=float)
            sp = math.hypot(v[0], v[1])
            self._speeds.append(sp)
            if sp >= MIN_SPEED:
                vv = epoch_var(self.vel_var, fix.vel_var, self.use_reported)
                leg.course.append(math.atan2(v[1], v[0]))
                leg.var_c.append(vv / (sp * sp))

    def _judge(self, leg):
        """``(D, var)`` of a finished leg (module docstring), or None when too short or vague."""
        if len(leg.t) < MIN_EPOCHS or leg.duration < MIN_LEG_S:
            return None
        if len(self._speeds) == len(leg.t) and np.median(self._speeds) >= self.track_speed:
            return None           # the GNSS track's and the mounting check's (docstring)
        if len(leg.course) == len(leg.t):
            res = leg.difference(fold_reverse=False)
        else:
            res = fitted_course(leg, self.markov_var, self.markov_tau)
        if res is None:
            return None
        D, sig_c = res
        var = sig_c ** 2 + self.var_s
        if not var <= (MAX_COURSE_SIGMA ** 2 + self.var_s):
            return None
        self.n_judged += 1
        return D, var

    def fix(self, t, C_b_n, D, var):
        """Return the heading (:class:`~.heading.HeadingFix`) of a judged leg at ``t``."""
        yaw = math.atan2(C_b_n[1, 0], C_b_n[0, 0])
        return HeadingFix(t, wrap(yaw + D), var)

    def result(self, t, D, var, result, var_h):
        """Record what the engine did with a leg's fix (``'used'``, ``'taken'``, ``'rejected'``).

        ``var_h`` the filter's heading variance before the fix. A rejected fix, or a leg
        beyond ``sigmas`` of a heading the aid has already set, disagrees; returns the
        variance (rad^2) to widen the heading by when the aid turns itself off, else None.
        """
        self.last = (t, D, math.sqrt(var), result)
        if result == 'taken':
            self.n_taken += 1
        elif result == 'used':
            self.n_used += 1
        disagrees = result == 'rejected' or (
            result == 'used' and self.n_taken + self.n_used > 1
            and D * D > self.sigmas ** 2 * (var + var_h))
        if not disagrees:
            self._run = 0
            return None
        self.n_disagree += 1
        self._run += 1
        self._worst = max(self._worst if self._run > 1 else 0.0, D * D)
        if self._run < MAX_DISAGREE:
            return None
        self.off = True
        self.finding = (f'GNSS course of {self._run} straight legs running {math.degrees(D):+.1f} '
                        f'deg from the heading (sideslip allowed '
                        f'{math.degrees(math.sqrt(self.var_s)):g} deg): the vehicle crabs or '
                        'moves sideways (a boat in a current?); the course is no heading here: '
                        'course heading aid off, heading covariance widened '
                        '(course_heading_sideslip_deg)')
        return self._worst

    def status(self):
        """Figures for diagnostics."""
        s = {'course_heading_on': not self.off, 'course_heading_legs': self.n_judged,
             'course_heading_taken': self.n_taken, 'course_heading_used': self.n_used,
             'course_heading_disagreeing': self.n_disagree}
        if self.last is not None:
            s.update(course_heading_last_diff_deg=math.degrees(self.last[1]),
                     course_heading_last_sigma_deg=math.degrees(self.last[2]))
        return s


#: correlation times (s) over which the position errors' worst case is sought
TAUS = np.geomspace(0.1, 1000.0, 25)


def fitted_course(leg, markov_var=0.0, markov_tau=60.0):
    """``(D, sigma_c)`` of a positions-only ``leg`` from a straight-line fit, rad; or None.

    The velocity is the least-squares slope of the ENU positions over time,
    ``v = sum_i w_i p_i`` with ``w_i = (t_i - t_mean) / sum_j (t_j - t_mean)^2``; the course
    its direction, ``D`` that less the filter's mean yaw. Its 1-sigma is the cross-track
    velocity error over the speed, ``sqrt(w^T S w) / |v|``, ``S`` the covariance of one
    axis's position errors: their variance ``sigma_p^2`` (the configured or reported one)
    correlated as ``exp(-|dt| / tau)`` with the ``tau`` of :data:`TAUS` that makes it
    largest (a consumer receiver's correlation time is not known; white noise would give
    ``sigma_p / sqrt(sum (t - t_mean)^2)``, several times less), plus the configured
    Gauss-Markov error's ``w^T S_m w`` at its own ``tau``.
    """
    lat, lon, h = (np.array([p[i] for p in leg.pos]) for i in range(3))
    enu = earth.local_offset_m(lat[0], lon[0], h[0], lat, lon, h)[:, :2]
    t = np.asarray(leg.t, dtype=float)
    dt = t - t.mean()
    Stt = float(dt @ dt)
    if not Stt > 0.0:
        return None
    w = dt / Stt
    v = w @ enu
    speed = float(np.hypot(*v))
    if not speed > 0.0:
        return None
    lag = np.abs(t[:, None] - t[None, :])
    var_p = float(np.mean(leg.pos_var))
    var_v = var_p * max(float(w @ np.exp(-lag / tau) @ w) for tau in TAUS)
    if markov_var > 0.0:
        var_v += markov_var * float(w @ np.exp(-lag / markov_tau) @ w)
    yaw = math.atan2(np.mean(np.sin(leg.yaw)), np.mean(np.cos(leg.yaw)))
    leg.length = speed * (t[-1] - t[0])
    return wrap(math.atan2(v[1], v[0]) - yaw), math.sqrt(var_v) / speed


def for_stage(engine: Engine, cfg):
    """Return the aid of a fine stage running ``engine`` with parameters ``cfg``, or None.

    None for the still-base engines and with ``course_heading`` off.
    """
    if engine.restages or not cfg['course_heading']:
        return None
    return CourseHeading(cfg['course_heading_sideslip_deg'], cfg['slow_monitor_sigmas'],
                         cfg['gnss_pos_sigma_m'], cfg['gnss_vel_sigma_mps'],
                         cfg['gnss_position_markov_sigma_m'], cfg['gnss_position_markov_tau_s'],
                         cfg['track_min_speed_mps'], uses_reported_covariance(cfg))
