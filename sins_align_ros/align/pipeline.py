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
"""
from collections import deque
from dataclasses import dataclass

import numpy as np

from . import params as prm
from ..filters import kf
from ..models.stationary import NoiseSpec, StationaryModel
from ..nav import coarse, earth
from ..nav.frames import (DEG, dcm_to_euler, dcm_to_quat, euler_cov_from_phi_cov,
                          euler_sigma_one, rotvec_to_dcm)
from ..nav.mechanization import StationaryStrapdown

WAITING, COARSE, FINE, ALIGNED = 'waiting', 'coarse', 'fine', 'aligned'
PHASES = (WAITING, COARSE, FINE, ALIGNED)
_DPH = DEG / 3600.0
_DPSH = DEG / 60.0
_UG = 1e-6 * earth.G0


@dataclass
class Output:
    """Rows for N processed samples.

    ``t`` (N,) stamps (s); ``q`` (N, 4) quaternion x, y, z, w body FLU -> ENU
    (NaN while unknown); ``euler`` (N, 3) REP-103 roll, pitch, yaw (rad);
    ``sigma`` (N, 3) 1-sigma of those angles (rad); ``P_phi`` (N, 3, 3)
    covariance of the misalignment about the ENU axes (rad^2); ``phase`` (N,)
    phase names.
    """

    t: np.ndarray
    q: np.ndarray
    euler: np.ndarray
    sigma: np.ndarray
    P_phi: np.ndarray
    phase: np.ndarray

    @staticmethod
    def concat(parts):
        """Join several outputs in time order."""
        parts = [p for p in parts if len(p.t)]
        if not parts:
            return Output.empty()
        if len(parts) == 1:
            return parts[0]
        return Output(*(np.concatenate([getattr(p, f) for p in parts])
                        for f in ('t', 'q', 'euler', 'sigma', 'P_phi', 'phase')))

    @staticmethod
    def empty():
        """Return an output with no rows."""
        return Output(np.zeros(0), np.zeros((0, 4)), np.zeros((0, 3)), np.zeros((0, 3)),
                      np.zeros((0, 3, 3)), np.zeros(0, dtype=object))

    def __len__(self):
        return len(self.t)


class _Rows:
    """Fine-phase rows before conversion: attitudes (N, 3, 3) and one covariance."""

    __slots__ = ('t', 'C', 'P_phi', 'phase')

    def __init__(self, t, C, P_phi, phase):
        self.t, self.C, self.P_phi, self.phase = t, C, P_phi, phase

    def output(self):
        return _assemble([self])


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
        done.append(Output(t, dcm_to_quat(C), eul, sig, P, ph))
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
        self.noise = NoiseSpec(gyro_bias=cfg['gyro_bias_dph'] * _DPH,
                               gyro_arw=cfg['gyro_arw_dpsh'] * _DPSH,
                               accel_bias=cfg['accel_bias_ug'] * _UG,
                               accel_vrw=cfg['accel_vrw_ug_rthz'] * _UG)
        self.model = StationaryModel(cfg["fine_filter"])
        #: the last valid GNSS fix (t, lat_deg, lon_deg, h), kept across resets
        self.last_fix = None
        self.reset()

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

    def position_fix(self, t, lat_deg, lon_deg, h):
        """Record a valid GNSS position (deg, deg, m).

        The position is fixed when coarse alignment ends (the stationary models
        keep it constant, seed 002 Table 1); the latest fix before that is used.
        """
        self.last_fix = (float(t), float(lat_deg), float(lon_deg), float(h))

    def _choose_position(self):
        if self.cfg['use_gnss_position'] and self.last_fix is not None:
            _, la, lo, h = self.last_fix
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
                    out.phase[-1] = FINE
                    self._fill_last(out)
                outs.append(out)
                i = j
                continue
            # fine / aligned: mechanize up to the next filter epoch
            period = 1.0 / self.cfg['fine_update_hz']
            if n == 1:
                return self._one(t[0], dtheta[0], dv[0], period)
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
        C = self.mech.step(dtheta, dv, dt)
        self.t_last = t
        self._since_update += dt
        if self._since_update >= period - 1e-9:
            self._filter_step(self._since_update)
            self._since_update = 0.0
            C = self.mech.C_b_n
        P = self.attitude_cov()
        eul = dcm_to_euler(C)
        return Output(np.array([t]), dcm_to_quat(C)[None], eul[None],
                      euler_sigma_one(eul, P.tolist())[None], P[None],
                      np.array([self.phase], dtype=object))

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
        if method == 'analytic':
            C = coarse.analytic(dth, dvv, dts, lat)
        else:
            C = coarse.inertial_frame(dth, dvv, dts, lat, h)
        T = float(np.sum(dts))
        self.coarse_info = {'method': method, 'motion_detected': moving,
                            'rate_scatter_dph': rate_sc / _DPH, 'tilt_scatter_urad': tilt_sc * 1e6,
                            'duration_s': T}
        self._init_fine(C, self._coarse_sigma(T, lat, moving))

    def _coarse_sigma(self, T, lat, moving):
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
        head = min(max(head, 0.5 * DEG), 30.0 * DEG)
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
        if self.stage < self.cfg['max_stages']:
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
            ip = self.model.i_phi
            self._att_cov = self._P[np.ix_(ip, ip)] + np.diag(self.floor)
        return self._att_cov

    def _fill_last(self, out):
        """Put the coarse result into the last row of a coarse block."""
        r = _Rows(out.t[-1:], self.mech.C_b_n[None], self.attitude_cov(), FINE).output()
        out.q[-1], out.euler[-1], out.sigma[-1], out.P_phi[-1] = r.q[0], r.euler[0], \
            r.sigma[0], r.P_phi[0]

    def status(self):
        """Key figures for diagnostics (plain Python types)."""
        s = {'phase': self.phase, 'elapsed_s': self.elapsed, 'fine_filter': self.model.name,
             'position_source': self.position_source or 'none', 'stage': self.stage,
             'filter_updates': self.n_updates}
        if self.position is not None:
            s['latitude_deg'] = self.position[0] / DEG
        if self.P is not None:
            P_e = euler_cov_from_phi_cov(dcm_to_euler(self.mech.C_b_n), self.attitude_cov())
            for k, name in enumerate(('roll', 'pitch', 'yaw')):
                s[f'sigma_{name}_deg'] = float(np.sqrt(max(P_e[k, k], 0.0)) / DEG)
            s['innovation_nis'] = self.last_nis
        s.update({f'coarse_{k}': v for k, v in self.coarse_info.items()})
        return s
