"""Cubature Kalman filter and its square-root form (seed 000 sec. 3, eq. 22-38).

Generic: nothing here knows about navigation. ``fx(x) -> x'`` and ``hx(x) -> z``
act on one state (n,); they are applied column by column to the cubature points.

Shapes: ``x`` (n,), ``P`` and ``S`` (n, n) with ``P = S S^T`` (S lower
triangular), ``Q``/``R`` and their square roots ``SQ``/``SR``, ``z`` (m,).
A function marked with :func:`batched` takes all points at once as columns
(n, 2n), which is much faster than one call per point.
"""
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from .. import compiled
from .kf import nis


@lru_cache(maxsize=None)
def cubature_points(n):
    """Return the unit cubature points ``sqrt(n) [I, -I]`` (seed 000 eq. 22), (n, 2n).

    One read-only array per ``n``, built once (every update used to build it again).
    """
    points = np.sqrt(n) * np.hstack([np.eye(n), -np.eye(n)])
    points.flags.writeable = False
    return points


def tria(A):
    """Lower-triangular ``S`` with ``S S^T = A A^T`` by QR of ``A^T`` (seed 000 "Tria").

    ``A`` (n, k): compiled Householder triangularisation (:func:`_tria_householder`)
    for k >= n when the kernels are; LAPACK's QR otherwise. Both give the unique factor
    with a non-negative diagonal, equal to round-off (test_filters).
    """
    A = np.asarray(A, dtype=float)
    if compiled.COMPILED and A.shape[1] >= A.shape[0]:
        S = np.empty((A.shape[0], A.shape[0]))
        _tria_householder(np.ascontiguousarray(A), S)
        return S
    return tria_lapack(A)


@compiled.jit(sig='void(f8[:, :], f8[:, :])')
def _tria_householder(A, S):
    """Write into ``S`` (n, n) the lower factor of ``A`` (n, k >= n): Householder on ``A^T``.

    Reflections zero the columns of ``R = A^T`` (k, n) below the diagonal one at a time;
    ``S = R[:n].T`` with each column's sign made non-negative (``S S^T = A A^T``).
    """
    n, k = A.shape
    R = A.T.copy()
    v = np.empty(k)
    for j in range(n):
        norm2 = 0.0
        for i in range(j, k):
            norm2 += R[i, j] * R[i, j]
        if norm2 == 0.0:
            continue
        alpha = -np.sqrt(norm2) if R[j, j] >= 0.0 else np.sqrt(norm2)
        for i in range(j, k):
            v[i] = R[i, j]
        v[j] -= alpha
        vv = norm2 - R[j, j] * R[j, j] + v[j] * v[j]
        if vv == 0.0:
            continue
        for c in range(j, n):
            dot = 0.0
            for i in range(j, k):
                dot += v[i] * R[i, c]
            f = 2.0 * dot / vv
            for i in range(j, k):
                R[i, c] -= f * v[i]
    for r in range(n):
        sign = -1.0 if R[r, r] < 0.0 else 1.0
        for c in range(n):
            S[c, r] = sign * R[r, c] if c >= r else 0.0


@compiled.warms_up
def _first_calls():
    _tria_householder(np.zeros((2, 4)), np.empty((2, 2)))
    _predict_moments(np.zeros((2, 4)), np.ones(2), np.eye(2), np.empty(2), np.empty((2, 4)),
                     np.empty((2, 2)))
    _update_moments(np.zeros((2, 4)), np.zeros(2), np.zeros((1, 4)), np.zeros(1),
                    np.eye(1), np.empty(2), np.empty((2, 2)), np.empty(1), np.empty(1),
                    np.empty((1, 4)), np.empty((2, 4)), np.empty((1, 1)), np.empty((2, 1)),
                    np.empty((2, 1)), np.empty(1))


def tria_lapack(A):
    """:func:`tria` by LAPACK's QR (any shape of ``A``)."""
    r = np.linalg.qr(A.T, mode='r')
    S = r.T
    # fix the signs so the diagonal is non-negative (unique factor)
    d = np.sign(np.diag(S))
    d[d == 0] = 1.0
    return S * d[None, :]


def chol_lower(P):
    """Lower Cholesky factor of a symmetric positive definite matrix."""
    return np.linalg.cholesky(0.5 * (P + P.T))


