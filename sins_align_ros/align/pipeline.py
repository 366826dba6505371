"""The alignment pipeline: waiting -> coarse -> fine -> aligned, at IMU rate.

One object, driven the same way by ``alignment_node`` (one message at a time)
and by ``sins_align_replay`` (whole arrays): feed IMU increments with their
stamps to :meth:`AlignmentPipeline.process`, GNSS fixes to
:meth:`AlignmentPipeline.position_fix`; every processed sample yields an output
row (attitude, 1-sigma Euler angles, phase).

Fine alignment (seed 002): the stationary mechanization with the model's
equivalence operations (Table 1) runs at IMU rate; every ``1/fine_update_hz``
the zero-velocity Kalman filter is updated and its misalignment and velocity
estimates are fed back into the mechanization. When the heading uncertainty
has converged the filter is re-initialised (bias states restart from their
prior): seed 002's closing suggestion of staged re-initialisation, which
removes the error that the first transient leaves in the bias estimates.
After ``max_stages`` stages
the phase becomes ``aligned`` (the filter keeps refining).

Moving base (``fine_filter`` ckf or asckf, seed 000): coarse alignment is the
inertial-frame method with the GNSS velocity change removed, and the heading
is taken from the GNSS track when the vehicle moves faster than
``track_min_speed_mps``; fine alignment is :mod:`.moving` (full mechanization,
large-azimuth model, CKF/ASCKF at every GNSS epoch). GNSS epochs are queued
and applied at the first IMU sample at or after their stamp (the measurement
is moved back to the fix time with the current velocity). ``vbckf`` and ``vbch``
(seed 004) use the same coarse stage and :mod:`.robust` (12-state large-misalignment
model, GNSS velocity measured, variational-Bayes R, H-infinity robust factor).
"""
import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from . import params as prm
from .gnss_input import reported_variances
from .moving import FilterDiverged, GnssFix, MovingBaseAlignment
from .navigation import IntegratedNavigation, gyro_tau, model_noise as nav_model_noise
from .preprocess import Preprocessor
from .robust import RobustAlignment, model_noise
from ..filters import kf
from ..models.stationary import NoiseSpec, StationaryModel
from ..nav import coarse, earth
from ..nav.frames import (DEG, dcm_to_euler, dcm_to_quat, euler_cov_from_phi_cov,
                          euler_sigma_one, euler_to_dcm, rotvec_to_dcm)
from ..nav.mechanization import StationaryStrapdown

WAITING, COARSE, FINE, ALIGNED = 'waiting', 'coarse', 'fine', 'aligned'
PHASES = (WAITING, COARSE, FINE, ALIGNED)
_DPH = DEG / 3600.0
_DPSH = DEG / 60.0
_UG = 1e-6 * earth.G0
#: GNSS history kept for the moving-base coarse alignment, s
_GNSS_KEEP = 3600.0
#: a queued GNSS epoch older than this (against the IMU stamps) is dropped, s
_GNSS_MAX_LAG = 1.0
#: a GNSS epoch stamped this far ahead of the IMU clock is dropped (clocks disagree), s
_GNSS_MAX_LEAD = 10.0
#: fixes whose median gives the stationary models their position
_MEDIAN_FIXES = 31
#: the moving-base filters say they run unaided after this long without a GNSS epoch, s
_OUTAGE_WARN_S = 5.0


@dataclass
class Output:
    """Rows for N processed samples.

    ``t`` (N,) stamps (s); ``q`` (N, 4) quaternion x, y, z, w body FLU -> ENU
    (NaN while unknown); ``euler`` (N, 3) REP-103 roll, pitch, yaw (rad);
    ``sigma`` (N, 3) 1-sigma of those angles (rad); ``P_phi`` (N, 3, 3)
    covariance of the misalignment about the ENU axes (rad^2); ``phase`` (N,)
    phase names; ``nav`` (N, 6) or None: the navigation solution of the navigation
    filters (``kf``, ``vbakf``, ``mvbakf``, ``ukf``) at each sample, latitude and
    longitude (rad), height (m), ENU velocity (m/s); NaN where there is none.
    """

    t: np.ndarray
    q: np.ndarray
    euler: np.ndarray
    sigma: np.ndarray
    P_phi: np.ndarray
    phase: np.ndarray
    nav: np.ndarray = None

    @staticmethod
    def concat(parts):
        """Join several outputs in time order."""
        parts = [p for p in parts if len(p.t)]
        if not parts:
            return Output.empty()
        if len(parts) == 1:
            return parts[0]
        out = Output(*(np.concatenate([getattr(p, f) for p in parts])
                       for f in ('t', 'q', 'euler', 'sigma', 'P_phi', 'phase')))
        out.nav = _concat_nav(parts)
        return out

    @staticmethod
    def empty():
        """Return an output with no rows."""
        return Output(np.zeros(0), np.zeros((0, 4)), np.zeros((0, 3)), np.zeros((0, 3)),
                      np.zeros((0, 3, 3)), np.zeros(0, dtype=object))

    def __len__(self):
        return len(self.t)


class _Rows:
    """Fine-phase rows before conversion.

    Attitudes (N, 3, 3), one covariance, and the navigation solution (N, 6) or None.
    """

    __slots__ = ('t', 'C', 'P_phi', 'phase', 'nav')

    def __init__(self, t, C, P_phi, phase, nav=None):
        self.t, self.C, self.P_phi, self.phase, self.nav = t, C, P_phi, phase, nav

    def output(self):
        return _assemble([self])


def _concat_nav(parts):
    """Join the parts' navigation rows (N, 6), NaN for parts without; None if none has any."""
    if all(p.nav is None for p in parts):
        return None
    return np.concatenate([p.nav if p.nav is not None else np.full((len(p.t), 6), np.nan)
                           for p in parts])


