"""The standard linear Kalman filter of seed 001 (eq. 3) with the common filter interface.

Generic (nothing here knows about navigation), with the interface of the cubature
filters (:class:`~sins_align_ros.filters.base.GaussianFilter`) so the moving-base
engines can drive it: ``step(fx, z, hx, idx, max_nis)``, ``predict(fx)``, ``x``, ``P``,
``Q``, ``R``, ``rejected``. It takes the transition matrix from ``fx.F``
(:func:`linear`) and ``H = hx(I)`` (:func:`measurement_matrix`). The adaptive
variants of seed 001 derive from it: :class:`~sins_align_ros.filters.vbakf.VBAKF`
and :class:`~sins_align_ros.filters.mvbakf.MVBAKF`.

Shapes: ``x`` (n,), ``P``/``Q`` (n, n), ``z`` (m,), ``R`` (M, M) over the full
measurement vector of which an epoch's ``z`` holds rows ``idx``.

An epoch rejected by the innovation gate (``max_nis``) keeps the prediction; the
adaptive filters still learn R from it (not in the seeds): each row's prior
innovation squared less its predicted state part, winsorised at
:data:`~sins_align_ros.filters.kf.CLIP` times its predicted variance
(:func:`rejected_noise`), enters the R statistics as one epoch. Otherwise a lasting
rise of the receiver noise (seed 001's 4x step) is rejected epoch after epoch and
never learnt -- the filter then re-anchors by force and the pipeline restarts --,
while a single outlier moves R by a bounded step that the forgetting removes again.
"""
import numpy as np

from .base import CovarianceFilter, PriorInnovation, measurement_rows
from .cubature import batched
from .kf import CLIP


def _identity(n):
    """Return the identity (n, n), shared and read-only (``H = hx(I)`` and the Joseph form's)."""
    eye = _IDENTITY.get(n)
    if eye is None:
        eye = _IDENTITY[n] = np.eye(n)
        eye.flags.writeable = False
    return eye


_IDENTITY = {}


def rejected_noise(y, S, HPH):
    """Per-row R sample of a rejected epoch: ``y^2 - (H P H^T)_ii`` in ``[0, CLIP S_ii]``."""
    s = np.diag(S)
    return np.clip(y * y - np.diag(HPH), 0.0, CLIP * s)


def linear(F):
    """Return the batched transition ``x -> F x``, carrying its matrix as ``.F`` (n, n)."""
    fn = batched(lambda X: F @ X)
    fn.F = F
    return fn


def measurement_matrix(hx, n):
    """``H = hx(I)`` (m, n) of a linear (batched) measurement function of ``n`` states.

    ``I`` is the shared read-only identity (:func:`_identity`): ``hx`` must not write
    into its argument (selecting or combining rows does not).
    """
    return np.asarray(hx(_identity(n)), dtype=float)


class KF(CovarianceFilter):
    """Standard Kalman filter (seed 001 eq. 3) with the cubature filters' interface.

    The bookkeeping (``x``, ``P``, ``Q``, ``R``, ``transform``) is
    :class:`~sins_align_ros.filters.base.CovarianceFilter`'s. Subclasses adapt R
    through :meth:`R_prior`, :meth:`_update` and :meth:`_learn_rejected`.
    """

    def __init__(self, x0, P0, Q, R):
        super().__init__(x0, P0, Q, R)
        #: the nominal one-step prediction covariance of the last epoch (n, n)
        self.P_nominal = None

    def predict(self, fx):
        """Time update ``x = F x``, ``P = F P F^T + Q`` (seed 001 eq. 3)."""
        F = fx.F
        self.x = F @ self.x
        P = F @ self.P @ F.T + self.Q
        self.P = 0.5 * (P + P.T)
        return self.x, self.P

    def _prior(self, fx, z, hx, idx):
        """Predict; return ``(H, y, S, R_sub)`` of the epoch under the current R."""
        self.predict(fx)
        self.P_nominal = self.P
        H = measurement_matrix(hx, len(self.x))
        R = self.R_prior()[idx][:, idx]                 # the rows and columns of idx
        y = z - H @ self.x
        S = H @ self.P @ H.T + R
        self.last = PriorInnovation(y, S)
        return H, y, S, R

    def R_prior(self):
        """Return the measurement noise the prior innovation is judged with (M, M)."""
        return self.R

    def step(self, fx, z, hx, idx=None, max_nis=None):
        """Predict with ``fx``, gate (``max_nis``), update with ``z`` of ``hx`` rows ``idx``.

        A rejected epoch (NIS above ``max_nis``) keeps the prediction. Returns the
        prior innovation and its covariance (``y``, ``Pzz``).
        """
        idx = measurement_rows(idx, len(self.R))
        H, y, S, R = self._prior(fx, z, hx, idx)
        self.rejected = max_nis is not None and self.last.nis() > max_nis
        if self.rejected:
            self._learn_rejected(y, S, H @ self.P @ H.T, idx)
        else:
            self._update(H, z, y, S, R, idx)
        return self.last

    def _learn_rejected(self, y, S, HPH, idx):
        """Learn from a rejected epoch (module docstring); the plain KF does not adapt."""

    def _update(self, H, z, y, S, R, idx):
        """Measurement update in Joseph form with the epoch's ``R`` (seed 001 eq. 3).

        The :attr:`consider` states' gain rows are zeroed first; the Joseph form is exact
        for any gain, so their covariance stays honest.
        """
        K = np.linalg.solve(S, H @ self.P).T
        if self.consider is not None:
            K[self.consider] = 0.0
        self.x = self.x + K @ y
        I_KH = _identity(len(self.x)) - K @ H
        P = I_KH @ self.P @ I_KH.T + K @ R @ K.T
        self.P = 0.5 * (P + P.T)
