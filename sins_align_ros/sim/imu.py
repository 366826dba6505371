"""IMU increments consistent with a trajectory, and IMU error models.

Ideal increments are the exact integrals over each sample interval of the
body angular rate ``w_ib_b = w_nb_b + C_n_b (w_ie_n + w_en_n)`` and of the
specific force ``f_b = C_n_b (a_n + (2 w_ie_n + w_en_n) x v_n - g_n)``,
evaluated with 4-point Gauss-Legendre quadrature (exact for polynomials of
degree 7: round-off level at IMU rates). Earth rate, transport rate, Coriolis
and normal gravity come from :mod:`sins_align_ros.nav.earth`, the same model
the mechanization uses, so error-free data integrate back to the truth.

Errors (:class:`ImuSpec`, datasheet units) are added to the increments of each
triad (gyro: angle, accelerometer: velocity)::

    measured = (I + S + M) true + (bias + markov) dt + white + vibration

with ``S = diag(scale factors)`` and ``M`` the axis misalignment (non-orthogonality):
zero diagonal, off-diagonal entry ``M[i, j]`` the share of axis ``j``'s true input
that axis ``i`` reads. Then quantization, with the remainder carried to the next
sample (as a real counter does). White noise is the angle/velocity random walk,
markov a first-order Gauss-Markov bias (sigma, tau). The vibration (optional, of the
vehicle rather than the sensor) is the difference of a bounded band-limited process
across each interval: large sample-to-sample rate and specific-force noise that does
not integrate into drift (see :class:`ImuSpec`).
"""
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.signal import lfilter

from ..nav import earth
from ..nav.frames import euler_rates_to_w_nb_b, euler_to_dcm
from ..units import ARCSEC, DEG, DPH, DPSH, UG
from .trajectory import PositionIntegrator

_GL_X, _GL_W = np.polynomial.legendre.leggauss(4)


def _vec3(x):
    return np.broadcast_to(np.asarray(x, dtype=float), (3,)).copy()


_OFF_DIAGONAL = ~np.eye(3, dtype=bool)


def _misalignment(x):
    """3x3 misalignment (dimensionless) of a ``*_misalign_ppm`` value, zero diagonal."""
    m = np.broadcast_to(np.asarray(x, dtype=float), (3, 3)) * 1e-6
    return np.where(_OFF_DIAGONAL, m, 0.0)


@dataclass(frozen=True)
class ImuSpec:
    """IMU error parameters in datasheet units (scalars apply to all three axes).

    Attributes
    ----------
    gyro_bias_dph : float or (3,)
        Constant gyro bias, deg/h.
    gyro_arw_dpsh : float
        Angle random walk, deg/sqrt(h).
    gyro_markov_dph, gyro_markov_tau_s : float
        First-order Gauss-Markov bias: steady-state sigma (deg/h), correlation time (s).
    gyro_scale_ppm : float or (3,)
        Scale-factor error per axis, ppm (the diagonal of ``S``).
    gyro_misalign_ppm : float or (3, 3)
        Axis misalignment (non-orthogonality), ppm: a scalar puts that value on all six
        off-diagonal entries of ``M``; a 3x3 array gives them (its diagonal is ignored).
    gyro_quant_arcsec : float
        Angle increment LSB, arcsec (0: none).
    accel_bias_ug : float or (3,)
        Constant accelerometer bias, micro-g.
    accel_vrw_ug_rthz : float
        Velocity random walk as white-noise density, micro-g/sqrt(Hz).
    accel_markov_ug, accel_markov_tau_s : float
    accel_scale_ppm : float or (3,)
    accel_misalign_ppm : float or (3, 3)
        As for the gyros.
    accel_quant_mps : float
        Velocity increment LSB, m/s (0: none).
    vibration_gyro_dps, vibration_accel_mps2 : float
        Vibration: RMS of the angular rate (deg/s) and specific force (m/s^2) it adds
        to each sample, per axis (0: none). Built as the difference across each sample
        interval of a first-order Gauss-Markov angle/velocity with correlation time
        ``vibration_tau_s``, scaled so that the sample RMS at the IMU rate is the value
        given: its sum over any span is bounded (a vibrating mount does not drift).
    vibration_tau_s : float
        Correlation time of the vibration's angle/velocity, s.
    vibration_full_speed_mps : float
        0: the vibration is there all the time; > 0: its amplitude grows with the
        true horizontal speed, ``min(1, speed / value)`` (none at rest).
    random_bias : bool
        Draw the turn-on errors per run instead of using the values as given
        (Monte Carlo runs): the constant biases, the scale factors (per axis) and the
        misalignments (per entry) as N(0, value^2). Drawn only for non-zero values,
        so a spec without them draws what it always did.
    """

    gyro_bias_dph: object = 0.0
    gyro_arw_dpsh: float = 0.0
    gyro_markov_dph: float = 0.0
    gyro_markov_tau_s: float = 3600.0
    gyro_scale_ppm: object = 0.0
    gyro_misalign_ppm: object = 0.0
    gyro_quant_arcsec: float = 0.0
    accel_bias_ug: object = 0.0
    accel_vrw_ug_rthz: float = 0.0
    accel_markov_ug: float = 0.0
    accel_markov_tau_s: float = 3600.0
    accel_scale_ppm: object = 0.0
    accel_misalign_ppm: object = 0.0
    accel_quant_mps: float = 0.0
    vibration_gyro_dps: float = 0.0
    vibration_accel_mps2: float = 0.0
    vibration_tau_s: float = 0.05
    vibration_full_speed_mps: float = 0.0
    random_bias: bool = False

    def with_(self, **kw):
        """Return a copy with some fields changed."""
        return replace(self, **kw)

    @property
    def ideal(self):
        """True when the spec adds no error at all."""
        return not any(np.any(np.asarray(getattr(self, f)) != 0) for f in (
            'gyro_bias_dph', 'gyro_arw_dpsh', 'gyro_markov_dph', 'gyro_scale_ppm',
            'gyro_misalign_ppm', 'gyro_quant_arcsec', 'accel_bias_ug', 'accel_vrw_ug_rthz',
            'accel_markov_ug', 'accel_scale_ppm', 'accel_misalign_ppm', 'accel_quant_mps',
            'vibration_gyro_dps', 'vibration_accel_mps2'))


