"""The variational-Bayes adaptive Kalman filter (VBAKF), seed 001's baseline.

Sarkka & Nummenmaa (2009, seed 001 ref. 10/15): the linear
:class:`~sins_align_ros.filters.linear_kf.KF` with a diagonal R of inverse-Gamma
posteriors, forgetting factor ``rho`` on their parameters, ``N`` fixed-point iterations
(:func:`~sins_align_ros.filters.variational.vb_update`). A rejected epoch still teaches
R (:mod:`~sins_align_ros.filters.linear_kf`). Seed 001's modified filter is
:class:`~sins_align_ros.filters.mvbakf.MVBAKF`.

The R estimate carried from epoch to epoch never exceeds ``r_max_scale`` times the
nominal R, row by row (:data:`R_MAX_SCALE` by default; not in the seeds). Without a
ceiling a VB filter whose state model is wrong (a MEMS gyro under a navigation-grade
model, a lost heading) explains the innovations the model cannot by a larger R: the
state stops listening to the measurements, its covariance stops being tested, and the
published sigma becomes a claim nobody checks (on seed 001's flight with a MEMS IMU,
VBAKF's position R reached hundreds of times the nominal while the heading was lost
and the position went kilometres off). The ceiling leaves room for a receiver
noisier than configured (seed 001's 4x step is 16x in variance) and hands a larger
misfit to the consistency monitor, which can tell a model error from noise.
"""
import numpy as np

from .linear_kf import KF, rejected_noise
from .variational import prior_alpha, vb_update

#: default ceiling of the R estimate, as a multiple of the nominal variance (10x in sigma)
R_MAX_SCALE = 100.0


class VBAKF(KF):
    """Variational-Bayes adaptive KF estimating a diagonal R (Sarkka & Nummenmaa 2009).

    ``rho``: forgetting factor of the inverse-Gamma parameters (seed 001 sec. 3.2:
    0.95 for every element); ``n_iter``: fixed-point iterations per epoch. The prior
    counts the nominal R as one memory's worth of epochs (``alpha0 = 0.5 / (1 - rho)``).
    ``r_max_scale``: ceiling of the R estimate over the nominal one (module docstring;
    None: no ceiling, the seed). Interface:
    :class:`~sins_align_ros.filters.base.GaussianFilter`.
    """

    #: the filter estimates R itself (the engine does not set it per epoch)
    estimates_R = True

    def __init__(self, x0, P0, Q, R, rho=0.95, n_iter=5, r_max_scale=R_MAX_SCALE):
        super().__init__(x0, P0, Q, R)
        self.rho = float(rho)
        self.n_iter = int(n_iter)
        self.alpha = prior_alpha(self.rho, len(self.R))
        self.beta = self.alpha * np.diag(self.R)
        self.r_max = None if r_max_scale is None else float(r_max_scale) * np.diag(self.R)
        #: epochs at which the ceiling held the R estimate
        self.n_r_capped = 0

    def _cap(self):
        """Hold the R estimate ``beta / alpha`` at the ceiling (module docstring)."""
        if self.r_max is not None:
            lim = self.r_max * self.alpha
            if np.any(self.beta > lim):
                self.n_r_capped += 1
                self.beta = np.minimum(self.beta, lim)
        self.R = self.R_prior()

    def R_prior(self):
        """Predicted diagonal ``rho beta / (rho alpha)`` = the last estimate."""
        return np.diag(self.beta / self.alpha)

    def _update(self, H, z, y, S, R, idx):
        a_pred, b_pred = self.rho * self.alpha[idx], self.rho * self.beta[idx]
        self.x, self.P, a, b, _, _ = vb_update(self.x, self.P, z, H, a_pred, b_pred,
                                               self.n_iter)
        self.alpha[idx], self.beta[idx] = a, b
        self._cap()

    def _learn_rejected(self, y, S, HPH, idx):
        self.alpha[idx] = self.rho * self.alpha[idx] + 0.5
        self.beta[idx] = self.rho * self.beta[idx] + 0.5 * rejected_noise(y, S, HPH)
        self._cap()
