"""GNSS/INS integrated navigation that aligns and then keeps navigating (seeds 001, 003).

The full strapdown mechanization runs at IMU rate on increments corrected by the
current sensor-error estimates; at every GNSS epoch the loosely coupled error model
(:mod:`~sins_align_ros.models.loosely_coupled`: 15 states of seed 001 for ``kf``,
``vbakf`` and ``mvbakf``, 18 states of seed 003 for ``ukf``) is propagated over the
interval at the interval's mean specific force, velocity and attitude, updated with
INS minus GNSS position (and velocity when the epoch has one), and the whole
estimate is fed back (seed 003 sec. 4: feedback correction every filter cycle):
attitude, velocity and position into the mechanization, the gyro and accelerometer
errors into the sensor compensation. The error state is zero after each epoch; the
Markov parts of the compensation decay with their correlation time, as the expected
value of a first-order Markov process does, so the residual error keeps the model's
dynamics.

Large heading errors with a poor gyro (issue 21): the force the model takes, the heading
variance held within the linear model's range, a lost heading found again by a nonlinear
acquisition, the heading claimed only within the linearisation: :mod:`.heading_range`.

The filter is the engine class's (:meth:`IntegratedNavigation._make_filter`): seed 001's
KF, VBAKF and MVBAKF and seed 003's UKF are the classes of :mod:`.navigation_filters`,
each naming its row of the filter table (``fine_filter``, :mod:`..filter_table`).

The IMU-rate driver and the GNSS bookkeeping (intervals without a fix, the innovation
gate with forced acceptances) are :class:`~.aided.GnssAidedEngine`'s. The
navigation solution is the mechanization's at every IMU sample (100 Hz at a 100 Hz
IMU, seed 003's output rate).
"""
import math

import numpy as np

from ...filters.linear_kf import linear, measurement_matrix
from ...models import loosely_coupled as lc
from ...nav import earth
from ...nav.frames import orthonormalize, reorthonormalize, rotvec_to_dcm
from ...units import DPH, UG
from .aided import GnssAidedEngine
from .gnss_gate import GnssGate
from .gnss_markov_states import GnssMarkovStates
from .gyro_scale import GyroScaleStates
from .still_rate import REST_SPEED_MAX, StillRate
from .heading_range import (HEADING_CLAIM_MAX_VAR, HEADING_LINEAR_MAX_DEG,
                            HEADING_LINEAR_MAX_VAR, HeadingRange)


def gyro_tau(n_states, gyro, tau_g):
    """Correlation time (s) the model gives its gyro Markov state.

    ``gyro``: ``(constant sigma, Markov sigma)`` rad/s, ``tau_g``: the Markov part's
    correlation time. The 18-state model keeps the constant apart and uses ``tau_g``;
    the 15-state model folds both into one state whose time is
    :func:`~sins_align_ros.models.loosely_coupled.fold_markov`'s. Pass the result as
    :class:`IntegratedNavigation`'s ``tau_g`` and :func:`model_noise`'s.
    """
    if n_states == 15:
        return lc.fold_markov(gyro[0], gyro[1], tau_g)[1]
    return float(tau_g)


