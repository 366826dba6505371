"""The fine stage's measurement epochs: queued GNSS fixes and external headings.

A mixin of :class:`~.fine_stage.FineStage`: at the sample an epoch is due at, the
queued fixes (moved from the antenna to the IMU, :mod:`.installation`) and then the
external headings go to the engine; after each GNSS update the consistency monitor
(:class:`~.consistency.ConsistencyMonitor`) is given its innovations and its remedy is
applied, and the under-way mounting check (:mod:`.sideslip`) the fix's velocity; the
slow-error monitor (:mod:`.slow_monitor`) takes each accepted epoch and the self-check in
motion (:mod:`.motion_check`) judges the IMU samples up to it, each opening the engine's
model where the data disagree. A filter failure (:class:`~.gnss_gate.FilterDiverged`)
comes back as its reason. Uses the stage's ``engine``, ``t0``, ``install``, ``headings``,
``consistency``, ``sideslip``, ``slow``, ``motion_check``, ``turn_scale``, ``heading_known``,
``attitude_cov()``, ``rate_var()``, ``note_update()`` and ``_epoch_done()``; of the engine,
only what its contract declares (:class:`~..engines.base.Engine`; the GNSS epochs come to
GNSS-aided engines only, :class:`~..engines.base.AidedEngine`): the last epoch's record and the
remedies, never its filter.
"""
import numpy as np

from . import course_heading
from ..engines.base import AidedEngine
from ..engines.gnss_gate import FilterDiverged


