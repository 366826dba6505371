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

Without GNSS for :data:`MAX_PREDICT` seconds the filter predicts without an
update, so an outage only widens the covariance.
"""
import math
from dataclasses import dataclass

import numpy as np

from ..filters.asckf import ASCKF, CKF
from ..filters.cubature import batched
from ..filters.kf import chi2_quantile, nis
from ..models import large_azimuth as la
from ..nav import earth
from ..nav.frames import orthonormalize
from ..nav.mechanization import MechanizationOptions, Strapdown

I_V, I_P, I_PHI, I_EPS = slice(0, 2), slice(2, 4), slice(4, 7), slice(7, 10)
#: default fading proportions (seed 000 eq. 8): velocity, position and misalignment fade,
#: the gyro drift does not (fading a random constant with a 1e-16 variance made every
#: run diverge in bench/moving_base.py: the factors compound over the V_k memory)
ALPHA = np.r_[np.ones(7), np.zeros(3)]
#: fading only while the innovations of the last 10 epochs are too large for their
#: covariance (99%) and keep their sign (lag-1 correlation above 0.5, about 2.2 sigma
#: for white 2-vectors): see ASCKF ``whiteness``
WHITENESS = (10, 0.5)
#: the longest interval the error model is propagated without a measurement, s
MAX_PREDICT = 2.0
#: forced acceptances (after ``gate_max_rejects`` rejections each) in a row after which the
#: inertial solution and GNSS are taken to disagree for good: the caller restarts alignment
MAX_FORCED = 3


class FilterDiverged(RuntimeError):
    """The filter's numbers became non-finite or singular; the caller restarts alignment."""


@dataclass
class GnssFix:
    """One GNSS epoch: position (rad, rad, m), optional ENU velocity (3,) and variances.

    ``pos_var`` (2,): east and north position variance (m^2) the receiver reports,
    or None; ``vel_var`` (2,): east and north velocity variance ((m/s)^2) or None.
    """

    t: float
    lat: float
    lon: float
    h: float
    v_n: np.ndarray = None
    pos_var: np.ndarray = None
    vel_var: np.ndarray = None