def _one_row(t, C, P, phase, nav):
    """One-row :class:`Output` from an attitude (3, 3) and its covariance (3, 3)."""
    eul = dcm_to_euler(C)
    return Output(np.array([t]), dcm_to_quat(C)[None], eul[None],
                  euler_sigma_one(eul, P.tolist())[None], P[None],
                  np.array([phase], dtype=object), nav)


def _assemble(parts):
    """Convert runs of fine-phase :class:`_Rows` in one vectorised pass; join everything."""
    done, run = [], []

    def flush():
        if not run:
            return
        t = np.concatenate([r.t for r in run])
        C = np.concatenate([r.C for r in run])
        P = np.concatenate([np.broadcast_to(r.P_phi, (len(r.t), 3, 3)) for r in run])
        ph = np.concatenate([np.full(len(r.t), r.phase, dtype=object) for r in run])
        eul = dcm_to_euler(C)
        P_e = euler_cov_from_phi_cov(eul, P)
        sig = np.sqrt(np.clip(np.diagonal(P_e, axis1=1, axis2=2), 0.0, None))
        done.append(Output(t, dcm_to_quat(C), eul, sig, P, ph, _concat_nav(run)))
        run.clear()

    for p in parts:
        if isinstance(p, _Rows):
            run.append(p)
        else:
            flush()
            done.append(p)
    flush()
    return Output.concat(done)


def _unknown(t, phase):
    n = len(t)
    nan3 = np.full((n, 3), np.nan)
    return Output(np.asarray(t, float), np.full((n, 4), np.nan), nan3, nan3.copy(),
                  np.full((n, 3, 3), np.nan), np.full(n, phase, dtype=object))


