"""Linear adaptive Kalman filters of seed 001 (KF, VBAKF, MVBAKF) and the UKF of seed 003.

Generic (nothing here knows about navigation), with the interface of the cubature
filters (:class:`~sins_align_ros.filters.asckf.CKF`) so the moving-base engines can
drive any of them: ``step(fx, z, hx, idx, max_nis)``, ``predict(fx)``, ``x``, ``P``,
``Q``, ``R``, ``rejected``. The linear filters take the transition matrix from
``fx.F`` (:func:`linear`) and ``H = hx(I)``; the UKF calls ``fx`` on its sigma points.

* :class:`KF`: the standard Kalman filter (seed 001 eq. 3).
* :class:`VBAKF`: the variational-Bayes adaptive KF of Sarkka & Nummenmaa (2009, seed
  001 ref. 10/15), the baseline: diagonal R with inverse-Gamma posteriors, forgetting
  factor ``rho`` on their parameters, ``N`` fixed-point iterations.
* :class:`MVBAKF`: seed 001 sec. 2 -- inverse-Wishart priors for the one-step
  prediction covariance ``P(k|k-1)`` (eq. 8-10, tuning factor ``tau``) and for the
  full ``R`` (eq. 11-13, forgetting factor ``rho``); ``N`` fixed-point iterations of
  eq. 20-34; the results eq. 35-39.
* :class:`UKF`: the scaled unscented filter (seed 003 eq. 4-15) on a nonlinear ``fx``.

Shapes: ``x`` (n,), ``P``/``Q`` (n, n), ``z`` (m,), ``R`` (M, M) over the full
measurement vector of which an epoch's ``z`` holds rows ``idx``.

An epoch rejected by the innovation gate (``max_nis``) keeps the prediction; the
adaptive filters still learn R from it (not in the seeds): each row's prior
innovation squared less its predicted state part, winsorised at :data:`CLIP` times
its predicted variance, enters the R statistics as one epoch. Otherwise a lasting
rise of the receiver noise (seed 001's 4x step) is rejected epoch after epoch and
never learnt -- the filter then re-anchors by force and the pipeline restarts --,
while a single outlier moves R by a bounded step that the forgetting removes again.
"""
import numpy as np

from .asckf import CKF
from .cubature import batched
from .kf import nis
from .ukf import ukf_predict, ukf_update
from .vb import _Innovation, vb_update

#: winsorisation of a rejected epoch's innovation, in predicted variances (99.9% of chi2(1))
CLIP = 10.83


def _rejected_noise(y, S, HPH):
    """Per-row R sample of a rejected epoch: ``y^2 - (H P H^T)_ii`` in ``[0, CLIP S_ii]``."""
    s = np.diag(S)
    return np.clip(y * y - np.diag(HPH), 0.0, CLIP * s)


def linear(F):
    """Return the batched transition ``x -> F x``, carrying its matrix as ``.F`` (n, n)."""
    fn = batched(lambda X: F @ X)
    fn.F = F
    return fn


def _H(hx, n):
    return np.asarray(hx(np.eye(n)), dtype=float)