def model_noise(n_states, sigma_phi, sigma_v, sigma_p, gyro, accel, gyro_arw, accel_vrw,
                tau_g, tau_a, q_scale=1.0):
    """P0 (n, n) and Qc (n,) of the 15- or 18-state model.

    ``sigma_phi`` (3,) rad, ``sigma_v`` m/s, ``sigma_p`` m: initial navigation errors.
    ``gyro``, ``accel``: ``(constant sigma, Markov sigma)`` of the sensor errors (rad/s,
    m/s^2); the 15-state model has one Markov state per sensor whose steady sigma is
    their root sum square (seed 001's first-order Markov errors; ``tau_g`` must then be
    :func:`gyro_tau`'s, which keeps the Markov part's drive), the 18-state model
    a random constant and a Markov state for the gyro (seed 003 eq. 23-24) and a Markov
    accelerometer error of the total sigma (eq. 25). ``gyro_arw`` rad/sqrt(s),
    ``accel_vrw`` m/s/sqrt(s). ``q_scale`` multiplies Qc (seed 001 runs its filters
    with Q nine times the truth). Sigmas have floors of 1e-3 deg/h and 1 micro-g (a
    zero variance makes the sigma points degenerate).
    """
    g_floor, a_floor = 1e-3 * DPH, UG
    s_a = max(math.hypot(*accel), a_floor)
    q_a = lc.markov_q(s_a, tau_a)
    if n_states == 15:
        s_g = max(math.hypot(*gyro), g_floor)
        bias_var = [s_g ** 2] * 3 + [s_a ** 2] * 3
        q_bias = [lc.markov_q(s_g, tau_g)] * 3 + [q_a] * 3
    else:
        s_gb, s_gr = max(gyro[0], g_floor), max(gyro[1], g_floor)
        bias_var = [s_gb ** 2] * 3 + [s_gr ** 2] * 3 + [s_a ** 2] * 3
        q_bias = [0.0] * 3 + [lc.markov_q(s_gr, tau_g)] * 3 + [q_a] * 3
    P0 = np.diag(np.r_[np.asarray(sigma_phi, float) ** 2, [sigma_v ** 2] * 3,
                       [sigma_p ** 2] * 3, bias_var])
    Qc = q_scale * np.r_[[gyro_arw ** 2] * 3, [accel_vrw ** 2] * 3, [0.0] * 3, q_bias]
    return P0, Qc


