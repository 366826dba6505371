"""The alignment pipeline: waiting -> coarse -> fine -> aligned, at IMU rate.

A short façade over parts with one job each, driven the same way by the node and
the replay tool (through :class:`~.session.AlignmentSession`), the benchmarks and
the tests: feed IMU increments with their stamps to :meth:`AlignmentPipeline.feed`
(or :meth:`~AlignmentPipeline.process`), GNSS fixes and velocities to
:meth:`~AlignmentPipeline.position_fix` and :meth:`~AlignmentPipeline.velocity_fix`;
every processed sample yields an output row (attitude, 1-sigma Euler angles, phase).

* :mod:`.preprocess`: the optional wavelet pre-processing stage (seed 004);
* :mod:`.coarse_stage`: the coarse window and the coarse attitude with its sigma, on
  a still base or (GNSS-aided filters) a moving one;
* :mod:`.gnss_buffer`: GNSS history and the queue of epochs waiting for the IMU;
* :mod:`.motion`: whether GNSS shows the base moving; what ``fine_filter: auto`` runs;
  when a base that rested and then drives ends its coarse window (``Onset``);
* :mod:`.handover`: from the full coarse window to a running fine stage (the filter
  ``auto`` runs, the sensor self-check, the coarse attitude, the engine);
* :mod:`.factory`: the engine of ``fine_filter`` (stationary seed 002; GNSS-aided
  seeds 000, 001, 003, 004);
* :mod:`.fine_stage`: stepping the engine, its GNSS epochs, convergence, rows;
* :mod:`.report`: the status and degraded conditions for diagnostics.

A filter failure restarts the alignment from coarse, keeping the GNSS history.
"""
import math

import numpy as np

from .stages import coarse_stage, coarse_window
from .inputs import motion
from . import params as prm
from .forecast.expectation import Forecaster
from .engines.factory import is_aided, noise_spec
from .stages.fine_stage import ALIGNED, FINE, Clock
from .inputs.gnss_buffer import GnssBuffer
from .stages.handover import fine_stage_for, hand_over
from .stages.reprocess import CATCH_UP_SAMPLES
from .inputs.heading import HeadingBuffer
from .inputs.installation import Installation
from .output import Output, Rows, assemble, unknown
from .inputs.preprocess import Preprocessor
from .inputs.sample_store import SampleStore
from .forecast.report import ConditionReport, pipeline_status

WAITING, COARSE = 'waiting', 'coarse'
PHASES = (WAITING, COARSE, FINE, ALIGNED)
__all__ = ['AlignmentPipeline', 'PHASES', 'WAITING', 'COARSE', 'FINE', 'ALIGNED']


