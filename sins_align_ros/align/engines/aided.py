"""What every GNSS-aided engine shares: IMU-rate mechanization, GNSS epochs, feedback.

The full strapdown mechanization runs at IMU rate; the samples between two filter
epochs are summed (:class:`IntervalSums`: length, specific-force increment,
velocity and attitude integrals) so the error model can be propagated over the
interval at its mean values; at every GNSS epoch the filter predicts over the
interval, updates with the engine's measurement (gated by a
:class:`~.gnss_gate.GnssGate`) and the engine feeds the estimate back into the
mechanization through :class:`~sins_align_ros.nav.mechanization.Strapdown`'s
correction methods. Without GNSS for :data:`MAX_PREDICT` seconds the filter
predicts without an update, so an outage only widens the covariance.

:class:`GnssAidedEngine` is the driver; each family (seed 000's 10 states
:mod:`.moving`, seed 004's 12 :mod:`.robust`, seeds 001/003's 15/18
:mod:`.navigation`) builds its filter and supplies the hooks ``_transition``,
``measurement`` and ``_feedback`` (and optionally ``_correct_imu``,
``_set_process_noise``, ``_interval_ended``). Its mixins hold the other jobs: what is
done to the prior before the first epoch (:class:`~.prior_shaping.PriorShaping`), the
consistency monitor's remedies (:class:`~.consistency_remedies.ConsistencyRemedies`),
each interval's process noise and the other monitors' widening of it
(:class:`~.process_noise.ProcessNoise`), which horizontal force the model may use
(:class:`~.force.ForceModel`), the external heading's epochs
(:class:`~.heading_update.ExternalHeading`), each GNSS epoch's measurement noise
(:class:`~.epoch_noise.EpochNoise`) and offline runs over arrays
(:class:`~.array_feed.ArrayFeed`). What the stages may use of it is declared in
:class:`~.base.AidedEngine`.
"""
import math
from dataclasses import dataclass

import numpy as np

from ...filters.cubature import batched
from ... import compiled
from ...nav import kernels
from ...nav.mechanization import MechanizationOptions, Strapdown
from ...units import DPH
from .array_feed import ArrayFeed
from .epoch_noise import EpochNoise
from .consistency_remedies import ConsistencyRemedies
from .force import ForceModel
from .force_error import ForceError
from .gnss_gate import FilterDiverged
from .heading_update import ExternalHeading
from .prior_shaping import HEADING_PRIOR_MAX, PriorShaping
from .process_noise import ProcessNoise
from .rotation_error import RotationError

#: the longest interval the error model is propagated without a measurement, s
MAX_PREDICT = 2.0
#: samples looked ahead at a time by :meth:`GnssAidedEngine.step_block` for the next
#: prediction (bounds its work on a long stretch without GNSS)
STRETCH = 4096
#: what the interval-sum kernel is given for ``C_sum`` when it keeps none (not written)
_NO_C_SUM = np.zeros((3, 3))


class IntervalSums:
    """Sums over the samples since the last filter epoch.

    ``T`` (s), ``dv_sum`` (3,) specific-force increments in ENU, ``v_sum`` (3,)
    velocity integral, and with ``attitude`` the attitude integral ``C_sum`` (3, 3).
    """

    def __init__(self, attitude=False):
        self.attitude = bool(attitude)
        self.restart()

    def restart(self):
        """Start a new interval."""
        self.T = 0.0
        self.dv_sum = np.zeros(3)
        self.v_sum = np.zeros(3)
        self.C_sum = np.zeros((3, 3)) if self.attitude else None

    def add(self, mech, C, dt):
        """Add one mechanized sample (attitude ``C`` (3, 3), interval ``dt``)."""
        self.T += dt
        self.dv_sum += mech.dv_sf
        self.v_sum += mech.v_n * dt
        if self.attitude:
            self.C_sum += C * dt

    def add_block(self, out, dt):
        """Add mechanized samples in order, as :meth:`add` one at a time (sequential sums).

        ``out``: :meth:`~sins_align_ros.nav.mechanization.Strapdown.run`'s record of them;
        ``dt`` (N,) their intervals.
        """
        self.T = kernels.interval_sums(
            self.T, self.dv_sum, self.v_sum, self.C_sum if self.attitude else _NO_C_SUM,
            self.attitude, out['dv_sf'], out['v_n'], out['C_b_n'],
            compiled.kernel_array(dt))


#: no sample index (:meth:`GnssAidedEngine._interval_full` between GNSS epochs)
_NO_INDEX = np.zeros(0, dtype=np.intp)