def ideal_increments(traj, t_grid, pos_fn):
    """Exact angle and velocity increments over consecutive intervals of ``t_grid``.

    Parameters
    ----------
    traj : Trajectory
    t_grid : ndarray (N+1,)
        Sample times; increment k covers ``[t_grid[k], t_grid[k+1]]``.
    pos_fn : callable
        ``pos_fn(t) -> (M, 3)`` geodetic positions valid on the grid's span.

    Returns
    -------
    dtheta, dv : ndarray (N, 3), rad and m/s, body (FLU) axes.
    """
    t_grid = np.asarray(t_grid, dtype=float)
    a, b = t_grid[:-1], t_grid[1:]
    half = 0.5 * (b - a)
    tq = (0.5 * (a + b))[:, None] + half[:, None] * _GL_X[None, :]
    n, m = tq.shape
    tf = tq.ravel()
    kin = traj.kinematics(tf)
    pos = pos_fn(tf)
    lat, h = pos[:, 0], pos[:, 2]
    C_b_n = euler_to_dcm(kin.euler)
    w_ie = earth.w_ie_n(lat)
    w_en = earth.w_en_n(lat, h, kin.v_n)
    w_in = w_ie + w_en
    w_nb_b = euler_rates_to_w_nb_b(kin.euler, kin.euler_rate)
    w_ib_b = w_nb_b + np.einsum('kji,kj->ki', C_b_n, w_in)
    f_n = specific_force_n(kin, lat, h)
    f_b = np.einsum('kji,kj->ki', C_b_n, f_n)
    wts = (half[:, None] * _GL_W[None, :])[..., None]
    dtheta = (w_ib_b.reshape(n, m, 3) * wts).sum(axis=1)
    dv = (f_b.reshape(n, m, 3) * wts).sum(axis=1)
    return dtheta, dv


def specific_force_n(kin, lat, h):
    """Return the true specific force in ENU (N, 3), m/s^2, of trajectory kinematics ``kin``.

    ``f_n = a_n + (2 w_ie_n + w_en_n) x v_n - g_n`` at latitudes ``lat`` (rad) and
    heights ``h`` (m); ``kin`` as returned by ``Trajectory.kinematics``.
    """
    w = 2.0 * earth.w_ie_n(lat) + earth.w_en_n(lat, h, kin.v_n)
    return kin.a_n + np.cross(w, kin.v_n) - earth.gravity_n(lat, h)


