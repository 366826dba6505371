"""The process noise of a GNSS-aided engine's intervals, and its widening by the monitors.

A mixin of :class:`~.aided.GnssAidedEngine` (:class:`ProcessNoise`): each interval's Q
(``diag(Qc) T`` and the parts of a dropped force and the gyro and accelerometer scale
errors), and what the fine stage's monitors do to the continuous densities ``Qc`` when the
data show more than the model: the motion check widens rows of it
(:meth:`ProcessNoise.widen_process_noise`, :mod:`~..stages.motion_check`), the slow-error
monitor raises the gyro drift's (:meth:`ProcessNoise.raise_drift_noise`,
:mod:`~..stages.slow_monitor`). Both change the model's own ``_Qc0`` too, so that relaxing
an inflation (:meth:`~.consistency_remedies.ConsistencyRemedies.relax`) returns to the
widened model, not below it.
"""
import math

import numpy as np


class ProcessNoise:
    """Q of each interval and the monitors' widening of ``Qc`` (a mixin; module docstring).

    Uses the engine's ``kf``, ``sums``, ``Qc``, ``own_Q``, ``i_eps`` and the bookkeeping
    ``_Qc0`` (the model's densities) and ``_held`` (states without process noise of their own).
    """

    def _set_process_noise(self):
        """Set Q of the interval since the last epoch; return what was lent, or None.

        ``diag(Qc) T`` plus a dropped force's velocity noise
        (:meth:`~.force.ForceModel._force_noise`) and the rotation-proportional noise of the
        gyro scale factors and misalignment (:mod:`.rotation_error`) and the accelerometer's
        force-proportional velocity noise (:mod:`.force_error`). A filter that estimates
        Q (``own_Q``) keeps its own; the parts beyond ``diag(Qc) T`` are lent to it for the
        step (``kf.Q_lent``: the ASCKF's, the one filter that estimates Q; never estimated
        into its Q) and taken back after it (:meth:`_return_process_noise`).
        """
        T = max(self.sums.T, 1e-3)
        E = self._force_noise(T)
        for E_more in (self._rotation_noise(T), self._force_error_noise(T)):
            if E_more is not None:
                E = E_more if E is None else E + E_more
        if not self.own_Q:
            self.kf.Q = np.diag(self.Qc * T) + (0.0 if E is None else E)
            return None
        if E is not None:
            self.kf.Q_lent = E      # used with Q, never estimated into it
        return E

    def _return_process_noise(self, lent):
        """Take back the process noise :meth:`_set_process_noise` lent (None: nothing)."""
        if lent is not None:
            self.kf.Q_lent = None

    def widen_process_noise(self, rows, factor, floor):
        """Multiply the process noise of state ``rows`` (a slice) by ``factor`` (< 1 narrows).

        The continuous densities ``Qc`` and the model's own ``_Qc0`` (so that relaxing an
        inflation returns to the widened model, not below it), at least ``floor`` each; an
        adaptive filter's own Q estimate (ASCKF's Sage-Husa) has those rows and columns scaled
        as :meth:`~.consistency_remedies.ConsistencyRemedies.inflate` scales all of it.
        """
        k = np.arange(len(self.Qc))[rows]
        for name in ('Qc', '_Qc0'):
            q = np.array(getattr(self, name), dtype=float)
            q[k] = np.maximum(q[k] * factor, floor)
            setattr(self, name, q)
        if self.own_Q:
            s = np.ones(len(self.Qc))
            s[k] = math.sqrt(factor)
            self.kf.Q = self.kf.Q * np.outer(s, s)

    def raise_drift_noise(self, q):
        """Raise the gyro-drift states' process noise (rad^2/s^3) to at least ``q``, for good.

        The continuous density ``Qc`` and the model's own ``_Qc0`` (which relaxing an inflation
        returns to), and a drift the model held constant is held no longer.
        """
        if self.i_eps is None or not q > 0.0:
            return
        k = np.arange(len(self.Qc))[self.i_eps]
        self._raise_Qc(k, q)
        held = np.array(self._held)
        held[k] = False
        self._held = held

    def _raise_Qc(self, k, q):
        """Raise ``Qc`` and the model's own ``_Qc0`` at states ``k`` (indices) to ``q``."""
        for name in ('Qc', '_Qc0'):
            v = np.array(getattr(self, name), dtype=float)
            v[k] = np.maximum(v[k], q)
            setattr(self, name, v)

    def _append_states(self, var, qc):
        """Grow the state by ``len(var)`` zero-mean states; return their slice.

        ``var`` (k,) their prior variances (uncorrelated), ``qc`` (k,) their process-noise
        densities (0: held constant). The filter appends them (``kf.append_states``: a
        covariance filter pads ``x``, ``P`` and ``Q``, the ASCKF its square-root factor), and
        ``Qc``, ``_Qc0`` and ``_held`` follow; the last interval's model (``_F``, ``_Phi``),
        made for fewer states, is dropped.
        """
        var, qc = np.asarray(var, dtype=float), np.asarray(qc, dtype=float)
        n0 = self.n
        self.kf.append_states(var)
        self.Qc, self._Qc0 = np.r_[self.Qc, qc], np.r_[self._Qc0, qc]
        self._held = np.r_[self._held, qc <= 0.0]
        self.n = n0 + len(var)
        self._F = self._Phi = None
        return slice(n0, self.n)