@dataclass
class Block:
    """What :meth:`GnssAidedEngine.step_block` did with a block of samples.

    ``C`` (end, 3, 3) the attitude after each sample; ``nav`` (end, 6) latitude,
    longitude (rad), height (m) and ENU velocity (m/s) after each; ``predicted`` the
    indices of the samples after which a prediction ran (an interval without GNSS);
    ``end`` the samples done (all, or up to the one at which the filter diverged);
    ``reason`` that divergence, or None.
    """

    C: np.ndarray
    nav: np.ndarray
    predicted: list
    end: int
    reason: str = None


class GnssAidedEngine(PriorShaping, ConsistencyRemedies, ProcessNoise, ForceModel,
                      ExternalHeading, EpochNoise, RotationError, ForceError, ArrayFeed):
    """Mechanization + error-state filter at GNSS epochs; see the module docstring.

    It satisfies :class:`~.base.AidedEngine`, the contract the fine stage steps it by.

    Parameters
    ----------
    C_b_n, v_n, lat, lon, h
        Initial attitude (body FLU -> ENU), ENU velocity (m/s), position (rad, rad, m).
    kf
        The filter (:class:`~sins_align_ros.filters.base.GaussianFilter`).
    Qc : ndarray (n,)
        Continuous-time noise densities (per second).
    R : ndarray (m, m)
        Nominal measurement noise.
    rows : ndarray
        State rows measured by the full measurement vector.
    gate : GnssGate
    attitude_sums : bool
        Also sum the attitude over each interval (models linear in it).
    adaptive, use_reported_cov : bool
        The filter estimates Q itself (Q is then not set per interval); R is taken from
        each fix's reported variances.
    """

    #: misalignment, velocity-error and gyro-drift slices of the state (set by families)
    i_phi = i_v = i_eps = None
    #: the engine keeps navigating after alignment (``~/odom``, navigation CSV columns)
    navigates = False
    #: zero-rate epochs at rest (:mod:`.still_rate`)
    still_rate = False
    #: the aided filters run one stage (only the stationary filter is re-initialised)
    restages = False
    #: the model estimates the accelerometer bias (else bias / g is added to the tilt)
    has_accel_bias = True
    #: the ENU axis of each row of the full measurement vector: 0-2 position E, N, U,
    #: 3-5 velocity E, N, U (where a lever arm's variance ``GnssFix.arm_var`` goes)
    MEAS_ENU = np.array([0, 1, 3, 4])

    def __init__(self, C_b_n, v_n, lat, lon, h, kf, Qc, R, rows, gate, use_velocity=False,
                 attitude_sums=False, adaptive=False, use_reported_cov=False):
        self.mech = Strapdown(C_b_n, v_n, lat, lon, h, MechanizationOptions())
        self.kf = kf
        self.Qc = np.asarray(Qc, dtype=float)
        self.R_nominal = np.asarray(R, dtype=float).copy()
        self.rows = np.asarray(rows)
        self.gate = gate
        self.use_velocity = bool(use_velocity)
        self.adaptive = bool(adaptive)
        self.use_reported_cov = bool(use_reported_cov) and not self.adaptive
        #: the filter estimates Q itself (Sage-Husa with ``adapt_q``); else the engine sets
        #: ``diag(Qc) T`` each interval, as for every filter (an ASCKF that estimates R
        #: only kept ``diag(Qc) * 1 s`` per epoch whatever the interval: at 5 Hz RTK five
        #: times the model's noise, heading 1-sigma 0.70 deg against kf's 0.46)
        self.own_Q = self.adaptive and bool(getattr(getattr(kf, 'noise', None), 'adapt_q',
                                                    False))
        self.sums = IntervalSums(attitude_sums)
        self.n_updates = 0
        self.n_predict_only = 0
        self.last_nis = float('nan')
        #: measurements in the last epoch (the NIS's degrees of freedom), their
        #: innovations normalised row by row and their rows of the measurement vector
        self.last_dof = 0
        self.last_u = self.last_rows = None
        self._Qc0 = self.Qc.copy()
        #: states the model holds constant (no process noise of their own)
        self._held = self._Qc0 <= 0.0
        #: factors on the measurement noise variances (the consistency monitor's remedy);
        #: used by filters that take R from the engine (not ``estimates_R``, not adaptive)
        self.R_scale = np.ones(len(self.R_nominal))
        self.sets_R = not (getattr(kf, 'estimates_R', False) or self.adaptive)

    # -- IMU rate -------------------------------------------------------------------
    def step_imu(self, dtheta, dv, dt):
        """Mechanize one sample; returns the current ``C_b_n`` (3, 3)."""
        dtheta, dv = self._correct_imu(dtheta, dv, dt)
        self._add_rotation(dtheta)
        if self.still_rate:
            self._count_still_rate(dtheta, dt)
        m = self.mech
        C = m.step(dtheta, dv, dt)
        self.sums.add(m, C, dt)
        if self.sums.T >= MAX_PREDICT:
            self.predict()
        return C

    def step_block(self, dtheta, dv, dt):
        """Mechanize N samples as N calls of :meth:`step_imu` would, in compiled blocks.

        ``dtheta``, ``dv`` (N, 3), ``dt`` (N,); no GNSS epoch is applied here. The samples
        run through :meth:`Strapdown.run(as_step=True)
        <sins_align_ros.nav.mechanization.Strapdown.run>` up to each sample at which the
        interval reaches :data:`MAX_PREDICT` (a prediction there, as :meth:`step_imu`
        makes), with the sensor compensation of each stretch. Returns a :class:`Block`.
        """
        n = len(dt)
        C, nav = np.empty((n, 3, 3)), np.empty((n, 6))
        predicted = []
        i = 0
        while i < n:
            w = dt[i:i + STRETCH]
            over = self._interval_full(w)
            j = i + (int(over[0]) + 1 if len(over) else len(w))
            dth, dvc = self._correct_imu(dtheta[i:j], dv[i:j], dt[i:j, None])
            self._add_rotation(dth)
            if self.still_rate:
                self._count_still_rate(dth, dt[i:j])
            out = self.mech.run(dth, dvc, dt[i:j], as_step=True)
            self.sums.add_block(out, dt[i:j])
            C[i:j] = out['C_b_n']
            nav[i:j, :3], nav[i:j, 3:] = out['pos'], out['v_n']
            if len(over):
                try:
                    self.predict()
                except FilterDiverged as exc:
                    return Block(C[:j], nav[:j], predicted, j, str(exc))
                predicted.append(j - 1)
            i = j
        return Block(C, nav, predicted, n)

    def _interval_full(self, w):
        """Return the samples of intervals ``w`` (N,) after which the interval is full (indices).

        Those where ``T`` summed sample by sample (as :class:`IntervalSums` sums it)
        reaches :data:`MAX_PREDICT`. Between GNSS epochs it never does, which the sum of
        ``w`` tells without the running sum: non-negative intervals, their sum short of
        MAX_PREDICT by far more than any summation order's round-off (N u of it).
        """
        T = self.sums.T
        if (T >= 0.0 and T + np.add.reduce(w) < MAX_PREDICT * (1.0 - 1e-9)
                and np.minimum.reduce(w) >= 0.0):
            return _NO_INDEX
        return np.flatnonzero(np.cumsum(np.concatenate(([T], w)))[1:] >= MAX_PREDICT)

    def predict(self, without_gnss=True):
        """Predict over the interval so far without a GNSS measurement.

        ``without_gnss``: count it as an epoch without GNSS (``predict_only_epochs``); an
        external heading's epoch predicts too but is not one. Raises
        :class:`FilterDiverged` when the numbers break down.
        """
        try:
            fx = self._transition()
            lent = self._set_process_noise()
            self.kf.predict(fx)
            self._return_process_noise(lent)
        except (np.linalg.LinAlgError, ValueError) as exc:
            raise FilterDiverged(f'filter diverged in a prediction ({exc})') from None
        self.n_predict_only += without_gnss
        self._restart_interval()

    def _correct_imu(self, dtheta, dv, dt):
        """Sensor compensation before the mechanization (none by default)."""
        return dtheta, dv

    def _restart_interval(self):
        self._interval_ended(self.sums.T)
        self.sums.restart()

    def _interval_ended(self, T):
        """Act on the end of an interval of ``T`` seconds (before the sums restart)."""

    def _transition(self):
        raise NotImplementedError

    def measurement(self, fix, t_now):
        """Innovation ``(z, idx)`` of ``fix``: ``idx`` the rows of the full vector present."""
        raise NotImplementedError

    def _feedback(self, fix):
        """Move the estimate into the mechanization; ``fix`` None after a rejected epoch."""
        raise NotImplementedError

    def _before_epoch(self, fix):
        """Act before ``fix``'s epoch, ahead of its transition (states to append: none)."""

    def _hx(self, idx):
        """Return the measurement function (batched) of the full vector's rows ``idx``."""
        rows = self.rows[idx]
        return batched(lambda X: X[rows])

    # -- GNSS epochs ------------------------------------------------------------------
    def update(self, fix, t_now):
        """Filter epoch for ``fix``: predict over the interval, update, feed back.

        Returns the filter's update record. Raises :class:`FilterDiverged` on
        non-finite, overflowing or singular numbers and when the gate gives up
        (``GnssGate``): an ASCKF on a raw-MEMS ground case carried its height past 1e154 m
        and ``earth.gravity`` overflowed, aborting a benchmark instead of restarting.
        """
        kf = self.kf
        self._before_epoch(fix)
        try:
            z, idx = self.measurement(fix, t_now)
            fx = self._transition()
        except (np.linalg.LinAlgError, ValueError, ArithmeticError):
            raise FilterDiverged(f'filter diverged at t={fix.t:.3f} s (non-finite navigation '
                                 'state)') from None
        rows = self.rows[idx]
        hx = self._hx(idx)
        lent = self._set_process_noise()
        self._set_epoch_noise(fix)
        arm = self._lend_arm_noise(fix)
        max_nis = self.gate.threshold(len(idx), kf)
        try:
            upd = kf.step(fx, z, hx, idx, max_nis=max_nis)
            self._return_process_noise(lent)
            if arm is not None:
                self._return_arm_noise()
            # (a linear KF's innovation has computed its NIS for the gate already)
            self.last_nis = upd.nis()
            self.last_dof = len(upd.y)
            self.last_u = upd.y / np.sqrt(upd.Pzz.diagonal())
            self.last_rows = np.asarray(idx)
        except (np.linalg.LinAlgError, ValueError):
            upd = None
        if upd is None or not (np.isfinite(kf.x).all() and np.isfinite(kf.P).all()):
            raise FilterDiverged(f'filter diverged at t={fix.t:.3f} s (non-finite or '
                                 f'singular covariance)')
        self._restart_interval()
        if kf.rejected:
            self.gate.rejected(fix.t, self.last_nis, max_nis, rows, upd.y)
            self._feedback(None)
            return upd
        self.n_updates += 1
        self.gate.accepted()
        self._feedback(fix)
        if self.still_rate:
            self._still_rate_epoch(self._at_rest())
        return upd

    # -- the contract's read-outs (base.AidedEngine) ---------------------------------------
    @property
    def estimates_R(self):
        """Tell whether the filter estimates the measurement noise itself (variational Bayes)."""
        return bool(getattr(self.kf, 'estimates_R', False))

    @property
    def rejected(self):
        """Tell whether the filter's innovation gate rejected the last GNSS epoch."""
        return bool(self.kf.rejected)

    def heading_found(self):
        """Act on a held-lost heading that a linear heading update set (found again)."""
        self._heading_taken()

    def heading_measured(self):
        """Act on a coarse heading an external source measured (nothing to drop here)."""

    def nav_cov(self):
        """Return None: only the navigating engines (:mod:`.navigation`) have one."""
        return None

    # -- output -------------------------------------------------------------------------
    @property
    def P(self):
        """Error-state covariance (n, n)."""
        return self.kf.P

    def attitude_cov(self):
        """Misalignment covariance about ENU (3, 3), rad^2, with the coarse heading prior.

        When the filter was started from a capped heading prior
        (:data:`HEADING_PRIOR_MAX`), the heading variance is ``1 / (1 / P_uu - 1 / cap^2 +
        1 / sigma_0^2)``: the capped prior's information replaced by the coarse one's,
        never below the filter's own variance, so it equals the coarse bound until the
        GNSS has told the filter something and the filter's own variance once it has
        learned much more than either prior. The heading row and column are scaled
        together, so the matrix stays positive semi-definite.
        """
        P = self.kf.P[self.i_phi, self.i_phi]
        if self.heading_prior_var is None:
            return P
        v = float(P[2, 2])
        if v <= 0.0:
            return P
        learned = max(1.0 / v - 1.0 / HEADING_PRIOR_MAX ** 2, 0.0)
        v_pub = max(v, 1.0 / (learned + 1.0 / self.heading_prior_var))
        s = np.ones(3)
        s[2] = math.sqrt(v_pub / v)
        return P * np.outer(s, s)

    def status(self):
        """Filter internals for diagnostics (plain Python types)."""
        kf = self.kf
        s = {'filter_updates': self.n_updates, 'predict_only_epochs': self.n_predict_only,
             'innovation_nis': self.last_nis, 'divergence_test_fired': kf.divergence_flags,
             'Q_diag': [float(v) for v in np.diag(kf.Q)],
             'R_diag': [float(v) for v in np.diag(kf.R)],
             'R_scale': [float(v) for v in self.R_scale],
             'velocity_jitter_mps': math.sqrt(self.velocity_jitter_var),
             'gyro_drift_dph': [float(v) for v in kf.x[self.i_eps] / DPH],
             'zero_rate_epochs': getattr(self, 'n_still_rate', 0),
             'zero_rate_refused': getattr(self, 'n_still_rate_refused', 0)}
        s.update(self.gate.status())
        if self.heading_gate is not None:
            s.update(self.heading_gate.status())
        if getattr(kf, 'lam', None) is not None:
            s['fading_factors'] = [float(v) for v in kf.lam]
            s['fading_epochs'] = int(kf.n_faded)
        return s