class ImuErrors:
    """Stateful error generator for a stream of increments (one per IMU).

    Parameters
    ----------
    spec : ImuSpec
    rng : numpy.random.Generator
    """

    def __init__(self, spec, rng):
        self.spec = spec
        self.rng = rng
        gb = _vec3(spec.gyro_bias_dph) * DPH
        ab = _vec3(spec.accel_bias_ug) * UG
        if spec.random_bias:
            gb = gb * rng.standard_normal(3)
            ab = ab * rng.standard_normal(3)
        #: the constant biases actually applied, rad/s and m/s^2 (the truth)
        self.gyro_bias = gb
        self.accel_bias = ab
        self._gm = spec.gyro_markov_dph * DPH * rng.standard_normal(3)
        self._am = spec.accel_markov_ug * UG * rng.standard_normal(3)
        self._gq = np.zeros(3)
        self._aq = np.zeros(3)
        # turn-on scale factors and misalignments (drawn after the draws above, and only
        # when present: the streams of specs without them are unchanged)
        gs, as_ = _vec3(spec.gyro_scale_ppm) * 1e-6, _vec3(spec.accel_scale_ppm) * 1e-6
        gm, am = _misalignment(spec.gyro_misalign_ppm), _misalignment(spec.accel_misalign_ppm)
        if spec.random_bias:
            gs, as_ = (x * rng.standard_normal(3) if np.any(x) else x for x in (gs, as_))
            gm, am = (x * rng.standard_normal((3, 3)) if np.any(x) else x for x in (gm, am))
        #: the matrices ``S + M`` actually applied to the gyro and accelerometer triads
        #: (dimensionless; the truth): measured = (I + S + M) true + ...
        self.gyro_sm = np.diag(gs) + gm
        self.accel_sm = np.diag(as_) + am
        self._vib = None     # vibration state: (angle (3,), velocity (3,)) or None

    @staticmethod
    def _markov(x0, sigma, tau, dt, rng, n):
        """Exact discretisation of a first-order Gauss-Markov process, (n, 3)."""
        if sigma == 0.0:
            return np.zeros((n, 3)), x0
        phi = np.exp(-dt / tau)
        w = sigma * np.sqrt(1.0 - phi * phi) * rng.standard_normal((n, 3))
        out, _ = lfilter([1.0], [1.0, -phi], w, axis=0, zi=(phi * x0)[None, :])
        return out, out[-1].copy()

    @staticmethod
    def _quantize(x, lsb, carry):
        """Quantize increments to ``lsb`` keeping the remainder, like an integrating counter."""
        if lsb <= 0.0:
            return x, carry
        total = np.cumsum(x, axis=0) + carry
        counts = np.floor(total / lsb + 0.5)
        out = np.diff(np.vstack([np.zeros((1, 3)), counts]), axis=0) * lsb
        return out, total[-1] - counts[-1] * lsb

    def _vibration(self, n, dt, gain):
        """Vibration increments (angle, velocity), each (n, 3); see :class:`ImuSpec`.

        ``gain`` (n,) or None scales the amplitude per sample. The increments are the
        differences of ``gain * x`` with ``x`` a Gauss-Markov process: their sums stay
        bounded by the process's sigma.
        """
        s = self.spec
        phi = np.exp(-dt / s.vibration_tau_s)
        # sample RMS of the differences: sigma_x sqrt(2 (1 - phi)) = amplitude * dt
        k = dt / np.sqrt(2.0 * (1.0 - phi))
        sig = np.array([s.vibration_gyro_dps * DEG * k] * 3 + [s.vibration_accel_mps2 * k] * 3)
        if self._vib is None:
            x0 = sig * self.rng.standard_normal(6)
            g0 = 0.0 if gain is None else gain[0]   # the level before the first sample
            self._vib = (x0, g0)
        x0, g0 = self._vib
        w = sig * np.sqrt(1.0 - phi * phi) * self.rng.standard_normal((n, 6))
        x, _ = lfilter([1.0], [1.0, -phi], w, axis=0, zi=(phi * x0)[None, :])
        gx = x if gain is None else x * gain[:, None]
        prev = np.vstack([(x0 if gain is None else x0 * g0)[None, :], gx[:-1]])
        self._vib = (x[-1].copy(), 1.0 if gain is None else gain[-1])
        d = gx - prev
        return d[:, :3], d[:, 3:]

    def apply(self, dtheta, dv, dt, speed=None):
        """Return corrupted copies of ideal increments (N, 3) sampled every ``dt`` s.

        ``speed`` (N,), the true horizontal speed at the samples (m/s), sets the vibration's
        amplitude when ``vibration_full_speed_mps`` > 0 (None: full amplitude).
        """
        s, rng, n = self.spec, self.rng, len(dtheta)
        gm, self._gm = self._markov(self._gm, s.gyro_markov_dph * DPH,
                                    s.gyro_markov_tau_s, dt, rng, n)
        am, self._am = self._markov(self._am, s.accel_markov_ug * UG,
                                    s.accel_markov_tau_s, dt, rng, n)
        g_white = s.gyro_arw_dpsh * DPSH * np.sqrt(dt) * rng.standard_normal((n, 3))
        a_white = s.accel_vrw_ug_rthz * UG * np.sqrt(dt) * rng.standard_normal((n, 3))
        dth = dtheta + (self.gyro_bias + gm) * dt + g_white
        dvel = dv + (self.accel_bias + am) * dt + a_white
        if np.any(self.gyro_sm):
            dth += dtheta @ self.gyro_sm.T
        if np.any(self.accel_sm):
            dvel += dv @ self.accel_sm.T
        if s.vibration_gyro_dps or s.vibration_accel_mps2:
            gain = None
            if s.vibration_full_speed_mps > 0.0 and speed is not None:
                gain = np.minimum(1.0, np.asarray(speed, float) / s.vibration_full_speed_mps)
            vth, vv = self._vibration(n, dt, gain)
            dth, dvel = dth + vth, dvel + vv
        dth, self._gq = self._quantize(dth, s.gyro_quant_arcsec * ARCSEC, self._gq)
        dvel, self._aq = self._quantize(dvel, s.accel_quant_mps, self._aq)
        return dth, dvel


