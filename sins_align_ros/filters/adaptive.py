"""Adaptive layers of seed 000: strong tracking fading factors and the Sage-Husa estimator.

* :class:`StrongTracking` — multiple fading factors computed from the cubature
  covariances instead of Jacobians (seed 000 eq. 7-17).
* :class:`SageHusa` — the improved time-varying noise estimator (eq. 39) with the
  divergence test (eq. 20-21).
"""
import numpy as np

from .kf import CLIP


class StrongTracking:
    """Multiple fading factors (seed 000 eq. 7-17).

    Parameters
    ----------
    alpha : array_like (n,)
        Per-state proportions ``alpha_i`` (eq. 8), from prior knowledge.
    rho : float
        Forgetting factor of the innovation covariance ``V_k`` (eq. 10), 0 < rho <= 1.
    beta : float
        Weakening factor (eq. 9), usually 3.
    lambda_max : float
        Upper bound of each factor (not in the seed; see ``align/engines/moving.py``).
        ``alpha_i = 0`` keeps state i free of fading (its factor is 1).
    """

    def __init__(self, alpha, rho=0.95, beta=3.0, lambda_max=np.inf):
        self.alpha = np.asarray(alpha, dtype=float)
        self.lambda_max = float(lambda_max)
        self.rho = float(rho)
        self.beta = float(beta)
        self.V = None
        self.lambda0 = 1.0

    def factors(self, y, P_pred, Pxz, Q, R):
        """Fading factors ``lambda_i`` (n,) from the un-faded prediction (superscript (l)).

        ``y`` innovation (m,); ``P_pred`` one-step covariance without fading;
        ``Pxz`` its cross covariance with the measurement; ``Q``, ``R`` noise.
        :meth:`add_innovation` then :meth:`current_factors`.
        """
        self.add_innovation(y)
        return self.current_factors(P_pred, Pxz, Q, R)

    def add_innovation(self, y):
        """Take the epoch's innovation ``y`` (m,) into its covariance ``V_k`` (eq. 10).

        Every epoch, whether its factors are wanted or not (:meth:`current_factors`).
        """
        yy = np.outer(y, y)
        self.V = yy if self.V is None else (self.rho * self.V + yy) / (1.0 + self.rho)  # eq. 10

    def current_factors(self, P_pred, Pxz, Q, R):
        """Fading factors ``lambda_i`` (n,) with the current ``V_k`` (eq. 8-16).

        Arguments as :meth:`factors`'; after :meth:`add_innovation` of the epoch.
        """
        # eq. 13, H = Pxz^T P^-1, solved on the correlation matrix: P mixes
        # variances of metres and of micro-radians per second, so P itself is
        # too ill-conditioned (1e16 here) to be inverted as it stands
        d = np.sqrt(np.clip(np.diag(P_pred), 1e-300, None))
        Pn = P_pred / np.outer(d, d)
        H = np.linalg.solve(Pn, Pxz / d[:, None]).T / d[None, :]           # eq. 13
        N = self.V - self.beta * R - H @ Q @ H.T                             # eq. 14
        trM = np.trace(H @ (P_pred - Q) @ H.T)                               # tr of eq. 16
        self.lambda0 = np.trace(N) / trM if trM > 0 else 1.0                 # eq. 8
        lam = np.minimum(self.alpha * self.lambda0, self.lambda_max)
        return np.where(self.lambda0 > 1.0, np.maximum(lam, 1.0), 1.0)

    @staticmethod
    def sqrt_factors(lam):
        """Square roots of the factors, the form applied in eq. 35 (eq. 17)."""
        return np.sqrt(lam)


