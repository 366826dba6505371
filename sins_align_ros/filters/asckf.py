"""The improved strong-tracking adaptive square-root CKF of seed 000 (sec. 2-3, steps 1-18).

Each improvement can be switched off, so that CKF -> SRCKF -> SRCKF + fading -> ASCKF
can be compared one step at a time:

* square-root CKF with QR ``Tria`` (eq. 23-38);
* multiple fading factors from the un-faded cubature covariances (eq. 7-17), applied
  as their square roots inside the square-root prediction (eq. 35);
* the improved Sage-Husa Q/R estimator (eq. 39) with the divergence test (eq. 20-21).

Generic: ``fx(x)`` and ``hx(x)`` act on one state vector.
"""
import numpy as np

from .adaptive import SageHusa, StrongTracking
from .cubature import (chol_lower, ckf_predict, ckf_update, sqrt_psd, srckf_predict,
                       srckf_update, tria)


class ASCKF:
    """Seed 000's filter; see the module docstring.

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
    gate, adapt_q, r_ceiling, r_when_identifiable
        Passed to :class:`~sins_align_ros.filters.adaptive.SageHusa`.
    """

    def __init__(self, x0, P0, Q, R, fading=True, adaptive=True, alpha=None, rho=0.95,
                 beta=3.0, b=0.97, gate=True, adapt_q=True, lambda_max=np.inf,
                 r_ceiling=np.inf, r_when_identifiable=False, fading_gate=None):
        n = len(x0)
        self.x = np.array(x0, dtype=float)
        self.S = chol_lower(np.asarray(P0, dtype=float))
        self.Q = np.array(Q, dtype=float)
        self.R = np.array(R, dtype=float)
        self.fading = fading
        self.adaptive = adaptive
        self._alpha = np.ones(n) if alpha is None else np.asarray(alpha, dtype=float)
        self._rho, self._beta, self._lambda_max = rho, beta, lambda_max
        self.fading_gate = fading_gate
        #: one strong-tracking state per measurement subset (its V_k has that dimension)
        self._tracking = {}
        self.noise = SageHusa(self.Q, self.R, b=b, gate=gate, adapt_q=adapt_q,
                              r_ceiling=r_ceiling, r_when_identifiable=r_when_identifiable)
        self.lam = np.ones(n)
        self.last = None

    @property
    def P(self):
        """Current covariance ``S S^T`` (n, n)."""
        return self.S @ self.S.T

    @P.setter
    def P(self, value):
        self.S = chol_lower(np.asarray(value, dtype=float))

    def transform(self, T):
        """Change state coordinates: ``x <- T x``, ``P <- T P T^T`` (square-root form)."""
        self.x = T @ self.x
        self.S = tria(T @ self.S)

    @property
    def divergence_flags(self):
        """How often the divergence test of eq. 20 fired."""
        return self.noise.divergence_flags

    def predict(self, fx):
        """Time update only (no measurement this epoch): eq. 23-27 without fading."""
        self.x, self.S, _ = srckf_predict(self.x, self.S, fx, sqrt_psd(self.Q))

    def step(self, fx, z, hx, idx=None):
        """One prediction with ``fx`` and one update with measurement ``z`` of ``hx``.

        ``idx`` (m,): which rows of the full measurement vector (and of R) ``z``
        holds, for epochs where part of the measurement is missing; default all.
        Returns the :class:`~sins_align_ros.filters.cubature.CubatureUpdate` of the update.
        """
        idx = np.arange(len(self.R)) if idx is None else np.asarray(idx)
        SQ, SR = sqrt_psd(self.Q), sqrt_psd(self.R[np.ix_(idx, idx)])
        xp, S_l, chi_star = srckf_predict(self.x, self.S, fx, SQ)               # eq. 23-27
        if self.fading:
            _, _, probe = srckf_update(xp, S_l, z, hx, SR)                       # (l) quantities
            key = tuple(idx.tolist())
            tracking = self._tracking.get(key)
            if tracking is None:
                tracking = self._tracking[key] = StrongTracking(
                    self._alpha, self._rho, self._beta, self._lambda_max)
            self.lam = tracking.factors(probe.y, S_l @ S_l.T, probe.Pxz, self.Q,
                                        self.R[np.ix_(idx, idx)])
            if self.fading_gate is not None:
                nis = float(probe.y @ np.linalg.solve(probe.Pzz, probe.y))
                if nis <= self.fading_gate[len(idx)]:
                    self.lam = np.ones_like(self.lam)
            lam_sqrt = StrongTracking.sqrt_factors(self.lam)                     # eq. 17
            S_p = tria(np.hstack([lam_sqrt[:, None] * chi_star, SQ]))             # eq. 35
        else:
            S_p = S_l
        self.x, self.S, upd = srckf_update(xp, S_p, z, hx, SR)                   # eq. 28-38
        if self.adaptive:
            self.Q, self.R = self.noise.update(upd, idx)                         # eq. 39, 20
        self.last = upd
        return upd


class CKF:
    """The conventional cubature Kalman filter (seed 000 eq. 22-34) with ASCKF's interface.

    Covariance form, points re-drawn for the update (eq. 28); fixed Q and R.
    """

    def __init__(self, x0, P0, Q, R):
        self.x = np.array(x0, dtype=float)
        self.P = np.array(P0, dtype=float)
        self.Q = np.array(Q, dtype=float)
        self.R = np.array(R, dtype=float)
        self.lam = None
        self.divergence_flags = 0
        self.last = None

    def transform(self, T):
        """Change state coordinates: ``x <- T x``, ``P <- T P T^T``."""
        self.x = T @ self.x
        self.P = T @ self.P @ T.T

    def predict(self, fx):
        """Time update only (eq. 23-26)."""
        self.x, self.P, _ = ckf_predict(self.x, self.P, fx, self.Q)

    def step(self, fx, z, hx, idx=None):
        """Time update and measurement update; ``idx`` as in :meth:`ASCKF.step`."""
        idx = np.arange(len(self.R)) if idx is None else np.asarray(idx)
        xp, Pp, _ = ckf_predict(self.x, self.P, fx, self.Q)
        self.x, self.P, upd = ckf_update(xp, Pp, z, hx, self.R[np.ix_(idx, idx)])
        self.last = upd
        return upd
