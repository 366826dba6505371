"""Unscented Kalman filter with scaled (van der Merwe) sigma points.

Generic, like :mod:`sins_align_ros.filters.cubature`: ``fx(x)`` and ``hx(x)`` act on
one state, or on all points at once if marked :func:`~.cubature.batched`. Shapes as
there. Seed 003 uses the UKF for its 18-state model.
"""
import numpy as np

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


def ukf_update(x, P, z, hx, R, points=None, alpha=1e-3, beta=2.0, kappa=0.0):
    """UKF measurement update.

    The sigma points are drawn again from the predicted ``(x, P)`` (so they carry
    the process noise), unless ``points`` (n, 2n+1) are given, e.g. the propagated
    ones of :func:`ukf_predict`. Returns ``(x, P, y, S)`` with the innovation and
    its covariance.
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
    x = x + K @ y
    P = P - K @ S @ K.T
    return x, 0.5 * (P + P.T), y, S