@dataclass
class ImuChunk:
    """A block of simulated IMU samples with the truth at each sample time.

    ``t`` (N,) is the end of each increment's interval; ``dtheta``, ``dv`` (N, 3)
    body FLU; truth: ``euler`` (N, 3) REP-103, ``v_n`` (N, 3) ENU, ``pos`` (N, 3)
    ``[lat, lon, h]``.
    """

    t: np.ndarray
    dtheta: np.ndarray
    dv: np.ndarray
    euler: np.ndarray
    v_n: np.ndarray
    pos: np.ndarray
    extra: dict = field(default_factory=dict)


class ImuSimulator:
    """Streams IMU increments along a trajectory, chunk by chunk, deterministically.

    Parameters
    ----------
    traj : Trajectory
    spec : ImuSpec
    rate_hz : float
    seed : int
        Seeds the error generator; the same seed gives the same stream.
    """

    def __init__(self, traj, spec, rate_hz, seed=0):
        self.traj = traj
        self.spec = spec
        self.dt = 1.0 / float(rate_hz)
        self.rng = np.random.default_rng(seed)
        self.errors = ImuErrors(spec, self.rng)
        self.positions = PositionIntegrator(traj)
        self.k = 0   # samples produced so far

    def truth_at(self, t, pos_fn):
        """Truth (euler, v_n, pos) at times ``t`` inside the current chunk."""
        kin = self.traj.kinematics(t)
        return kin.euler, kin.v_n, pos_fn(t)

    def initial_truth(self):
        """Truth at t = 0: ``(euler (3,), v_n (3,), pos (3,))``."""
        kin = self.traj.kinematics(0.0)
        return kin.euler[0], kin.v_n[0], self.traj.initial_position

    def next_chunk(self, n):
        """Simulate the next ``n`` samples as an :class:`ImuChunk`."""
        k0 = self.k
        t_grid = (k0 + np.arange(n + 1)) * self.dt
        pos_fn = self.positions.advance(t_grid[-1])
        dtheta, dv = ideal_increments(self.traj, t_grid, pos_fn)
        t = t_grid[1:]
        euler, v_n, pos = self.truth_at(t, pos_fn)
        if not self.spec.ideal:
            dtheta, dv = self.errors.apply(dtheta, dv, self.dt,
                                           speed=np.hypot(v_n[:, 0], v_n[:, 1]))
        self.k += n
        return ImuChunk(t=t, dtheta=dtheta, dv=dv, euler=euler, v_n=v_n, pos=pos,
                        extra={'pos_fn': pos_fn})


def simulate(traj, spec, rate_hz, duration, seed=0):
    """Simulate the whole ``duration`` (s) as one :class:`ImuChunk`."""
    sim = ImuSimulator(traj, spec, rate_hz, seed)
    return sim.next_chunk(int(round(duration * rate_hz)))
