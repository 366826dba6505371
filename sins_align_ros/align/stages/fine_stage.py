"""The fine stage: an engine stepped at IMU rate, its epochs, convergence, rows.

The epochs themselves (GNSS, external heading, the consistency remedy) are
:mod:`.fine_epochs`.

Two ways of stepping, by the engine's kind: the stationary engine mechanizes whole
blocks between its own filter epochs (vectorised); the GNSS-aided engines step
sample by sample and take each queued GNSS epoch at the first sample at or past its
stamp. Either way, every filter epoch is followed by the convergence check
(:class:`~.convergence.ConvergenceMonitor`): a converged stage restages the
stationary filter (up to ``max_stages``) or turns ``fine`` into ``aligned``.

The GNSS-aided engines' innovations are checked against their covariance
(:class:`~.consistency.ConsistencyMonitor`); an inconsistent filter has its covariance
inflated and is not ``aligned`` until the test passes again. Their heading is also held
against the GNSS course on straight legs (:mod:`.slow_monitor`: a slow model error the
innovations do not show), and their IMU samples against the sensor model while the vehicle
moves (:mod:`.motion_check`: vibration and turns the coarse window did not show).

``aligned`` means good enough for the user (docs/design.md: the attitude meets the user's
thresholds and the consistency checks pass): the roll/pitch and heading 1-sigma must be
within ``aligned_max_tilt_sigma_deg`` / ``aligned_max_heading_sigma_deg`` and the
consistency monitor must pass; when either stops holding the phase goes back to
``fine`` with the reason. Before that, the stage must have settled once: the
still-base family's last stage must have converged (its convergence restages it), a
GNSS-aided filter must have run ``stage_min_duration`` seconds. An aided filter's
sigma may keep shrinking for minutes (a USV's heading from its sway, 14' and still
falling at 300 s); waiting for it to stop, as the still-base stages do, left such runs
``fine`` to the end with an attitude far inside the bounds. A heading the sensors
cannot observe (``heading_known`` False: a gyro that cannot see Earth rate at rest) is
published with the variance of an unknown angle, :data:`HEADING_UNKNOWN_VAR`, and the
roll/pitch variances are then at least ``tilt_bound``: with the heading unknown the
filter cannot know how a body-frame accelerometer bias lies against the horizontal, so at
rest tilt and bias stay one (seed 002 eq. 15: a / g), however much its heading wanders
(a GNSS-aided VBCH on a still MEMS IMU reported 14' of tilt under a 17' bias bound while
50' off, the wandering heading having "separated" them).

Where the self-check's mounting check finds the vehicle frame far from level
(:attr:`~.self_check.SelfCheck.mounting_doubt`: an IMU mounted rotated and untold), or
the GNSS velocity far from the vehicle's forward axis (:mod:`.sideslip`), the
attitude is the IMU's, not the vehicle's: all three angles are published with the
variance of an unknown angle and the stage is never ``aligned``.

A still-base engine's zero-velocity innovations are watched through the whole stage
(:mod:`.still_watch`): when they show the base moving, the zero-velocity filter stops
(its last seconds undone), the attitude coasts on the gyros with a growing covariance and
the phase is ``fine`` with the reason :data:`~.still_watch.MOVING_WITHOUT_GNSS`, until the
IMU has shown rest for a whole coarse window. With GNSS fixes coming in, the stage ends
instead, so that the pipeline's coarse stage hands over to a GNSS-aided filter.

A filter failure (:class:`~.gnss_gate.FilterDiverged`) ends the stage: the methods
return its reason and the pipeline restarts from coarse alignment.
"""
import math

import numpy as np

from ..engines.prior_shaping import cap_angles
from .consistency import ConsistencyMonitor
from .convergence import ConvergenceMonitor
from .fine_epochs import EpochUpdates
from ..engines.gnss_gate import FilterDiverged
from ..inputs.imu_input import intervals
from . import course_heading, motion_check, slow_monitor
from ..output import ANGLE_UNKNOWN_VAR, HEADING_UNKNOWN_VAR, Rows, one_row
from .sideslip import SideslipCheck
from .sigma_history import SigmaHistory
from ..engines.still_watch import StillWatch
from ...units import DPH

