"""Linear Kalman filter steps, filterpy-style pure functions.

Shapes: ``x`` (n,), ``P`` (n, n), ``F`` (n, n), ``Q`` (n, n), ``z`` (m,),
``H`` (m, n), ``R`` (m, m). Returned arrays are new objects.
"""
import numpy as np

#: winsorisation bound of an innovation squared, in predicted variances (99.9% of chi2(1))
CLIP = 10.83


def predict(x, P, F, Q):
    """Time update: ``x = F x``, ``P = F P F^T + Q``."""
    x = F @ x
    P = F @ P @ F.T + Q
    return x, 0.5 * (P + P.T)


def update(x, P, z, H, R):
    """Measurement update in Joseph form.

    Returns
    -------
    x, P : updated state and covariance
    y : ndarray (m,)
        Innovation ``z - H x``.
    S : ndarray (m, m)
        Innovation covariance ``H P H^T + R``.
    """
    y = z - H @ x
    PHt = P @ H.T
    S = H @ PHt + R
    K = np.linalg.solve(S, PHt.T).T
    x = x + K @ y
    I_KH = np.eye(len(x)) - K @ H
    P = I_KH @ P @ I_KH.T + K @ R @ K.T
    return x, 0.5 * (P + P.T), y, S


def discretize(F, G, Qc, dt):
    """Van Loan discretisation of ``x' = F x + G w``, ``E[w w^T] = Qc delta(t)``.

    Returns ``(Phi, Qd)`` with ``Phi = expm(F dt)`` and
    ``Qd = int_0^dt Phi(s) G Qc G^T Phi(s)^T ds``.
    """
    from scipy.linalg import expm       # here: only the stationary filters discretize
    n = F.shape[0]
    M = np.zeros((2 * n, 2 * n))
    M[:n, :n] = -F
    M[:n, n:] = G @ Qc @ G.T
    M[n:, n:] = F.T
    E = expm(M * dt)
    Phi = E[n:, n:].T
    Qd = Phi @ E[:n, n:]
    return Phi, 0.5 * (Qd + Qd.T)


def nis(y, S):
    """Normalised innovation squared ``y^T S^-1 y`` (chi-square with m dof when consistent)."""
    return float(y @ np.linalg.solve(S, y))
