"""The conventional cubature Kalman filter of seed 000 (sec. 3, eq. 22-34).

Covariance form, points re-drawn for the update (eq. 28); fixed Q and R. The
baseline of :class:`~sins_align_ros.filters.asckf.ASCKF` and the time update of
:class:`~sins_align_ros.filters.vbckf.VBCKF` (seed 004 eq. 16-17). Generic:
``fx(x)`` and ``hx(x)`` act on one state vector (:mod:`~sins_align_ros.filters.cubature`).
"""
import numpy as np

from .base import CovarianceFilter, measurement_rows
from .cubature import ckf_predict, ckf_update
from .kf import nis


class CKF(CovarianceFilter):
    """The conventional cubature Kalman filter (seed 000 eq. 22-34) with ASCKF's interface.

    Covariance form, points re-drawn for the update (eq. 28); fixed Q and R.
    Interface: :class:`~sins_align_ros.filters.base.GaussianFilter`.
    """

    def predict(self, fx):
        """Time update only (eq. 23-26)."""
        self.x, self.P, _ = ckf_predict(self.x, self.P, fx, self.Q)

    def step(self, fx, z, hx, idx=None, max_nis=None):
        """Time update and measurement update.

        ``idx``, ``max_nis`` as in :meth:`~sins_align_ros.filters.asckf.ASCKF.step`.
        """
        idx = measurement_rows(idx, len(self.R))
        xp, Pp, _ = ckf_predict(self.x, self.P, fx, self.Q)
        x, P, upd = ckf_update(xp, Pp, z, hx, self.R[np.ix_(idx, idx)])
        self.rejected = max_nis is not None and nis(upd.y, upd.Pzz) > max_nis
        self.x, self.P = (xp, Pp) if self.rejected else (x, P)
        self.last = upd
        return upd