class IntegratedNavigation(HeadingRange, GyroScaleStates, GnssMarkovStates, StillRate,
                           GnssAidedEngine):
    """Mechanization + seed 001/003 filter; see the module docstring.

    The base of the navigation engines: a subclass makes the filter
    (:meth:`_make_filter`) and names its row of the filter table (``fine_filter``).

    Parameters
    ----------
    C_b_n, v_n, lat, lon, h
        Initial attitude (body FLU -> ENU), ENU velocity (m/s), position (rad, rad, m).
    P0 : ndarray (n, n)
    Qc : ndarray (n,)
        Continuous-time noise densities; the discrete Q of an interval T is
        ``(Phi diag(Qc) Phi^T + diag(Qc)) T / 2``.
    R : ndarray (6, 6)
        Measurement noise, position E, N, U (m^2) then velocity E, N, U ((m/s)^2).
    tau_g, tau_a : float
        Correlation times of the Markov gyro and accelerometer errors, s.
    use_velocity : bool
        Measure GNSS velocity when the epoch has one.
    gate_probability, gate_max_rejects
        The GNSS innovation gate (None: off), :class:`~.gnss_gate.GnssGate`.
    track_heading_sigma_deg, track_min_speed_mps
        The GNSS-track heading that replaces a heading lost to the linear model (module
        docstring): its 1-sigma and the least horizontal speed (the parameters of the
        same names; their defaults).
    use_reported_cov : bool
        Take the east and north position and velocity noise of each epoch from the
        receiver's reported variances (``GnssFix.pos_var``, ``vel_var``) instead of ``R``'s
        (:meth:`~.epoch_noise.EpochNoise._set_epoch_noise`); ignored by ``vbakf`` and
        ``mvbakf``, whose R is their own estimate.
    heading_lost : bool
        The heading handed over is beyond the model's range (an unknown angle): lost
        until a nonlinear acquisition finds it (:mod:`.heading_range`).
    **options
        The filter's own (:meth:`options`, :meth:`_make_filter`).
    """

    i_phi, i_v = lc.I_PHI, lc.I_V
    navigates = True
    still_rate = True
    MEAS_ENU = np.arange(6)             # position then velocity, each E, N, U
    #: states of the seed model: seed 001's 15 (seed 003's 18:
    #: :class:`~.navigation_filters.UnscentedNavigation`)
    n_states = 15
    #: largest coarse heading sigma (rad) the model takes: beyond it the heading is handed
    #: over lost (:mod:`.heading_range`)
    heading_sigma_max = math.radians(HEADING_LINEAR_MAX_DEG)

    def __init__(self, C_b_n, v_n, lat, lon, h, P0, Qc, R, tau_g=300.0, tau_a=3600.0,
                 use_velocity=True, gate_probability=None, gate_max_rejects=10,
                 track_heading_sigma_deg=10.0, track_min_speed_mps=2.0, use_reported_cov=False,
                 heading_lost=False, **options):
        #: states of the seed model (15 or 18); ``n`` adds the gyro scale factors once
        #: modelled (:mod:`.gyro_scale`)
        self.n0 = self.n = len(P0)
        x0 = np.zeros(self.n)
        Q = np.diag(np.asarray(Qc, dtype=float))
        kf = self._make_filter(x0, P0, Q, R, **options)
        kf_sets_R = not getattr(kf, 'estimates_R', False)
        self.tau_g, self.tau_a = float(tau_g), float(tau_a)
        self.i_eps = lc.I_EPS15 if self.n0 == 15 else lc.I_EPSB
        self.i_nab = lc.I_NAB15 if self.n0 == 15 else lc.I_NAB18
        #: epochs at which the heading variance was held at the linear model's range, and
        #: times the heading was then taken from the GNSS track
        self.n_heading_held = self.n_heading_reacquired = 0
        self.heading_lost = bool(heading_lost)
        #: the last fix showed the base under way (:meth:`measurement`)
        self._under_way = False
        #: horizontal speed (m/s) of the last fix with a velocity
        self._fix_speed = math.inf
        #: seconds the heading has been lost (the wait for a nonlinear acquisition)
        self.lost_s = 0.0
        self.track_heading_sigma = math.radians(float(track_heading_sigma_deg))
        self.track_min_speed = float(track_min_speed_mps)
        #: sensor compensation: gyro constant, gyro Markov, accelerometer (body, SI)
        self.eps_const = np.zeros(3)
        self.eps_markov = np.zeros(3)
        self.nab = np.zeros(3)
        self._F = self._Phi = self._T_last = None
        super().__init__(C_b_n, v_n, lat, lon, h, kf, Qc, R, rows=lc.MEAS_STATES,
                         gate=GnssGate(gate_probability, gate_max_rejects, sizes=(3, 6)),
                         use_velocity=use_velocity, attitude_sums=True,
                         use_reported_cov=use_reported_cov and kf_sets_R)

    @staticmethod
    def options(cfg):
        """Return the filter's constructor options from parameter values ``cfg`` (none)."""
        return {}

    @classmethod
    def prior_sigma(cls, sigma):
        """Return the coarse attitude sigma (3,) rad the model is given (``sigma`` itself)."""
        return sigma

    def _make_filter(self, x0, P0, Q, R, **options):
        """Return the filter of state ``x0`` (n,), ``P0``, ``Q`` (n, n), ``R`` (6, 6)."""
        raise NotImplementedError('a navigation engine class makes its filter')

    # -- IMU rate ---------------------------------------------------------------------
    def _correct_imu(self, dtheta, dv, dt):
        """Return the increments corrected by the sensor-error estimates.

        The drift, then the scale factors when modelled (:mod:`.gyro_scale`).
        """
        return (self._compensate_scale(dtheta - (self.eps_const + self.eps_markov) * dt),
                dv - self.nab * dt)

    def _interval_ended(self, T):
        """Decay the Markov compensation over the interval that ended; bound the heading.

        And take the gyro scale factors into states once the heading is known
        (:mod:`.gyro_scale`).
        """
        self._interval_ended_bound()
        self._scale_states_due()
        self._count_lost(T)
        if T > 0.0:
            self.eps_markov *= math.exp(-T / self.tau_g)
            self.nab *= math.exp(-T / self.tau_a)

    def _transition(self):
        s = self.sums
        T = s.T
        if T <= 0.0:
            self._F, self._Phi = np.zeros((self.n, self.n)), np.eye(self.n)
            return linear(self._Phi)
        self._T_last = T
        f_n, v_n, C = s.dv_sum / T, s.v_sum / T, s.C_sum / T
        C = orthonormalize(C)
        m = self.mech
        self.kf.consider = None
        if self._holding_lost():
            f_n = self._drop_horizontal_force(f_n, m.lat, m.h, HEADING_LINEAR_MAX_VAR)
            if self._unmodelled_acc_var > 0.0 and self._under_way:
                self.kf.consider = self._tilt_considered()
        else:
            f_n = self._interval_force(f_n, m.lat, m.h)
        F = lc.F_matrix(C, f_n, v_n, m.lat, m.h, self.tau_g, self.tau_a, self.n0)
        w_b = None
        F = np.pad(F, (0, self.n - self.n0))
        if self.i_sf is not None:          # gyro scale-factor states (:mod:`.gyro_scale`)
            w_b = self._interval_rate(T)
            self._scale_columns(F, C, w_b)
        self._markov_columns(F)            # the receiver's error (:mod:`.gnss_markov_states`)
        self._F = F
        self._Phi = lc.transition(self._F, T)
        return self._propagation(f_n, v_n, C, T, w_b)

    def _interval_force(self, f_n, lat, h):
        """Return the specific force (3,) the model takes: the significant part (:mod:`.force`)."""
        return self._model_force(f_n, lat, h)

    def _propagation(self, f_n, v_n, C, T, w_b):
        """Return the interval's propagation for the filter: the linear ``Phi``."""
        return linear(self._Phi)

    def _set_process_noise(self):
        """Q of the interval: trapezoid of ``Phi Qc Phi^T`` and ``Qc`` over its length T."""
        T = max(self.sums.T, 1e-3)
        if self._F is None:
            Phi = np.eye(self.n)
        elif T == self.sums.T:      # the interval's transition, as _transition made it
            Phi = self._Phi
        else:
            Phi = lc.transition(self._F, T)
        Q = self._process_noise(Phi, T)
        # gyro scale factors and misalignment (:mod:`.rotation_error`), the accelerometer's
        # (:mod:`.force_error`)
        for E in (self._rotation_noise(T), self._force_error_noise(T)):
            if E is not None:
                Q = Q + E
        self.kf.Q = Q

    def _process_noise(self, Phi, T):
        """Q (n, n) of ``T`` s with transition ``Phi``: the trapezoid, a dropped force's part."""
        Q = 0.5 * ((Phi * self.Qc) @ Phi.T + np.diag(self.Qc)) * T
        E = self._force_noise(T)             # a dropped horizontal force (:mod:`.force`)
        if E is not None:
            Q = Q + E
        return 0.5 * (Q + Q.T)

    def forecast_model(self):
        """Return the last epoch's linear model, for a covariance forecast (:mod:`.expectation`).

        A dict: ``P`` (n, n) the covariance now; ``Phi``, ``Q`` (n, n) the transition and
        process noise of the last interval (``T`` s, its motion); ``H`` (m, n), ``R`` (m, m)
        the last update's measurement rows and noise; ``i_phi`` the attitude states;
        ``heading_cap`` the heading variance the linear model is held within
        (:meth:`_interval_ended_bound`, None for the unscented filter) and
        ``heading_claim`` the variance beyond which the heading is published as unknown
        (:meth:`attitude_cov`). None before the first GNSS update.
        """
        if self._F is None or self.last_rows is None or not self._T_last:
            return None
        T, Phi = self._T_last, self._Phi           # as _transition made them
        idx = np.asarray(self.last_rows)
        H = measurement_matrix(self._hx(idx), self.n)
        return dict(P=self.kf.P.copy(), Phi=Phi, Q=self._process_noise(Phi, T), H=H,
                    R=np.asarray(self.kf.R)[np.ix_(idx, idx)], T=T, i_phi=self.i_phi,
                    heading_cap=self.heading_cap,
                    heading_claim=HEADING_CLAIM_MAX_VAR)

    # -- GNSS epochs --------------------------------------------------------------------
    def measurement(self, fix, t_now):
        """INS minus GNSS position (m, ENU) and, when present, velocity (m/s, ENU).

        The INS position is moved back to the fix stamp with the current velocity.
        Returns ``(z, idx)`` with ``idx`` the rows of the full 6-vector present.
        """
        m = self.mech
        back = max(0.0, t_now - fix.t)
        R_M, R_N = earth.radii(m.lat)
        lat = m.lat - m.v_n[1] * back / (R_M + m.h)
        lon = m.lon - m.v_n[0] * back / ((R_N + m.h) * math.cos(m.lat))
        h = m.h - m.v_n[2] * back
        z = [(lon - fix.lon) * (R_N + m.h) * math.cos(m.lat), (lat - fix.lat) * (R_M + m.h),
             h - fix.h]
        idx = [0, 1, 2]
        self.velocity_measured = self.use_velocity and fix.v_n is not None
        self._under_way = False
        if self.velocity_measured:
            v = np.asarray(fix.v_n, dtype=float)
            z += list(m.v_n - v)
            idx += [3, 4, 5]
            # the fix's speed beyond 3 of its sigmas: a horizontal force the filter finds
            # significant is then a turn or a braking as much as its own tilt error (at
            # rest it is the tilt error alone, which must be corrected: a still MEMS base,
            # its tilt frozen on such intervals, ended 4.8 sigma off)
            var_v = max(float(self.kf.R[3, 3]), float(self.kf.R[4, 4]))
            self._fix_speed = math.hypot(v[0], v[1])
            self._under_way = self._fix_speed > 3.0 * math.sqrt(var_v)
        return np.array(z), np.array(idx)

    def _at_rest(self):
        """Tell whether the last fix measured the base at rest (a velocity, not under way)."""
        return (self.velocity_measured and not self._under_way
                and self._fix_speed <= REST_SPEED_MAX)

    def _rate_compensation(self):
        """Return the drift (3,) rad/s the increments are compensated by (:meth:`_correct_imu`)."""
        return self.gyro_bias

    def _eps_slices(self):
        """Return the gyro-drift slices: one state, or the constant and the Markov one."""
        return (lc.I_EPS15,) if self.n0 == 15 else (lc.I_EPSB, lc.I_EPSR)

    def _feedback(self, fix):
        """Feed the whole estimate back (module docstring); the error state becomes zero."""
        m, kf = self.mech, self.kf
        x = kf.x
        m.C_b_n = reorthonormalize(self._attitude_correction(x[lc.I_PHI]) @ m.C_b_n)
        m.correct_velocity(x[lc.I_V].copy())
        R_M, R_N = earth.radii(m.lat)
        m.correct_position(np.array([x[7] / (R_M + m.h), x[6] / ((R_N + m.h) * math.cos(m.lat)),
                                     x[8]]))
        self._feed_back_scale(x)
        if self.n0 == 15:
            self.eps_markov += x[lc.I_EPS15]
            self.nab += x[lc.I_NAB15]
        else:
            self.eps_const += x[lc.I_EPSB]
            self.eps_markov += x[lc.I_EPSR]
            self.nab += x[lc.I_NAB18]
        kf.x = self._kept_state(x)        # zero, but the receiver's error (its own states)
        self._reacquire_heading(fix)

    # -- output -------------------------------------------------------------------------
    def nav_cov(self):
        """Return the covariance (9, 9) of position, velocity and misalignment errors.

        Position in m and velocity in m/s (ENU), misalignment in rad about the ENU axes,
        in that order, with their cross terms.
        """
        i = np.r_[6:9, 3:6, 0:3]
        return self.kf.P[np.ix_(i, i)]

    @property
    def gyro_bias(self):
        """Current gyro-error compensation, body axes, rad/s (3,)."""
        return self.eps_const + self.eps_markov

    def status(self):
        """Filter internals for diagnostics: the base ones plus the sensor estimates."""
        s = super().status()
        s['gyro_drift_dph'] = [float(v) for v in self.gyro_bias / DPH]
        s['accel_bias_ug'] = [float(v) for v in self.nab / UG]
        s['R_sigma'] = [float(v) for v in np.sqrt(np.diag(self.kf.R))]
        s['heading_claimed'] = self.heading_claimed
        s['heading_held_epochs'] = self.n_heading_held
        s['heading_from_track'] = self.n_heading_reacquired
        s.update(self.scale_status())
        s.update(self.markov_status())
        return s

    @staticmethod
    def _attitude_correction(phi):
        """Return the DCM (3, 3) the estimated misalignment ``phi`` (3,) rad applies."""
        return rotvec_to_dcm(phi)
