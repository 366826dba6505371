"""The variational-Bayes adaptive Kalman filter (VBAKF), seed 001's baseline.

Sarkka & Nummenmaa (2009, seed 001 ref. 10/15): the linear
:class:`~sins_align_ros.filters.linear_kf.KF` with a diagonal R of inverse-Gamma
posteriors, forgetting factor ``rho`` on their parameters, ``N`` fixed-point iterations
(:func:`~sins_align_ros.filters.variational.vb_update`). A rejected epoch still teaches
R (:mod:`~sins_align_ros.filters.linear_kf`). Seed 001's modified filter is
:class:`~sins_align_ros.filters.mvbakf.MVBAKF`.
"""
import numpy as np

from .linear_kf import KF, rejected_noise
from .variational import prior_alpha, vb_update


class VBAKF(KF):
    """Variational-Bayes adaptive KF estimating a diagonal R (Sarkka & Nummenmaa 2009).

    ``rho``: forgetting factor of the inverse-Gamma parameters (seed 001 sec. 3.2:
    0.95 for every element); ``n_iter``: fixed-point iterations per epoch. The prior
    counts the nominal R as one memory's worth of epochs (``alpha0 = 0.5 / (1 - rho)``).
    Interface: :class:`~sins_align_ros.filters.base.GaussianFilter`.
    """

    def __init__(self, x0, P0, Q, R, rho=0.95, n_iter=5):
        super().__init__(x0, P0, Q, R)
        self.rho = float(rho)
        self.n_iter = int(n_iter)
        self.alpha = prior_alpha(self.rho, len(self.R))
        self.beta = self.alpha * np.diag(self.R)

    def R_prior(self):
        """Predicted diagonal ``rho beta / (rho alpha)`` = the last estimate."""
        return np.diag(self.beta / self.alpha)

    def _update(self, H, z, y, S, R, idx):
        a_pred, b_pred = self.rho * self.alpha[idx], self.rho * self.beta[idx]
        self.x, self.P, a, b, _, _ = vb_update(self.x, self.P, z, H, a_pred, b_pred,
                                               self.n_iter)
        self.alpha[idx], self.beta[idx] = a, b
        self.R = self.R_prior()

    def _learn_rejected(self, y, S, HPH, idx):
        self.alpha[idx] = self.rho * self.alpha[idx] + 0.5
        self.beta[idx] = self.rho * self.beta[idx] + 0.5 * rejected_noise(y, S, HPH)
        self.R = self.R_prior()
