"""The improved strong-tracking adaptive square-root CKF of seed 000 (sec. 2-3, steps 1-18).

Each improvement can be switched off, so that CKF -> SRCKF -> SRCKF + fading -> ASCKF
can be compared one step at a time (the conventional CKF is
:class:`~sins_align_ros.filters.ckf.CKF`):

* square-root CKF with QR ``Tria`` (eq. 23-38);
* multiple fading factors from the un-faded cubature covariances (eq. 7-17), applied
  as their square roots inside the square-root prediction (eq. 35);
* the improved Sage-Husa Q/R estimator (eq. 39) with the divergence test (eq. 20-21).

Generic: ``fx(x)`` and ``hx(x)`` act on one state vector.
"""
from collections import deque

import numpy as np

from .adaptive import SageHusa, StrongTracking
from .base import measurement_rows
from .cubature import chol_lower, sqrt_psd, srckf_predict, srckf_update, tria
from .chi2 import chi2_quantile


def lag1_correlation(w):
    """Lag-1 correlation coefficient of a sequence of innovation vectors ``w`` (L+1, m).

    ``sum_k w_k . w_{k-1} / sum_k |w_k|^2`` over the sequence: about 0 (spread
    ``1/sqrt(L m)``) for white innovations whatever their size, near 1 for
    innovations that keep their sign.
    """
    W = np.asarray(w)
    den = float(np.sum(W * W))
    return float(np.sum(W[1:] * W[:-1])) / den if den > 0 else 0.0