class SageHusa:
    """Improved Sage-Husa Q/R estimator (seed 000 eq. 39) with the divergence test (eq. 20).

    Parameters
    ----------
    Q0, R0 : ndarray
        Initial noise covariances.
    b : float
        Forgetting factor, 0 < b < 1 (0.95-0.99), giving ``d_k = (1-b)/(1-b^k)``.
    gate : bool
        Apply the divergence test of eq. 20 (the seed's algorithm). As written it
        updates R only from innovations larger than predicted, which biases R
        upwards; ``gate=False`` is the plain estimator of eq. 39.
    r_ceiling : float
        Largest eigenvalue of R, as a multiple of the initial mean variance.
    r_when_identifiable : bool
        Estimate R (its diagonal) only at epochs whose predicted innovation
        covariance is dominated by R (``tr(Pzz) <= 2 tr(R)``) and on the rows where
        it is (``Pzz_ii <= 2 R_ii``), not in a transient of the state, and from
        innovations winsorised at ``clip`` times their predicted variance, so that
        one outlier moves R by a bounded factor (not in the seed).
    clip : float
        Winsorising bound of ``y_i^2 / Pzz_ii`` (default
        :data:`~sins_align_ros.filters.kf.CLIP`, the 99.9% point of chi-square with
        one degree of freedom).
    adapt_q : bool
        Estimate Q as well (eq. 39). Q and R are not separately identifiable from
        the innovations of a weakly observable state; adapting both lets Q absorb
        measurement noise.
    prior_epochs : float or None
        Epochs of evidence the initial Q0 and R0 count as (not in the seed): the weight
        of epoch ``k`` is ``d_k = (1-b)/(1-b^(k + prior_epochs))``. The seed's
        ``d_k = (1-b)/(1-b^k)`` (``prior_epochs=0``) gives the first innovation weight 1,
        replacing the configured R by one squared innovation: on a moored ship (tactical
        IMU, seed 1001 of the integrity matrix) the GNSS velocity variance fell 10x at
        the second epoch, the filter pulled the heading 147 deg off and GNSS was rejected
        until alignment restarted. Default: the estimator's memory, ``1/(1-b)``, so the
        configured noise is worth as much as a memory of data.
    """

    def __init__(self, Q0, R0, b=0.97, gate=True, adapt_q=True, r_ceiling=np.inf,
                 r_when_identifiable=False, clip=CLIP, prior_epochs=None):
        self.gate = bool(gate)
        self.r_when_identifiable = bool(r_when_identifiable)
        self.adapt_q = bool(adapt_q)
        self.clip = float(clip)
        self.Q = np.array(Q0, dtype=float)
        self.R = np.array(R0, dtype=float)
        #: eigenvalue floor that keeps R positive definite (1e-3 of the initial mean variance)
        self.r_floor = 1e-3 * float(np.trace(self.R)) / len(self.R)
        #: eigenvalue ceiling of R as a multiple of the initial mean variance (not in the
        #: seed): a large model error (heading error in an acceleration) otherwise feeds
        #: a runaway, R up -> measurements ignored -> larger innovations -> R up
        self.r_ceiling = float(r_ceiling) * float(np.trace(self.R)) / len(self.R)
        #: per-row bounds of the diagonal estimate (same factors, each row's own start)
        self._r_lo = 1e-3 * np.diag(self.R).copy()
        self._r_hi = float(r_ceiling) * np.diag(self.R).copy()
        self.b = float(b)
        self.prior_epochs = 1.0 / (1.0 - self.b) if prior_epochs is None else float(prior_epochs)
        self.k = 0
        self.divergence_flags = 0

    def update(self, upd, idx=None, lent=None):
        """Update Q and R from a :class:`~sins_align_ros.filters.cubature.CubatureUpdate`.

        Eq. 20: if ``y^T y <= tr(E[y y^T])`` (the innovation is consistent with its
        predicted covariance) only Q is updated (eq. 21); otherwise both (eq. 39),
        following step 17 of the seed's algorithm. ``idx`` (m,): the rows of the
        full measurement vector this update used (default all); only that block
        of R is estimated. ``lent`` (len(R),): variances the update used on top of R
        because they are known (a lever arm's share of the attitude uncertainty,
        ``align/engines/aided.py``): they are taken out of the innovations' second moment like
        ``H P H^T``, and counted with it in the test of which rows R dominates; the
        estimate stays the receiver's own. Returns ``(Q, R)``.
        """
        self.k += 1
        d = (1.0 - self.b) / (1.0 - self.b ** (self.k + self.prior_epochs))
        y, K, eta = upd.y, upd.K, upd.eta
        if self.adapt_q:
            Ky = K @ y
            self.Q = (1.0 - d) * self.Q + d * np.outer(Ky, Ky)
        if float(y @ y) <= upd.Pzz.trace():
            if self.gate:
                return self.Q, self.R                                        # eq. 21
        else:
            self.divergence_flags += 1
        idx = np.arange(len(self.R)) if idx is None else np.asarray(idx)
        if self.r_when_identifiable:
            return self.Q, self._update_identifiable_rows(upd, idx, d, lent)
        blk = np.ix_(idx, idx)
        known = 0.0 if lent is None else np.diag(np.asarray(lent, dtype=float)[idx])
        R_new = (1.0 - d) * self.R[blk] + d * (np.outer(y, y) - eta @ eta.T - known)  # eq. 39
        # keep R positive definite: the subtraction may remove too much
        w, U = np.linalg.eigh(0.5 * (R_new + R_new.T))
        self.R = self.R.copy()
        self.R[blk] = (U * np.clip(w, self.r_floor, self.r_ceiling)) @ U.T
        return self.Q, self.R

    def _update_identifiable_rows(self, upd, idx, d, lent=None):
        """Diagonal eq. 39 on the rows where R dominates ``Pzz``, winsorised innovations.

        ``lent`` (len(R),) or None: known variances the update used on top of R
        (:meth:`update`); they are state uncertainty seen through the measurement, so
        they must not make a row look identifiable.
        """
        # array methods, not numpy's functions: a few rows, so their dispatch is the cost
        hph = (upd.eta * upd.eta).sum(axis=1)                     # diag(eta eta^T)
        r = self.R.diagonal()[idx]
        if lent is not None:
            hph = hph + np.asarray(lent, dtype=float)[idx]
        ok = hph <= r
        if not ok.any() or hph.sum() > r.sum():
            return self.R
        y2 = np.minimum(upd.y ** 2, self.clip * upd.Pzz.diagonal())
        r_new = (1.0 - d) * r + d * (y2 - hph)
        rows = idx[ok]
        self.R = self.R.copy()
        self.R[rows, rows] = np.minimum(np.maximum(r_new[ok], self._r_lo[rows]),
                                        self._r_hi[rows])
        return self.R