FINE, ALIGNED = 'fine', 'aligned'
#: GNSS fixes this recent (s) make a still-base stage that finds its base moving end, so
#: that a GNSS-aided filter takes over; older ones: it coasts
GNSS_RECENT_S = 5.0


class Clock:
    """Stamps of the pipeline: the first sample's interval start and the last sample (s)."""

    def __init__(self):
        self.t_first = None
        self.t_last = None


class FineStage(EpochUpdates):
    """One engine from the end of coarse alignment on; see the module docstring.

    ``floor`` (3,) variances (rad^2) added to the engine's attitude covariance;
    ``clock`` the pipeline's :class:`Clock` (its ``t_last`` is advanced here);
    ``tilt_bound`` the least roll/pitch variance (rad^2) while the heading is unknown;
    ``install`` the :class:`~.installation.Installation` (each GNSS epoch is moved from
    the antenna to the IMU with the attitude and rate of the sample it is applied at) and
    ``noise`` the sensor model (NoiseSpec) whose gyro error that move takes into account.
    """

    def __init__(self, engine, floor, clock, cfg, heading_known=True, tilt_bound=0.0,
                 install=None, noise=None, headings=None):
        self.engine = engine
        #: the external heading's queue (:class:`~.heading.HeadingBuffer`), or None
        self.headings = headings
        self.install = install
        self.noise = noise
        self.heading_known = bool(heading_known)
        #: least roll/pitch variance (rad^2) while the heading is unknown
        self.tilt_bound = float(tilt_bound)
        self.max_tilt = math.radians(cfg['aligned_max_tilt_sigma_deg'])
        self.max_heading = math.radians(cfg['aligned_max_heading_sigma_deg'])
        #: the stage has settled (latched; the module docstring): from then on the
        #: bounds and the consistency monitor decide
        self.converged = False
        self._floor = np.asarray(floor, dtype=float)
        self.clock = clock
        self.phase = FINE
        self.stage = 1
        self.t0 = clock.t_last
        self.max_stages = cfg['max_stages']
        self.monitor = ConvergenceMonitor(cfg['stage_min_duration'])
        self.monitor.start(self.t0)
        #: the misalignment variances at ~1 s spacing (the forecast's trend, :mod:`.expectation`)
        self.history = SigmaHistory()
        #: stamp of the first ``aligned`` epoch, or None
        self.t_aligned = None
        #: innovation consistency of the GNSS-aided engines (:mod:`.consistency`)
        self.consistency = ConsistencyMonitor()
        #: the navigation solution goes out with the rows (``~/odom``)
        self.navigating = engine.navigates and cfg['continue_navigation']
        #: why the vehicle frame cannot be the told one (the self-check's mounting check):
        #: then the attitude is published as unknown and the stage is never ``aligned``
        self.mounting_doubt = ''
        #: the same check under way, from the GNSS velocity (:mod:`.sideslip`), or None
        self.sideslip = (SideslipCheck(cfg['mounting_check_max_sideslip_deg'])
                         if cfg['sensor_self_check'] and not engine.restages else None)
        self._att_cov = None
        #: whether a still-base engine's base still rests (:mod:`.still_watch`), or None
        self.still = (StillWatch(engine, cfg['fine_update_hz'], cfg['coarse_duration'],
                                 cfg['gyro_bias_instability_dph'] * DPH)
                      if engine.restages else None)
        #: the heading against the GNSS course (:mod:`.slow_monitor`) and the sensor model
        #: against the IMU in motion (:mod:`.motion_check`), aided engines only, or None
        self.slow = slow_monitor.for_stage(engine, cfg)
        self.motion_check = motion_check.for_stage(engine, cfg, noise)
        #: the straight legs' GNSS course as a heading fix while the heading is unknown
        #: (:mod:`.course_heading`), aided engines only, or None
        self.course = course_heading.for_stage(engine, cfg)

    @property
    def moving(self):
        """Why the base is taken as moving without GNSS ('' at rest; :mod:`.still_watch`)."""
        return '' if self.still is None else self.still.moving

    @property
    def floor(self):
        """Variances (3,) rad^2 added to the engine's attitude covariance at output.

        The engine's own (``make_engine``'s) plus, for the aided engines, the tilt the gyro
        misalignment leaves (:meth:`~.rotation_error.RotationError.tilt_floor`), as the
        model has it now.
        """
        more = getattr(self.engine, 'tilt_floor', None)
        return self._floor if more is None else self._floor + more()

    @property
    def mech(self):
        return self.engine.mech

    def rate_var(self, dt):
        """Variance per axis ((rad/s)^2) of one sample's measured rate over ``dt`` seconds.

        The gyro bias and the white noise of the configured (self-checked) model.
        """
        return self.noise.gyro_bias ** 2 + self.noise.gyro_arw ** 2 / dt

    def attitude_cov(self):
        """Misalignment covariance about ENU (3, 3) with the floor; cached between epochs."""
        if self._att_cov is None:
            P = self.engine.attitude_cov() + np.diag(self.floor)
            if self.mounting_doubt:       # the IMU's attitude, not the vehicle's
                P = np.diag(np.full(3, ANGLE_UNKNOWN_VAR))
            elif not self.heading_known:
                P = P.copy()
                P[2, :2] = P[:2, 2] = 0.0
                P[2, 2] = HEADING_UNKNOWN_VAR
                # raising diagonal entries keeps P positive semi-definite
                for k in (0, 1):
                    P[k, k] = max(P[k, k], self.tilt_bound)
            elif (P.diagonal() > ANGLE_UNKNOWN_VAR).any():
                P = cap_angles(P, np.arange(3))
            self._att_cov = P
        return self._att_cov

    def readiness(self):
        """Return ``(tilt_ready, heading_ready)``: the 1-sigma within the ``aligned`` bounds."""
        P = self.attitude_cov()
        tilt = math.sqrt(max(P[0, 0], P[1, 1], 0.0)) <= self.max_tilt
        heading = self.heading_known and math.sqrt(max(P[2, 2], 0.0)) <= self.max_heading
        return tilt, heading

    def why_not_aligned(self):
        """Return why the phase is not ``aligned`` ('' when it is)."""
        if self.phase == ALIGNED:
            return ''
        if self.moving:
            return self.moving
        why = [] if self.converged else ['converging']
        ready = self._ready_reason()
        return '; '.join(why + ([ready] if ready else []))

    def _ready_reason(self):
        """Return why the attitude is not good enough for ``aligned`` ('' when it is)."""
        tilt, heading = self.readiness()
        if self.moving:
            return self.moving
        if self.mounting_doubt:
            return 'vehicle frame far from level: imu_mounting_rpy_deg untold? (self-check)'
        if not self.heading_known:
            return 'heading unobservable'
        why = []
        if not self.consistency.consistent:
            why.append(f'innovations inconsistent (NIS/dof {self.consistency.ratio:.2f} > '
                       f'{self.consistency.bound:.2f}): {self.consistency.remedy}')
        if self.slow is not None and self.slow.reason:
            why.append(self.slow.reason)
        if not tilt:
            why.append(f'tilt 1-sigma above {math.degrees(self.max_tilt):g} deg')
        if not heading:
            why.append(f'heading 1-sigma above {math.degrees(self.max_heading):g} deg')
        return ', '.join(why)

    def widen(self, var_phi, var_v):
        """Widen the engine's covariance by an error the input may have left (a bridge)."""
        if var_phi > 0.0 or var_v > 0.0:
            self.engine.widen(var_phi, var_v)
            self._att_cov = None

    def _still_epoch(self, t, gnss):
        """After a still-base engine's zero-velocity epoch at ``t``: the motion watch.

        Returns the reason to end the stage, or None (:meth:`.still_watch.StillWatch.epoch`).
        """
        fix = None if gnss is None else gnss.last_fix
        event, reason = self.still.epoch(
            t, fix is not None and t - fix[0] <= GNSS_RECENT_S, self._heading_sigma)
        if event == 'resume':                   # filtering again: it must settle again
            self.converged = False
            self.monitor.start(t)
        elif event == 'coast':
            self.phase = FINE
        if event is not None:
            self._att_cov = None
        return reason

    def _heading_sigma(self):
        """Return the published heading's 1-sigma (rad); pi when the gyros cannot find north."""
        P = self.attitude_cov()
        return math.sqrt(max(P[2, 2], 0.0)) if self.heading_known else math.pi

    def _epoch_done(self, t):
        """After a filter epoch at ``t``: the convergence check."""
        self._att_cov = None
        P = self.attitude_cov()
        self.history.add(t, P.diagonal())
        if self.moving:
            self.phase = FINE
            return
        sig_u = math.sqrt(max(P[2, 2], 0.0))
        if not self.converged:
            if not self.engine.restages:
                if t - self.monitor.t0 < self.monitor.min_duration:
                    return
            elif not self.monitor.converged(t, sig_u):
                return
            elif self.engine.restage_helps and self.stage < self.max_stages:
                self.engine.restage()
                self._att_cov = None
                self.stage += 1
                self.monitor.start(t)
                return
            self.converged = True
        ready = not self._ready_reason()
        if self.phase == FINE and ready:
            self.phase = ALIGNED
            if self.t_aligned is None:
                self.t_aligned = t
        elif self.phase == ALIGNED and not ready:
            self.phase = FINE

    # -- stepping --------------------------------------------------------------------------
    def run(self, t, dtheta, dv, i, gnss):
        """Process samples from index ``i``: returns ``(parts, end index, diverged reason)``.

        ``parts`` are :class:`~.output.Rows`; on a divergence the rows end with the sample
        at which it happened and the reason is a string (else None).
        """
        if self.engine.restages:
            c = self.clock
            hd = self._heading_due_index(t, i)
            end = len(t) if hd is None else hd + 1
            t_prev = c.t_last
            j, C, epoch = self.engine.run_block(t[:end], dtheta[:end], dv[:end], i, c.t_last)
            c.t_last = t[j - 1]
            if self.still is not None:
                self.still.push(t[i:j], dtheta[i:j], dv[i:j], t_prev)
            reason = None
            if epoch:
                reason = self._still_epoch(c.t_last, gnss)
                C[-1] = self.mech.C_b_n
                if reason is None:
                    self._epoch_done(c.t_last)
            if reason is None and j == end and hd is not None:
                dt = t[hd] - (t[hd - 1] if hd > i else t_prev)
                reason = self._apply_heading(t[hd], dtheta[hd], dt)
                C[-1] = self.mech.C_b_n
            phase = self.phase if reason is None else FINE
            return [Rows(t[i:j], C, self.attitude_cov(), phase)], j, reason
        return self._run_aided(t[i:], dtheta[i:], dv[i:], gnss, i)

    def _run_aided(self, t, dtheta, dv, gnss, offset):
        """Run the aided engines' block path: compiled stretches between GNSS epochs.

        The same rows, covariances and phases as :meth:`step` sample by sample (a test
        keeps them equal): each stretch ends at the sample a queued GNSS epoch is due at;
        the rows are cut where the covariance changes, at a prediction without GNSS and at
        a GNSS epoch.
        """
        eng, c = self.engine, self.clock
        m = eng.mech
        n = len(t)
        if self.motion_check is not None:
            self.motion_check.push(t, dtheta, dv, intervals(t, c.t_last))
        Cs = np.empty((n, 3, 3))
        nav = np.empty((n, 6)) if self.navigating else None
        parts, start = [], 0

        def cut(end, cov, phase):
            parts.append(Rows(t[start:end], Cs[start:end], cov, phase,
                              None if nav is None else nav[start:end]))

        k = 0
        while k < n:
            due = [d for d in (gnss.next_due_index(t, k), self._heading_due_index(t, k))
                   if d is not None]
            due_at = min(due) if due else None
            end = n if due_at is None else due_at + 1
            dt = intervals(t[k:end], c.t_last)
            blk = eng.step_block(dtheta[k:end], dv[k:end], dt)
            last = k + blk.end - 1
            Cs[k:last + 1] = blk.C
            if nav is not None:
                nav[k:last + 1] = blk.nav
            c.t_last = t[last]
            for e in [k + p for p in blk.predicted] + ([last] if blk.reason is not None else []):
                if e == last and blk.reason is not None:       # diverged in a prediction
                    Cs[e] = m.C_b_n
                    if nav is not None:
                        nav[e] = np.nan
                    cut(e + 1, eng.attitude_cov(), FINE)
                    return parts, offset + e + 1, blk.reason
                if e > start:                  # the rows so far keep their covariance
                    cut(e, self.attitude_cov(), self.phase)
                    start = e
                self._att_cov = None           # an epoch without GNSS: the sigma grew
            if due_at is not None:
                e = due_at
                if e > start:
                    cut(e, self.attitude_cov(), self.phase)
                    start = e
                reason = self._apply_epochs(t[e], gnss, dtheta[e], dt[-1])
                Cs[e] = m.C_b_n
                if reason is not None:         # diverged: the stage ends at this row
                    if nav is not None:
                        nav[e] = np.nan
                    cut(e + 1, eng.attitude_cov(), FINE)
                    return parts, offset + e + 1, reason
                if nav is not None:
                    v = m.v_n
                    nav[e] = (m.lat, m.lon, m.h, v[0], v[1], v[2])
            k = end
        cut(n, self.attitude_cov(), self.phase)
        return parts, offset + n, None

    def step(self, t, dtheta, dv, gnss):
        """One sample with scalar arithmetic (the live node's path): ``(Output, reason)``."""
        eng, c = self.engine, self.clock
        dt = t - c.t_last
        if eng.restages:
            C, epoch = eng.step(dtheta, dv, dt)
            c.t_last = t
            if self.still is not None:
                self.still.push(t, dtheta, dv, t - dt)
            if epoch:
                reason = self._still_epoch(t, gnss)
                C = eng.mech.C_b_n
                if reason is not None:
                    return one_row(t, C, eng.attitude_cov(), FINE, None), reason
                self._epoch_done(t)
            if self.headings is not None and self.headings.due(t):
                reason = self._apply_heading(t, dtheta, dt)
                C = eng.mech.C_b_n
                if reason is not None:               # diverged: the stage ends at this row
                    return one_row(t, C, eng.attitude_cov(), FINE, None), reason
        else:
            n_pred = eng.n_predict_only
            if self.motion_check is not None:
                self.motion_check.push(t, dtheta, dv, dt)
            try:
                C = eng.step_imu(dtheta, dv, dt)
                reason = None
            except FilterDiverged as exc:
                reason = str(exc)
            c.t_last = t
            if reason is None and eng.n_predict_only != n_pred:    # the sigma grew
                self._att_cov = None
            if reason is None and (gnss.due(t) or (self.headings is not None
                                                   and self.headings.due(t))):
                reason = self._apply_epochs(t, gnss, dtheta, dt)
                C = eng.mech.C_b_n
            if reason is not None:                   # diverged: the stage ends at this row
                nav = np.full((1, 6), np.nan) if self.navigating else None
                return one_row(t, eng.mech.C_b_n, eng.attitude_cov(), FINE, nav), reason
        nav = None
        if self.navigating:
            m = eng.mech
            nav = np.array([[m.lat, m.lon, m.h, m.v_n[0], m.v_n[1], m.v_n[2]]])
        return one_row(t, C, self.attitude_cov(), self.phase, nav), None
