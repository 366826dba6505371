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
from .cubature import chol_lower, srckf_predict, srckf_update, tria


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
    b : float
        Sage-Husa forgetting factor.
    gate, adapt_q : bool
        Passed to :class:`~sins_align_ros.filters.adaptive.SageHusa`.
    """

    def __init__(self, x0, P0, Q, R, fading=True, adaptive=True, alpha=None, rho=0.95,
                 beta=3.0, b=0.97, gate=True, adapt_q=True):
        n = len(x0)
        self.x = np.array(x0, dtype=float)
        self.S = chol_lower(np.asarray(P0, dtype=float))
        self.Q = np.array(Q, dtype=float)
        self.R = np.array(R, dtype=float)
        self.fading = fading
        self.adaptive = adaptive
        self.tracking = StrongTracking(np.ones(n) if alpha is None else alpha, rho, beta)
        self.noise = SageHusa(self.Q, self.R, b=b, gate=gate, adapt_q=adapt_q)
        self.lam = np.ones(n)
        self.last = None

    @property
    def P(self):
        """Current covariance ``S S^T`` (n, n)."""
        return self.S @ self.S.T

    def step(self, fx, z, hx):
        """One prediction with ``fx`` and one update with measurement ``z`` of ``hx``.

        Returns the :class:`~sins_align_ros.filters.cubature.CubatureUpdate` of the update.
        """
        SQ, SR = chol_lower(self.Q), chol_lower(self.R)
        xp, S_l, chi_star = srckf_predict(self.x, self.S, fx, SQ)               # eq. 23-27
        if self.fading:
            _, _, probe = srckf_update(xp, S_l, z, hx, SR)                       # (l) quantities
            self.lam = self.tracking.factors(probe.y, S_l @ S_l.T, probe.Pxz, self.Q, self.R)
            lam_sqrt = StrongTracking.sqrt_factors(self.lam)                     # eq. 17
            S_p = tria(np.hstack([lam_sqrt[:, None] * chi_star, SQ]))             # eq. 35
        else:
            S_p = S_l
        self.x, self.S, upd = srckf_update(xp, S_p, z, hx, SR)                   # eq. 28-38
        if self.adaptive:
            self.Q, self.R = self.noise.update(upd)                              # eq. 39, 20
        self.last = upd
        return upd
