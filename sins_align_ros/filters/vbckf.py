"""The variational-Bayes cubature Kalman filter (VBCKF), seed 004's baseline.

A nonlinear transition ``fx`` with the cubature time update (seed 004 eq. 9, 16-17,
:class:`~sins_align_ros.filters.ckf.CKF`'s) and a *linear* measurement ``z = H x + v``
with a diagonal, unknown and time-varying ``R`` (seed 004 eq. 5), estimated in ``N``
variational-Bayes fixed-point iterations from inverse-Gamma posteriors (seed 004
eq. 23-24; Sarkka & Nummenmaa 2009): :func:`~sins_align_ros.filters.variational.vb_update`,
whose docstring lists where the update differs from the seed's algorithm box.

Where the filter differs from the seed, and why:

* The forgetting factor ``rho`` predicts the inverse-Gamma parameters
  (``alpha <- rho alpha``, ``beta <- rho beta``); the seed quotes rho = 1e-3, which
  leaves about one measurement in the estimate (R becomes the last residual
  squared); we read it as ``1 - rho = 1e-3`` (memory ~1000 epochs) and default to
  0.98 (memory ~50 epochs, for the seed's time-varying noise), a parameter.
* The prior: ``alpha0 = 0.5 / (1 - rho)`` (the stationary value of the recursion) and
  ``beta0 = alpha0 R0``: the nominal R counts as one memory's worth of measurements
  (:func:`~sins_align_ros.filters.variational.prior_alpha`).
* Outliers: the optional Student-t noise scale of ``dof`` degrees of freedom
  (:mod:`~sins_align_ros.filters.variational`); ``dof`` None: the seed.
"""
import numpy as np

from .base import PriorInnovation, measurement_rows
from .ckf import CKF
from .cubature import ckf_predict
from .chi2 import chi2_quantile
from .linear_kf import measurement_matrix
from .variational import prior_alpha, vb_update

#: probability above which an epoch's innovation is counted as an outlier (diagnostics)
OUTLIER_PROBABILITY = 0.999
#: an epoch whose Student-t noise scale falls below this was down-weighted as an outlier
OUTLIER_SCALE = 0.1


class VBCKF(CKF):
    """Seed 004's baseline (module docstring).

    The time update is :class:`~sins_align_ros.filters.ckf.CKF`'s (seed 004 eq. 16-17).
    Interface: :class:`~sins_align_ros.filters.base.GaussianFilter`.

    Parameters
    ----------
    x0 : ndarray (n,)
    P0, Q : ndarray (n, n)
    R : ndarray (m, m)
        Nominal (initial) measurement noise; only its diagonal is used.
    rho : float
        Forgetting factor in (0, 1].
    n_iter : int
        Variational iterations per epoch (seed 004: N = 20).
    dof : float or None
        Student-t outlier scale's degrees of freedom (None or inf: off, the seed).
    """

    #: the filter estimates R itself (the engine does not set it per epoch)
    estimates_R = True

    def __init__(self, x0, P0, Q, R, rho=0.98, n_iter=20, dof=None):
        self.rho = float(rho)
        self.alpha = prior_alpha(self.rho, len(R))
        super().__init__(x0, P0, Q, R)            # x, P, Q, R (-> beta), bookkeeping
        self.n_iter = int(n_iter)
        self.dof = None if dof is None or not np.isfinite(dof) else float(dof)
        self.L = self.C = self.var_max = None         # VBCH's
        self.gamma2 = np.nan
        self.lam_t = 1.0
        self.n_downweighted = 0
        self.n_outliers = 0
        self.last_nis = np.nan

    @property
    def robust(self):
        """Whether the H-infinity posterior is used (VBCH)."""
        return self.L is not None

    @property
    def R(self):
        """Current estimate of the measurement noise covariance (m, m)."""
        return np.diag(self.beta / self.alpha)

    @R.setter
    def R(self, value):
        """Set the estimate to the diagonal of ``value`` (the prior's weight is kept)."""
        self.beta = self.alpha * np.diag(np.asarray(value, dtype=float))

    @property
    def gamma(self):
        """Robust factor of the last update (NaN for VBCKF)."""
        return float(np.sqrt(self.gamma2))

    def step(self, fx, z, hx, idx=None, max_nis=None):
        """Time update and VB measurement update.

        ``hx`` must be linear; ``H = hx(I)`` (a :func:`~.cubature.batched` function
        applied to the identity's columns). ``idx``: rows of the full measurement
        vector present in ``z`` (their alpha/beta are used and updated). ``max_nis``:
        reject the epoch (prediction kept, noise estimate untouched) if its normalised
        innovation squared under the current R estimate exceeds it.
        Returns the prior innovation and its covariance (``y``, ``Pzz``).
        """
        idx = measurement_rows(idx, len(self.alpha))
        H = measurement_matrix(hx, len(self.x))
        xp, Pp, _ = ckf_predict(self.x, self.P, fx, self.Q)
        a_pred, b_pred = self.rho * self.alpha[idx], self.rho * self.beta[idx]
        y = z - H @ xp
        S = H @ Pp @ H.T + np.diag(b_pred / a_pred)
        self.last = PriorInnovation(y, S)
        self.last_nis = self.last.nis()
        if self.last_nis > chi2_quantile(OUTLIER_PROBABILITY, len(idx)):
            self.n_outliers += 1
        self.rejected = max_nis is not None and self.last_nis > max_nis
        if self.rejected:
            self.x, self.P = xp, Pp
            return self.last
        x, P, a, b, g2, lam = vb_update(xp, Pp, z, H, a_pred, b_pred, self.n_iter,
                                        L=self.L, C=self.C, var_max=self.var_max,
                                        dof=self.dof)
        self.x, self.P = x, P
        self.alpha[idx], self.beta[idx] = a, b
        self.gamma2, self.lam_t = g2, lam
        if lam < OUTLIER_SCALE:
            self.n_downweighted += 1
        return self.last