class AlignmentPipeline:
    """Coarse + fine alignment of a (nearly) stationary IMU. See the module docstring.

    Parameters
    ----------
    values : dict
        Alignment parameters by name (``align.params``); missing ones take defaults.
    """

    def __init__(self, values=None):
        cfg = prm.defaults()
        cfg.update(prm.validate(values or {}))
        self.cfg = cfg
        self.noise = NoiseSpec(gyro_bias=math.hypot(cfg['gyro_bias_dph'],
                                                    cfg['gyro_bias_instability_dph']) * _DPH,
                               gyro_arw=cfg['gyro_arw_dpsh'] * _DPSH,
                               accel_bias=cfg['accel_bias_ug'] * _UG,
                               accel_vrw=cfg['accel_vrw_ug_rthz'] * _UG)
        self.moving = cfg['fine_filter'] in prm.MOVING_FILTERS
        self.model = None if self.moving else StationaryModel(cfg['fine_filter'])
        #: the last valid GNSS fix (t, lat_deg, lon_deg, h), kept across resets
        self.last_fix = None
        #: recent fixes (lat_deg, lon_deg, h): their median is the stationary position
        self.recent_fixes = deque(maxlen=_MEDIAN_FIXES)
        self.reset()

    def inherit_gnss(self, other):
        """Take over the GNSS position history of ``other`` (a pipeline being replaced)."""
        self.last_fix = other.last_fix
        self.recent_fixes.extend(other.recent_fixes)

    # -- state ------------------------------------------------------------------
    def reset(self):
        """Forget everything but the parameters and the last GNSS fix; phase -> waiting."""
        self.phase = WAITING
        self.t_last = None
        self.t_first = None
        self._coarse = []            # (t, dtheta, dv) arrays of the coarse window
        self._coarse_T = 0.0
        self.coarse_info = {}
        self.mech = None
        self.x = self.P = None
        self.stage = 0
        self.stage_t0 = None
        self._since_update = 0.0
        self._sig_hist = deque()
        self.n_updates = 0
        self.last_nis = float('nan')
        self.position_source = None
        self.position = None
        self.warnings = []
        self.engine = None
        self._fixes = deque()        # (t, lat, lon, h, pos_var) in rad, rad, m, m^2
        self._vels = deque()         # (t, v_n (3,), vel_var)
        self._pending = deque(maxlen=100)    # fixes waiting for the IMU to pass their stamp
        self.gnss_counts = {'used': 0, 'late': 0, 'before_start': 0, 'ahead_of_imu': 0,
                            'queue_full': 0}
        self._t_gnss_used = None
        self._reported = {'rejected': 0, 'forced': 0, 'ahead_of_imu': 0, 'queue_full': 0}
        cfg = self.cfg
        w = cfg['preprocess_window'] + cfg['preprocess_window'] % 2
        self.pre = Preprocessor(cfg['preprocess_factor'], w, max(1, w // 4),
                                cfg['preprocess_wavelet']) if cfg['preprocess'] else None

    def position_fix(self, t, lat_deg, lon_deg, h, pos_var=None):
        """Record a valid GNSS position (deg, deg, m); ``pos_var`` (2,) east/north m^2 or None.

        ``pos_var`` is taken as the receiver reports it; unless both values are
        finite and positive it is ignored (the configured sigma is used).

        Stationary models: the position is fixed when coarse alignment ends (seed
        002 Table 1), from the latest fix. Moving-base models: every fix is also a
        measurement, applied when the IMU stream passes its stamp.
        """
        t = float(t)
        if self.t_last is not None and t > self.t_last + _GNSS_MAX_LEAD:
            self.gnss_counts['ahead_of_imu'] += 1
            return
        self.last_fix = (t, float(lat_deg), float(lon_deg), float(h))
        self.recent_fixes.append(self.last_fix[1:])
        if not self.moving:
            return
        rec = (t, lat_deg * DEG, lon_deg * DEG, float(h), reported_variances(pos_var))
        self._fixes.append(rec)
        while self._fixes and self._fixes[0][0] < t - _GNSS_KEEP:
            self._fixes.popleft()
        if self.engine is not None:
            if len(self._pending) == self._pending.maxlen:
                self.gnss_counts['queue_full'] += 1     # the oldest is dropped
            self._pending.append(rec)

    def velocity_fix(self, t, v_n, vel_var=None):
        """Record a GNSS ENU velocity (m/s, (3,)); ``vel_var`` (2,) east/north (m/s)^2 or None.

        ``vel_var`` is checked as ``pos_var`` of :meth:`position_fix`.
        """
        if not self.moving:
            return
        t = float(t)
        self._vels.append((t, np.asarray(v_n, dtype=float).copy(),
                           reported_variances(vel_var)))
        while self._vels and self._vels[0][0] < t - _GNSS_KEEP:
            self._vels.popleft()

    def _choose_position(self):
        """Latitude, longitude, height for the fine filter: GNSS (median) or parameters.

        Stationary models: the median of the recent fixes, so that an outlier or a
        short jump does not set their latitude. Moving base: the last fix (the
        filter's innovation gate judges the fixes that follow).
        """
        if self.cfg['use_gnss_position'] and self.recent_fixes:
            if self.moving:
                la, lo, h = self.last_fix[1:]
            else:
                la, lo, h = np.median(np.array(self.recent_fixes), axis=0)
            self.position_source = 'gnss'
        else:
            la, lo, h = (self.cfg['initial_latitude_deg'], self.cfg['initial_longitude_deg'],
                         self.cfg['initial_height_m'])
            self.position_source = 'parameters'
        self.position = np.array([la * DEG, lo * DEG, h])

    @property
    def elapsed(self):
        """Seconds of IMU data since the first sample."""
        return 0.0 if self.t_first is None else self.t_last - self.t_first

    # -- processing ---------------------------------------------------------------
    def feed(self, t, dtheta, dv):
        """Process samples through the optional pre-processing stage (``preprocess``).

        Without it this is :meth:`process`. With it the samples are resampled and
        denoised (:mod:`.preprocess`) and come out later, each with its own stamp:
        the returned :class:`Output` has a row per sample finished by this call
        (none while the stage fills, several at once after).
        """
        if self.pre is None:
            return self.process(t, dtheta, dv)
        t, dtheta, dv = self.pre.push(t, dtheta, dv)
        return self.process(t, dtheta, dv) if len(t) else Output.empty()

    def flush(self):
        """Process the samples the pre-processing stage still holds (end of a recording)."""
        if self.pre is None:
            return Output.empty()
        t, dtheta, dv = self.pre.flush()
        return self.process(t, dtheta, dv) if len(t) else Output.empty()

    def process(self, t, dtheta, dv):
        """Process samples with end stamps ``t`` (N,) and increments (N, 3) over (t_{k-1}, t_k].

        The interval of the very first sample starts at the stamp given to
        :meth:`start_clock`; without it, the first interval is taken equal to the
        second. Returns an :class:`Output` with N rows.
        """
        t = np.atleast_1d(np.asarray(t, dtype=float))
        dtheta = np.atleast_2d(np.asarray(dtheta, dtype=float))
        dv = np.atleast_2d(np.asarray(dv, dtype=float))
        outs = []
        i, n = 0, len(t)
        while i < n:
            if self.phase == WAITING:
                if self.t_last is None:
                    self.t_last = t[i] - self._dt_guess(t, i)
                self.phase = COARSE
                self.t_first = self.t_last
            if self.phase == COARSE:
                j = i
                need = self.cfg['coarse_duration'] - self._coarse_T
                while j < n and need > 1e-9:
                    need -= t[j] - (self.t_last if j == i else t[j - 1])
                    j += 1
                self._coarse_T += t[j - 1] - self.t_last
                self._coarse.append((t[i:j], dtheta[i:j], dv[i:j]))
                self.t_last = t[j - 1]
                out = _unknown(t[i:j], COARSE)
                if self._coarse_T >= self.cfg['coarse_duration'] - 1e-9:
                    self._finish_coarse()
                    if self.phase == FINE:            # else degenerate: coarse again
                        out.phase[-1] = FINE
                        self._fill_last(out)
                outs.append(out)
                i = j
                continue
            # fine / aligned
            period = 1.0 / self.cfg['fine_update_hz']
            if n == 1:                      # the live node's path: scalar arithmetic
                return self._one(t[0], dtheta[0], dv[0], period)
            if self.engine is not None:
                out, used = self._process_moving(t[i:], dtheta[i:], dv[i:])
                outs.append(out)
                i += used
                continue
            # mechanize up to the next filter epoch
            j = i
            acc = self._since_update
            while j < n:
                acc += t[j] - (self.t_last if j == i else t[j - 1])
                j += 1
                if acc >= period - 1e-9:
                    break
            dts = np.diff(np.concatenate([[self.t_last], t[i:j]]))
            res = self.mech.run(dtheta[i:j], dv[i:j], dts)
            self.t_last = t[j - 1]
            self._since_update = acc
            if acc >= period - 1e-9:
                self._filter_step(acc)
                self._since_update = 0.0
                res['C_b_n'][-1] = self.mech.C_b_n
            outs.append(_Rows(t[i:j], res['C_b_n'], self.attitude_cov(), self.phase))
            i = j
        return _assemble(outs)

    def _one(self, t, dtheta, dv, period):
        """Single-sample fine step with scalar arithmetic (the live node's path)."""
        dt = t - self.t_last
        if self.engine is not None:
            C = self.engine.step_imu(dtheta, dv, dt)
            self.t_last = t
            if self._pending and self._pending[0][0] <= t + 1e-9:
                eng = self.engine
                self._apply_pending(t)
                if self.engine is not eng:             # diverged: restarted from coarse
                    nav = (np.full((1, 6), np.nan) if isinstance(eng, IntegratedNavigation)
                           and self.cfg['continue_navigation'] else None)
                    return _one_row(t, eng.mech.C_b_n, eng.attitude_cov(), FINE, nav)
                C = self.mech.C_b_n
        else:
            C = self.mech.step(dtheta, dv, dt)
            self.t_last = t
            self._since_update += dt
            if self._since_update >= period - 1e-9:
                self._filter_step(self._since_update)
                self._since_update = 0.0
                C = self.mech.C_b_n
        nav = None
        if self.navigating:
            m = self.mech
            nav = np.array([[m.lat, m.lon, m.h, m.v_n[0], m.v_n[1], m.v_n[2]]])
        return _one_row(t, C, self.attitude_cov(), self.phase, nav)

    def widen(self, var_phi, var_v=0.0):
        """Widen the fine filter's covariance by an error the input may have left.

        Adds ``var_phi`` (rad^2) to each misalignment variance and ``var_v``
        ((m/s)^2) to each velocity variance (a bridged gap,
        :class:`~sins_align_ros.align.imu_input.ImuInput`). No effect before fine
        alignment.
        """
        if self.phase not in (FINE, ALIGNED) or not (var_phi > 0.0 or var_v > 0.0):
            return
        if self.engine is not None:
            eng = self.engine
            P = eng.kf.P
            k = np.arange(len(P))
            P[k[eng.i_phi], k[eng.i_phi]] += var_phi
            P[k[eng.i_v], k[eng.i_v]] += var_v
            eng.kf.P = P
        else:
            m = self.model
            P = self.P.copy()
            P[m.i_phi, m.i_phi] += var_phi
            P[m.i_v, m.i_v] += var_v
            self.P = P
        self._att_cov = None

    def start_clock(self, t0):
        """Set the stamp that the first increment starts from (before the first process call)."""
        self.t_last = float(t0)

    @staticmethod
    def _dt_guess(t, i):
        if i + 1 < len(t):
            return t[i + 1] - t[i]
        return 0.01

    def start_fine(self, C_b_n, sigma_phi, t0, lat=None, h=0.0):
        """Skip coarse alignment: start fine alignment at ``t0`` from ``C_b_n``.

        ``sigma_phi`` (3,) rad is the misalignment uncertainty; ``lat`` (rad) and
        ``h`` override the position. Used by experiments that impose a known
        initial misalignment (seed 002's 1/5/10 deg cases).
        """
        if self.moving:
            raise ValueError('start_fine is for the stationary models; the moving-base '
                             'filters start from coarse alignment with GNSS')
        self.reset()
        self.t_first = self.t_last = float(t0)
        self._choose_position()
        if lat is not None:
            self.position = np.array([lat, self.position[1], h])
        self._init_fine(np.asarray(C_b_n, float), np.asarray(sigma_phi, float))

    def _finish_coarse(self):
        tt = np.concatenate([c[0] for c in self._coarse])
        dth = np.concatenate([c[1] for c in self._coarse])
        dvv = np.concatenate([c[2] for c in self._coarse])
        dts = np.diff(np.concatenate([[self.t_first], tt]))
        self._coarse = []
        self._choose_position()          # a GNSS fix may have come in during coarse
        lat, _, h = self.position
        method = self.cfg['coarse_method']
        moving, rate_sc, tilt_sc = coarse.detect_motion(dth, dvv, dts, self.noise.gyro_arw,
                                                        self.noise.accel_vrw)
        if method == 'auto':
            method = 'inertial_frame' if moving else 'analytic'
        if self.moving:
            C = None
        elif method == 'analytic':
            C = coarse.analytic(dth, dvv, dts, lat)
        else:
            C = coarse.inertial_frame(dth, dvv, dts, lat, h)
        T = float(np.sum(dts))
        self.coarse_info = {'method': method, 'motion_detected': moving,
                            'rate_scatter_dph': rate_sc / _DPH, 'tilt_scatter_urad': tilt_sc * 1e6,
                            'duration_s': T}
        if self.moving:
            self.coarse_info['method'] = 'inertial_frame'
            self._finish_coarse_moving(tt, dth, dvv, dts, moving, T)
            return
        if not self._coarse_ok(C):
            return
        self._init_fine(C, self._coarse_sigma(T, lat, moving))

    def _coarse_ok(self, C):
        """Check a coarse result; if non-finite, restart coarse alignment (with the reason)."""
        if np.all(np.isfinite(C)):
            return True
        self._diverged('coarse alignment degenerate: no usable gravity or Earth-rate '
                       'direction in the window (gyro or accelerometer output near zero?)')
        return False

    # -- moving base ----------------------------------------------------------------
    def _process_moving(self, t, dtheta, dv):
        """Mechanize samples, applying queued GNSS epochs as the stamps pass them.

        Returns ``(Output, number of samples consumed)``: fewer than given when the
        filter diverged and the pipeline went back to coarse alignment.
        """
        eng = self.engine
        m = eng.mech
        n = len(t)
        Cs = np.empty((n, 3, 3))
        nav = np.empty((n, 6)) if self.navigating else None
        parts, start = [], 0
        for k in range(n):
            tk = t[k]
            Cs[k] = eng.step_imu(dtheta[k], dv[k], tk - self.t_last)
            self.t_last = tk
            if self._pending and self._pending[0][0] <= tk + 1e-9:
                if k > start:
                    parts.append(_Rows(t[start:k], Cs[start:k], self.attitude_cov(), self.phase,
                                       None if nav is None else nav[start:k]))
                    start = k
                self._apply_pending(tk)
                Cs[k] = m.C_b_n
                if self.engine is not eng:             # diverged: restarted from coarse
                    if nav is not None:
                        nav[k] = np.nan
                    parts.append(_Rows(t[start:k + 1], Cs[start:k + 1], eng.attitude_cov(),
                                       FINE, None if nav is None else nav[start:k + 1]))
                    return _assemble(parts), k + 1
            if nav is not None:
                v = m.v_n
                nav[k] = (m.lat, m.lon, m.h, v[0], v[1], v[2])
        parts.append(_Rows(t[start:], Cs[start:], self.attitude_cov(), self.phase,
                           None if nav is None else nav[start:]))
        return _assemble(parts), n

    def _apply_pending(self, t_now):
        while self._pending and self._pending[0][0] <= t_now + 1e-9:
            t_f, lat, lon, h, pv = self._pending.popleft()
            if t_f <= self.stage_t0:
                self.gnss_counts['before_start'] += 1
                continue
            if t_now - t_f > _GNSS_MAX_LAG:
                self.gnss_counts['late'] += 1
                continue
            v, vv = self._velocity_at_stamp(t_f)
            try:
                self.engine.update(GnssFix(t_f, lat, lon, h, v, pv, vv), t_now)
            except FilterDiverged as exc:
                self._diverged(str(exc))
                return
            self._t_gnss_used = t_f
            self.gnss_counts['used'] += 1
            self._att_cov = None
            self._check_convergence()

    def _diverged(self, reason):
        """Restart from coarse alignment after a filter failure, keeping GNSS history."""
        fixes, vels, last = self._fixes, self._vels, self.last_fix
        t = self.t_last
        self.reset()
        self.last_fix, self._fixes, self._vels = last, fixes, vels
        self.t_last = t
        self.n_restarts = getattr(self, 'n_restarts', 0) + 1
        self.warnings.append(f'{reason}: alignment restarted from coarse')

    def _velocity_at_stamp(self, t_f):
        """GNSS velocity with the fix's stamp (within 20 ms), or (None, None)."""
        for t_v, v, vv in reversed(self._vels):
            if abs(t_v - t_f) <= 0.02:
                return v, vv
            if t_v < t_f - 0.02:
                break
        return None, None

    def _gnss_velocity(self, tt):
        """GNSS velocity at stamps ``tt`` (N, 3), its 1-sigma (m/s), source; or (None, ...).

        From gnss/vel when at least two messages cover the window, else from the
        fixes by a least-squares slope over +-3 epochs.
        """
        lo, hi = tt[0] - 2.0, tt[-1] + 2.0
        vels = [(tv, v) for tv, v, _ in self._vels if lo <= tv <= hi]
        if len(vels) >= 2 and vels[0][0] <= tt[0] + 2.0 and vels[-1][0] >= tt[-1] - 2.0:
            tv = np.array([a for a, _ in vels])
            V = np.array([b for _, b in vels])
            out = np.column_stack([np.interp(tt, tv, V[:, i]) for i in range(3)])
            return out, self.cfg['gnss_vel_sigma_mps'], 'gnss_velocity'
        fixes = [f for f in self._fixes if lo <= f[0] <= hi]
        if len(fixes) < 7 or fixes[0][0] > tt[0] + 2.0 or fixes[-1][0] < tt[-1] - 2.0:
            return None, None, 'none'
        tf = np.array([f[0] for f in fixes])
        lat0, lon0, h0 = fixes[0][1:4]
        enu = earth.local_offset_m(lat0, lon0, h0, np.array([f[1] for f in fixes]),
                                   np.array([f[2] for f in fixes]),
                                   np.array([f[3] for f in fixes]))
        w = 3
        vt, vv = [], []
        for i in range(w, len(tf) - w):
            sl = slice(i - w, i + w + 1)
            tc = tf[sl] - tf[i]
            vv.append((tc @ (enu[sl] - enu[sl].mean(axis=0))) / (tc @ tc))
            vt.append(tf[i])
        vt, vv = np.array(vt), np.array(vv)
        out = np.column_stack([np.interp(tt, vt, vv[:, i]) for i in range(3)])
        dt_fix = float(np.median(np.diff(tf)))
        sig = self.cfg['gnss_pos_sigma_m'] * math.sqrt(12.0 / (2 * w + 1) / (
            (2 * w + 1) ** 2 - 1)) / dt_fix
        return out, sig, 'gnss_positions'

    def _finish_coarse_moving(self, tt, dth, dvv, dts, moving, T):
        """Coarse alignment on a moving base and the start of the seed 000 filter."""
        cfg, nz = self.cfg, self.noise
        lat, lon, h = self.position
        V, v_sig, v_src = self._gnss_velocity(tt)
        steady = V is not None and _steady_velocity(V, v_sig)
        dv_n = None if V is None or steady else V - V[0]
        C = coarse.inertial_frame(dth, dvv, dts, lat, h, dv_n=dv_n)
        if not self._coarse_ok(C):
            return
        sigma = self._coarse_sigma(T, lat, moving, cap=90.0 * DEG)
        if dv_n is not None:
            # the GNSS velocity noise enters the fit against the horizontal gravity
            # integral, which grows as g W cos(L) T^2 / 2 (about 1 m/s after 60 s)
            signal = earth.gravity(lat, h) * earth.OMEGA_IE * math.cos(lat) * T * T / 2.0
            sigma[2] = min(math.hypot(sigma[2], 3.0 * math.sqrt(2.0) * v_sig / signal),
                           90.0 * DEG)
        if V is None and moving:
            sigma[:2] *= 3.0
            self.warnings.append('the base moves and no GNSS velocity covers the coarse window: '
                                 'tilt from specific force alone')
        v_end = np.zeros(3) if V is None else V[-1]
        speed = float(np.hypot(v_end[0], v_end[1]))
        head_src = 'inertial_frame'
        if V is not None and speed >= cfg['track_min_speed_mps']:
            eul = dcm_to_euler(C)
            eul[2] = math.atan2(v_end[1], v_end[0])
            C = euler_to_dcm(eul)
            sigma[2] = cfg['track_heading_sigma_deg'] * DEG
            head_src = 'gnss_track'
        if self.last_fix is not None and cfg['use_gnss_position']:
            t_f = self.last_fix[0]
            R_M, R_N = earth.radii(lat)
            lat += v_end[1] * (self.t_last - t_f) / (R_M + h)
            lon += v_end[0] * (self.t_last - t_f) / ((R_N + h) * math.cos(lat))
        s_v = 0.5 if v_sig is None else max(2.0 * v_sig, 0.02)
        # drift states: a random constant, plus a random walk that lets them follow a
        # Gauss-Markov bias of the given sigma and correlation time (2 sigma^2 / tau)
        q_drift = 2.0 * (cfg['gyro_bias_instability_dph'] * _DPH) ** 2 / cfg['gyro_bias_tau_s']
        gate = dict(gate_probability=(None if cfg['gnss_gate_probability'] >= 1.0
                                      else cfg['gnss_gate_probability']),
                    gate_max_rejects=cfg['gnss_gate_max_rejects'])
        drift0 = max(nz.gyro_bias, 1e-3 * _DPH) ** 2
        if cfg['fine_filter'] in prm.ROBUST_FILTERS:
            self.engine = self._robust_engine(C, v_end, lat, lon, h, sigma, s_v, q_drift,
                                              gate)
        elif cfg['fine_filter'] in prm.NAV_FILTERS:
            self.engine = self._nav_engine(C, v_end, lat, lon, h, sigma, s_v, gate)
        else:
            s_p = cfg['gnss_pos_sigma_m']
            P0 = np.diag(np.r_[[s_v ** 2] * 2, [s_p ** 2] * 2, sigma ** 2, [drift0] * 3])
            Qc = np.r_[[nz.accel_vrw ** 2] * 2, 0.0, 0.0, [nz.gyro_arw ** 2] * 3,
                       [q_drift] * 3]
            use_vel = bool(cfg['use_gnss_velocity'] and self._vels)
            R = [s_p ** 2] * 2 + ([cfg['gnss_vel_sigma_mps'] ** 2] * 2 if use_vel else [])
            asckf = cfg['fine_filter'] == 'asckf'
            self.engine = MovingBaseAlignment(
                C, v_end, lat, lon, h, P0, Qc, np.diag(R), use_velocity=use_vel,
                square_root=asckf, fading=asckf and cfg['asckf_fading'],
                adaptive=asckf and cfg['asckf_adaptive'], adapt_q=cfg['asckf_adapt_q'],
                b=cfg['asckf_forgetting'], use_reported_cov=cfg['use_reported_gnss_covariance'],
                **gate)
        self.mech = self.engine.mech
        self.coarse_info.update({'velocity_source': v_src, 'heading_source': head_src,
                                 'speed_mps': speed, 'steady_velocity': bool(steady)})
        self.phase = FINE
        self.stage = 1
        self.stage_t0 = self.t_last
        # the 10-state model has no accelerometer bias: the tilt it leaves (bias / g)
        # is added at the output, as for the stationary models' attitude floor (the
        # 12-state model of vbckf/vbch estimates the bias itself)
        tilt_floor = 0.0 if isinstance(self.engine, (RobustAlignment, IntegratedNavigation)) \
            else (nz.accel_bias / earth.gravity(lat, h)) ** 2
        self.floor = np.array([tilt_floor, tilt_floor, 0.0])
        self._sig_hist.clear()
        self.P = self.engine.P
        # fixes that came in during coarse alignment are history, not measurements
        self._pending.clear()

    def _robust_engine(self, C, v_n, lat, lon, h, sigma, s_v, q_drift, gate):
        """Seed 004's VBCKF / VBCH engine (12 states, GNSS velocity measured)."""
        cfg = self.cfg
        P0, Qc = model_noise(sigma, s_v, self.noise, q_drift)
        R = np.eye(3) * cfg['gnss_vel_sigma_mps'] ** 2
        if not self._vels:
            self.warnings.append(f"{cfg['fine_filter']} measures the GNSS velocity: no "
                                 'velocity has arrived yet (fixes reset the position only)')
        return RobustAlignment(C, v_n, lat, lon, h, P0, Qc, R,
                               robust=cfg['fine_filter'] == 'vbch', rho=cfg['vb_forgetting'],
                               n_iter=cfg['vb_iterations'], C=cfg['vbch_c'],
                               dof=cfg['vb_outlier_dof'] or None, **gate)

    def _nav_engine(self, C, v_n, lat, lon, h, sigma, s_v, gate):
        """Seed 001's 15-state (kf, vbakf, mvbakf) or seed 003's 18-state (ukf) engine."""
        cfg = self.cfg
        ff = cfg['fine_filter']
        n = 18 if ff == 'ukf' else 15
        gyro = (cfg['gyro_bias_dph'] * _DPH, cfg['gyro_bias_instability_dph'] * _DPH)
        accel = (cfg['accel_bias_ug'] * _UG, 0.0)
        tau_g = gyro_tau(n, gyro, cfg['gyro_bias_tau_s'])
        P0, Qc = nav_model_noise(n, sigma, s_v, max(cfg['gnss_pos_sigma_m'],
                                                    cfg['gnss_height_sigma_m']),
                                 gyro, accel, self.noise.gyro_arw, self.noise.accel_vrw,
                                 tau_g, cfg['accel_bias_tau_s'], q_scale=cfg['nav_q_scale'])
        R = np.diag([cfg['gnss_pos_sigma_m'] ** 2] * 2 + [cfg['gnss_height_sigma_m'] ** 2]
                    + [cfg['gnss_vel_sigma_mps'] ** 2] * 3)
        return IntegratedNavigation(
            C, v_n, lat, lon, h, P0, Qc, R, method=ff, tau_g=tau_g,
            tau_a=cfg['accel_bias_tau_s'], rho=cfg['nav_forgetting'],
            n_iter=cfg['nav_iterations'], tau=cfg['mvbakf_tau'],
            moment=cfg['mvbakf_moment'],
            use_velocity=cfg['use_gnss_velocity'], **gate)

    @property
    def navigating(self):
        """Tell whether a navigation filter runs and ``continue_navigation`` wants its output."""
        return isinstance(self.engine, IntegratedNavigation) and self.cfg['continue_navigation']

    def nav_cov(self):
        """Covariance (9, 9) of position, velocity and misalignment errors, or None.

        :meth:`~sins_align_ros.align.navigation.IntegratedNavigation.nav_cov`.
        """
        return self.engine.nav_cov() if isinstance(self.engine, IntegratedNavigation) else None

    def _coarse_sigma(self, T, lat, moving, cap=30.0 * DEG):
        """Conservative 1-sigma misalignment (rad) after coarse alignment over T seconds."""
        nz = self.noise
        g = earth.gravity(lat, 0.0)
        wc = earth.OMEGA_IE * np.cos(lat)
        tilt = 3.0 * np.hypot(nz.accel_bias / g, nz.accel_vrw / (g * np.sqrt(T)))
        head = 3.0 * np.hypot(nz.gyro_bias, nz.gyro_arw / np.sqrt(T)) / wc
        head += abs(np.tan(lat)) * tilt
        if moving:
            tilt, head = 2.0 * tilt, 2.0 * head
        tilt = max(tilt, 0.05 * DEG)
        head = min(max(head, 0.5 * DEG), cap)
        if nz.gyro_bias > 0.5 * wc:
            self.warnings.append(
                f'gyro bias {nz.gyro_bias / _DPH:.3g} deg/h is not small against the '
                f'horizontal Earth rate {wc / _DPH:.3g} deg/h: heading cannot be found on a '
                f'still base (motion with GNSS aiding is needed)')
        return np.array([tilt, tilt, head])

    def _init_fine(self, C_b_n, sigma_phi):
        lat, lon, h = self.position
        m = self.model
        self.mech = StationaryStrapdown(C_b_n, lat, lon, h, coriolis=m.mech.coriolis,
                                        hold_vertical=m.mech.hold_vertical)
        self.g = earth.gravity(lat, h)
        self.x = np.zeros(m.n)
        self.P = m.P0(0.01, sigma_phi, self.noise)
        self.H = m.H()
        self.R = np.eye(len(m.meas)) * self.cfg['zero_velocity_sigma'] ** 2
        self.floor = m.attitude_floor(lat, self.noise)
        self.phase = FINE
        self.stage = 1
        self.stage_t0 = self.t_last
        self._since_update = 0.0
        self._sig_hist.clear()
        self._disc_cache = {}

    def _discretize(self, dt):
        m = self.model
        key = round(dt, 9)
        if m.name == 'reduced7' and key in self._disc_cache:
            return self._disc_cache[key]
        F = m.F(self.mech.C_b_n, self.position[0], self.g)
        G, Qc = m.G_Qc(self.mech.C_b_n, self.noise)
        res = kf.discretize(F, G, Qc, dt)
        if m.name == 'reduced7':
            self._disc_cache[key] = res
        return res

    def _filter_step(self, dt):
        m = self.model
        Phi, Qd = self._discretize(dt)
        self.x, self.P = kf.predict(self.x, self.P, Phi, Qd)
        z = self.mech.v_n[m.meas]
        self.x, self.P, y, S = kf.update(self.x, self.P, z, self.H, self.R)
        self.last_nis = kf.nis(y, S)
        self.n_updates += 1
        # feedback: C = exp([phi x]) C~ (seed 002 eq. 3), velocity error removed
        phi = self.x[m.i_phi]
        self.mech.C_b_n = rotvec_to_dcm(phi) @ self.mech.C_b_n
        dvel = np.zeros(3)
        dvel[m.meas] = self.x[m.i_v]
        self.mech.v_n = self.mech.v_n - dvel
        self.mech._v_prev = self.mech._v_prev - dvel
        self.x[m.i_phi] = 0.0
        self.x[m.i_v] = 0.0
        self._check_convergence()

    def _check_convergence(self):
        if self.engine is not None:
            sig_u = math.sqrt(max(self.attitude_cov()[2, 2], 0.0))
        else:
            i_u = self.model.i_phi[2]
            sig_u = np.sqrt(self.P[i_u, i_u] + self.floor[2])
        t = self.t_last
        self._sig_hist.append((t, sig_u))
        while self._sig_hist and self._sig_hist[0][0] < t - 10.0:
            self._sig_hist.popleft()
        if t - self.stage_t0 < self.cfg['stage_min_duration']:
            return
        t_old, s_old = self._sig_hist[0]
        if t - t_old < 9.0 or sig_u < 0.98 * s_old:
            return
        if self.stage < self.cfg['max_stages'] and self.engine is None:
            self._restage()
        elif self.phase == FINE:
            self.phase = ALIGNED

    def _restage(self):
        """Seed 002 sec. 4: re-initialise the filter from the corrected attitude.

        The bias states, which absorbed the transient of the first stage (the
        nonlinear effect of a large initial misalignment), restart from their
        prior, uncorrelated with the misalignment.

        * reduced7: the misalignment keeps its current variance. Its unobservable
          part is not in P but added at the output (attitude floor), so nothing
          is counted twice; keeping the variance keeps the averaging already done
          on the heading (a widened restart let it wander outside the limit band).
        * stationary10/12: their P holds the bias/misalignment ambiguity itself;
          a fresh bias prior next to the old misalignment variance would count
          that information twice (Monte Carlo: 92% inside 3 sigma, NEES 6.9), so
          the misalignment restarts from three times its current sigma.
        """
        m = self.model
        ip = m.i_phi
        widen = 1.0 if m.name == 'reduced7' else 3.0
        P_phi = np.diag(np.diag(self.P)[ip]) * widen ** 2
        self.x, self.P = m.reset_biases(self.x, self.P, self.noise)
        other = np.setdiff1d(np.arange(m.n), ip)
        self.P[np.ix_(ip, ip)] = P_phi
        self.P[np.ix_(ip, other)] = 0.0
        self.P[np.ix_(other, ip)] = 0.0
        self.stage += 1
        self.stage_t0 = self.t_last
        self._sig_hist.clear()

    # -- output -------------------------------------------------------------------
    @property
    def P(self):
        """Filter covariance (n, n); setting it refreshes the cached attitude covariance."""
        return self._P

    @P.setter
    def P(self, value):
        self._P = value
        self._att_cov = None

    def attitude_cov(self):
        """Misalignment covariance about ENU (3, 3), including what the model cannot see.

        Cached between filter epochs: the per-sample output path reads it at IMU rate.
        """
        if self._att_cov is None:
            if self.engine is not None:
                self._att_cov = self.engine.attitude_cov() + np.diag(self.floor)
            else:
                ip = self.model.i_phi
                self._att_cov = self._P[np.ix_(ip, ip)] + np.diag(self.floor)
        return self._att_cov

    def _fill_last(self, out):
        """Put the coarse result into the last row of a coarse block."""
        r = _Rows(out.t[-1:], self.mech.C_b_n[None], self.attitude_cov(), FINE).output()
        out.q[-1], out.euler[-1], out.sigma[-1], out.P_phi[-1] = r.q[0], r.euler[0], \
            r.sigma[0], r.P_phi[0]

    def conditions(self):
        """Return the current degraded conditions as ``[(level, text)]`` (1 warn, 2 error).

        Counts are compared with the previous call, so each rejection is reported
        once: GNSS epochs rejected by the innovation gate, re-anchoring after a run
        of rejections, fixes stamped ahead of the IMU clock, and a moving-base
        filter running without GNSS.
        """
        out = []
        eng = self.engine
        if eng is not None:
            n = self._since_reported('rejected', eng.n_rejected)
            if n > 0:
                t_r, nis, thr = eng.last_rejection
                out.append((1, f'{n} GNSS epoch(s) rejected by the innovation gate (last at '
                               f't={t_r:.1f} s: NIS {nis:.1f} > {thr:.1f}, chi-square '
                               f'{eng.gate_probability})'))
            if self._since_reported('forced', eng.n_forced) > 0:
                out.append((1, f'GNSS accepted again after {eng.gate_max_rejects} rejected '
                               'epochs, with widened position/velocity variance '
                               '(re-anchored: position jump or filter lag)'))
            t_ref = self._t_gnss_used if self._t_gnss_used is not None else self.stage_t0
            if t_ref is not None and self.t_last - t_ref > _OUTAGE_WARN_S:
                out.append((1, f'no GNSS epoch used for {self.t_last - t_ref:.1f} s: '
                               'moving-base filter running unaided (attitude sigma growing)'))
        n = self._since_reported('queue_full', self.gnss_counts['queue_full'])
        if n > 0:
            out.append((1, f'{n} GNSS epoch(s) dropped: more than {self._pending.maxlen} '
                           'waiting for the IMU stream to reach their stamps'))
        n = self._since_reported('ahead_of_imu', self.gnss_counts['ahead_of_imu'])
        if n > 0:
            out.append((1, f'{n} GNSS message(s) stamped more than {_GNSS_MAX_LEAD:.0f} s '
                           'ahead of the IMU clock: skipped (clocks disagree)'))
        return out

    def _since_reported(self, key, count):
        """Return how much ``count`` grew since the last call for ``key``."""
        n = count - self._reported[key]
        self._reported[key] = count
        return n

    def status(self):
        """Key figures for diagnostics (plain Python types)."""
        s = {'phase': self.phase, 'elapsed_s': self.elapsed,
             'fine_filter': self.cfg['fine_filter'],
             'position_source': self.position_source or 'none', 'stage': self.stage,
             'filter_updates': self.n_updates}
        if self.position is not None:
            s['latitude_deg'] = self.position[0] / DEG
        if self.P is not None:
            P_e = euler_cov_from_phi_cov(dcm_to_euler(self.mech.C_b_n), self.attitude_cov())
            for k, name in enumerate(('roll', 'pitch', 'yaw')):
                s[f'sigma_{name}_deg'] = float(np.sqrt(max(P_e[k, k], 0.0)) / DEG)
            s['innovation_nis'] = self.last_nis
        if self.engine is not None:
            s.update(self.engine.status())
            s.update({f'gnss_{k}': v for k, v in self.gnss_counts.items()})
        s.update({f'coarse_{k}': v for k, v in self.coarse_info.items()})
        return s


def _steady_velocity(V, v_sig):
    """Tell whether the horizontal velocity (N, 3) is constant within its noise ``v_sig``.

    Then the inertial-frame coarse alignment is better off assuming no velocity
    change than subtracting a noisy one: its heading signal after T seconds is only
    about g W cos(L) T^2 / 2 (1 m/s at 60 s), so 0.05 m/s of noise on the first
    velocity alone would turn the heading by degrees.
    """
    dev = V[:, :2] - V[:, :2].mean(axis=0)
    return bool(np.mean(np.sum(dev * dev, axis=1)) < 2.0 * (2.0 * v_sig * v_sig))


def feed_arrays(p, imu, gnss, use_velocity=True, block=100, callback=None):
    """Feed whole recorded or simulated arrays to pipeline ``p`` in time order.

    ``imu`` has ``t``, ``dtheta``, ``dv`` (N, ...); ``gnss`` has ``t``, ``lat``,
    ``lon`` (rad), ``h``, ``v_n`` (M, 3), ``fix`` (M,) bool and ``pos_cov``/``vel_cov``
    (ENU variances), or is None. GNSS epochs are given before the IMU block that
    passes their stamps, as a live node would receive them. ``callback(p)``, if given,
    is called after each block (e.g. to record filter internals). Returns the
    :class:`Output`.
    """
    outs, gi = [], 0
    n = len(imu.t)
    m = 0 if gnss is None else len(gnss.t)
    for i in range(0, n, block):
        j = min(n, i + block)
        while gi < m and gnss.t[gi] <= imu.t[j - 1] + 1e-9:
            if gnss.fix[gi]:
                p.position_fix(gnss.t[gi], gnss.lat[gi] / DEG, gnss.lon[gi] / DEG, gnss.h[gi],
                               pos_var=np.asarray(gnss.pos_cov)[:2])
                if use_velocity:
                    p.velocity_fix(gnss.t[gi], gnss.v_n[gi],
                                   vel_var=np.asarray(gnss.vel_cov)[:2])
            gi += 1
        outs.append(p.feed(imu.t[i:j], imu.dtheta[i:j], imu.dv[i:j]))
        if callback is not None:
            callback(p)
    outs.append(p.flush())
    return Output.concat(outs)
