"""Unscented Kalman filter with scaled (van der Merwe) sigma points (seed 003 eq. 4-15).

Generic, like :mod:`sins_align_ros.filters.cubature`: ``fx(x)`` and ``hx(x)`` act on
one state, or on all points at once if marked :func:`~.cubature.batched`. Shapes as
there. Seed 003 uses the UKF for its 18-state model: :class:`UKF`, the scaled unscented
filter on a nonlinear ``fx`` with the common interface, on the pure functions
:func:`ukf_predict` and :func:`ukf_update`.
"""
import numpy as np

from .base import CovarianceFilter, PriorInnovation, measurement_rows
from .cubature import _propagate, chol_lower


def merwe_weights(n, alpha=1e-3, beta=2.0, kappa=0.0):
    """Scaled sigma-point weights: ``(lambda_, Wm (2n+1,), Wc (2n+1,))``."""
    lam = alpha ** 2 * (n + kappa) - n
    Wm = np.full(2 * n + 1, 0.5 / (n + lam))
    Wc = Wm.copy()
    Wm[0] = lam / (n + lam)
    Wc[0] = lam / (n + lam) + (1.0 - alpha ** 2 + beta)
    return lam, Wm, Wc


def sigma_points(x, P, lam):
    """Sigma points (n, 2n+1): ``x``, ``x +- columns of chol((n+lambda) P)``."""
    n = len(x)
    S = chol_lower((n + lam) * P)
    return np.hstack([x[:, None], x[:, None] + S, x[:, None] - S])


def ukf_predict(x, P, fx, Q, alpha=1e-3, beta=2.0, kappa=0.0):
    """UKF time update; returns ``(x_pred, P_pred, X_prop)``."""
    lam, Wm, Wc = merwe_weights(len(x), alpha, beta, kappa)
    X = sigma_points(x, P, lam)
    Xp = _propagate(fx, X)
    xp = Xp @ Wm
    D = Xp - xp[:, None]
    Pp = (D * Wc) @ D.T + Q
    return xp, 0.5 * (Pp + Pp.T), Xp


def ukf_update(x, P, z, hx, R, points=None, alpha=1e-3, beta=2.0, kappa=0.0, consider=None):
    """UKF measurement update.

    The sigma points are drawn again from the predicted ``(x, P)`` (so they carry
    the process noise), unless ``points`` (n, 2n+1) are given, e.g. the propagated
    ones of :func:`ukf_predict`. ``consider`` (n,) bool: states left uncorrected
    (zero gain rows; the covariance then takes the general-gain form
    ``P - K Pxz^T - Pxz K^T + K S K^T``). Returns ``(x, P, y, S)`` with the innovation
    and its covariance.
    """
    lam, Wm, Wc = merwe_weights(len(x), alpha, beta, kappa)
    if points is None:
        points = sigma_points(x, P, lam)
    Z = _propagate(hx, points)
    zp = Z @ Wm
    Dz = Z - zp[:, None]
    Dx = points - x[:, None]
    S = (Dz * Wc) @ Dz.T + R
    Pxz = (Dx * Wc) @ Dz.T
    K = np.linalg.solve(S.T, Pxz.T).T
    y = z - zp
    if consider is None:
        x = x + K @ y
        P = P - K @ S @ K.T
    else:
        K[consider] = 0.0
        x = x + K @ y
        P = P - K @ Pxz.T - Pxz @ K.T + K @ S @ K.T
    return x, 0.5 * (P + P.T), y, S


class UKF(CovarianceFilter):
    """Scaled unscented Kalman filter (seed 003 eq. 4-15) with the common interface.

    Interface: :class:`~sins_align_ros.filters.base.GaussianFilter`; the bookkeeping
    (``x``, ``P``, ``Q``, ``R``, ``transform``) is
    :class:`~sins_align_ros.filters.base.CovarianceFilter`'s.

    ``alpha``, ``beta``, ``kappa``: sigma-point scaling (defaults 1, 2, 0: the points at
    ``sqrt(n)`` sigma, the spread a large heading error needs; ``alpha`` 1e-3 gives the
    textbook near-linear points).
    """

    def __init__(self, x0, P0, Q, R, alpha=1.0, beta=2.0, kappa=0.0):
        super().__init__(x0, P0, Q, R)
        self.sp = dict(alpha=alpha, beta=beta, kappa=kappa)

    def predict(self, fx):
        """Unscented time update (eq. 5-10)."""
        self.x, self.P, _ = ukf_predict(self.x, self.P, fx, self.Q, **self.sp)
        return self.x, self.P

    def step(self, fx, z, hx, idx=None, max_nis=None):
        """Unscented time and measurement update (eq. 6-15).

        Gate (``max_nis``) and return as :meth:`~sins_align_ros.filters.linear_kf.KF.step`.
        """
        idx = measurement_rows(idx, len(self.R))
        self.predict(fx)
        xp, Pp = self.x, self.P
        x, P, y, S = ukf_update(xp, Pp, z, hx, self.R[np.ix_(idx, idx)], **self.sp,
                                consider=self.consider)
        self.last = PriorInnovation(y, S)
        self.rejected = max_nis is not None and self.last.nis() > max_nis
        if not self.rejected:
            self.x, self.P = x, P
        return self.last
