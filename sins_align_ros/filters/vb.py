"""Variational-Bayes cubature filters of seed 004: VBCKF and the cubature H-infinity VBCH.

Generic (nothing here knows about navigation): a nonlinear transition ``fx`` (cubature
time update, seed 004 eq. 9, 16-17) and a *linear* measurement ``z = H x + v`` with a
diagonal, unknown and time-varying ``R`` (seed 004 eq. 5).

* VBCKF: cubature time update; measurement update with ``N`` variational-Bayes
  fixed-point iterations estimating ``R`` from inverse-Gamma posteriors (seed 004
  eq. 23-24; Sarkka & Nummenmaa 2009).
* VBCH: the same with the H-infinity posterior covariance (eq. 10-13) for the
  auxiliary output ``y = L x`` and the adaptive robust factor gamma (eq. 14-15,
  constant ``C``), per the algorithm box of seed 004 sec. 2.4.

Where we differ from the box, and why:

* The H-infinity posterior is ``P = (P_kf^-1 - gamma^-2 L^T L)^-1`` evaluated as
  ``P_kf + P_kf L^T (gamma^2 I - L P_kf L^T)^-1 L P_kf`` with ``P_kf`` the Kalman
  posterior; the box writes ``P_k|k-1`` in the middle factor, which is indefinite
  whenever ``gamma^2`` lies between the posterior's and the prior's largest
  eigenvalue -- exactly where eq. 15 puts it.
* eq. 15, ``gamma^2 = (1 + C I^T I) maxeig(L (P_kf^-1 ... )^-1 L^T)``: the innovation
  energy ``I^T I`` is taken normalised, the epoch's ``y^T S^-1 y`` under the current R
  (the box's ``I^T I`` has the unit of the measurement, m^2/s^2 for velocity, and
  would make gamma depend on the choice of units); gamma is computed from the same
  iteration's ``P_kf`` (so the Riccati inequality eq. 12 holds by construction,
  ``gamma^2 > maxeig``).
* The H-infinity posterior never makes a variance larger than its initial value
  (``var_max``, not in the seed): it inflates the least observable direction (the
  heading) by ``1 + 1 / (C nu)`` every epoch, which without a bound compounded
  until the cubature points spread over the whole circle.
* The forgetting factor ``rho`` predicts the inverse-Gamma parameters
  (``alpha <- rho alpha``, ``beta <- rho beta``); the seed quotes rho = 1e-3, which
  leaves about one measurement in the estimate (R becomes the last residual
  squared); we read it as ``1 - rho = 1e-3`` (memory ~1000 epochs) and default to
  0.98 (memory ~50 epochs, for the seed's time-varying noise), a parameter.
* Outliers (not in the seed, whose inverse-Gamma R has a memory of many epochs, so a
  single 20-sigma epoch still pulls the state): optionally each epoch's noise is
  ``R / lam`` with a Gamma-distributed scale ``lam`` of ``dof`` degrees of freedom
  (Student-t measurement noise), estimated in the same fixed-point iterations,
  ``lam = (dof + m) / (dof + sum((r^2 + diag(H P H^T)) / R))``; an outlier epoch gets
  ``lam << 1`` and hardly moves the state or the R estimate. ``dof`` None: the seed.
* The prior: ``alpha0 = 0.5 / (1 - rho)`` (the stationary value of the recursion) and
  ``beta0 = alpha0 R0``: the nominal R counts as one memory's worth of measurements.
"""
import numpy as np

from .asckf import CKF
from .cubature import ckf_predict
from .kf import chi2_quantile, nis

#: probability above which an epoch's innovation is counted as an outlier (diagnostics)
OUTLIER_PROBABILITY = 0.999
#: an epoch whose Student-t noise scale falls below this was down-weighted as an outlier
OUTLIER_SCALE = 0.1


def hinf_posterior(P_kf, L, gamma2):
    """H-infinity posterior covariance ``(P_kf^-1 - gamma^-2 L^T L)^-1`` (seed 004 eq. 13).

    ``P_kf`` (n, n) the Kalman posterior, ``L`` (p, n), ``gamma2`` > maxeig(L P_kf L^T).
    """
    PL = P_kf @ L.T
    M = gamma2 * np.eye(L.shape[0]) - L @ PL
    P = P_kf + PL @ np.linalg.solve(M, PL.T)
    return 0.5 * (P + P.T)


def robust_gamma2(P_kf, L, nu, C):
    """Adaptive robust factor ``gamma^2 = (1 + C nu) maxeig(L P_kf L^T)`` (seed 004 eq. 15).

    ``nu``: normalised innovation energy (see the module docstring).
    """
    lam = float(np.linalg.eigvalsh(L @ P_kf @ L.T)[-1])
    return (1.0 + C * max(nu, 0.0)) * lam