def sqrt_psd(A):
    """Return a square root ``L`` with ``L L^T = A`` for a positive *semi*-definite ``A``.

    Cholesky when ``A`` is definite; otherwise the symmetric eigen-root with
    negative round-off eigenvalues clipped to zero. Only ``L L^T`` matters where
    it is used (inside ``Tria``), so it need not be triangular.
    """
    A = np.asarray(A, dtype=float)
    d = A.diagonal()
    if np.count_nonzero(A) == np.count_nonzero(d):
        # diagonal (the usual Q and R): its root directly; Cholesky's where definite, and
        # no failed factorisation and eigen-decomposition where a state has no noise
        return np.diag(np.sqrt(np.maximum(d, 0.0)))
    A = 0.5 * (A + A.T)
    try:
        return np.linalg.cholesky(A)
    except np.linalg.LinAlgError:
        w, U = np.linalg.eigh(A)
        return U * np.sqrt(np.clip(w, 0.0, None))


def batched(fn):
    """Mark ``fn`` as taking a batch of states as columns (n, N) and returning (m, N)."""
    fn.batched = True
    return fn


def _propagate(fn, X):
    if getattr(fn, 'batched', False):
        return fn(X)
    return np.column_stack([fn(X[:, i]) for i in range(X.shape[1])])


@dataclass
class CubatureUpdate:
    """Intermediate quantities of a measurement update, for the adaptive layers.

    ``y`` innovation (m,), ``z_pred`` (m,), ``Pzz`` innovation covariance, ``Pxz``
    cross covariance, ``K`` gain, ``eta`` (m, 2n) weighted measurement deviations
    (eq. 32), ``chi`` (n, 2n) weighted state deviations (eq. 34). The square-root
    update also gives ``Szz`` (m, m), the lower factor of ``Pzz`` (eq. 33), and ``w`` (m,),
    the whitened innovation ``Szz^-1 y`` (``w^T w`` is the NIS, :meth:`nis`).
    """

    y: np.ndarray
    z_pred: np.ndarray
    Pzz: np.ndarray
    Pxz: np.ndarray
    K: np.ndarray
    eta: np.ndarray
    chi: np.ndarray
    Szz: np.ndarray = None
    w: np.ndarray = None

    def nis(self):
        """Return the NIS ``y^T Pzz^-1 y`` (``w^T w`` where there is ``w``)."""
        if self.w is not None:
            return float(self.w @ self.w)
        return nis(self.y, self.Pzz)


def ckf_predict(x, P, fx, Q):
    """CKF time update (eq. 23-25 with the covariance form of eq. 26).

    Returns ``(x_pred, P_pred, X_prop)`` with ``X_prop`` the propagated points (n, 2n).
    """
    n = len(x)
    X = chol_lower(P) @ cubature_points(n) + x[:, None]
    Xp = _propagate(fx, X)
    xp = Xp.mean(axis=1)
    D = Xp - xp[:, None]
    Pp = D @ D.T / (2 * n) + Q
    return xp, 0.5 * (Pp + Pp.T), Xp


def ckf_update(x, P, z, hx, R, points=None):
    """CKF measurement update (eq. 28-37, covariance form).

    ``points`` (n, 2n): cubature points to use instead of re-sampling from ``P``
    (eq. 28); passing the propagated points of :func:`ckf_predict` reproduces
    filters that skip the re-sampling (e.g. filterpy's).
    Returns ``(x, P, CubatureUpdate)``.
    """
    n = len(x)
    X = chol_lower(P) @ cubature_points(n) + x[:, None] if points is None else points
    Z = _propagate(hx, X)
    zp = Z.mean(axis=1)
    w = 1.0 / np.sqrt(2 * n)
    eta = (Z - zp[:, None]) * w
    chi = (X - X.mean(axis=1)[:, None]) * w
    Pzz = eta @ eta.T + R
    Pxz = chi @ eta.T
    K = np.linalg.solve(Pzz.T, Pxz.T).T
    y = z - zp
    x = x + K @ y
    P = P - K @ Pzz @ K.T
    return x, 0.5 * (P + P.T), CubatureUpdate(y, zp, Pzz, Pxz, K, eta, chi)


