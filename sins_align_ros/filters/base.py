"""The interface the alignment engines use from a filter, and the bookkeeping it shares.

:class:`GaussianFilter` declares what ``align/engines/moving.py``, ``align/engines/robust.py`` and
``align/engines/navigation.py`` call on their ``self.kf``, whichever filter it is:
:class:`~sins_align_ros.filters.ckf.CKF`, :class:`~sins_align_ros.filters.asckf.ASCKF`,
:class:`~sins_align_ros.filters.linear_kf.KF`, :class:`~sins_align_ros.filters.vbakf.VBAKF`,
:class:`~sins_align_ros.filters.mvbakf.MVBAKF`, :class:`~sins_align_ros.filters.ukf.UKF`,
:class:`~sins_align_ros.filters.vbckf.VBCKF`, :class:`~sins_align_ros.filters.vbch.VBCH`.
Each filter adds its own diagnostics (``n_faded``, ``p_ratio``, ``gamma`` ...), read
only by the engine built for it.

Shapes: ``n`` states, ``M`` rows of the full measurement vector, ``m`` of them present
at an epoch (rows ``idx``).

``fx`` and ``hx`` act on one state (n,) -> (n,) / (m,), or on all points at once
(n, N) -> (n, N) / (m, N) if marked :func:`~sins_align_ros.filters.cubature.batched`.
The linear filters (KF, VBAKF, MVBAKF) read the transition matrix from ``fx.F``
(:func:`~sins_align_ros.filters.linear_kf.linear`) and ``H = hx(I)``; so do VBCKF and
VBCH for ``H`` (their measurement must be linear).
"""
from typing import Optional, Protocol, runtime_checkable

import numpy as np

from .kf import nis


@runtime_checkable
class Innovation(Protocol):
    """What a filter epoch returns: the prior innovation and its covariance.

    :class:`PriorInnovation` or :class:`~sins_align_ros.filters.cubature.CubatureUpdate`.
    """

    #: innovation ``z - h(x_pred)`` (m,)
    y: np.ndarray
    #: its predicted covariance (m, m)
    Pzz: np.ndarray

    def nis(self) -> float:
        """Return the normalised innovation squared ``y^T Pzz^-1 y``, the epoch's NIS."""


@runtime_checkable
class GaussianFilter(Protocol):
    """The members the alignment engines use from a filter (see the module docstring)."""

    #: state estimate (n,); the engines write into it (closed-loop feedback zeroes entries)
    x: np.ndarray
    #: state covariance (n, n); may be a property (ASCKF keeps ``S`` with ``P = S S^T``):
    #: set it whole, do not write into the array read
    P: np.ndarray
    #: process noise of the coming prediction (n, n); the engines set it per interval
    #: (the adaptive ASCKF keeps its own estimate)
    Q: np.ndarray
    #: measurement noise of the full measurement vector (M, M), the current estimate for
    #: the adaptive filters; may be a property (VBCKF): set it whole
    R: np.ndarray
    #: whether the last :meth:`step` rejected its measurement (NIS above ``max_nis``)
    rejected: bool
    #: the :class:`Innovation` of the last :meth:`step` (None before the first)
    last: Optional[Innovation]
    #: fading factors of the last step (n,), or None for a filter without fading
    lam: Optional[np.ndarray]
    #: how often a divergence test fired (0 for a filter without one)
    divergence_flags: int

    def predict(self, fx) -> object:
        """Time update only (no measurement this epoch) with the transition ``fx``.

        The return value is not part of the interface (the linear KF and the UKF
        return ``(x, P)``, the cubature filters None).
        """

    def step(self, fx, z, hx, idx=None, max_nis=None) -> Innovation:
        """Predict with ``fx``, then update with ``z`` (m,) measured by ``hx``.

        ``idx`` (m,): the rows of the full measurement vector (and of ``R``) that
        ``z`` holds (None: all M). ``max_nis``: innovation gate (None: off); an
        epoch whose normalised innovation squared exceeds it is rejected
        (:attr:`rejected`) and keeps the prediction. Returns the prior
        :class:`Innovation`.
        """

    def transform(self, T) -> None:
        """Change state coordinates (T (n, n)): ``x <- T x``, ``P <- T P T^T``."""

    def append_states(self, var) -> None:
        """Append zero-mean random constants of variances ``var`` (k,), uncorrelated.

        ``x`` grows by zeros, ``P`` by the diagonal block ``diag(var)``, ``Q`` by zeros
        (no process noise of their own).
        """


class PriorInnovation:
    """Prior innovation ``y`` (m,) and its covariance ``Pzz`` (m, m) of one epoch."""

    __slots__ = ('y', 'Pzz', '_nis')

    def __init__(self, y, Pzz):
        self.y, self.Pzz = y, Pzz
        self._nis = None

    def nis(self):
        """Return the NIS ``y^T Pzz^-1 y``, solved once (the gate and diagnostics ask)."""
        if self._nis is None:
            self._nis = nis(self.y, self.Pzz)
        return self._nis


def measurement_rows(idx, M):
    """Rows of the full measurement vector present at an epoch: ``idx``, default all ``M``."""
    return np.arange(M) if idx is None else np.asarray(idx)


class CovarianceFilter:
    """Bookkeeping of the covariance-form filters (CKF, KF and their variants, UKF).

    Holds ``x`` (n,), ``P``, ``Q`` (n, n), ``R`` (M, M) and the diagnostics of
    :class:`GaussianFilter` (no fading, no divergence test); subclasses provide
    ``predict`` and ``step``.

    ``consider`` (n,) bool or None: states the measurement update does not correct
    (the Schmidt-Kalman "consider" states: their gain rows are zero and the covariance
    takes that suboptimal gain exactly, so their variance and cross-covariances stay
    honest). Honoured by :class:`~.linear_kf.KF` and :class:`~.ukf.UKF` (not the VB
    filters' iterations).
    """

    def __init__(self, x0, P0, Q, R):
        self.x = np.array(x0, dtype=float)
        self.P = np.array(P0, dtype=float)
        self.Q = np.array(Q, dtype=float)
        self.R = np.array(R, dtype=float)
        self.lam = None
        self.divergence_flags = 0
        self.last = None
        self.rejected = False
        self.consider = None

    def transform(self, T):
        """Change state coordinates: ``x <- T x``, ``P <- T P T^T``."""
        self.x = T @ self.x
        self.P = T @ self.P @ T.T

    def append_states(self, var):
        """Append zero-mean random constants of variances ``var`` (k,): ``GaussianFilter``'s."""
        var = np.asarray(var, dtype=float)
        n, k = len(self.x), len(var)
        P, Q = np.zeros((n + k, n + k)), np.zeros((n + k, n + k))
        P[:n, :n], Q[:n, :n] = self.P, self.Q
        P[n:, n:] = np.diag(var)
        self.x, self.P, self.Q = np.r_[self.x, np.zeros(k)], P, Q
