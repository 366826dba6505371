"""The external heading's filter epoch, shared by every GNSS-aided engine.

A mixin of :class:`~.aided.GnssAidedEngine`: a GNSS compass's or gyrocompass's yaw
(``heading/in``) updates the engine's misalignment between GNSS epochs, or, while the
heading is still beyond the small-angle model, is taken directly
(:mod:`.heading` has the measurement itself; :func:`gated_yaw_update` takes it through
the innovation gate).
"""
import math

import numpy as np

from .gnss_gate import FilterDiverged, GnssGate
from ..inputs.heading import LINEAR_MAX, take_heading, yaw_update


def gated_yaw_update(gate, owner, x, P, i_phi, C_b_n, fix, yaw):
    """Update ``x``, ``P`` with ``fix`` (yaw carried to ``yaw``) through ``gate``; (x, P) or None.

    The update is :func:`~.heading.yaw_update`; ``gate`` the engine's heading
    :class:`~.gnss_gate.GnssGate` (its forced acceptance widens ``owner.P``, the object
    holding the filter's covariance); a rejected epoch is counted there and returns None.
    A non-finite result raises :class:`~.gnss_gate.FilterDiverged`.
    """
    max_nis = gate.threshold(1, owner)
    x, P, y, S, ok = yaw_update(x, P, i_phi, C_b_n, yaw, fix.var, max_nis)
    if not ok:
        k_up = np.arange(len(x))[i_phi][2]
        gate.rejected(fix.t, y * y / S, max_nis, np.array([k_up]), np.array([y]))
        return None
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(P))):
        raise FilterDiverged(f'filter diverged at t={fix.t:.3f} s (heading update)')
    gate.accepted()
    return x, P


class ExternalHeading:
    """Yaw epochs of an external heading.

    Uses the engine's ``kf``, ``mech``, ``sums``, ``gate``, ``i_phi``, ``predict`` and
    ``_feedback``; :meth:`_heading_taken` is the families' hook.
    """

    #: the external heading's innovation gate, made at its first epoch
    heading_gate = None
    #: the smallest variance (rad^2) of a heading fix taken or used so far (a heading
    #: floor derived for a heading found from the accelerations yields to it)
    min_heading_fix_var = math.inf

    def update_heading(self, fix, t_now, w_up=0.0, linear_max=LINEAR_MAX):
        """Filter epoch for an external heading ``fix`` (:class:`~.heading.HeadingFix`).

        Predicts over the interval so far, then updates the misalignment with the yaw
        (:func:`~.heading.yaw_update`, carried from the fix's stamp to ``t_now`` with the up
        rate ``w_up``, rad/s) and feeds the estimate back as a GNSS epoch without a
        position does; above :data:`~.heading.LINEAR_MAX` the heading is taken directly.
        ``linear_max`` (rad) replaces that bound (0: always taken; the GNSS course of
        :mod:`.course_heading`). Outliers are gated with the GNSS gate's probability (a gate
        of its own). Returns
        ``'used'``, ``'taken'`` or ``'rejected'``; raises
        :class:`~.gnss_gate.FilterDiverged`.
        """
        if self.sums.T > 1e-6:
            self.predict(without_gnss=False)
        kf = self.kf
        if self.heading_gate is None:
            self.heading_gate = GnssGate(self.gate.probability, self.gate.max_rejects, (1,),
                                         name='heading')
        yaw = fix.yaw + w_up * (t_now - fix.t)
        k_up = np.arange(len(kf.x))[self.i_phi][2]
        P = kf.P
        if P[k_up, k_up] > linear_max ** 2:
            self.mech.C_b_n, kf.P = take_heading(self.mech.C_b_n, P, k_up, yaw, fix.var)
            x = kf.x.copy()
            x[k_up] = 0.0
            kf.x = x
            self.heading_prior_var = None
            self.min_heading_fix_var = min(self.min_heading_fix_var, fix.var)
            self._heading_taken()
            return 'taken'
        upd = gated_yaw_update(self.heading_gate, kf, kf.x, kf.P, self.i_phi, self.mech.C_b_n,
                               fix, yaw)
        if upd is None:
            return 'rejected'
        kf.x, kf.P = upd
        self.min_heading_fix_var = min(self.min_heading_fix_var, fix.var)
        self._feedback(None)
        return 'used'

    def _heading_taken(self):
        """Act on a heading taken directly (the navigation filters' heading is found again)."""