def cap_variances(P, var_max):
    """Scale rows and columns of ``P`` so no variance exceeds ``var_max`` (n,) (stays PSD)."""
    d = np.sqrt(np.minimum(1.0, var_max / np.maximum(np.diag(P), 1e-300)))
    return P * d[:, None] * d[None, :]


def vb_update(xp, Pp, z, H, alpha, beta, n_iter, L=None, C=None, var_max=None, dof=None):
    """Variational-Bayes measurement update (seed 004 eq. 24 and the algorithm box).

    ``xp`` (n,), ``Pp`` (n, n): prediction; ``z`` (m,); ``H`` (m, n); ``alpha``,
    ``beta`` (m,): the *predicted* inverse-Gamma parameters. With ``L`` (p, n) and
    ``C`` the H-infinity posterior is used (VBCH), else the Kalman one (VBCKF);
    ``var_max`` (n,) caps its variances (:func:`cap_variances`). ``dof``: degrees of
    freedom of the Student-t outlier scale (module docstring; None: off, the seed).
    Returns ``(x, P, alpha, beta, gamma2, lam)``: gamma2 NaN for VBCKF, ``lam`` the
    epoch's noise scale (1: a normal epoch, << 1: judged an outlier).
    """
    m = len(z)
    alpha = alpha + 0.5
    beta_pred = beta
    beta = beta_pred.copy()
    PHt = Pp @ H.T
    HPH = H @ PHt
    y0 = z - H @ xp
    gamma2, lam = np.nan, 1.0
    x, P = xp, Pp
    for _ in range(max(1, int(n_iter))):
        R = beta / alpha
        S = HPH + np.diag(R / lam)
        K = np.linalg.solve(S, PHt.T).T
        x = xp + K @ y0
        P = Pp - K @ S @ K.T
        P = 0.5 * (P + P.T)
        r = z - H @ x
        e2 = r ** 2 + np.einsum('ij,jk,ik->i', H, P, H)
        if dof is not None:
            lam = (dof + m) / (dof + float(np.sum(e2 / R)))
        if L is not None:
            gamma2 = robust_gamma2(P, L, float(y0 @ np.linalg.solve(S, y0)), C)
            P = hinf_posterior(P, L, gamma2)
            if var_max is not None:
                P = cap_variances(P, var_max)
            e2 = r ** 2 + np.einsum('ij,jk,ik->i', H, P, H)
        beta = beta_pred + 0.5 * lam * e2
    return x, P, alpha, beta, gamma2, lam


class VBCKF(CKF):
    """Seed 004's baseline (module docstring), with the cubature filters' interface.

    The time update is :class:`~sins_align_ros.filters.asckf.CKF`'s (seed 004 eq. 16-17).

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

    def __init__(self, x0, P0, Q, R, rho=0.98, n_iter=20, dof=None):
        self.rho = float(rho)
        self.alpha = np.full(len(R), 0.5 / max(1.0 - self.rho, 1e-6))
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
        n = len(self.x)
        m_all = len(self.alpha)
        idx = np.arange(m_all) if idx is None else np.asarray(idx)
        H = np.asarray(hx(np.eye(n)), dtype=float)
        xp, Pp, _ = ckf_predict(self.x, self.P, fx, self.Q)
        a_pred, b_pred = self.rho * self.alpha[idx], self.rho * self.beta[idx]
        y = z - H @ xp
        S = H @ Pp @ H.T + np.diag(b_pred / a_pred)
        self.last_nis = nis(y, S)
        if self.last_nis > chi2_quantile(OUTLIER_PROBABILITY, len(idx)):
            self.n_outliers += 1
        self.rejected = max_nis is not None and self.last_nis > max_nis
        self.last = _Innovation(y, S)
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


class VBCH(VBCKF):
    """Seed 004's variational-Bayes cubature H-infinity filter (module docstring).

    As :class:`VBCKF`, plus ``L`` (p, n) the H-infinity auxiliary output, ``C`` the
    robust-factor constant and ``cap_at_p0`` (no posterior variance above its P0).
    """

    def __init__(self, x0, P0, Q, R, L, rho=0.98, n_iter=20, C=1.5, cap_at_p0=True, dof=None):
        super().__init__(x0, P0, Q, R, rho=rho, n_iter=n_iter, dof=dof)
        self.L = np.asarray(L, dtype=float)
        self.C = float(C)
        self.var_max = np.diag(self.P).copy() if cap_at_p0 else None


class _Innovation:
    """Prior innovation ``y`` (m,) and its covariance ``Pzz`` (m, m) of one epoch."""

    __slots__ = ('y', 'Pzz')

    def __init__(self, y, Pzz):
        self.y, self.Pzz = y, Pzz
