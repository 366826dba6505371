"""Moving-base GNSS-aided fine alignment with a large heading error (seed 000).

The full strapdown mechanization (transport rate, Coriolis, position) runs at
IMU rate; at every GNSS epoch the large-azimuth error model
(:mod:`~sins_align_ros.models.large_azimuth`, seed 000 eq. 1-6) is propagated
over the interval by RK4 at the interval's mean specific force and velocity,
updated with the GNSS position difference (and optionally velocity), and its
misalignment, velocity and position estimates are fed back into the
mechanization (closed loop). The gyro drift state stays in the filter; it is
resolved in the computed frame, so a heading correction turns it too.

Drift in the body (where we differ from seed 000): the seed's drift states
``eps_E, eps_N, eps_U`` (eq. 4 and the state vector after eq. 5) are a random
constant in the navigation frame. A gyro bias is fixed in the body: resolved in the
computed frame it is ``C~_b_n eps_b`` and turns as the vehicle turns. So at the end of
each interval the drift state is turned by ``C~_now C~_last^T``, the computed attitude's
rotation since it was last turned (:meth:`MovingBaseAlignment._interval_ended`; a
feedback's correction turns it too, :meth:`MovingBaseAlignment._feedback`). Held
constant, the drift learnt before a ship's 80 deg turn no longer held after it and the
ASCKF's heading sigma came out too small: on the navigation-grade ``ship_underway``
(heading 100 deg, latitude 36 deg) with turn-on biases drawn per run, heading 1.25' RMS
under a 0.90' sigma and 4 of 20 runs silent wrong; turned, 0.51' under 0.66' and 1 of 20
(its east tilt; bench/results/asckf_ship.md). ``drift_in_body=False`` is the seed's model.

Model size (where we differ from seed 000): with ``accel_bias`` given (the pipeline
gives the configured ``accel_bias_ug``, :func:`model_noise`) the model has 13 states,
seed 000's 10 plus the accelerometer bias in body axes (a random constant; a random
walk of density ``accel_bias_q`` if one is given), which stays in the filter like the
drift and enters the velocity error through the interval's mean computed attitude. Seed
000's 10 states take a bias for a tilt of bias / g; when the ship turns the bias turns
with it and the 10-state filter put the difference into the heading (ship_underway,
bench/results/moving_base_integrity.md). Without
``accel_bias`` the engine is seed 000's 10-state model, and the pipeline adds bias / g
to its tilt variance instead (``has_accel_bias`` False).

Lost heading (where we differ from seed 000, as the navigation filters do,
:mod:`.navigation`): a heading handed over as an unknown angle (the coarse sigma beyond the
cubature cap :data:`~.prior_shaping.HEADING_PRIOR_MAX`: no track, a gyro that cannot gyrocompass)
is lost, and while it is the model is given the vertical specific force alone
(:meth:`~.force.ForceModel._drop_horizontal_force`): the turns' velocity error of a
heading anywhere in the circle is process noise, not heading information, until a
nonlinear acquisition (a straight leg's course, :mod:`.course_heading`, or an external
heading, taken directly) finds it, for at most :data:`~.force.LOST_WAIT_S`
(``hold_lost_heading``: the pipeline's while the course aid runs). The seed's
model reads it from the first turns: on a vibrating skid-steer robot at 1 m/s with RTK
velocities (robot:rtk, raw AHRS triads told right, seed 1001) the ASCKF claimed 8 deg of
sigma about a heading 48 deg off within 16 s of the fine stage (its cubature points
162 deg apart), the mounting check took the 48 deg for an IMU turned and untold, and the
run published nothing after; on others it claimed 4-6 deg about a heading 15-35 deg off
for minutes while the course aid, a bootstrap, never fed it (the heading looked found).
Held lost, the aid takes the first leg's course 10 s into the fine stage (turning the
heading by 91-175 deg on seeds 1000, 1001, 1005 of that cell) and feeds the next legs
(about 21 a run); with the velocity jitter (:mod:`.epoch_noise`) the robot:rtk ASCKF cells
went from 1, 10, 2, 10 silent-wrong runs of 10 (mems, mems_ahrs; told defaults, right)
to none, every run ending inside 3 sigma (heading 1-sigma at the end 4.2-4.8 deg).

Gyro scale factors (not in seed 000, whose IMU is calibrated): as the navigation engine,
the engine carries them as random-constant states once the heading is known and GNSS
velocity is measured (:mod:`.gyro_scale`), and as noise (:mod:`.rotation_error`) before;
the transition adds ``C~ diag(w_b) ds`` to the drift of the interval.

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

from ...filters.asckf import ASCKF
from ...filters.ckf import CKF
from ...filters.cubature import batched
from ...models import large_azimuth as la
from ...nav import earth
from ...nav.frames import orthonormalize, reorthonormalize
from ...units import DPH, UG
from .aided import GnssAidedEngine
from ..inputs.gnss_fix import GnssFix
from .gnss_gate import FilterDiverged, GnssGate  # noqa: F401  (FilterDiverged re-exported)
from .gyro_scale import GyroScaleStates
from .prior_shaping import HEADING_PRIOR_MAX
from .still_rate import REST_SPEED_MAX, StillRate

I_V, I_P, I_PHI, I_EPS = slice(0, 2), slice(2, 4), slice(4, 7), slice(7, 10)
#: accelerometer bias, body axes (13-state model only)
I_NAB = slice(10, 13)
#: default fading proportions (seed 000 eq. 8): velocity, position and misalignment fade,
#: the gyro drift does not (fading a random constant with a 1e-16 variance made every
#: run diverge in bench/moving_base.py: the factors compound over the V_k memory), nor
#: the accelerometer bias of the 13-state model (zeros appended)
ALPHA = np.r_[np.ones(7), np.zeros(3)]
#: smallest accelerometer bias sigma of the 13-state model (as the navigation filters'), m/s^2
ACCEL_BIAS_FLOOR = UG
#: fading only while the innovations of the last 10 epochs are too large for their
#: covariance (99%) and keep their sign (lag-1 correlation above 0.5, about 2.2 sigma
#: for white 2-vectors): see ASCKF ``whiteness``
WHITENESS = (10, 0.5)


def model_noise(sigma, s_v, s_p, noise, q_drift, accel_bias_q=0.0, accel_bias=True):
    """P0 and Qc of the seed 000 engine from the coarse result and the sensor model.

    ``sigma`` (3,) coarse misalignment sigma (rad), ``s_v`` velocity sigma (m/s),
    ``s_p`` GNSS position sigma (m), ``noise`` the
    :class:`~sins_align_ros.models.stationary.NoiseSpec`, ``q_drift`` the drift's random
    walk density (rad^2/s^3), ``accel_bias_q`` the accelerometer bias's
    ((m/s^2)^2/s; 0: a random constant). ``accel_bias`` False: seed 000's 10 states.
    Returns ``(P0, Qc)``, 13 (or 10) long.
    """
    drift0 = max(noise.gyro_bias, 1e-3 * DPH) ** 2
    p0 = [s_v ** 2] * 2 + [s_p ** 2] * 2 + list(np.asarray(sigma) ** 2) + [drift0] * 3
    qc = [noise.accel_vrw ** 2] * 2 + [0.0, 0.0] + [noise.gyro_arw ** 2] * 3 + [q_drift] * 3
    if accel_bias:
        p0 += [max(noise.accel_bias, ACCEL_BIAS_FLOOR) ** 2] * 3
        qc += [accel_bias_q] * 3
    return np.diag(p0), np.array(qc)


def true_specific_force(f_c, C_b_n, x):
    """Return the specific force (ENU, (3,)) the 13-state model wants, at the estimate ``x``.

    Seed 000 eq. 3 takes the true specific force. The mechanization's ``f_c`` is
    ``C~_b_n (f_b + nab) = C_n^n' f_n + C~_b_n nab`` (``C_b_n`` the computed attitude):
    read as true it adds ``(C_n^n' - I) C~ nab``, heading error x bias, to the velocity
    error, which the mechanization does not have (5 mg and 30 deg in a turn: 2.4 m/s in
    60 s, test_moving.py). So the estimated bias comes out and the estimated misalignment
    is turned back, ``C_n^n'^T (f_c - C~_b_n nab)``; after the feedback ``x``'s
    misalignment is zero and only the bias term is left.

    At the estimate, not at each cubature point: turning each point's own misalignment
    back (measured on the integrity matrix's CKF/ASCKF cells) has each point see a gravity
    tilted by its own tilt, and the still-ship cells at tactical grade went from 0 to 3-4
    silent-wrong runs in 10; at the estimate they are unchanged.
    """
    return la.C_n_nprime(x[I_PHI]).T @ (np.asarray(f_c) - C_b_n @ x[I_NAB])


class MovingBaseAlignment(GyroScaleStates, StillRate, GnssAidedEngine):
    """Mechanization + seed 000 filter; see the module docstring.

    ``i_phi``, ``i_v``, ``i_eps``: the misalignment, velocity-error and gyro-drift slices
    of the state; ``n`` its size (10, or 13 with the accelerometer bias; ``n0`` that, and
    ``n`` adds the gyro scale factors once they are states, :mod:`.gyro_scale`).

    Parameters
    ----------
    C_b_n : ndarray (3, 3)
        Initial attitude (from coarse alignment), body FLU -> ENU.
    v_n : ndarray (3,)
        Initial ENU velocity, m/s.
    lat, lon, h : float
        Initial position (rad, rad, m).
    P0 : ndarray (10, 10) or (13, 13)
        Initial covariance of the error state (see ``large_azimuth.LABELS``); 13 states
        are seed 000's 10 plus the accelerometer bias (module docstring).
    Qc : ndarray (10,) or (13,)
        Continuous-time noise densities (per second); the discrete Q of an
        interval T is ``diag(Qc) T``, for the ASCKF too unless it estimates Q
        (``adapt_q``), when it starts from ``Qc * 1 s``.
    accel_bias : float or None
        Accelerometer bias 1-sigma (m/s^2) for a 10-state ``P0``/``Qc``: the
        accelerometer bias states are appended (sigma at least :data:`ACCEL_BIAS_FLOOR`)
        with random-walk density ``accel_bias_q`` ((m/s^2)^2/s).
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
    drift_in_body : bool
        Turn the drift state with the computed attitude (a gyro bias fixed in the body;
        module docstring); False: seed 000's drift, constant in the navigation frame.
    cap_at_p0 : bool
        The fading never makes a variance larger than its P0 (not in the seed):
        a weakly observable heading faded epoch after epoch otherwise grows
        without bound. With an over-confident P0 this also keeps the fading from
        rescuing it; start from an honest P0 (the pipeline's coarse stage does).
    gate_probability, gate_max_rejects
        The GNSS innovation gate (not in the seed; None: off), :class:`~.gnss_gate.GnssGate`.
    hold_lost_heading : bool
        A heading handed over beyond the cubature cap is lost until a heading is taken
        (module docstring; not in the seed). The pipeline holds it while the course heading
        aid runs, the one that takes it; False (the engine alone) is the seed's acquisition
        from the first manoeuvre: seed 000's ship started 180 deg off recovers from its
        0.1 g burst at 60 s, held lost for those 60 s it ended 52' off at 600 s.
    """

    i_phi, i_v, i_eps = I_PHI, I_V, I_EPS
    still_rate = True
    #: seed 000's 10-state model has no accelerometer bias: bias / g is added to the
    #: tilt; set per instance (True with 13 states)
    has_accel_bias = False

    def __init__(self, C_b_n, v_n, lat, lon, h, P0, Qc, R, use_velocity=False,
                 square_root=True, fading=True, adaptive=True, use_reported_cov=False,
                 alpha=ALPHA, rho=0.95, beta=3.0, b=0.97, gate=False, lambda_max=np.inf,
                 adapt_q=False, r_ceiling=1e4, fading_gate=None, whiteness=WHITENESS,
                 cap_at_p0=True, gate_probability=None, gate_max_rejects=10,
                 accel_bias=None, accel_bias_q=0.0, drift_in_body=True,
                 hold_lost_heading=False):
        Qc = np.asarray(Qc, dtype=float)
        R = np.asarray(R, dtype=float)
        P0 = np.asarray(P0, dtype=float)
        if accel_bias is not None and len(P0) == la.N_STATES:
            P0 = np.pad(P0, (0, 3))
            P0[I_NAB, I_NAB] = np.eye(3) * max(accel_bias, ACCEL_BIAS_FLOOR) ** 2
            Qc = np.r_[Qc, [accel_bias_q] * 3]
        self.n0 = self.n = len(P0)
        if self.n not in (la.N_STATES, la.N_STATES_ACCEL) or len(Qc) != self.n:
            raise ValueError(f'P0 ({self.n}) and Qc ({len(Qc)}) must have 10 or 13 states')
        self.has_accel_bias = self.n == la.N_STATES_ACCEL
        self.i_nab = I_NAB if self.has_accel_bias else None
        P0 = self.cap_heading_prior(P0)
        alpha = np.asarray(alpha, dtype=float)
        if len(alpha) < self.n:
            alpha = np.r_[alpha, np.zeros(self.n - len(alpha))]
        if square_root:
            kf = ASCKF(np.zeros(self.n), P0, np.diag(Qc), R, fading=fading,
                       adaptive=adaptive, alpha=alpha, rho=rho, beta=beta, b=b, gate=gate,
                       lambda_max=lambda_max, adapt_q=adapt_q, r_ceiling=r_ceiling,
                       r_when_identifiable=True, fading_gate=fading_gate, whiteness=whiteness,
                       var_max=np.diag(P0).copy() if cap_at_p0 else None)
        else:
            kf = CKF(np.zeros(self.n), P0, np.diag(Qc), R)
        super().__init__(C_b_n, v_n, lat, lon, h, kf, Qc, R,
                         rows=[2, 3, 0, 1] if use_velocity else [2, 3],
                         gate=GnssGate(gate_probability, gate_max_rejects, sizes=(2, 4)),
                         use_velocity=use_velocity, adaptive=square_root and adaptive,
                         use_reported_cov=use_reported_cov,
                         attitude_sums=True)
        self.drift_in_body = bool(drift_in_body)
        #: the heading is lost (an unknown angle at the hand-over, the prior capped):
        #: the horizontal force stays out of the model until a nonlinear acquisition
        #: (:meth:`_transition`), at most ``LOST_WAIT_S``
        self.heading_lost = bool(hold_lost_heading) and self.heading_prior_var is not None
        #: seconds the heading has been lost
        self.lost_s = 0.0
        #: horizontal speed (m/s) of the last fix with a velocity (:meth:`_at_rest`)
        self._fix_speed = math.inf
        #: computed attitude (3, 3) when the drift was last turned (:meth:`_interval_ended`,
        #: :meth:`_feedback`)
        self._C_drift = self.mech.C_b_n.copy()

    def _transition(self):
        """Batched ``f(x)`` over the interval since the last filter epoch."""
        s = self.sums
        T = s.T
        if T <= 0.0:
            return batched(lambda X: X)
        f_n = s.dv_sum / T
        v_n = s.v_sum / T
        lat, h = self.mech.lat, self.mech.h
        C = orthonormalize(s.C_sum / T)
        if self.has_accel_bias:
            f_n = true_specific_force(f_n, C, self.kf.x)
        if self._holding_lost():
            f_n = self._drop_horizontal_force(f_n, lat, h, HEADING_PRIOR_MAX ** 2)
        else:
            f_n = self._model_force(f_n, lat, h)
        sub = max(1, int(math.ceil(T / 1.0)))
        C_nab = C if self.has_accel_bias else None
        if self.i_sf is None:
            return batched(lambda X: la.propagate(X, f_n, v_n, lat, h, T, substeps=sub,
                                                  C_b_n=C_nab))
        # gyro scale-factor states (:mod:`.gyro_scale`): the drift the interval sees is the
        # bias plus C~ diag(w_b) ds, both constant over it, resolved in the computed frame
        C_w = C * self._interval_rate(T)
        n0 = self.n0

        def fx(X):
            Y = X.copy()
            Y[I_EPS] += C_w @ X[self.i_sf]
            Y[:n0] = la.propagate(Y[:n0], f_n, v_n, lat, h, T, substeps=sub, C_b_n=C_nab)
            Y[I_EPS] = X[I_EPS]
            return Y
        return batched(fx)

    def _interval_ended(self, T):
        """Turn the drift with the computed attitude since it was last turned.

        The drift is a gyro bias fixed in the body: resolved in the computed frame it is
        ``C~_b_n eps_b``, and turns by ``C~_now C~_last^T`` (``J`` on the drift rows of
        ``x`` and ``P``) as the vehicle turns. A correction turns the computed frame too:
        :meth:`_feedback` turns the drift by it and records the corrected attitude, so
        nothing is turned twice; a heading taken directly (``ExternalHeading``) is turned
        here at the next interval's end. Seed 000 holds the drift constant in the
        navigation frame (eq. 4-5; ``drift_in_body`` False): on a ship that turns 80 deg
        and back, the drift learnt before the turn no longer held after it, and the
        heading was certain of a gyrocompass error it no longer had (module docstring,
        bench/results/asckf_ship.md).
        """
        super()._interval_ended(T)
        self._count_lost(T)
        self._scale_states_due()
        if not self.drift_in_body:
            return
        C = self.mech.C_b_n
        J = np.eye(self.n)
        J[I_EPS, I_EPS] = C @ self._C_drift.T
        self.kf.transform(J)
        self._C_drift = C.copy()

    def _heading_taken(self):
        """Mark the heading found: a heading (a straight leg's course, heading/in) was taken."""
        self.heading_lost = False

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
        self.velocity_measured = self.use_velocity and fix.v_n is not None
        if self.velocity_measured:
            z += [m.v_n[0] - fix.v_n[0], m.v_n[1] - fix.v_n[1]]
            idx += [2, 3]
            self._fix_speed = math.hypot(fix.v_n[0], fix.v_n[1])
        return np.array(z), np.array(idx)

    def _at_rest(self):
        """Tell whether the last fix measured the base at rest (:mod:`.still_rate`).

        Its horizontal speed within 3 sigmas of the velocity noise, at most
        :data:`~.still_rate.REST_SPEED_MAX`.
        """
        if not self.velocity_measured:
            return False
        R = np.asarray(self.kf.R)
        var_v = max(float(R[2, 2]), float(R[3, 3]))
        return self._fix_speed <= min(3.0 * math.sqrt(var_v), REST_SPEED_MAX)

    def _drift_row(self, H, C, axis=2):
        """Put the drift's row about ENU ``axis`` into ``H`` (n,) (:mod:`.still_rate`).

        The drift states are resolved in the computed frame (module docstring): the row
        is their component's about that axis.
        """
        H[I_EPS.start + axis] = 1.0

    def _feedback(self, fix):
        """Move the estimated errors into the mechanization (closed loop).

        ``fix`` None (a rejected epoch): the predicted errors only; the vertical
        channel is not touched.
        """
        m, kf = self.mech, self.kf
        x = kf.x
        self._feed_back_scale(x)            # into the compensation (:mod:`.gyro_scale`)
        C_n_np = la.C_n_nprime(x[I_PHI])
        m.C_b_n = reorthonormalize(C_n_np.T @ m.C_b_n)
        self._C_drift = m.C_b_n.copy()      # the drift is turned by C_n_np^T below
        m.correct_velocity(np.array([x[0], x[1], 0.0]))
        R_M, R_N = earth.radii(m.lat)
        m.correct_position(np.array([x[3] / (R_M + m.h),
                                     x[2] / ((R_N + m.h) * math.cos(m.lat)), 0.0]))
        # vertical channel: not in the model; held to the GNSS height (and velocity)
        if fix is not None:
            m.hold_vertical(fix.h, fix.v_n[2] if fix.v_n is not None else 0.0)
        # the corrected frame differs from the old computed one by C_n^n'^T: the drift,
        # a vector resolved in the computed frame, turns with it (C_n^n'^T); the
        # accelerometer bias is in body axes and stays. The misalignment is the
        # rotation being reset: its residual error keeps its heading and has its tilts
        # turned by the heading correction only (``la.reset_jacobian``)
        T = np.eye(self.n)
        T[I_PHI, I_PHI] = la.reset_jacobian(x[I_PHI])
        T[I_EPS, I_EPS] = C_n_np.T
        kf.transform(T)
        kf.x[:7] = 0.0
        if self.i_sf is not None:
            kf.x[self.i_sf] = 0.0

    def _correct_imu(self, dtheta, dv, dt):
        """Divide the gyro increments by ``1 + s`` of the scale-factor states (:mod:`.gyro_scale`).

        The drift and the accelerometer bias stay in the filter (module docstring).
        """
        return self._compensate_scale(dtheta), dv

    def attitude_cov(self):
        """As every aided engine's, with the scale-factor states' floor (:mod:`.gyro_scale`)."""
        return self._heading_floor(super().attitude_cov())

    def status(self):
        """Filter internals for diagnostics; with 13 states the accelerometer bias estimate."""
        s = super().status()
        if self.has_accel_bias:
            s['accel_bias_ug'] = [float(v) for v in self.kf.x[I_NAB] / UG]
        s.update(self.scale_status())
        return s

    @staticmethod
    def _gnss_fix(gnss, i):
        """Epoch ``i`` of the arrays given to :meth:`feed` (position only)."""
        return GnssFix(gnss.t[i], gnss.lat[i], gnss.lon[i], gnss.h[i])


class CKFAlignment(MovingBaseAlignment):
    """``ckf``: seed 000's conventional cubature KF (eq. 22-34)."""

    fine_filter = 'ckf'

    @staticmethod
    def options(cfg):
        """Return the constructor's filter options: no square root, fading or adaptation."""
        return dict(square_root=False, fading=False, adaptive=False)


class ASCKFAlignment(MovingBaseAlignment):
    """``asckf``: seed 000's square-root CKF with fading factors and Sage-Husa noise."""

    fine_filter = 'asckf'

    @staticmethod
    def options(cfg):
        """Return the square root with fading and adaptation as parameter values ``cfg`` say."""
        return dict(square_root=True, fading=cfg['asckf_fading'],
                    adaptive=cfg['asckf_adaptive'])