class KF(CKF):
    """Standard Kalman filter (seed 001 eq. 3) with the cubature filters' interface.

    The bookkeeping (``x``, ``P``, ``Q``, ``R``, ``transform``) is the CKF's.
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
        H = _H(hx, len(self.x))
        R = self.R_prior()[np.ix_(idx, idx)]
        y = z - H @ self.x
        S = H @ self.P @ H.T + R
        self.last = _Innovation(y, S)
        return H, y, S, R

    def R_prior(self):
        """Return the measurement noise the prior innovation is judged with (M, M)."""
        return self.R

    def step(self, fx, z, hx, idx=None, max_nis=None):
        """Predict with ``fx``, gate (``max_nis``), update with ``z`` of ``hx`` rows ``idx``.

        A rejected epoch (NIS above ``max_nis``) keeps the prediction. Returns the
        prior innovation and its covariance (``y``, ``Pzz``).
        """
        idx = np.arange(len(self.R)) if idx is None else np.asarray(idx)
        H, y, S, R = self._prior(fx, z, hx, idx)
        self.rejected = max_nis is not None and nis(y, S) > max_nis
        if self.rejected:
            self._learn_rejected(y, S, H @ self.P @ H.T, idx)
        else:
            self._update(H, z, y, S, R, idx)
        return self.last

    def _learn_rejected(self, y, S, HPH, idx):
        """Learn from a rejected epoch (module docstring); the plain KF does not adapt."""

    def _update(self, H, z, y, S, R, idx):
        K = np.linalg.solve(S, H @ self.P).T
        self.x = self.x + K @ y
        I_KH = np.eye(len(self.x)) - K @ H
        P = I_KH @ self.P @ I_KH.T + K @ R @ K.T
        self.P = 0.5 * (P + P.T)


class VBAKF(KF):
    """Variational-Bayes adaptive KF estimating a diagonal R (Sarkka & Nummenmaa 2009).

    ``rho``: forgetting factor of the inverse-Gamma parameters (seed 001 sec. 3.2:
    0.95 for every element); ``n_iter``: fixed-point iterations per epoch. The prior
    counts the nominal R as one memory's worth of epochs (``alpha0 = 0.5 / (1 - rho)``).
    """

    def __init__(self, x0, P0, Q, R, rho=0.95, n_iter=5):
        super().__init__(x0, P0, Q, R)
        self.rho = float(rho)
        self.n_iter = int(n_iter)
        self.alpha = np.full(len(self.R), 0.5 / max(1.0 - self.rho, 1e-6))
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
        self.beta[idx] = self.rho * self.beta[idx] + 0.5 * _rejected_noise(y, S, HPH)
        self.R = self.R_prior()


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

    Measurement subsets (``idx`` of fewer than M rows): the sub-block of ``U`` is
    updated; the other entries are rescaled so their R estimate is kept (an
    inverse-Wishart marginal has the same ``u - M - 1`` as the full one).
    """

    def __init__(self, x0, P0, Q, R, tau=6.0, rho=0.95, n_iter=5, u0=None, moment='mean'):
        super().__init__(x0, P0, Q, R)
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
        self.u, self.U = u_new, 0.5 * (U_new + U_new.T)
        self.R = self.U / (self.u - M - 1.0)                             # eq. 38

    def _learn_rejected(self, y, S, HPH, idx):
        u_p, U_p, U_sub, d_sub = self._r_prior(idx)
        self._absorb(u_p, U_p, d_sub, U_sub, np.diag(_rejected_noise(y, S, HPH)), idx)

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


class UKF(KF):
    """Scaled unscented Kalman filter (seed 003 eq. 4-15) with the common interface.

    ``alpha``, ``beta``, ``kappa``: sigma-point scaling (defaults 1, 2, 0: the points at
    ``sqrt(n)`` sigma, the spread a large heading error needs; ``alpha`` 1e-3 gives the
    textbook near-linear points).
    """

    def __init__(self, x0, P0, Q, R, alpha=1.0, beta=2.0, kappa=0.0):
        super().__init__(x0, P0, Q, R)
        self.sp = dict(alpha=alpha, beta=beta, kappa=kappa)

    def predict(self, fx):
        """Unscented time update (eq. 5-10)."""
        self.x, self.P, _ = ukf_predict(self.x, self.P, fx, self.Q, **self.sp)
        return self.x, self.P

    def step(self, fx, z, hx, idx=None, max_nis=None):
        """Unscented time and measurement update (eq. 6-15); gate as :meth:`KF.step`."""
        idx = np.arange(len(self.R)) if idx is None else np.asarray(idx)
        self.predict(fx)
        xp, Pp = self.x, self.P
        x, P, y, S = ukf_update(xp, Pp, z, hx, self.R[np.ix_(idx, idx)], **self.sp)
        self.last = _Innovation(y, S)
        self.rejected = max_nis is not None and nis(y, S) > max_nis
        if not self.rejected:
            self.x, self.P = x, P
        return self.last