class AlignmentPipeline:
    """Coarse + fine alignment; see the module docstring.

    Parameters
    ----------
    values : dict
        Alignment parameters by name (``align.params``); missing ones take defaults.
    """

    def __init__(self, values=None):
        cfg = prm.defaults()
        cfg.update(prm.validate(values or {}))
        #: the parameters as configured; ``cfg`` holds them as the self-check left them
        self.configured = cfg
        self.cfg = dict(cfg)
        #: the sensor model in SI units (NoiseSpec) the filters use
        self.noise = noise_spec(cfg)
        #: the IMU mounting rotation and the GNSS lever arm (:mod:`.installation`)
        self.install = Installation.from_params(cfg)
        self.gnss = GnssBuffer()
        #: the external heading (:mod:`.heading`)
        self.headings = HeadingBuffer(math.radians(cfg['heading_offset_deg']))
        self.n_restarts = 0
        #: the last seconds of processed samples, for a restart to reuse
        self.store = SampleStore()
        self.reset()

    def inherit_gnss(self, other):
        """Take over the GNSS position history of ``other`` (a pipeline being replaced)."""
        self.gnss.inherit(other.gnss)

    def reset(self, keep_gnss_history=False):
        """Forget everything but the parameters and the GNSS position; phase -> waiting."""
        self.clock = Clock()
        self.window = coarse_window.CoarseWindow(self.cfg['coarse_duration'])
        self.coarse_info = {}
        self.check = None
        self.cfg = dict(self.configured)
        self.noise = noise_spec(self.cfg)
        self.install = self.install.with_lever_arm(self.cfg['gnss_lever_arm_m'])
        #: the fine filter is GNSS-aided (it runs on a moving base); with ``auto``, decided
        #: when coarse alignment ends
        self.aided = is_aided(self.cfg['fine_filter'])
        self.fine = None
        #: a reprocessing stage's stored samples still to run over (:mod:`.reprocess`)
        self.catch_up = None
        self.position_source = None
        self.position = None
        self.warnings = []
        self.gnss.reset(keep_history=keep_gnss_history)
        #: when GNSS showed the base start moving (the coarse window may end early)
        self.onset = motion.Onset()
        if keep_gnss_history:
            self.headings.pending.clear()
        else:
            self.headings.reset()
        #: an external heading set the coarse heading
        self.heading_measured = False
        self.report = ConditionReport()
        #: the time and accuracy to expect (:mod:`.expectation`)
        self.forecast = Forecaster()
        cfg = self.cfg
        w = cfg['preprocess_window'] + cfg['preprocess_window'] % 2
        self.pre = Preprocessor(cfg['preprocess_factor'], w, max(1, w // 4),
                                cfg['preprocess_wavelet']) if cfg['preprocess'] else None

    # -- read-outs ------------------------------------------------------------------------
    @property
    def phase(self):
        """One of :data:`PHASES`."""
        if self.fine is not None and self.catch_up is None:
            return self.fine.phase
        return WAITING if self.clock.t_first is None else COARSE

    @property
    def t_last(self):
        """Stamp of the last processed sample (s), or None (queued ones while catching up)."""
        if self.catch_up is not None:
            return self.catch_up.t_last
        return self.clock.t_last

    @property
    def elapsed(self):
        """Seconds of IMU data since the first sample."""
        c = self.clock
        return 0.0 if c.t_first is None else self.t_last - c.t_first

    @property
    def engine(self):
        """The fine-alignment engine, or None before fine alignment."""
        return None if self.fine is None else self.fine.engine

    @property
    def mech(self):
        """The engine's strapdown state, or None before fine alignment."""
        return None if self.fine is None else self.fine.mech

    @property
    def gnss_counts(self):
        """GNSS epochs by what became of them (:mod:`.gnss_buffer`)."""
        return self.gnss.counts

    @property
    def navigating(self):
        """Tell whether a navigation filter runs and ``continue_navigation`` wants its output."""
        return self.fine is not None and self.fine.navigating

    def attitude_cov(self):
        """Misalignment covariance about ENU (3, 3), including what the model cannot see."""
        return self.fine.attitude_cov()

    def nav_cov(self):
        """Covariance (9, 9) of position, velocity and misalignment errors, or None."""
        eng = self.engine
        return eng.nav_cov() if eng is not None and eng.navigates else None

    def status(self):
        """Key figures for diagnostics (plain Python types), with the forecast."""
        return pipeline_status(self)

    def expectation(self):
        """Return the time and 1-sigma to expect (:class:`~.expectation.Expectation`) now."""
        return self.forecast.expect(self)

    def conditions(self):
        """Return the new degraded conditions: ``[(level, text)]``, 1 warn, 2 error."""
        return self.report.conditions(self)

    # -- input ----------------------------------------------------------------------------
    def position_fix(self, t, lat_deg, lon_deg, h, pos_var=None):
        """Record a valid GNSS position (deg, deg, m); ``pos_var`` (2,) east/north m^2 or None.

        ``pos_var`` is taken as the receiver reports it; unless both values are
        finite and positive it is ignored (the configured sigma is used).

        Stationary models: the position is fixed when coarse alignment ends (seed
        002 Table 1), from the recent fixes. GNSS-aided filters: every fix is also a
        measurement, applied when the IMU stream passes its stamp.
        """
        coarse = self.fine is None
        # queued in coarse alignment too: a fix stamped after the window's end (a replay's
        # block reaches past it) is the fine filter's first epoch, as on the live path
        # (the IMU's stamp: while a stage catches up, the last queued sample's)
        self.gnss.position_fix(t, lat_deg, lon_deg, h, pos_var, self.t_last,
                               queue=coarse or self.aided)
        if coarse and self.clock.t_last is not None:
            self.gnss.drop_pending(self.clock.t_last)
        self._watch_motion(t)

    def velocity_fix(self, t, v_n, vel_var=None):
        """Record a GNSS ENU velocity (m/s, (3,)); ``vel_var`` (2,) east/north (m/s)^2 or None."""
        self.gnss.velocity_fix(t, v_n, vel_var)
        self._watch_motion(t)

    def _watch_motion(self, t):
        """Restart when GNSS shows motion a running filter cannot take (:func:`motion.watch`).

        Keeps when the motion began (:class:`~.motion.Onset`); a restart for it begins its
        coarse window with the stored rest before it (:mod:`.sample_store`).
        """
        if self._may_restart_for_motion:
            self.onset.fix(self.gnss, self.cfg, t)
        if self.fine is not None:
            reason = motion.watch(self.gnss, self.cfg, t, self.aided, self.fine.heading_known,
                                  self.install.speed_since(t - 3.0), self.install.arm_m)
            if reason is not None:
                self._diverged(reason, reuse=True)

    @property
    def _may_restart_for_motion(self):
        """Tell whether motion can end this stage: coarse, or one :func:`motion.watch` restarts.

        Only then are the motion's onset and the samples a restart reuses kept (an aided
        stage with its heading known runs on through any motion).
        """
        f = self.fine
        return f is None or not (self.aided and f.heading_known)

    def heading_fix(self, t, yaw, var):
        """Record an external heading: the source's yaw (rad, REP-103) and its variance (rad^2).

        ``heading_offset_deg`` turns it into the vehicle's. The coarse stage takes the last
        one as its heading; while a fine filter runs, each is a yaw measurement applied when
        the IMU stream passes its stamp (:mod:`.heading`).
        """
        self.headings.add(t, yaw, var, self.t_last, queue=True)
        if self.fine is None and self.clock.t_last is not None:   # as position_fix's
            self.headings.drop_pending(self.clock.t_last)

    def start_clock(self, t0):
        """Set the stamp that the first increment starts from (before the first process call)."""
        self.clock.t_last = float(t0)

    def widen(self, var_phi, var_v=0.0):
        """Widen the fine filter's covariance by an error the input may have left.

        Adds ``var_phi`` (rad^2) to each misalignment variance and ``var_v``
        ((m/s)^2) to each velocity variance (a bridged gap,
        :class:`~sins_align_ros.align.inputs.imu_input.ImuInput`). No effect before fine
        alignment.
        """
        if self.fine is not None:
            self.fine.widen(var_phi, var_v)

    # -- processing -----------------------------------------------------------------------
    def feed(self, t, dtheta, dv):
        """Process IMU-frame samples: into the vehicle frame (:mod:`.installation`), then on.

        Without pre-processing (``preprocess``) this is :meth:`process`. With it the samples
        are resampled and denoised (:mod:`.preprocess`) and come out later, each with its
        own stamp: the returned :class:`Output` has a row per sample finished by this call
        (none while the stage fills, several at once after).
        """
        dtheta, dv = self.install.take(t, dtheta, dv, self.t_last)
        if self.pre is None:
            return self.process(t, dtheta, dv)
        t, dtheta, dv = self.pre.push(t, dtheta, dv)
        return self.process(t, dtheta, dv) if len(t) else Output.empty()

    def flush(self):
        """Process the samples the pre-processing stage still holds (end of a recording)."""
        if self.pre is None:
            return Output.empty()
        t, dtheta, dv = self.pre.flush()
        return self.process(t, dtheta, dv) if len(t) else Output.empty()

    def process(self, t, dtheta, dv):
        """Process samples with end stamps ``t`` (N,) and increments (N, 3) over (t_{k-1}, t_k].

        The interval of the very first sample starts at the stamp given to
        :meth:`start_clock`; without it, the first interval is taken equal to the
        second. Returns an :class:`Output` with N rows.
        """
        t = np.atleast_1d(np.asarray(t, dtype=float))
        dtheta = np.atleast_2d(np.asarray(dtheta, dtype=float))
        dv = np.atleast_2d(np.asarray(dv, dtype=float))
        outs, i, n = [], 0, len(t)
        if self._may_restart_for_motion:
            self.store.push(t, dtheta, dv)
        while i < n:
            c = self.clock               # a restart (reset) replaces the clock
            if c.t_first is None:
                if c.t_last is None:
                    c.t_last = t[i] - (t[i + 1] - t[i] if i + 1 < n else 0.01)
                c.t_first = c.t_last
            if self.fine is None:
                w, still = self.window, not self.aided and self.onset.t is None
                end = self.onset.window_end(self.cfg, c.t_first)
                w.t_end = None if w.short_end_refused else end
                w.plan(c.t_first, self.cfg, still)
                # (a restart's window, begun with stored samples, may be complete already)
                j = i if w.full else w.take(t, dtheta, dv, i, c.t_last)
                if j > i:
                    c.t_last = t[j - 1]
                w.refuse_short_end(self.onset.t, c.t_first, self.cfg, self.noise, self.gnss)
                w.judge(c.t_first, self.cfg, self.noise, self.gnss, still)
                w.hold_for_drive_test(c.t_first, self.cfg, self.noise, self.gnss)
                out = unknown(t[i:j], COARSE)
                if w.full:
                    self._finish_coarse()
                    if self.catch_up is not None:
                        self._catch_up(max(CATCH_UP_SAMPLES, 2 * n))
                    if self.catch_up is not None:   # still behind: the rest of this call
                        self.catch_up.add(t[j:], dtheta[j:], dv[j:])    # waits, unknown
                        outs.extend([out, unknown(t[j:], COARSE)])
                        break
                    if self.fine is not None and j > i:   # (aligned after a reprocessing)
                        self._fill_last(out)
                outs.append(out)
                i = j
                continue
            if self.catch_up is not None:   # still behind: these samples wait in its queue
                self.catch_up.add(t[i:], dtheta[i:], dv[i:])
                self._catch_up(max(CATCH_UP_SAMPLES, 2 * n))
                if self.fine is None:       # it diverged: these samples open the new window
                    continue
                if self.catch_up is not None:
                    outs.append(unknown(t[i:], COARSE))
                    break
                # caught up with these samples too: publish the last one's estimate
                out = unknown(t[i:], COARSE)
                self._fill_last(out)
                outs.append(out)
                break
            if n == 1:                      # the live node's path: scalar arithmetic
                out, reason = self.fine.step(t[0], dtheta[0], dv[0], self.gnss)
                if reason is not None:
                    self._diverged(reason, reuse=self._moved_off)
                return out
            parts, i, reason = self.fine.run(t, dtheta, dv, i, self.gnss)
            outs.extend(parts)
            if reason is not None:
                self._diverged(reason, reuse=self._moved_off)
        return assemble(outs)

    @property
    def _moved_off(self):
        """Tell whether the stage ended because a still base started moving (its rest watch).

        Its restart reuses the stored rest, as one for GNSS motion does (:meth:`_diverged`).
        """
        return self.fine is not None and self.fine.moved_off

    def start_fine(self, C_b_n, sigma_phi, t0, lat=None, h=0.0):
        """Skip coarse alignment: start fine alignment at ``t0`` from ``C_b_n``.

        ``sigma_phi`` (3,) rad is the misalignment uncertainty; ``lat`` (rad) and
        ``h`` override the position. Used by experiments that impose a known
        initial misalignment (seed 002's 1/5/10 deg cases).
        """
        if self.aided:
            raise ValueError('start_fine is for the stationary models; the moving-base '
                             'filters start from coarse alignment with GNSS')
        self.reset()
        self.clock.t_first = self.clock.t_last = float(t0)
        self._choose_position()
        if lat is not None:
            self.position = np.array([lat, self.position[1], h])
        start = coarse_stage.CoarseResult(np.asarray(C_b_n, float),
                                          np.asarray(sigma_phi, float), self.position)
        self.fine, warnings = fine_stage_for(start, self.cfg, self.noise, bool(self.gnss.vels),
                                             True, False, self.clock, self.install,
                                             self.headings)
        self.warnings.extend(warnings)

    def restart_from_coarse(self, reason):
        """Restart from coarse alignment (keeping the GNSS history) and say why."""
        self._diverged(reason)

    # -- stages ---------------------------------------------------------------------------
    def _choose_position(self):
        self.position, self.position_source = self.gnss.position(self.cfg, self.aided)

    def _finish_coarse(self):
        window = self.window.arrays(self.clock.t_first)
        t_end = self.clock.t_last
        self.window = coarse_window.CoarseWindow(self.cfg['coarse_duration'])
        start, reason = hand_over(window, self.cfg, self.noise, self.clock, self.gnss,
                                  self.headings, self.install)
        if reason is not None:
            self._diverged(reason)
            return
        self.cfg, self.noise, self.aided = start.cfg, start.noise, start.aided
        self.position, self.position_source = start.position, start.position_source
        self.check, self.coarse_info = start.check, start.coarse_info
        self.heading_measured = start.heading_measured
        self.warnings.extend(start.warnings)
        self.fine = start.fine
        self.catch_up = start.catch_up
        self.install = start.install
        # fixes that came in during coarse alignment are history, not measurements; those
        # stamped after its last sample are the aided filter's
        self.gnss.drop_pending(t_end if self.aided else math.inf)
        if self.aided and self.catch_up is not None:     # it runs over the window's fixes
            self.gnss.requeue(self.clock.t_first, t_end)
        self.headings.drop_pending(t_end)
        if self.catch_up is not None:                    # and its external headings
            self.headings.requeue(self.clock.t_first, t_end)

    def _catch_up(self, budget):
        """Run the reprocessing stage over at most ``budget`` queued samples (reprocess)."""
        done, reason = self.catch_up.run(self.fine, self.gnss, budget)
        if done:
            self.catch_up = None
        if reason is not None:
            self._diverged(reason)

    def _fill_last(self, out):
        """Put the fine stage's current estimate and phase into the last row of ``out``."""
        r = Rows(out.t[-1:], self.mech.C_b_n[None], self.attitude_cov(),
                 self.fine.phase).output()
        out.q[-1], out.euler[-1], out.sigma[-1], out.P_phi[-1] = r.q[0], r.euler[0], \
            r.sigma[0], r.P_phi[0]
        out.phase[-1] = self.fine.phase

    def _diverged(self, reason, reuse=False):
        """Restart from coarse alignment after a filter failure, keeping GNSS history.

        ``reuse`` (GNSS, or a still-base stage's rest watch, shows the base start moving):
        the new coarse window begins with the stored samples from the rest before the
        motion (:mod:`.sample_store`; before this restart where GNSS has not yet shown it),
        and the motion's onset is kept, so that the window may end soon after it.
        """
        t = self.clock.t_last
        onset = self.onset
        self.reset(keep_gnss_history=True)
        self.clock.t_last = t
        self.n_restarts += 1
        self.warnings.append(f'{reason}: alignment restarted from coarse')
        if not reuse:
            return
        # the rest the early end needs, but no more than leaves the window room for the
        # motion's coarse_motion_s (a short coarse_duration)
        cfg = self.cfg
        ref = t if onset.t is None else onset.t
        kept = self.store.since(max(ref - cfg['coarse_min_duration'] - 1.0,
                                    ref + cfg['coarse_motion_s'] - cfg['coarse_duration']), t)
        if kept is None:
            return
        if onset.t is not None:
            self.onset = onset
        self.window.prefill(*kept)
        self.clock.t_first = kept[0]
