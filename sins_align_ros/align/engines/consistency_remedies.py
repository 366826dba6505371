"""What the consistency monitor and the pipeline ask of a GNSS-aided engine.

A mixin of :class:`~.aided.GnssAidedEngine` (:class:`ConsistencyRemedies`): inflate the
process noise and the covariance, relax them back, inflate a measurement row's noise,
widen the attitude and velocity (:mod:`.consistency` decides when).
"""
import math

import numpy as np

from .force import ANGLE_UNKNOWN_VAR
from .prior_shaping import cap_angles

#: seconds over which an inflation's process-noise floor would add the state's variance
INFLATION_SPAN = 100.0
#: largest inflation of a measurement noise variance by the consistency monitor
MAX_NOISE_SCALE = 100.0


class ConsistencyRemedies:
    """What the consistency monitor (:mod:`.consistency`) and the pipeline ask of an engine.

    A mixin of :class:`~.aided.GnssAidedEngine`, whose ``kf``, ``Qc``, ``R_scale``, ``adaptive``,
    ``i_phi``, ``i_v`` and process-noise bookkeeping (``_Qc0``, ``_held``) it uses.
    """

    def inflate(self, factor):
        """Inflate the process noise by ``factor`` (up to 1e4x) and the covariance by its root.

        The consistency monitor's remedy for innovations larger than the filter predicts
        (:mod:`.consistency`): the state is less certain than the filter thought, and its
        model drives it too little. The covariance takes only the square root of the
        factor: the NIS ratio measures the innovation covariance, which a too-small Q
        keeps too small at every epoch, so most of the remedy belongs in Q; a full jump
        of P by up to 10x at each failed window threw the attitude of a GNSS-aided
        filter out of its small-angle model (seed 003's car with default parameters).
        States the model holds constant (zero Qc) get the process noise that would add
        ``factor - 1`` times their variance over :data:`INFLATION_SPAN` seconds, since
        a zero cannot be scaled.

        A square-root filter (``kf.S``, ``P = S S^T``: the ASCKF) has its factor scaled, by
        ``factor^(1/4)`` and the angle rows by :func:`~.prior_shaping.cap_angles`'s
        factors, which is the same ``P`` without factorising it again: a near-singular
        ``P`` (rounded indefinite) made the Cholesky of setting ``kf.P`` raise (a robot
        with RTK in the integrity matrix), where scaling ``S`` keeps it a factor of a
        semi-definite ``P``.
        """
        if getattr(self.kf, 'S', None) is not None:      # square root: no Cholesky of P
            S = self.kf.S * factor ** 0.25
            d = np.einsum('ij,ij->i', S, S)              # diag(S S^T)
            c = np.ones(len(d))
            rows = np.arange(len(d))[self.i_phi]
            c[rows] = np.sqrt(np.minimum(1.0, ANGLE_UNKNOWN_VAR / d[rows]))
            self.kf.S = c[:, None] * S
        else:
            P = self.kf.P * math.sqrt(factor)
            self.kf.P = cap_angles(P, np.arange(len(P))[self.i_phi])
        # states the model holds constant (zero process noise) get some: the model
        # error may be theirs (a bias that varies, a constant one larger than its prior)
        floor = (factor - 1.0) * np.diag(self.kf.P) / INFLATION_SPAN
        self._set_Qc(np.where(self._held, np.maximum(self.Qc, floor),
                              np.minimum(self.Qc * factor, self._Qc0 * 1e4)))

    def relax(self):
        """Halve the process noise raised by :meth:`inflate` back towards the model's."""
        self._set_Qc(np.where(self._held, 0.5 * self.Qc, np.maximum(0.5 * self.Qc, self._Qc0)))

    def _set_Qc(self, Qc):
        """Set the process noise densities ``Qc`` (n,); an adaptive filter's Q follows them.

        A filter that estimates Q (``own_Q``) keeps its own (it starts from ``diag(Qc) *
        1 s``): it gets the change ``diag(Qc_new - Qc_old) * 1 s`` on top of its estimate,
        so an inflation is taken back by :meth:`relax` as with the other filters. (Before,
        an ASCKF's Q was multiplied by the factor and the estimator's copy overwrote it at
        the next epoch: the inflation never reached it, ``filters/asckf.py``.)
        """
        Qc = np.asarray(Qc, dtype=float)
        if self.own_Q:
            Q = self.kf.Q.copy()
            Q[np.diag_indices(len(Q))] += Qc - self.Qc
            self.kf.Q = Q
        self.Qc = Qc

    def inflate_noise(self, factors):
        """Inflate measurement rows' noise variances: ``factors`` row -> factor.

        The consistency monitor's remedy when the innovations are larger than predicted
        but white (the receiver is noisier than configured). Capped at
        :data:`MAX_NOISE_SCALE`; no effect on filters that estimate R themselves.
        """
        for r, f in factors.items():
            self.R_scale[r] = min(self.R_scale[r] * f, MAX_NOISE_SCALE)

    def widen(self, var_phi, var_v):
        """Add ``var_phi`` (rad^2) to each misalignment and ``var_v`` to each velocity variance."""
        P = self.kf.P
        k = np.arange(len(P))
        P[k[self.i_phi], k[self.i_phi]] += var_phi
        P[k[self.i_v], k[self.i_v]] += var_v
        self.kf.P = P