class ASCKF:
    """Seed 000's filter; see the module docstring.

    Interface: :class:`~sins_align_ros.filters.base.GaussianFilter` (square-root form:
    ``P`` is a property over the Cholesky factor ``S``).

    Parameters
    ----------
    x0 : ndarray (n,)
    P0, Q, R : ndarray
        Initial covariance and (initial) noise covariances.
    fading : bool
        Use the multiple fading factors (eq. 7-17, 35).
    adaptive : bool
        Use the Sage-Husa estimator (eq. 39, 20).
    alpha : array_like (n,) or None
        Per-state fading proportions (eq. 8); default all ones.
    rho, beta : float
        Strong-tracking forgetting and weakening factors (eq. 9-10).
    lambda_max : float
        Upper bound of the fading factors.
    b : float
        Sage-Husa forgetting factor.
    fading_gate : dict or None
        If given, ``{m: threshold}``: the fading factors apply only at epochs whose
        un-faded innovation NIS exceeds the threshold for ``m`` measurements (not in
        the seed; V_k of eq. 10 is mostly the last two innovations, so without a
        gate chance fluctuations fade the covariance again and again).
    whiteness : tuple (L, r_min) or None
        If given, the fading factors apply only while the normalised innovations
        ``w`` of the last ``L`` epochs are both too large (``sum |w|^2`` above the
        99% point of chi-square with ``L m`` degrees of freedom) and correlated
        from one epoch to the next (lag-1 correlation coefficient above ``r_min``):
        seed 000's own condition 2 (sec. 2.1, residuals orthogonal in time) used as
        the test. A state error the model does not follow shows as innovations of
        a persistent sign; a jump of the measurement noise leaves them white, and
        is left to the Sage-Husa R. Conversely R is learnt only from white
        innovations (a correlated part is not measurement noise).
    var_max : array_like (n,) or None
        Largest variance the fading may give each state (not in the seed; the
        initial variances are a natural choice): a weakly observable state faded
        epoch after epoch otherwise grows without bound.
    gate, adapt_q, r_ceiling, r_when_identifiable
        Passed to :class:`~sins_align_ros.filters.adaptive.SageHusa`.
    """

    def __init__(self, x0, P0, Q, R, fading=True, adaptive=True, alpha=None, rho=0.95,
                 beta=3.0, b=0.97, gate=True, adapt_q=True, lambda_max=np.inf,
                 r_ceiling=np.inf, r_when_identifiable=False, fading_gate=None,
                 whiteness=None, var_max=None):
        n = len(x0)
        self.x = np.array(x0, dtype=float)
        self.S = chol_lower(np.asarray(P0, dtype=float))
        #: the Q/R estimator; it holds Q (:attr:`Q`)
        self.noise = SageHusa(np.array(Q, dtype=float), R, b=b, gate=gate, adapt_q=adapt_q,
                              r_ceiling=r_ceiling, r_when_identifiable=r_when_identifiable)
        self.R = np.array(R, dtype=float)
        self.fading = fading
        self.adaptive = adaptive
        self._alpha = np.ones(n) if alpha is None else np.asarray(alpha, dtype=float)
        self._rho, self._beta, self._lambda_max = rho, beta, lambda_max
        self.fading_gate = fading_gate
        self.whiteness = whiteness
        self.var_max = None if var_max is None else np.asarray(var_max, dtype=float)
        #: normalised innovations of the recent epochs, per measurement subset
        self._w_hist = {}
        #: epochs at which the fading factors were applied (some factor > 1)
        self.n_faded = 0
        self.faded = False
        #: False while the whiteness test finds the innovations correlated in time
        self.white = True
        #: one strong-tracking state per measurement subset (its V_k has that dimension)
        self._tracking = {}
        self.lam = np.ones(n)
        #: (len(R),) or None: known variances the caller lends to the measurement noise
        #: for its next updates (a lever arm's share of the attitude uncertainty,
        #: ``align/engines/aided.py``); used with R, never estimated into it (:meth:`_R_used`)
        self.R_lent = None
        #: (n, n) or None: known process noise the caller lends for its next prediction
        #: (the gyro scale-factor/misalignment noise of a turn, the accelerometer's
        #: force-proportional noise, a dropped force: ``align/engines/aided.py``); used with Q,
        #: never estimated into it (:meth:`_Q_used`)
        self.Q_lent = None
        self.last = None
        self.rejected = False

    @property
    def Q(self):
        """Process noise estimate (n, n): the estimator's (:class:`SageHusa`)."""
        return self.noise.Q

    @Q.setter
    def Q(self, value):
        """Set the process noise (n, n); the estimator continues from it.

        One copy: before, the filter's ``Q`` and the estimator's were two arrays, and
        the estimator's (the initial Q, ``adapt_q`` off) overwrote the filter's at every
        update, so what a caller put into ``Q`` (the engine's turn-rate noise lent per
        interval, the consistency monitor's inflation) was lost at the next update, and
        the engine's taking back of its loan then drove Q's velocity rows negative
        (car with RTK, MEMS IMU: -3.3e-6 m^2/s^2 after 2100 epochs).
        """
        self.noise.Q = np.array(value, dtype=float)

    def _Q_used(self):
        """Process noise (n, n) of the next prediction: the estimate plus what is lent."""
        return self.Q if self.Q_lent is None else self.Q + self.Q_lent

    @property
    def P(self):
        """Current covariance ``S S^T`` (n, n)."""
        return self.S @ self.S.T

    @P.setter
    def P(self, value):
        """Set ``S`` to a lower-triangular root of ``value`` (n, n).

        Cholesky where ``value`` is definite; a semi-definite one (a state held at zero
        variance, the product ``S S^T`` of a rank-deficient root read back, changed and
        set again: the Gauss-Markov position noise of ``align/engines/epoch_noise.py`` on a raw
        MEMS car, ground integrity matrix, seed run aborted with LinAlgError) takes the
        clipped eigen-root, made triangular by ``tria``.
        """
        value = np.asarray(value, dtype=float)
        try:
            self.S = chol_lower(value)
        except np.linalg.LinAlgError:
            self.S = tria(sqrt_psd(value))

    def append_states(self, var):
        """Append uncorrelated zero-mean random constants of variances ``var`` (k,).

        The factor grows by a diagonal block, ``S <- [[S, 0], [0, diag(sqrt(var))]]``, still
        lower triangular, so ``S S^T`` is ``P`` with the new block and no Cholesky is taken
        again; the new states get no process noise and no fading (proportion 0, as the
        drift's in ``align/engines/moving.py``; their fading cap is ``var``).
        """
        var = np.asarray(var, dtype=float)
        n, k = len(self.x), len(var)
        S = np.zeros((n + k, n + k))
        S[:n, :n] = self.S
        S[n:, n:] = np.diag(np.sqrt(var))
        Q = np.zeros((n + k, n + k))
        Q[:n, :n] = self.Q
        self.x, self.S, self.Q = np.r_[self.x, np.zeros(k)], S, Q
        self._alpha = np.r_[self._alpha, np.zeros(k)]
        for tracking in self._tracking.values():
            tracking.alpha = self._alpha
        if self.var_max is not None:
            self.var_max = np.r_[self.var_max, var]
        self.lam = np.r_[self.lam, np.ones(k)]

    def transform(self, T):
        """Change state coordinates: ``x <- T x``, ``P <- T P T^T`` (square-root form)."""
        self.x = T @ self.x
        self.S = tria(T @ self.S)

    @property
    def divergence_flags(self):
        """How often the divergence test of eq. 20 fired."""
        return self.noise.divergence_flags

    def _R_used(self, idx):
        """Measurement noise (m, m) of rows ``idx``: the estimate plus what is lent."""
        R = self.R[idx][:, idx]                         # the rows and columns of idx
        if self.R_lent is not None:
            R = R + np.diag(np.asarray(self.R_lent, dtype=float)[idx])
        return R

    def _faded_sqrt(self, S_l, chi_star, SQ, probe, idx):
        """Square root of the faded prediction covariance (eq. 7-17, 35); sets ``self.lam``.

        ``probe``: the update from the un-faded prediction ``S_l`` (the (l) quantities).
        The innovation enters ``V_k`` (eq. 10) at every epoch; the factors themselves
        (eq. 8-16) are computed only where the gate and the whiteness test let them apply
        (else they are all 1).
        """
        key = tuple(idx.tolist())
        tracking = self._tracking.get(key)
        if tracking is None:
            tracking = self._tracking[key] = StrongTracking(
                self._alpha, self._rho, self._beta, self._lambda_max)
        tracking.add_innovation(probe.y)                                          # eq. 10
        apply = True
        if self.fading_gate is not None:
            apply = probe.nis() > self.fading_gate[len(idx)]
        if self.whiteness is not None:
            L, r_min = self.whiteness
            hist = self._w_hist.setdefault(key, deque(maxlen=int(L) + 1))
            hist.append(probe.w)                 # Szz^-1 y: Szz is Pzz's Cholesky factor
            self.white = not (len(hist) > L and lag1_correlation(hist) > r_min)
            if apply and not self.white:
                W = np.asarray(hist)[1:]
                apply = float(np.sum(W * W)) > chi2_quantile(0.99, W.size)
            else:
                apply = False
        if not apply:
            self.lam = np.ones(len(self.x))
            self.faded = False
            return S_l
        P_l = S_l @ S_l.T
        self.lam = tracking.current_factors(P_l, probe.Pxz, self._Q_used(), self._R_used(idx))
        if self.var_max is not None:
            cap = np.maximum(self.var_max / np.clip(np.diag(P_l), 1e-300, None), 1.0)
            self.lam = np.minimum(self.lam, cap)
        self.faded = bool(np.any(self.lam > 1.0))
        self.n_faded += self.faded
        if not self.faded:      # every factor 1: eq. 35 is the un-faded S_l, bit for bit
            return S_l
        lam_sqrt = StrongTracking.sqrt_factors(self.lam)                         # eq. 17
        return tria(np.hstack([lam_sqrt[:, None] * chi_star, SQ]))                # eq. 35

    def predict(self, fx):
        """Time update only (no measurement this epoch): eq. 23-27 without fading."""
        self.x, self.S, _ = srckf_predict(self.x, self.S, fx, sqrt_psd(self._Q_used()))

    def step(self, fx, z, hx, idx=None, max_nis=None):
        """One prediction with ``fx`` and one update with measurement ``z`` of ``hx``.

        ``idx`` (m,): which rows of the full measurement vector (and of R) ``z``
        holds, for epochs where part of the measurement is missing; default all.
        ``max_nis``: innovation gate (not in the seed): if the normalised innovation
        squared ``y^T Pzz^-1 y`` of the un-faded prediction exceeds it, the
        measurement is rejected (``self.rejected``): the state keeps its
        prediction; the noise estimator still sees the innovation (winsorised,
        :class:`~sins_align_ros.filters.adaptive.SageHusa`), so a lasting rise of the
        noise is learnt rather than rejected for ever.
        Returns the :class:`~sins_align_ros.filters.cubature.CubatureUpdate` of the update.
        """
        idx = measurement_rows(idx, len(self.R))
        SQ, SR = sqrt_psd(self._Q_used()), sqrt_psd(self._R_used(idx))
        xp, S_l, chi_star = srckf_predict(self.x, self.S, fx, SQ)               # eq. 23-27
        self.faded, self.white = False, True
        self.rejected = False
        # the update from the un-faded prediction: the gate's and the fading's input
        unfaded = (srckf_update(xp, S_l, z, hx, SR)
                   if max_nis is not None or self.fading else None)
        probe = None if unfaded is None else unfaded[2]
        if max_nis is not None and probe.nis() > max_nis:
            self.x, self.S, self.rejected, self.last = xp, S_l, True, probe
            if self.adaptive:
                self.Q, self.R = self.noise.update(probe, idx, self.R_lent)
            return probe
        if self.fading:
            S_p = self._faded_sqrt(S_l, chi_star, SQ, probe, idx)
        else:
            S_p = S_l
        if S_p is S_l and unfaded is not None:     # not faded: the probe is the update
            self.x, self.S, upd = unfaded
        else:
            self.x, self.S, upd = srckf_update(xp, S_p, z, hx, SR)               # eq. 28-38
        if self.adaptive and self.white:
            self.Q, self.R = self.noise.update(upd, idx, self.R_lent)            # eq. 39, 20
        self.last = upd
        return upd