class MovingBaseAlignment:
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
    gate_probability : float or None
        GNSS innovation gate (not in the seed; None: off): an epoch whose
        normalised innovation squared exceeds the chi-square quantile of this
        probability (m degrees of freedom) is rejected as an outlier.
    gate_max_rejects : int
        After this many rejected epochs in a row the next one is accepted with the
        position and velocity variances widened by the last rejected innovation
        squared (a position jump, or the filter lagging behind a true change,
        then re-anchors to GNSS instead of being rejected for ever); if that
        happens :data:`MAX_FORCED` times without ``gate_max_rejects`` accepted
        epochs in between, :meth:`update` raises :class:`FilterDiverged`.
    """

    i_phi, i_v, i_eps = I_PHI, I_V, I_EPS
    #: measurement sizes whose gate thresholds the status reports
    gate_sizes = (2, 4)

    def __init__(self, C_b_n, v_n, lat, lon, h, P0, Qc, R, use_velocity=False,
                 square_root=True, fading=True, adaptive=True, use_reported_cov=False,
                 alpha=ALPHA, rho=0.95, beta=3.0, b=0.97, gate=False, lambda_max=np.inf,
                 adapt_q=False, r_ceiling=1e4, fading_gate=None, whiteness=WHITENESS,
                 cap_at_p0=True, gate_probability=None, gate_max_rejects=10):
        self.mech = Strapdown(C_b_n, v_n, lat, lon, h, MechanizationOptions())
        self.Qc = np.asarray(Qc, dtype=float)
        self.use_velocity = bool(use_velocity)
        self.rows = np.array([2, 3, 0, 1] if use_velocity else [2, 3])
        R = np.asarray(R, dtype=float)
        if square_root:
            self.kf = ASCKF(np.zeros(la.N_STATES), P0, np.diag(self.Qc), R, fading=fading,
                            adaptive=adaptive, alpha=alpha, rho=rho, beta=beta, b=b, gate=gate,
                            lambda_max=lambda_max, adapt_q=adapt_q, r_ceiling=r_ceiling,
                            r_when_identifiable=True, fading_gate=fading_gate,
                            whiteness=whiteness,
                            var_max=np.diag(P0).copy() if cap_at_p0 else None)
        else:
            self.kf = CKF(np.zeros(la.N_STATES), P0, np.diag(self.Qc), R)
        self.adaptive = bool(square_root and adaptive)
        self.use_reported_cov = bool(use_reported_cov) and not self.adaptive
        self.R_nominal = R.copy()
        self._T = 0.0
        self._dv_sum = np.zeros(3)
        self._v_sum = np.zeros(3)
        self.n_updates = 0
        self.n_predict_only = 0
        self.last_nis = float('nan')
        self.gate_probability = gate_probability
        self.gate_max_rejects = int(gate_max_rejects)
        self.n_rejected = self.n_forced = 0
        self.consecutive_rejects = self._accepted_run = self._forced_run = 0
        self._y_rejected = None
        #: (t, NIS, threshold) of the last rejected epoch
        self.last_rejection = None

    # -- IMU rate -------------------------------------------------------------------
    def step_imu(self, dtheta, dv, dt):
        """Mechanize one sample; returns the current ``C_b_n`` (3, 3)."""
        m = self.mech
        C = m.step(dtheta, dv, dt)
        self._accumulate(C, dt)
        if self._T >= MAX_PREDICT:
            fx = self._transition()
            self._set_process_noise()
            self.kf.predict(fx)
            self.n_predict_only += 1
            self._restart_interval()
        return C

    def _accumulate(self, C, dt):
        """Add one sample to the interval's sums (force, velocity) the transition uses."""
        m = self.mech
        self._T += dt
        self._dv_sum += m.dv_sf
        self._v_sum += m.v_n * dt

    def _set_process_noise(self):
        """Q of the interval since the last epoch; the adaptive filter keeps its estimate."""
        if not self.adaptive:
            self.kf.Q = np.diag(self.Qc * max(self._T, 1e-3))

    def _restart_interval(self):
        self._T = 0.0
        self._dv_sum = np.zeros(3)
        self._v_sum = np.zeros(3)

    def _transition(self):
        """Batched ``f(x)`` over the interval since the last filter epoch."""
        T = self._T
        if T <= 0.0:
            return batched(lambda X: X)
        f_n = self._dv_sum / T
        v_n = self._v_sum / T
        lat, h = self.mech.lat, self.mech.h
        sub = max(1, int(math.ceil(T / 1.0)))
        return batched(lambda X: la.propagate(X, f_n, v_n, lat, h, T, substeps=sub))

    # -- GNSS epochs ------------------------------------------------------------------
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

    def update(self, fix, t_now):
        """Filter epoch for ``fix``: predict over the interval, update, feed back.

        Returns the :class:`~sins_align_ros.filters.cubature.CubatureUpdate`.
        """
        z, idx = self.measurement(fix, t_now)
        fx = self._transition()
        rows = self.rows[idx]
        hx = batched(lambda X: X[rows])
        kf = self.kf
        self._set_process_noise()
        if self.use_reported_cov:          # never for the adaptive filter (see __init__)
            kf.R = self.R_nominal.copy()
            if fix.pos_var is not None:
                kf.R[0, 0], kf.R[1, 1] = fix.pos_var
            if self.use_velocity and fix.vel_var is not None:
                kf.R[2, 2], kf.R[3, 3] = fix.vel_var
        max_nis = self._gate(len(idx), rows)
        try:
            upd = kf.step(fx, z, hx, idx, max_nis=max_nis)
            self.last_nis = nis(upd.y, upd.Pzz)
        except (np.linalg.LinAlgError, ValueError):
            upd = None
        if upd is None or not (np.all(np.isfinite(kf.x)) and np.all(np.isfinite(kf.P))):
            raise FilterDiverged(f'filter diverged at t={fix.t:.3f} s (non-finite or '
                                 f'singular covariance)')
        self._restart_interval()
        if kf.rejected:
            self.n_rejected += 1
            self.consecutive_rejects += 1
            self._accepted_run = 0
            self._y_rejected = (rows, upd.y.copy())
            self.last_rejection = (fix.t, self.last_nis, max_nis)
            self._feedback(None)
            return upd
        self.n_updates += 1
        self.consecutive_rejects = 0
        self._accepted_run += 1
        if self._accepted_run >= self.gate_max_rejects:
            self._forced_run = 0
        self._feedback(fix)
        return upd

    def _gate(self, m, rows):
        """NIS threshold of this epoch, or None (gate off, or a forced acceptance).

        A forced acceptance first widens the variances of the measured states by
        the last rejected innovation squared (see ``gate_max_rejects``).
        """
        if self.gate_probability is None:
            return None
        if self.consecutive_rejects < self.gate_max_rejects:
            return self._threshold(m)
        self._forced_run += 1
        if self._forced_run >= MAX_FORCED:
            raise FilterDiverged(
                f'GNSS rejected by the innovation gate {self.gate_max_rejects} epochs in a row, '
                f'{MAX_FORCED} times without recovering: the inertial solution and GNSS '
                'disagree')
        r_rej, y_rej = self._y_rejected
        P = self.kf.P
        P[r_rej, r_rej] += y_rej ** 2
        self.kf.P = P
        self.n_forced += 1
        self.consecutive_rejects = 0
        return None

    def _threshold(self, m):
        """Chi-square quantile of ``gate_probability`` for ``m`` measurements."""
        return chi2_quantile(self.gate_probability, m)

    def _feedback(self, fix):
        """Move the estimated errors into the mechanization (closed loop).

        ``fix`` None (a rejected epoch): the predicted errors only; the vertical
        channel is not touched.
        """
        m, kf = self.mech, self.kf
        x = kf.x
        C_n_np = la.C_n_nprime(x[I_PHI])
        m.C_b_n = orthonormalize(C_n_np.T @ m.C_b_n)
        dv = np.array([x[0], x[1], 0.0])
        m.v_n = m.v_n - dv
        m._v_prev = m._v_prev - dv
        R_M, R_N = earth.radii(m.lat)
        dlat = x[3] / (R_M + m.h)
        dlon = x[2] / ((R_N + m.h) * math.cos(m.lat))
        m.lat -= dlat
        m.lon -= dlon
        m._pos_prev = m._pos_prev - np.array([dlat, dlon, 0.0])
        # vertical channel: not in the model; held to the GNSS height (and velocity)
        if fix is not None:
            m.h = fix.h
            m.v_n[2] = fix.v_n[2] if fix.v_n is not None else 0.0
            m._pos_prev[2] = fix.h
        # the corrected frame differs from the old computed one by C_n^n'^T: turn the
        # drift (resolved in the computed frame) and the residual tilts with it
        T = np.eye(la.N_STATES)
        T[I_PHI, I_PHI] = C_n_np.T
        T[I_EPS, I_EPS] = C_n_np.T
        kf.transform(T)
        kf.x[:7] = 0.0

    def feed(self, imu, gnss, t0):
        """Run samples 1..N-1 of ``imu`` (``t``, ``dtheta``, ``dv``) from stamp ``t0 = imu.t[0]``.

        GNSS epochs of ``gnss`` (``t``, ``lat``, ``lon``, ``h``; rad, rad, m) after
        ``t0`` are applied at the first sample at or past their stamp. Raises
        :class:`FilterDiverged` as :meth:`update` does.
        """
        gi, t_prev = 0, t0
        for k in range(1, len(imu.t)):
            t = imu.t[k]
            self.step_imu(imu.dtheta[k], imu.dv[k], t - t_prev)
            t_prev = t
            while gi < len(gnss.t) and gnss.t[gi] <= t + 1e-9:
                fix = self._gnss_fix(gnss, gi) if gnss.t[gi] > t0 else None
                if fix is not None:
                    self.update(fix, t)
                gi += 1

    @staticmethod
    def _gnss_fix(gnss, i):
        """Epoch ``i`` of the arrays given to :meth:`feed` as a :class:`GnssFix` (or None)."""
        return GnssFix(gnss.t[i], gnss.lat[i], gnss.lon[i], gnss.h[i])

    # -- output -------------------------------------------------------------------------
    @property
    def P(self):
        """Error-state covariance (10, 10)."""
        return self.kf.P

    def attitude_cov(self):
        """Misalignment covariance about ENU (3, 3), rad^2."""
        return self.kf.P[I_PHI, I_PHI]

    def status(self):
        """Filter internals for diagnostics (plain Python types)."""
        kf = self.kf
        s = {'filter_updates': self.n_updates, 'predict_only_epochs': self.n_predict_only,
             'innovation_nis': self.last_nis, 'divergence_test_fired': kf.divergence_flags,
             'Q_diag': [float(v) for v in np.diag(kf.Q)],
             'R_diag': [float(v) for v in np.diag(kf.R)],
             'gyro_drift_dph': [float(v) for v in kf.x[self.i_eps] / (math.pi / 180.0 / 3600.0)]}
        if self.gate_probability is not None:
            s.update({'gnss_gate_probability': self.gate_probability,
                      'gnss_gate_threshold': [self._threshold(m) for m in self.gate_sizes],
                      'gnss_rejected': self.n_rejected, 'gnss_forced': self.n_forced,
                      'gnss_consecutive_rejects': self.consecutive_rejects})
        if getattr(kf, 'lam', None) is not None:
            s['fading_factors'] = [float(v) for v in kf.lam]
            s['fading_epochs'] = int(kf.n_faded)
        return s
