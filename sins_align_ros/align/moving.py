"""Moving-base GNSS-aided fine alignment with a large heading error (seed 000).

The full strapdown mechanization (transport rate, Coriolis, position) runs at
IMU rate; at every GNSS epoch the 10-state large-azimuth error model
(:mod:`~sins_align_ros.models.large_azimuth`, seed 000 eq. 1-6) is propagated
over the interval by RK4 at the interval's mean specific force and velocity,
updated with the GNSS position difference (and optionally velocity), and its
misalignment, velocity and position estimates are fed back into the
mechanization (closed loop). The gyro drift state stays in the filter; it is
resolved in the computed frame, so a heading correction turns it too.

Filters (switchable one improvement at a time, seed 000 sec. 3):
``square_root=False`` is the conventional CKF (eq. 22-34); with
``square_root=True`` the QR square-root CKF, plus ``fading`` (multiple fading
factors, eq. 7-17, 35) and ``adaptive`` (Sage-Husa Q/R with the divergence
test, eq. 39, 20). All three on is the ASCKF.

The IMU-rate driver, the GNSS epochs and the innovation gate are
:class:`~.aided.GnssAidedEngine`'s.
"""
import math

import numpy as np

from ..filters.asckf import ASCKF
from ..filters.ckf import CKF
from ..filters.cubature import batched
from ..models import large_azimuth as la
from ..nav import earth
from ..nav.frames import orthonormalize
from .aided import GnssAidedEngine, GnssFix
from .gnss_gate import FilterDiverged, GnssGate  # noqa: F401  (FilterDiverged re-exported)

I_V, I_P, I_PHI, I_EPS = slice(0, 2), slice(2, 4), slice(4, 7), slice(7, 10)
#: default fading proportions (seed 000 eq. 8): velocity, position and misalignment fade,
#: the gyro drift does not (fading a random constant with a 1e-16 variance made every
#: run diverge in bench/moving_base.py: the factors compound over the V_k memory)
ALPHA = np.r_[np.ones(7), np.zeros(3)]
#: fading only while the innovations of the last 10 epochs are too large for their
#: covariance (99%) and keep their sign (lag-1 correlation above 0.5, about 2.2 sigma
#: for white 2-vectors): see ASCKF ``whiteness``
WHITENESS = (10, 0.5)


