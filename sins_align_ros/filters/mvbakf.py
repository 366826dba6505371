"""Seed 001's modified variational-Bayes adaptive Kalman filter (MVBAKF).

Seed 001 sec. 2: the linear :class:`~sins_align_ros.filters.linear_kf.KF` with
inverse-Wishart priors for the one-step prediction covariance ``P(k|k-1)`` (eq. 8-10,
tuning factor ``tau``) and for the full ``R`` (eq. 11-13, forgetting factor ``rho``);
``N`` fixed-point iterations of eq. 20-34; the results eq. 35-39. Its baseline is
:class:`~sins_align_ros.filters.vbakf.VBAKF`. A rejected epoch still teaches R
(:mod:`~sins_align_ros.filters.linear_kf`).

The R estimate never exceeds ``r_max_scale`` times the nominal R on its diagonal
(:data:`~sins_align_ros.filters.vbakf.R_MAX_SCALE` by default; not in the seed): the
rows and columns of ``U`` over the ceiling are scaled down, which keeps it positive
definite and its correlations. Why a ceiling: :mod:`~sins_align_ros.filters.vbakf`.
"""
import numpy as np

from .linear_kf import KF, rejected_noise
from .variational import cap_variances
from .vbakf import R_MAX_SCALE


class MVBAKF(KF):
    """Seed 001's modified variational-Bayes adaptive KF (module docstring).

    Parameters
    ----------
    x0, P0, Q : initial state, covariance and the (possibly wrong) process noise ``Q~``
    R : ndarray (M, M)
        Nominal measurement noise: the inverse-Wishart prior mean ``R~_0`` (eq. 11).
    tau : float
        Tuning factor of the ``P(k|k-1)`` prior, ``t = n + tau + 1`` (eq. 9-10).
    rho : float
        Forgetting factor of the R prior (eq. 12-13).
    n_iter : int
        Fixed-point iterations ``N`` (eq. 35-37).
    u0 : float or None
        Initial degrees of freedom of the R prior; default the stationary value of
        eq. 12, ``u - M - 1 = rho / (1 - rho)``.
    moment : str
        Which moment of the inverse-Wishart posteriors the state update uses.
        ``'mean'`` (default): seed 001 eq. 24 and 30 as printed, the posterior means
        ``T / (t - n - 1)`` and ``U / (u - m - 1)``. ``'inverse'``: ``E[P^-1]^-1 = T / t``
        and ``E[R^-1]^-1 = U / u``, what the variational derivation (eq. 15-19) asks
        for (Huang et al. 2017, seed 001 ref. 13); the seed's eq. 7 gives
        ``(lambda - d - 1) Psi^-1`` for ``E[B^-1]``, which is the inverse of the mean.
    r_max_scale : float or None
        Ceiling of the R estimate's diagonal over the nominal one (module docstring;
        None: no ceiling, the seed).

    Measurement subsets (``idx`` of fewer than M rows): the sub-block of ``U`` is
    updated; the other entries are rescaled so their R estimate is kept (an
    inverse-Wishart marginal has the same ``u - M - 1`` as the full one).

    Interface: :class:`~sins_align_ros.filters.base.GaussianFilter`.
    """

    #: the filter estimates R itself (the engine does not set it per epoch)
    estimates_R = True

    def __init__(self, x0, P0, Q, R, tau=6.0, rho=0.95, n_iter=5, u0=None, moment='mean',
                 r_max_scale=R_MAX_SCALE):
        super().__init__(x0, P0, Q, R)
        self.r_max = None if r_max_scale is None else float(r_max_scale) * np.diag(self.R)
        #: epochs at which the ceiling held the R estimate
        self.n_r_capped = 0
        if moment not in ('mean', 'inverse'):
            raise ValueError(f'moment must be mean or inverse, not {moment!r}')
        self.moment = moment
        self.tau = float(tau)
        self.rho = float(rho)
        self.n_iter = int(n_iter)
        M = len(self.R)
        d0 = self.rho / max(1.0 - self.rho, 1e-6) if u0 is None else float(u0) - M - 1
        self.u = d0 + M + 1.0                     # eq. 11: R~_0 = U / (u - M - 1)
        self.U = self.R * d0
        #: trace of the estimated P(k|k-1) over the nominal one (last epoch)
        self.p_ratio = 1.0

    def R_prior(self):
        """Predicted R mean ``U(k|k-1) / (u(k|k-1) - M - 1)`` (eq. 11-13)."""
        M = len(self.U)
        d = self.rho * (self.u - M - 1.0)
        return (self.rho * self.U) / d

    def _r_prior(self, idx):
        """Time update of the R prior (eq. 12-13): ``(u, U, U[idx, idx], u - M - 1)``."""
        M = len(self.U)
        u_p = self.rho * (self.u - M - 1.0) + M + 1.0
        U_p = self.rho * self.U
        return u_p, U_p, U_p[np.ix_(idx, idx)], u_p - M - 1.0

    def _absorb(self, u_p, U_p, d_sub, U_sub, B, idx):
        """Eq. 36-38: ``u = u + 1``, ``U[idx, idx] = U + B``; other rows keep their R."""
        M = len(self.U)
        u_new = u_p + 1.0
        U_new = U_p * ((u_new - M - 1.0) / d_sub)
        U_new[np.ix_(idx, idx)] = U_sub + B
        U_new = 0.5 * (U_new + U_new.T)
        if self.r_max is not None:
            lim = self.r_max * (u_new - M - 1.0)
            if np.any(np.diag(U_new) > lim):
                self.n_r_capped += 1
                U_new = cap_variances(U_new, lim)
        self.u, self.U = u_new, U_new
        self.R = self.U / (self.u - M - 1.0)                             # eq. 38

    def _learn_rejected(self, y, S, HPH, idx):
        u_p, U_p, U_sub, d_sub = self._r_prior(idx)
        self._absorb(u_p, U_p, d_sub, U_sub, np.diag(rejected_noise(y, S, HPH)), idx)

    def _update(self, H, z, y, S, R, idx):
        n, m = len(self.x), len(idx)
        u_p, U_p, U_sub, d_sub = self._r_prior(idx)   # d_sub: the marginal's u - m - 1
        # prior of P(k|k-1): t = n + tau + 1, T = tau P~ (eq. 8-10)
        P_t = self.P_nominal
        T = self.tau * P_t
        xp = self.x
        # denominators of the moment used: t - n - 1 or t (the same for u)
        p_den = self.tau + 1.0 + (n + 1.0 if self.moment == 'inverse' else 0.0)
        r_den = d_sub + 1.0 + (m + 1.0 if self.moment == 'inverse' else 0.0)
        # fixed-point iterations (eq. 19-34), started from the nominal prediction
        x, P = xp, P_t
        dx = np.zeros(n)
        r = y
        for _ in range(max(1, self.n_iter)):
            A = P + np.outer(dx, dx)                                     # eq. 20
            B = np.outer(r, r) + H @ P @ H.T                              # eq. 26
            P_pred = (T + A) / p_den                                     # eq. 22-24
            R_i = (U_sub + B) / r_den                                    # eq. 28-30
            S_i = H @ P_pred @ H.T + R_i
            K = np.linalg.solve(S_i, H @ P_pred).T                       # eq. 32
            x = xp + K @ y                                               # eq. 33
            P = P_pred - K @ H @ P_pred                                  # eq. 34
            P = 0.5 * (P + P.T)
            dx = x - xp
            r = z - H @ x
        self.x, self.P = x, P
        self.p_ratio = float(np.trace(P_pred) / np.trace(P_t))
        self._absorb(u_p, U_p, d_sub, U_sub, B, idx)