class EpochUpdates:
    """GNSS and external-heading epochs of the fine stage (a mixin; module docstring)."""

    def monitor_findings(self):
        """Return the new findings of the slow-error monitor and the motion check (WARNs)."""
        return [w for mon in (self.slow, self.motion_check, self.course, self.turn_scale)
                if mon is not None for w in mon.take_findings()]

    def monitor_status(self):
        """Diagnostics figures of the slow-error monitor and the motion check."""
        s = {}
        for mon in (self.slow, self.motion_check, self.course, self.turn_scale):
            if mon is not None:
                s.update(mon.status())
        return s

    def _heading_due_index(self, t, k):
        """Index of the sample of ``t`` (from ``k``) an external heading is due at, or None."""
        return None if self.headings is None else self.headings.next_due_index(t, k)

    def _check_long(self, fix, upd):
        """Give the long-horizon test (:class:`~.consistency.LongHorizonTest`) an epoch.

        ``upd`` the engine's update record of ``fix`` (None: nothing); where a row fails,
        the engine's GNSS model is widened and the monitor notes it for a WARN.
        """
        if upd is None:
            return
        eng: AidedEngine = self.engine
        mon = self.consistency
        excess = mon.add_long(fix.t, upd.y, upd.Pzz.diagonal(), eng.last_rows, eng.rejected)
        if excess:
            mon.note_widening(excess, *eng.widen_gnss_noise(excess, mon.long.block_s))

    def _apply_epochs(self, t_now, gnss, dtheta, dt):
        """Apply the GNSS epochs, then the external headings, due at ``t_now``; the reason."""
        reason = self._apply_gnss(t_now, gnss, dtheta, dt)
        if reason is None and self.headings is not None:
            reason = self._apply_heading(t_now, dtheta, dt)
        return reason

    def _apply_heading(self, t_now, dtheta, dt):
        """Give the engine the queued external headings up to ``t_now``; the reason if it diverged.

        ``dtheta`` (3,) rad over ``dt`` s: the sample's rate carries the yaw from the
        epoch's stamp to ``t_now``. A heading measured makes the heading known, whatever
        the gyros can see (:attr:`heading_known`). Not checked by the consistency monitor
        (its gate rejects outliers): the monitor's remedies are for the GNSS model.
        """
        while True:
            fix = self.headings.pop_due(t_now, self.t0)
            if fix is None:
                return None
            w_up = float(self.engine.mech.C_b_n[2] @ np.asarray(dtheta)) / max(float(dt), 1e-6)
            C_before = self.engine.mech.C_b_n.copy()
            try:
                result = self.engine.update_heading(fix, t_now, w_up)
            except FilterDiverged as exc:
                return str(exc)
            self.note_update(t_now, C_before)
            self.headings.counts[result] += 1
            if result != 'rejected':
                self.heading_known = True
            self._epoch_done(t_now)

    def _check_sideslip(self, fix):
        """Give the under-way mounting check (:mod:`.sideslip`) the epoch's velocity."""
        if self.sideslip is None or self.mounting_doubt or fix.v_n is None:
            return
        doubt = self.sideslip.add(fix.v_n, self.engine.mech.C_b_n, self.attitude_cov()[2, 2])
        if doubt:
            self.mounting_doubt = doubt
            self._att_cov = None

    def _watch_slow(self, t_now, fix):
        """Give the slow-error monitor (:mod:`.slow_monitor`) an accepted epoch; apply a remedy."""
        if (self.slow is None or self.mounting_doubt or not self.heading_known
                or self.engine.rejected):
            return
        m = self.engine.mech
        self._att_cov = None
        if self.slow.add(t_now, m.C_b_n, m.v_n, self.attitude_cov()[2, 2], fix):
            self.slow.remedy(self.engine)
            self._att_cov = None

    def _aid_course(self, t_now, fix):
        """Give the course heading aid (:mod:`.course_heading`) an accepted epoch.

        A judged leg's course goes to the engine as a heading fix while the published
        heading is less certain than it (taken directly while the engine's heading is
        beyond its linear range); a disagreement that turns the aid off widens the heading.
        Returns the reason if the engine diverged.
        """
        if (self.course is None or self.mounting_doubt or not self.heading_known
                or self.engine.rejected):
            return None
        eng: AidedEngine = self.engine
        m = eng.mech
        leg = self.course.add(t_now, m.C_b_n, m.v_n, fix)
        if leg is None:
            return None
        D, var = leg
        self._att_cov = None
        var_h = float(self.attitude_cov()[2, 2])
        # a bootstrap: a heading the filter found itself is the slow monitor's to judge; the
        # aid starts only on one declared unknown or beyond the linear range, then keeps it
        # while the published sigma is above half a leg's
        owned = self.course.n_taken + self.course.n_used > 0
        if not (owned or var_h > course_heading.LINEAR_MAX ** 2):
            return None
        if not var_h > var / course_heading.BETTER ** 2:   # known better: the slow monitor
            return None
        # a capped cubature prior, or a linear filter's heading held at its range before
        # the aid ever set it: taken directly; held after the aid set it: a linear update,
        # and taken if its gate rejects it (the held variance says too little)
        held = eng.heading_lost
        first = self.course.n_taken + self.course.n_used == 0
        take = eng.heading_prior_var is not None or (held and first)
        heading = self.course.fix(t_now, m.C_b_n, D, var)
        try:
            result = eng.update_heading(heading, t_now,
                                        linear_max=0.0 if take else course_heading.LINEAR_MAX)
            if held and result == 'rejected':
                result = eng.update_heading(heading, t_now, linear_max=0.0)
            elif held and result == 'used':
                eng.heading_found()
        except FilterDiverged as exc:
            return str(exc)
        widen = self.course.result(t_now, D, var, result, var_h)
        if widen is not None:
            eng.widen(widen, 0.0)
        self._att_cov = None
        return None

    def _apply_gnss(self, t_now, gnss, dtheta, dt):
        """Give the engine every queued epoch up to ``t_now``; the reason if it diverged.

        ``dtheta`` (3,) rad and ``dt`` s: the increment of the sample at ``t_now`` (its rate
        moves the epochs from the antenna to the IMU, :mod:`.installation`).
        """
        if self.motion_check is not None and self.motion_check.epoch(t_now, self.engine):
            self._att_cov = None
        while True:
            fix = gnss.pop_due(t_now, self.t0)
            if fix is None:
                return None
            if self.install is not None and not self.install.no_arm:
                dt = max(float(dt), 1e-6)
                fix = self.install.fix_to_imu(fix, self.engine.mech.C_b_n,
                                              np.asarray(dtheta) / dt, self.attitude_cov(),
                                              self.rate_var(dt))
            C_before = self.engine.mech.C_b_n.copy()
            try:
                upd = self.engine.update(fix, t_now)
            except FilterDiverged as exc:
                return str(exc)
            self.note_update(t_now, C_before)
            gnss.used(fix)
            self._check_sideslip(fix)
            self._check_long(fix, upd)
            if upd is not None:
                eng: AidedEngine = self.engine
                # white excess innovations (a noisier receiver) are answered by the
                # engine's R where it sets R, by the filter's own R posterior in the VB
                # family (no remedy from here), and for ASCKF, whose Sage-Husa R learns
                # only on epochs R dominates, by the state's inflation like every failure
                factor = self.consistency.add(eng.last_nis, eng.last_dof, eng.last_u,
                                              eng.last_rows if eng.sets_R or eng.estimates_R
                                              else None,
                                              rejected=eng.rejected,
                                              noise_remedy=eng.sets_R)
                if factor is not None:
                    eng.inflate(factor)
                if self.consistency.r_factors:
                    eng.inflate_noise(self.consistency.r_factors)
                if self.consistency.relax:
                    eng.relax()
                self._watch_slow(t_now, fix)
                if not (self.turn_scale is None or self.mounting_doubt or eng.rejected):
                    self.turn_scale.add(t_now, eng, fix)
                reason = self._aid_course(t_now, fix)
                if reason is not None:
                    return reason
            self._epoch_done(t_now)
