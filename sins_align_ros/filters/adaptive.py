"""Adaptive layers of seed 000: strong tracking fading factors and the Sage-Husa estimator.

* :class:`StrongTracking` — multiple fading factors computed from the cubature
  covariances instead of Jacobians (seed 000 eq. 7-17).
* :class:`SageHusa` — the improved time-varying noise estimator (eq. 39) with the
  divergence test (eq. 20-21).
"""
import numpy as np


class StrongTracking:
    """Multiple fading factors (seed 000 eq. 7-17).

    Parameters
    ----------
    alpha : array_like (n,)
        Per-state proportions ``alpha_i`` (eq. 8), from prior knowledge.
    rho : float
        Forgetting factor of the innovation covariance ``V_k`` (eq. 10), 0 < rho <= 1.
    beta : float
        Weakening factor (eq. 9), usually 3.
    """

    def __init__(self, alpha, rho=0.95, beta=3.0):
        self.alpha = np.asarray(alpha, dtype=float)
        self.rho = float(rho)
        self.beta = float(beta)
        self.V = None
        self.lambda0 = 1.0

    def factors(self, y, P_pred, Pxz, Q, R):
        """Fading factors ``lambda_i`` (n,) from the un-faded prediction (superscript (l)).

        ``y`` innovation (m,); ``P_pred`` one-step covariance without fading;
        ``Pxz`` its cross covariance with the measurement; ``Q``, ``R`` noise.
        """
        yy = np.outer(y, y)
        self.V = yy if self.V is None else (self.rho * self.V + yy) / (1.0 + self.rho)  # eq. 10
        H = np.linalg.solve(P_pred.T, Pxz).T                                # eq. 13
        N = self.V - self.beta * R - H @ Q @ H.T                             # eq. 14
        M = (P_pred - Q) @ H.T @ H                                           # eq. 16
        trM = np.trace(M)
        self.lambda0 = np.trace(N) / trM if trM > 0 else 1.0                 # eq. 8
        lam = self.alpha * self.lambda0
        return np.where(self.lambda0 > 1.0, np.maximum(lam, 1.0), 1.0)

    @staticmethod
    def sqrt_factors(lam):
        """Square roots of the factors, the form applied in eq. 35 (eq. 17)."""
        return np.sqrt(lam)


class SageHusa:
    """Improved Sage-Husa Q/R estimator (seed 000 eq. 39) with the divergence test (eq. 20).

    Parameters
    ----------
    Q0, R0 : ndarray
        Initial noise covariances.
    b : float
        Forgetting factor, 0 < b < 1 (0.95-0.99), giving ``d_k = (1-b)/(1-b^k)``.
    gate : bool
        Apply the divergence test of eq. 20 (the seed's algorithm). As written it
        updates R only from innovations larger than predicted, which biases R
        upwards; ``gate=False`` is the plain estimator of eq. 39.
    adapt_q : bool
        Estimate Q as well (eq. 39). Q and R are not separately identifiable from
        the innovations of a weakly observable state; adapting both lets Q absorb
        measurement noise.
    """

    def __init__(self, Q0, R0, b=0.97, gate=True, adapt_q=True):
        self.gate = bool(gate)
        self.adapt_q = bool(adapt_q)
        self.Q = np.array(Q0, dtype=float)
        self.R = np.array(R0, dtype=float)
        #: eigenvalue floor that keeps R positive definite (1e-3 of the initial mean variance)
        self.r_floor = 1e-3 * float(np.trace(self.R)) / len(self.R)
        self.b = float(b)
        self.k = 0
        self.divergence_flags = 0

    def update(self, upd):
        """Update Q and R from a :class:`~sins_align_ros.filters.cubature.CubatureUpdate`.

        Eq. 20: if ``y^T y <= tr(E[y y^T])`` (the innovation is consistent with its
        predicted covariance) only Q is updated (eq. 21); otherwise both (eq. 39),
        following step 17 of the seed's algorithm. Returns ``(Q, R)``.
        """
        self.k += 1
        d = (1.0 - self.b) / (1.0 - self.b ** self.k)
        y, K, eta = upd.y, upd.K, upd.eta
        if self.adapt_q:
            Ky = K @ y
            self.Q = (1.0 - d) * self.Q + d * np.outer(Ky, Ky)
        if float(y @ y) <= np.trace(upd.Pzz):
            if self.gate:
                return self.Q, self.R                                        # eq. 21
        else:
            self.divergence_flags += 1
        R_new = (1.0 - d) * self.R + d * (np.outer(y, y) - eta @ eta.T)     # eq. 39
        # keep R positive definite: the subtraction may remove too much
        w, U = np.linalg.eigh(0.5 * (R_new + R_new.T))
        self.R = (U * np.maximum(w, self.r_floor)) @ U.T
        return self.Q, self.R
