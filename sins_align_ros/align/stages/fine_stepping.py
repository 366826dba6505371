"""The fine stage's two ways of stepping an engine, one per engine kind.

Parts of :class:`~.fine_stage.FineStage`, which picks one when it starts, by the engine's
kind (:attr:`~..engines.base.Engine.restages`), and then steps through it without
asking again:

* :class:`StillStepping` (a :class:`~..engines.base.StillEngine`, seed 002): the engine
  mechanizes whole blocks up to its own zero-velocity epoch (vectorised); each epoch is
  followed by the rest watch (:mod:`~..engines.still_watch`) and the convergence check: a
  first stage whose heading sigma stopped falling may be restaged. The stage has settled
  by the settle test on its epochs' corrections, as an aided one (issue 46: waiting for the
  sigma to stop falling held a still navigation-grade base 30 s after it was right). A
  block's rows all take the covariance after its epoch.
* :class:`AidedStepping` (an :class:`~..engines.base.AidedEngine`): the engine is stepped
  in compiled stretches (or sample by sample on the live path) up to the sample each queued
  GNSS epoch or external heading is due at (:mod:`.fine_epochs`); rows are cut where the
  covariance changes. The stage has settled once its updates' corrections no longer
  shrink (:class:`~.aligned_gate.SettleTest`).

Each offers ``run`` (the block path), ``step`` (one sample), ``settled`` (the convergence
rule) and ``moving`` (why the base is taken as moving, '' at rest). The two paths stay
two: their rows differ by design (which covariance a row before an epoch carries), and
the goldens hold them byte for byte.
"""
import math

import numpy as np

from ..engines.base import AidedEngine, StillEngine
from .aligned_gate import SettleTest
from ..engines.gnss_gate import FilterDiverged
from ..engines.still_watch import StillWatch
from .coarse_window import DRIVE_TEST_S
from ..inputs.imu_input import intervals
from ..output import Rows, one_row
from ...units import DPH

FINE, ALIGNED = 'fine', 'aligned'
#: GNSS fixes this recent (s) make a still-base stage that finds its base moving end, so
#: that a GNSS-aided filter takes over; older ones: it coasts
GNSS_RECENT_S = 5.0


class StillStepping:
    """Step a still-base engine by its own epochs (module docstring); owns the rest watch."""

    def __init__(self, stage, cfg):
        self.stage = stage
        self.engine: StillEngine = stage.engine
        #: the epochs' corrections (:class:`~.aligned_gate.SettleTest`)
        self.settle = SettleTest(stage.t0)
        #: whether the base still rests (:mod:`~..engines.still_watch`)
        self.still = StillWatch(self.engine, cfg['fine_update_hz'],
                                max(cfg['coarse_duration'], DRIVE_TEST_S),
                                cfg['gyro_bias_instability_dph'] * DPH)

    @property
    def moving(self):
        """Why the base is taken as moving without GNSS ('' at rest)."""
        return self.still.moving

    @property
    def moved_off(self):
        """Tell whether the stage ended because the base moved while GNSS came."""
        return self.still.moved_off

    def settled(self, t, sigma_heading):
        """Tell whether the stage has settled at the epoch at ``t``; restage it if that helps.

        A first stage whose heading 1-sigma ``sigma_heading`` (rad) stopped falling
        (:class:`~.convergence.ConvergenceMonitor`) is restaged (up to ``max_stages``) where
        a restage helps (:func:`~..engines.stationary.restage_helps`): it starts settling
        again. Settled: the settle test on the epochs' corrections (:mod:`.aligned_gate`).
        """
        s, eng = self.stage, self.engine
        if (eng.restage_helps and s.stage < s.max_stages
                and s.monitor.converged(t, sigma_heading)):
            eng.restage()
            s._att_cov = None
            s.stage += 1
            s.monitor.start(t)
            self.settle = SettleTest(t)
            return False
        P = s.attitude_cov()
        return self.settle.settled(t, np.sqrt(np.maximum(P.diagonal(), 0.0)))

    def _epoch(self, t, gnss):
        """After a zero-velocity epoch at ``t``: the rest watch; the reason to end, or None.

        (:meth:`~..engines.still_watch.StillWatch.epoch`.)
        """
        s = self.stage
        fix = None if gnss is None else gnss.last_fix
        event, reason = self.still.epoch(
            t, fix is not None and t - fix[0] <= GNSS_RECENT_S, self._heading_sigma)
        if event == 'resume':                   # filtering again: it must settle again
            s.converged = False
            s.monitor.start(t)
            self.settle = SettleTest(t)
        elif event == 'coast':
            s.phase = FINE
        if event is not None:
            s._att_cov = None
        return reason

    def _note_epoch(self, t):
        """Give the settle test the correction the epoch at ``t`` fed back.

        (The engine's ``exp([phi x])`` is :func:`~.aligned_gate.rotation_vector`'s
        ``-phi``; the test compares sums, so only the sign convention must be one.)
        """
        self.settle.add(t, -self.engine.last_correction)

    def _heading_sigma(self):
        """Return the published heading's 1-sigma (rad); pi when the gyros cannot find north."""
        s = self.stage
        P = s.attitude_cov()
        return math.sqrt(max(P[2, 2], 0.0)) if s.heading_known else math.pi

    def run(self, t, dtheta, dv, i, gnss):
        """Process samples from ``i`` up to the next epoch: ``(parts, end index, reason)``."""
        s, eng = self.stage, self.engine
        c = s.clock
        hd = s._heading_due_index(t, i)
        end = len(t) if hd is None else hd + 1
        t_prev = c.t_last
        j, C, epoch = eng.run_block(t[:end], dtheta[:end], dv[:end], i, c.t_last)
        c.t_last = t[j - 1]
        self.still.push(t[i:j], dtheta[i:j], dv[i:j], t_prev)
        reason = None
        if epoch:
            self._note_epoch(c.t_last)
            reason = self._epoch(c.t_last, gnss)
            C[-1] = eng.mech.C_b_n
            if reason is None:
                s._epoch_done(c.t_last)
        if reason is None and j == end and hd is not None:
            dt = t[hd] - (t[hd - 1] if hd > i else t_prev)
            reason = s._apply_heading(t[hd], dtheta[hd], dt)
            C[-1] = eng.mech.C_b_n
        phase = s.phase if reason is None else FINE
        return [Rows(t[i:j], C, s.attitude_cov(), phase)], j, reason

    def step(self, t, dtheta, dv, gnss):
        """One sample with scalar arithmetic (the live node's path): ``(Output, reason)``."""
        s, eng = self.stage, self.engine
        c = s.clock
        dt = t - c.t_last
        C, epoch = eng.step(dtheta, dv, dt)
        c.t_last = t
        self.still.push(t, dtheta, dv, t - dt)
        if epoch:
            self._note_epoch(t)
            reason = self._epoch(t, gnss)
            C = eng.mech.C_b_n
            if reason is not None:
                return one_row(t, C, eng.attitude_cov(), FINE, None), reason
            s._epoch_done(t)
        if s.headings is not None and s.headings.due(t):
            reason = s._apply_heading(t, dtheta, dt)
            C = eng.mech.C_b_n
            if reason is not None:               # diverged: the stage ends at this row
                return one_row(t, C, eng.attitude_cov(), FINE, None), reason
        return one_row(t, C, s.attitude_cov(), s.phase, s.nav_row()), None


