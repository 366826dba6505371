"""The fine stage: an engine stepped at IMU rate, its epochs, convergence, rows.

The epochs themselves (GNSS, external heading, the consistency remedy) are
:mod:`.fine_epochs`.

The stage talks to its engine through the declared contract only
(:class:`~..engines.base.Engine`). Two ways of stepping, by the engine's kind, each a part
of its own (:mod:`.fine_stepping`, picked once when the stage starts): the stationary
engine mechanizes whole blocks between its own filter epochs (vectorised); the GNSS-aided
engines step sample by sample and take each queued GNSS epoch at the first sample at or
past its stamp. Either way, every filter epoch is followed by the settle check and the
``aligned`` gate; on a still base also by the convergence check
(:class:`~.convergence.ConvergenceMonitor`), whose converged first stage restages the
stationary filter (up to ``max_stages``).

The GNSS-aided engines' innovations are checked against their covariance
(:class:`~.consistency.ConsistencyMonitor`); an inconsistent filter has its covariance
inflated and is not ``aligned`` until the test passes again. Their heading is also held
against the GNSS course on straight legs (:mod:`.slow_monitor`: a slow model error the
innovations do not show), and their IMU samples against the sensor model while the vehicle
moves (:mod:`.motion_check`: vibration and turns the coarse window did not show).

``aligned`` means good enough for the user (docs/contracts.md: the attitude meets the user's
thresholds and the consistency checks pass). It is declared at the first filter epoch
where that is true and the estimate has settled, and left only on a clear failure
(:mod:`.aligned_gate`, issue 46: hysteresis on the thresholds and on the consistency
monitor, the hard conditions at once); ``why_not_aligned`` says why. A stage has settled
once its updates' corrections no longer shrink (:class:`~.aligned_gate.SettleTest`),
whatever its kind. A filter's sigma may keep shrinking for minutes (a USV's heading from
its sway, 14' and still falling at 300 s; a still navigation-grade base's heading over
its first minute); waiting for it to stop left such runs ``fine`` to the end with an
attitude far inside the bounds, or ``aligned`` 30 s after it was right. A heading the sensors
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

from ..engines.base import Engine
from ..engines.prior_shaping import cap_angles
from .aligned_gate import AlignedGate, rotation_vector
from .consistency import ConsistencyMonitor
from .convergence import ConvergenceMonitor
from .fine_epochs import EpochUpdates
from .fine_stepping import ALIGNED, FINE, AidedStepping, StillStepping
from . import course_heading, motion_check, slow_monitor, turn_scale
from ..output import ANGLE_UNKNOWN_VAR, HEADING_UNKNOWN_VAR
from .sideslip import SideslipCheck
from .sigma_history import SigmaHistory

__all__ = ['ALIGNED', 'FINE', 'Clock', 'FineStage']


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

    def __init__(self, engine: Engine, floor, clock, cfg, heading_known=True, tilt_bound=0.0,
                 install=None, noise=None, headings=None):
        self.engine: Engine = engine
        #: the external heading's queue (:class:`~.heading.HeadingBuffer`), or None
        self.headings = headings
        self.install = install
        self.noise = noise
        self.heading_known = bool(heading_known)
        #: least roll/pitch variance (rad^2) while the heading is unknown
        self.tilt_bound = float(tilt_bound)
        self.max_tilt = math.radians(cfg['aligned_max_tilt_sigma_deg'])
        self.max_heading = math.radians(cfg['aligned_max_heading_sigma_deg'])
        #: the thresholds with their hysteresis (:mod:`.aligned_gate`)
        self.gate = AlignedGate(self.max_tilt, self.max_heading)
        #: why the stage last left ``aligned`` ('' if it has not)
        self.left_reason = ''
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
        #: how the engine is stepped, by its kind (the one place the stage asks it,
        #: :attr:`~..engines.base.Engine.restages`): its own zero-velocity epochs and the
        #: rest watch, or the GNSS epochs (:mod:`.fine_stepping`)
        self.stepping = StillStepping(self, cfg) if engine.restages else AidedStepping(self)
        #: the same check under way, from the GNSS velocity (:mod:`.sideslip`), aided
        #: engines only, or None
        self.sideslip = (SideslipCheck(cfg['mounting_check_max_sideslip_deg'])
                         if cfg['sensor_self_check'] and isinstance(self.stepping, AidedStepping)
                         else None)
        self._att_cov = None
        #: the heading against the GNSS course (:mod:`.slow_monitor`) and the sensor model
        #: against the IMU in motion (:mod:`.motion_check`), aided engines only, or None
        self.slow = slow_monitor.for_stage(engine, cfg)
        self.motion_check = motion_check.for_stage(engine, cfg, noise)
        #: the straight legs' GNSS course as a heading fix while the heading is unknown
        #: (:mod:`.course_heading`), aided engines only, or None
        self.course = course_heading.for_stage(engine, cfg)
        #: the up gyro's scale factor from the turns between straight legs
        #: (:mod:`.turn_scale`), aided engines only, or None
        self.turn_scale = turn_scale.for_stage(engine, cfg)

    @property
    def moving(self):
        """Why the base is taken as moving without GNSS ('' at rest; :mod:`.still_watch`)."""
        return self.stepping.moving

    @property
    def moved_off(self):
        """Tell whether the stage ended because its base moved while GNSS came (still base)."""
        return self.stepping.moved_off

    @property
    def floor(self):
        """Variances (3,) rad^2 added to the engine's attitude covariance at output.

        The engine's own (``make_engine``'s) plus, for the aided engines, the tilt the gyro
        misalignment leaves (:meth:`~.rotation_error.RotationError.tilt_floor`), as the
        model has it now.
        """
        return self._floor + self.engine.tilt_floor()

    @property
    def mech(self):
        """The engine's strapdown state (:class:`~..engines.base.StrapdownState`)."""
        return self.engine.mech

    def nav_row(self):
        """Return the navigation row (1, 6) (lat, lon rad, h m, ENU velocity m/s), or None.

        None unless the stage publishes the navigation solution (:attr:`navigating`).
        """
        if not self.navigating:
            return None
        m = self.engine.mech
        return np.array([[m.lat, m.lon, m.h, m.v_n[0], m.v_n[1], m.v_n[2]]])

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

    def sigmas(self):
        """Return the published ``(tilt, heading)`` 1-sigma (rad): the worse of roll/pitch."""
        P = self.attitude_cov()
        return math.sqrt(max(P[0, 0], P[1, 1], 0.0)), math.sqrt(max(P[2, 2], 0.0))

    def readiness(self):
        """Return ``(tilt_ready, heading_ready)``: the 1-sigma within the ``aligned`` bounds."""
        tilt, heading = self.gate.ready(*self.sigmas())
        return tilt, self.heading_known and heading

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
        if self.mounting_doubt or not self.heading_known:
            return self._hard_reason()
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

    def _epoch_done(self, t):
        """After a filter epoch at ``t``: the convergence check."""
        self._att_cov = None
        P = self.attitude_cov()
        self.history.add(t, P.diagonal())
        if self.moving:
            self.phase = FINE
            return
        # asked at every epoch: a still-base stage may restage after it has settled
        settled = self.stepping.settled(t, math.sqrt(max(P[2, 2], 0.0)))
        if not self.converged:
            if not settled:
                return
            self.converged = True
        if self.phase == FINE:
            if not self._ready_reason():
                self.phase = ALIGNED
                if self.t_aligned is None:
                    self.t_aligned = t
            return
        why = self._hard_reason() or self.gate.leave_reason(*self.sigmas(), self.consistency)
        if why:                        # aligned, and a condition fails clearly
            self.phase = FINE
            self.gate.n_left += 1
            self.left_reason = why

    def _hard_reason(self):
        """Return why ``aligned`` must be left at once ('' if nothing; :mod:`.aligned_gate`)."""
        if self.mounting_doubt:
            return 'vehicle frame far from level: imu_mounting_rpy_deg untold? (self-check)'
        if not self.heading_known:
            return 'heading unobservable'
        if self.slow is not None and self.slow.reason:
            return self.slow.reason
        return ''

    def note_update(self, t, C_before):
        """Record the attitude correction of the update just applied at ``t`` (settle test).

        ``C_before`` (3, 3): the attitude before the update (:mod:`.aligned_gate`); the
        mounting check takes its part about the vertical (:meth:`.SideslipCheck.correct`).
        """
        phi = rotation_vector(C_before, self.engine.mech.C_b_n)
        if self.stepping.settle is not None:
            self.stepping.settle.add(t, phi)
        if self.sideslip is not None:
            self.sideslip.correct(phi[2])

    # -- stepping (by the engine's kind, :mod:`.fine_stepping`) --------------------------
    def run(self, t, dtheta, dv, i, gnss):
        """Process samples from index ``i``: returns ``(parts, end index, diverged reason)``.

        ``parts`` are :class:`~.output.Rows`; on a divergence the rows end with the sample
        at which it happened and the reason is a string (else None).
        """
        return self.stepping.run(t, dtheta, dv, i, gnss)

    def step(self, t, dtheta, dv, gnss):
        """One sample with scalar arithmetic (the live node's path): ``(Output, reason)``."""
        return self.stepping.step(t, dtheta, dv, gnss)
