"""The navigation engines, one class per fine filter: seed 001's kf, vbakf, mvbakf, 003's ukf.

Each makes its filter and names its row of the filter table (``fine_filter``,
:mod:`..filter_table`); everything else is :class:`~.navigation.IntegratedNavigation`'s.
The UKF's sigma-point path is its own: the nonlinear propagation, the whole force, no
heading range, the large-angle feedback.
"""
import math

import numpy as np

from ...filters.cubature import batched
from ...filters.linear_kf import KF
from ...filters.mvbakf import MVBAKF
from ...filters.ukf import UKF
from ...filters.vbakf import VBAKF
from ...models import large_misalignment as lm
from ...models import loosely_coupled as lc
from .navigation import IntegratedNavigation

#: largest coarse heading sigma handed to the UKF, rad (:meth:`UnscentedNavigation.prior_sigma`)
UKF_HEADING_SIGMA_MAX = math.radians(30.0)


class KalmanNavigation(IntegratedNavigation):
    """``kf``: seed 001's 15 states with the linear Kalman filter (seed 001's baseline)."""

    fine_filter = 'kf'

    def _make_filter(self, x0, P0, Q, R):
        return KF(x0, P0, Q, R)


class VBAKFNavigation(IntegratedNavigation):
    """``vbakf``: seed 001's variational-Bayes adaptive KF, R estimated (sec. 3.2)."""

    fine_filter = 'vbakf'

    @staticmethod
    def options(cfg):
        """Return the VB forgetting factor and iterations of parameter values ``cfg``."""
        return dict(rho=cfg['nav_forgetting'], n_iter=cfg['nav_iterations'])

    def _make_filter(self, x0, P0, Q, R, rho=0.95, n_iter=5):
        return VBAKF(x0, P0, Q, R, rho=rho, n_iter=n_iter)


class MVBAKFNavigation(IntegratedNavigation):
    """``mvbakf``: seed 001's filter, P(k|k-1) and a full R estimated (eq. 4-39)."""

    fine_filter = 'mvbakf'

    @staticmethod
    def options(cfg):
        """Return VBAKF's options and the P(k|k-1) prior's tuning factor and moment."""
        return dict(VBAKFNavigation.options(cfg), tau=cfg['mvbakf_tau'],
                    moment=cfg['mvbakf_moment'])

    def _make_filter(self, x0, P0, Q, R, rho=0.95, n_iter=5, tau=6.0, moment='mean'):
        return MVBAKF(x0, P0, Q, R, tau=tau, rho=rho, n_iter=n_iter, moment=moment)

    def status(self):
        """Return the base status plus the estimated over the nominal P(k|k-1) trace."""
        s = super().status()
        s['P_pred_trace_ratio'] = self.kf.p_ratio
        return s


class UnscentedNavigation(IntegratedNavigation):
    """``ukf``: seed 003's 18 states with the UKF, nonlinear in the heading error.

    Its sigma points go through the nonlinear model over the interval
    (:func:`~sins_align_ros.models.loosely_coupled.propagate18`, seed 004 eq. 3's heading),
    so it keeps its own force, holds no heading range (:mod:`.heading_range`) and feeds
    the misalignment back as the large-angle rotation
    (:func:`~sins_align_ros.models.large_misalignment.C_n_nprime`).
    """

    fine_filter = 'ukf'
    n_states = 18
    heading_cap = None
    heading_sigma_max = UKF_HEADING_SIGMA_MAX

    @classmethod
    def prior_sigma(cls, sigma):
        """Return ``sigma`` with the heading at most :data:`UKF_HEADING_SIGMA_MAX`.

        Sigma points sit at +-sqrt(n) sigma: a 90 deg heading sigma puts them 380 deg out,
        around the circle, and the tilt collapses (still MEMS IMU: tilt 10 sigma off).
        The heading is published as unknown above 10 deg anyway (:mod:`.heading_range`).
        """
        return np.minimum(sigma, [np.inf, np.inf, UKF_HEADING_SIGMA_MAX])

    def _make_filter(self, x0, P0, Q, R):
        return UKF(x0, P0, Q, R)

    def _interval_force(self, f_n, lat, h):
        """Return ``f_n``: the model is nonlinear in the heading and takes the whole force."""
        return f_n

    def _propagation(self, f_n, v_n, C, T, w_b):
        """Return the sigma points' propagation through the 18-state model over ``T`` s."""
        m = self.mech
        sub = max(1, int(math.ceil(T / 1.0)))
        args = (f_n, v_n, C, m.lat, m.h, self.tau_g, self.tau_a, T)
        # (the receiver's error states, when there, decay beside it: :mod:`.gnss_markov_states`)
        return self._markov_decayed(
            batched(lambda X: lc.propagate18(X, *args, substeps=sub, w_b=w_b)), T)

    @staticmethod
    def _attitude_correction(phi):
        """Return the large-angle misalignment's DCM (3, 3) (seed 004 eq. 3)."""
        return lm.C_n_nprime(phi).T