def srckf_predict(x, S, fx, SQ, fading_sqrt=None):
    """Square-root CKF time update (eq. 23-27), with optional fading (eq. 35).

    ``fading_sqrt`` (n,): the square roots of the multiple fading factors
    (eq. 17); they scale the rows of the weighted deviations before ``Tria``.
    Returns ``(x_pred, S_pred, chi_star)`` with ``chi_star`` (n, 2n) of eq. 27.
    After ``fx``, the moments and ``Tria`` are one compiled call when the kernels are
    (:func:`_predict_moments`); the numpy lines below are its reference.
    """
    n = len(x)
    X = S @ cubature_points(n) + x[:, None]
    Xp = _propagate(fx, X)
    if compiled.COMPILED:
        xp, chi_star, S_pred = np.empty(n), np.empty((n, 2 * n)), np.empty((n, n))
        fade = np.ones(n) if fading_sqrt is None else np.asarray(fading_sqrt, dtype=float)
        Xp, SQ = np.ascontiguousarray(Xp, dtype=float), np.ascontiguousarray(SQ, dtype=float)
        _check_shapes(Xp.shape == (n, 2 * n) and fade.shape == (n,) and SQ.ndim == 2
                      and SQ.shape[0] == n)
        _predict_moments(Xp, fade, SQ, xp, chi_star, S_pred)
        return xp, S_pred, chi_star
    xp = Xp.mean(axis=1)
    chi_star = (Xp - xp[:, None]) / np.sqrt(2 * n)
    lead = chi_star if fading_sqrt is None else fading_sqrt[:, None] * chi_star
    return xp, tria(np.hstack([lead, SQ])), chi_star


def _check_shapes(agree):
    """Raise ``ValueError`` unless the arguments of a compiled SRCKF call agree in shape.

    The kernels do not check bounds; numpy's reference lines raise ``ValueError`` for
    the same mismatches (a transition or measurement of the wrong size), which the
    engines report as a diverged filter.
    """
    if not agree:
        raise ValueError('square-root CKF: arguments of mismatched shapes')


@compiled.jit(sig='void(f8[:, :], f8[:], f8[:, :], f8[:], f8[:, :], f8[:, :])')
def _predict_moments(Xp, fade, SQ, xp, chi_star, S):
    """Compiled tail of :func:`srckf_predict`: ``xp`` (n,), ``chi_star`` (n, 2n), ``S`` (n, n).

    From the propagated points ``Xp`` (n, 2n), the fading roots ``fade`` (n,) and
    ``SQ`` (n, q): mean, weighted deviations (eq. 27) and ``Tria([fade chi*, SQ])``.
    """
    _tria_householder(_moments(Xp, fade, SQ, xp, chi_star), S)


@compiled.jit
def _moments(P, scale, root, mean, dev):
    """Row means of the points ``P`` (k, N) and their weighted deviations; return ``Tria``'s input.

    Writes ``mean`` (k,) and ``dev = (P - mean) / sqrt(N)`` (k, N); returns
    ``[scale dev, root]`` (k, N + r), ``scale`` (k,) scaling the rows, ``root`` (k, r).
    """
    k, N = P.shape
    r = root.shape[1]
    w = 1.0 / np.sqrt(N)
    A = np.empty((k, N + r))
    for i in range(k):
        m = 0.0
        for j in range(N):
            m += P[i, j]
        m /= N
        mean[i] = m
        for j in range(N):
            dev[i, j] = (P[i, j] - m) * w
            A[i, j] = scale[i] * dev[i, j]
        for j in range(r):
            A[i, N + j] = root[i, j]
    return A


