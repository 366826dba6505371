"""Robust large-misalignment alignment of a USV in severe sea (seed 004): VBCKF and VBCH.

The full strapdown mechanization runs at IMU rate; at every GNSS epoch the 12-state
large-misalignment model (:mod:`~sins_align_ros.models.large_misalignment`, seed 004
eq. 3-5) is propagated over the interval by RK4 at the interval's mean specific
force, velocity and attitude, updated with the INS minus GNSS velocity by the
variational-Bayes cubature filter (:class:`~sins_align_ros.filters.vb.VBCKF`) or the
cubature H-infinity one (:class:`~sins_align_ros.filters.vb.VBCH`), and the
misalignment and velocity estimates are fed back into the mechanization (closed
loop); the position is reset to the fix (it is not a state). Gyro drift and
accelerometer bias stay in the filter, in the body frame, so a feedback does not
turn them.

The GNSS bookkeeping (intervals without a fix, the optional innovation gate with
forced acceptances) is :class:`~sins_align_ros.align.moving.MovingBaseAlignment`'s.
"""
import math

import numpy as np

from ..filters.cubature import batched
from ..filters.vb import VBCH, VBCKF
from ..models import large_misalignment as lm
from ..nav import earth
from ..nav.frames import orthonormalize
from .moving import GnssFix, MovingBaseAlignment


def model_noise(sigma_phi, sigma_v, noise, q_drift):
    """P0 (12, 12) and Qc (12,) of the 12-state model for sensors ``noise``.

    ``sigma_phi`` (3,) initial misalignment sigma (rad), ``sigma_v`` velocity sigma (m/s),
    ``noise`` a :class:`~sins_align_ros.models.stationary.NoiseSpec` (SI units; its
    gyro bias includes the Gauss-Markov part), ``q_drift`` the drift random walk
    density (rad^2/s^3). Bias sigmas have floors of 1e-3 deg/h and 1 micro-g.
    """
    P0 = np.diag(np.r_[np.asarray(sigma_phi) ** 2, [sigma_v ** 2] * 3,
                       [max(noise.gyro_bias, 1e-3 * math.pi / 180 / 3600) ** 2] * 3,
                       [max(noise.accel_bias, 1e-6 * earth.G0) ** 2] * 3])
    Qc = np.r_[[noise.gyro_arw ** 2] * 3, [noise.accel_vrw ** 2] * 3, [q_drift] * 3,
               [0.0] * 3]
    return P0, Qc


class RobustAlignment(MovingBaseAlignment):
    """Mechanization + seed 004 filter; see the module docstring.

    Parameters
    ----------
    C_b_n, v_n, lat, lon, h
        Initial attitude (body FLU -> ENU), ENU velocity (m/s) and position (rad, rad, m).
    P0 : ndarray (12, 12)
        Initial covariance (``large_misalignment.LABELS``).
    Qc : ndarray (12,)
        Continuous-time noise densities; Q of an interval T is ``diag(Qc) T``.
    R : ndarray (3, 3)
        Nominal velocity measurement noise, (m/s)^2 (the VB estimate starts there).
    robust : bool
        VBCH (True) or VBCKF (False).
    rho, n_iter, C, dof
        VB forgetting factor, iterations per epoch, robust-factor constant, Student-t
        outlier degrees of freedom (None: off) (:mod:`~sins_align_ros.filters.vb`).
    gate_probability, gate_max_rejects
        As :class:`~sins_align_ros.align.moving.MovingBaseAlignment` (None: no gate).
    """

    i_phi, i_v, i_eps = lm.I_PHI, lm.I_V, lm.I_EPS
    gate_sizes = (3,)

    def __init__(self, C_b_n, v_n, lat, lon, h, P0, Qc, R, robust=True, rho=0.98,
                 n_iter=20, C=1.5, dof=None, gate_probability=None, gate_max_rejects=10):
        super().__init__(C_b_n, v_n, lat, lon, h, P0, Qc, R, use_velocity=True,
                         square_root=False, gate_probability=gate_probability,
                         gate_max_rejects=gate_max_rejects)
        Q = np.diag(self.Qc)
        if robust:
            self.kf = VBCH(np.zeros(lm.N_STATES), P0, Q, R, lm.L_attitude(), rho=rho,
                           n_iter=n_iter, C=C, dof=dof)
        else:
            self.kf = VBCKF(np.zeros(lm.N_STATES), P0, Q, R, rho=rho, n_iter=n_iter, dof=dof)
        self.rows = np.array([3, 4, 5])
        self._C_sum = np.zeros((3, 3))

    def _accumulate(self, C, dt):
        """Also the mean attitude of the interval (the bias terms are linear in it)."""
        super()._accumulate(C, dt)
        self._C_sum += C * dt

    def _restart_interval(self):
        super()._restart_interval()
        self._C_sum = np.zeros((3, 3))

    def _transition(self):
        T = self._T
        if T <= 0.0:
            return batched(lambda X: X)
        f_n, v_n, C = self._dv_sum / T, self._v_sum / T, self._C_sum / T
        lat, h = self.mech.lat, self.mech.h
        sub = max(1, int(math.ceil(T / 1.0)))
        return batched(lambda X: lm.propagate(X, f_n, v_n, C, lat, h, T, substeps=sub))

    def measurement(self, fix, t_now):
        """INS minus GNSS ENU velocity (m/s), (3,), and its rows ``[0, 1, 2]``."""
        return self.mech.v_n - np.asarray(fix.v_n, dtype=float), np.arange(3)

    def update(self, fix, t_now):
        """Filter epoch for ``fix`` (which must carry a velocity): predict, update, feed back.

        A fix without velocity only resets the position.
        """
        if fix.v_n is None:
            self._feedback_position(fix)
            return None
        return super().update(fix, t_now)

    def _feedback(self, fix):
        """Move the estimated misalignment and velocity error into the mechanization."""
        m, kf = self.mech, self.kf
        x = kf.x
        m.C_b_n = orthonormalize(lm.C_n_nprime(x[lm.I_PHI]).T @ m.C_b_n)
        dv = x[lm.I_V].copy()
        m.v_n = m.v_n - dv
        m._v_prev = m._v_prev - dv
        kf.x[:6] = 0.0
        if fix is not None:
            self._feedback_position(fix)

    def _feedback_position(self, fix):
        m = self.mech
        new = np.array([fix.lat, fix.lon, fix.h])
        m._pos_prev = m._pos_prev + (new - np.array([m.lat, m.lon, m.h]))
        m.lat, m.lon, m.h = (float(v) for v in new)

    @staticmethod
    def _gnss_fix(gnss, i):
        """Epoch ``i`` with its ENU velocity ``gnss.v_n[i]``; None without a fix."""
        if hasattr(gnss, 'fix') and not gnss.fix[i]:
            return None
        return GnssFix(gnss.t[i], gnss.lat[i], gnss.lon[i], gnss.h[i], gnss.v_n[i])

    def attitude_cov(self):
        """Misalignment covariance about ENU (3, 3), rad^2."""
        return self.kf.P[lm.I_PHI, lm.I_PHI]

    def status(self):
        """Filter internals for diagnostics: the seed 000 engine's, plus the VB ones."""
        kf = self.kf
        s = super().status()
        s.update({'gnss_outliers_judged': int(kf.n_outliers),
                  'gnss_downweighted': int(kf.n_downweighted), 'noise_scale': float(kf.lam_t),
                  'accel_bias_ug': [float(v) for v in kf.x[lm.I_NAB] / (earth.G0 * 1e-6)]})
        if kf.robust:
            s['robust_gamma'] = kf.gamma
        return s