class MovingBaseAlignment(GnssAidedEngine):
    """Mechanization + seed 000 filter; see the module docstring.

    ``i_phi``, ``i_v``, ``i_eps``: the misalignment, velocity-error and gyro-drift slices
    of the state.

    Parameters
    ----------
    C_b_n : ndarray (3, 3)
        Initial attitude (from coarse alignment), body FLU -> ENU.
    v_n : ndarray (3,)
        Initial ENU velocity, m/s.
    lat, lon, h : float
        Initial position (rad, rad, m).
    P0 : ndarray (10, 10)
        Initial covariance of the error state (see ``large_azimuth.LABELS``).
    Qc : ndarray (10,)
        Continuous-time noise densities (per second); the discrete Q of an
        interval T is ``diag(Qc) T``. The adaptive filter starts from ``Qc * 1 s``.
    R : ndarray (m, m)
        Measurement noise: position east/north (m^2), then velocity east/north
        ((m/s)^2) when ``use_velocity``.
    use_velocity : bool
        Measure the GNSS velocity as well as the position.
    square_root, fading, adaptive : bool
        Which of seed 000's filters (module docstring).
    use_reported_cov : bool
        Take R from each fix's reported variances (non-adaptive filters only).
    alpha, rho, beta, b, gate, lambda_max, adapt_q, r_ceiling, fading_gate, whiteness
        Strong-tracking and Sage-Husa settings (:class:`~sins_align_ros.filters.asckf.ASCKF`).
        Defaults differ from the seed in documented ways: ``alpha`` (:data:`ALPHA`)
        keeps the drift states out of the fading; ``adapt_q=False`` estimates R
        only (adapting Q as well let Q absorb the measurement noise and the filter
        diverged); ``gate=False`` lets R fall as well as rise (with the seed's
        eq. 20 gate R is only ever updated from large innovations and ran away to
        1e8 times the truth after a 3 deg heading error met a 0.1 g acceleration);
        ``r_ceiling`` bounds R at 1e4 times its initial value; the fading applies
        only while the innovations of the last epochs are too large *and* keep
        their sign (:data:`WHITENESS`; the seed's V_k is mostly the last two
        innovations, so ungated, chance fluctuations faded the covariance again
        and again, and with filter Q nine times the truth compounded to 9 deg of
        tilt sigma and a singular innovation covariance; a per-epoch chi-square
        gate alone still faded the heading through the 10x GNSS noise window of
        the wrong-noise benchmark until the filter diverged: that noise is large
        but white, and goes to R); R is learnt only
        from epochs where it dominates the innovation covariance (a 30 deg heading
        error met by an acceleration otherwise drove R to 5000 times the truth).
    cap_at_p0 : bool
        The fading never makes a variance larger than its P0 (not in the seed):
        a weakly observable heading faded epoch after epoch otherwise grows
        without bound. With an over-confident P0 this also keeps the fading from
        rescuing it; start from an honest P0 (the pipeline's coarse stage does).
    gate_probability, gate_max_rejects
        The GNSS innovation gate (not in the seed; None: off), :class:`~.gnss_gate.GnssGate`.
    """

    i_phi, i_v, i_eps = I_PHI, I_V, I_EPS
    #: the 10-state model has no accelerometer bias: bias / g is added to the tilt
    has_accel_bias = False

    def __init__(self, C_b_n, v_n, lat, lon, h, P0, Qc, R, use_velocity=False,
                 square_root=True, fading=True, adaptive=True, use_reported_cov=False,
                 alpha=ALPHA, rho=0.95, beta=3.0, b=0.97, gate=False, lambda_max=np.inf,
                 adapt_q=False, r_ceiling=1e4, fading_gate=None, whiteness=WHITENESS,
                 cap_at_p0=True, gate_probability=None, gate_max_rejects=10):
        Qc = np.asarray(Qc, dtype=float)
        R = np.asarray(R, dtype=float)
        if square_root:
            kf = ASCKF(np.zeros(la.N_STATES), P0, np.diag(Qc), R, fading=fading,
                       adaptive=adaptive, alpha=alpha, rho=rho, beta=beta, b=b, gate=gate,
                       lambda_max=lambda_max, adapt_q=adapt_q, r_ceiling=r_ceiling,
                       r_when_identifiable=True, fading_gate=fading_gate, whiteness=whiteness,
                       var_max=np.diag(P0).copy() if cap_at_p0 else None)
        else:
            kf = CKF(np.zeros(la.N_STATES), P0, np.diag(Qc), R)
        super().__init__(C_b_n, v_n, lat, lon, h, kf, Qc, R,
                         rows=[2, 3, 0, 1] if use_velocity else [2, 3],
                         gate=GnssGate(gate_probability, gate_max_rejects, sizes=(2, 4)),
                         use_velocity=use_velocity, adaptive=square_root and adaptive,
                         use_reported_cov=use_reported_cov)

    def _transition(self):
        """Batched ``f(x)`` over the interval since the last filter epoch."""
        s = self.sums
        T = s.T
        if T <= 0.0:
            return batched(lambda X: X)
        f_n = s.dv_sum / T
        v_n = s.v_sum / T
        lat, h = self.mech.lat, self.mech.h
        sub = max(1, int(math.ceil(T / 1.0)))
        return batched(lambda X: la.propagate(X, f_n, v_n, lat, h, T, substeps=sub))

    def measurement(self, fix, t_now):
        """Innovation vector of a fix taken at ``fix.t`` <= ``t_now`` (the last IMU stamp).

        Returns ``(z, idx)``: position difference east/north (m), then velocity
        difference (m/s) when the fix has one and velocity is used; ``idx`` the
        rows of the full measurement vector present.
        """
        m = self.mech
        back = max(0.0, t_now - fix.t)
        R_M, R_N = earth.radii(m.lat)
        lat = m.lat - m.v_n[1] * back / (R_M + m.h)
        lon = m.lon - m.v_n[0] * back / ((R_N + m.h) * math.cos(m.lat))
        z = [(lon - fix.lon) * (R_N + m.h) * math.cos(m.lat), (lat - fix.lat) * (R_M + m.h)]
        idx = [0, 1]
        if self.use_velocity and fix.v_n is not None:
            z += [m.v_n[0] - fix.v_n[0], m.v_n[1] - fix.v_n[1]]
            idx += [2, 3]
        return np.array(z), np.array(idx)

    def _feedback(self, fix):
        """Move the estimated errors into the mechanization (closed loop).

        ``fix`` None (a rejected epoch): the predicted errors only; the vertical
        channel is not touched.
        """
        m, kf = self.mech, self.kf
        x = kf.x
        C_n_np = la.C_n_nprime(x[I_PHI])
        m.C_b_n = orthonormalize(C_n_np.T @ m.C_b_n)
        m.correct_velocity(np.array([x[0], x[1], 0.0]))
        R_M, R_N = earth.radii(m.lat)
        m.correct_position(np.array([x[3] / (R_M + m.h),
                                     x[2] / ((R_N + m.h) * math.cos(m.lat)), 0.0]))
        # vertical channel: not in the model; held to the GNSS height (and velocity)
        if fix is not None:
            m.hold_vertical(fix.h, fix.v_n[2] if fix.v_n is not None else 0.0)
        # the corrected frame differs from the old computed one by C_n^n'^T: turn the
        # drift (resolved in the computed frame) and the residual tilts with it
        T = np.eye(la.N_STATES)
        T[I_PHI, I_PHI] = C_n_np.T
        T[I_EPS, I_EPS] = C_n_np.T
        kf.transform(T)
        kf.x[:7] = 0.0

    @staticmethod
    def _gnss_fix(gnss, i):
        """Epoch ``i`` of the arrays given to :meth:`feed` (position only)."""
        return GnssFix(gnss.t[i], gnss.lat[i], gnss.lon[i], gnss.h[i])