def srckf_update(x, S, z, hx, SR):
    """Square-root CKF measurement update (eq. 28-38).

    Returns ``(x, S, CubatureUpdate)``; ``Pzz = Szz Szz^T`` is given in full too.
    After ``hx``, the update is one compiled call when the kernels are
    (:func:`_update_moments`); the numpy lines below are its reference. Raises
    ``LinAlgError`` when the innovation covariance is singular.
    """
    n = len(x)
    X = S @ cubature_points(n) + x[:, None]
    Z = _propagate(hx, X)
    if compiled.COMPILED:
        X, Z = np.ascontiguousarray(X, dtype=float), np.ascontiguousarray(Z, dtype=float)
        x, z = np.asarray(x, dtype=float), np.asarray(z, dtype=float)
        SR = np.ascontiguousarray(SR, dtype=float)
        m = len(z)
        _check_shapes(Z.shape == (m, 2 * n) and SR.ndim == 2 and SR.shape[0] == m)
        x_new, S_new = np.empty(n), np.empty((n, n))
        y, zp, w = np.empty(m), np.empty(m), np.empty(m)
        eta, chi = np.empty((m, 2 * n)), np.empty((n, 2 * n))
        Szz, Pxz, K = np.empty((m, m)), np.empty((n, m)), np.empty((n, m))
        if not _update_moments(X, x, Z, z, SR, x_new, S_new, y, zp, eta, chi, Szz, Pxz, K, w):
            raise np.linalg.LinAlgError('Singular matrix')
        return x_new, S_new, CubatureUpdate(y, zp, Szz @ Szz.T, Pxz, K, eta, chi, Szz, w)
    zp = Z.mean(axis=1)
    w = 1.0 / np.sqrt(2 * n)
    eta = (Z - zp[:, None]) * w
    chi = (X - x[:, None]) * w
    Szz = tria(np.hstack([eta, SR]))
    Pxz = chi @ eta.T
    # eq. 36: K = (Pxz / Szz^T) / Szz, i.e. Pxz (Szz Szz^T)^-1 by two solves with the
    # triangular factors (numpy's general solve: scipy.linalg is not imported for this)
    K = np.linalg.solve(Szz.T, np.linalg.solve(Szz, Pxz.T)).T
    y = z - zp
    x = x + K @ y
    S = tria(np.hstack([chi - K @ eta, K @ SR]))
    w = np.linalg.solve(Szz, y)
    return x, S, CubatureUpdate(y, zp, Szz @ Szz.T, Pxz, K, eta, chi, Szz, w)


@compiled.jit(sig='b1(f8[:, :], f8[:], f8[:, :], f8[:], f8[:, :], f8[:], f8[:, :], f8[:], '
              'f8[:], f8[:, :], f8[:, :], f8[:, :], f8[:, :], f8[:, :], f8[:])')
def _update_moments(X, x, Z, z, SR, x_new, S_new, y, zp, eta, chi, Szz, Pxz, K, w):
    """Compiled :func:`srckf_update` after ``hx``; False (nothing usable) if ``Szz`` is singular.

    ``X`` (n, 2n) the points, ``Z`` (m, 2n) their measurements, ``SR`` (m, r). Writes
    ``x_new``, ``S_new``, ``y``, ``zp``, ``eta``, ``chi``, ``Szz``, ``Pxz``, ``K``
    (eq. 28-38; ``K`` by forward and back substitution with ``Szz``) and ``w = Szz^-1 y``.
    """
    n, N = X.shape
    m, r = Z.shape[0], SR.shape[1]
    weight = 1.0 / np.sqrt(N)
    _tria_householder(_moments(Z, np.ones(m), SR, zp, eta), Szz)
    for i in range(m):
        y[i] = z[i] - zp[i]
    for i in range(m):
        if Szz[i, i] == 0.0:
            return False
    for c in range(m):
        s = y[c]
        for j in range(c):
            s -= Szz[c, j] * w[j]
        w[c] = s / Szz[c, c]
    for i in range(n):
        for j in range(N):
            chi[i, j] = (X[i, j] - x[i]) * weight
        for c in range(m):
            s = 0.0
            for j in range(N):
                s += chi[i, j] * eta[c, j]
            Pxz[i, c] = s
        # K[i] = Pxz[i] (Szz Szz^T)^-1: Szz u = Pxz[i]^T, then Szz^T k = u
        for c in range(m):
            s = Pxz[i, c]
            for j in range(c):
                s -= Szz[c, j] * K[i, j]
            K[i, c] = s / Szz[c, c]
        for c in range(m - 1, -1, -1):
            s = K[i, c]
            for j in range(c + 1, m):
                s -= Szz[j, c] * K[i, j]
            K[i, c] = s / Szz[c, c]
    B = np.empty((n, N + r))
    for i in range(n):
        s = x[i]
        for c in range(m):
            s += K[i, c] * y[c]
        x_new[i] = s
        for j in range(N):
            s = chi[i, j]
            for c in range(m):
                s -= K[i, c] * eta[c, j]
            B[i, j] = s
        for j in range(r):
            s = 0.0
            for c in range(m):
                s += K[i, c] * SR[c, j]
            B[i, N + j] = s
    _tria_householder(B, S_new)
    return True