class AidedStepping:
    """Step a GNSS-aided engine to each queued epoch (module docstring)."""

    #: a GNSS-aided engine is never taken as moving without GNSS (its base may move), and
    #: its stage never ends for motion
    moving = ''
    moved_off = False

    def __init__(self, stage):
        self.stage = stage
        self.engine: AidedEngine = stage.engine
        #: the updates' corrections (:class:`~.aligned_gate.SettleTest`)
        self.settle = SettleTest(stage.t0)

    def settled(self, t, sigma_heading):
        """Tell whether the estimate has settled by the epoch at ``t`` (:mod:`.aligned_gate`)."""
        P = self.stage.attitude_cov()
        return self.settle.settled(t, np.sqrt(np.maximum(P.diagonal(), 0.0)))

    def run(self, t, dtheta, dv, i, gnss):
        """Process samples from index ``i``: compiled stretches between the queued epochs.

        The same rows, covariances and phases as :meth:`step` sample by sample (a test
        keeps them equal): each stretch ends at the sample a queued GNSS epoch is due at;
        the rows are cut where the covariance changes, at a prediction without GNSS and at
        a GNSS epoch. Returns ``(parts, end index, diverged reason)``.
        """
        s, eng = self.stage, self.engine
        c, offset = s.clock, i
        t, dtheta, dv = t[i:], dtheta[i:], dv[i:]
        m = eng.mech
        n = len(t)
        if s.motion_check is not None:
            s.motion_check.push(t, dtheta, dv, intervals(t, c.t_last))
        Cs = np.empty((n, 3, 3))
        nav = np.empty((n, 6)) if s.navigating else None
        parts, start = [], 0

        def cut(end, cov, phase):
            parts.append(Rows(t[start:end], Cs[start:end], cov, phase,
                              None if nav is None else nav[start:end]))

        k = 0
        while k < n:
            due = [d for d in (gnss.next_due_index(t, k), s._heading_due_index(t, k))
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
                    cut(e, s.attitude_cov(), s.phase)
                    start = e
                s._att_cov = None              # an epoch without GNSS: the sigma grew
            if due_at is not None:
                e = due_at
                if e > start:
                    cut(e, s.attitude_cov(), s.phase)
                    start = e
                reason = s._apply_epochs(t[e], gnss, dtheta[e], dt[-1])
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
        cut(n, s.attitude_cov(), s.phase)
        return parts, offset + n, None

    def step(self, t, dtheta, dv, gnss):
        """One sample with scalar arithmetic (the live node's path): ``(Output, reason)``."""
        s, eng = self.stage, self.engine
        c = s.clock
        dt = t - c.t_last
        n_pred = eng.n_predict_only
        if s.motion_check is not None:
            s.motion_check.push(t, dtheta, dv, dt)
        try:
            C = eng.step_imu(dtheta, dv, dt)
            reason = None
        except FilterDiverged as exc:
            reason = str(exc)
        c.t_last = t
        if reason is None and eng.n_predict_only != n_pred:    # the sigma grew
            s._att_cov = None
        if reason is None and (gnss.due(t) or (s.headings is not None
                                               and s.headings.due(t))):
            reason = s._apply_epochs(t, gnss, dtheta, dt)
            C = eng.mech.C_b_n
        if reason is not None:                   # diverged: the stage ends at this row
            nav = np.full((1, 6), np.nan) if s.navigating else None
            return one_row(t, eng.mech.C_b_n, eng.attitude_cov(), FINE, nav), reason
        return one_row(t, C, s.attitude_cov(), s.phase, s.nav_row()), None
