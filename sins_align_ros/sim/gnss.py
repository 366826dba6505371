"""GNSS position/velocity measurements with realistic errors.

Error model per axis (ENU): white noise plus a first-order Gauss-Markov
process (seed 003 eq. 26-27 model receiver position and velocity errors as
first-order Markov processes), outages (no fix), and outliers drawn from a
Bernoulli-contaminated Gaussian (seed 004 eq. 25): with probability ``p`` an
epoch's noise comes from ``N(0, scale^2 R)`` instead of ``N(0, R)``.
"""
from dataclasses import dataclass, replace
from types import SimpleNamespace

import numpy as np

from ..nav import earth


@dataclass(frozen=True)
class GnssSpec:
    """GNSS receiver error parameters (1-sigma, SI units).

    Attributes
    ----------
    rate_hz : float
    pos_sigma_h, pos_sigma_v : float
        White position noise, horizontal per axis and vertical, m.
    vel_sigma : float
        White velocity noise per axis, m/s.
    pos_markov_sigma, pos_markov_tau_s, vel_markov_sigma, vel_markov_tau_s : float
        First-order Markov position (m) and velocity (m/s) errors, all axes.
    outages : tuple of (start_s, end_s)
        Intervals without a fix (published with status NO_FIX).
    outlier_prob : float
        Bernoulli probability ``p`` of an outlier epoch (seed 004 eq. 25).
    outlier_scale : float
        Standard-deviation multiplier of the contaminating distribution.
    velocity : bool
        The receiver delivers a velocity (Doppler). False: a position-only receiver; its
        epochs carry no velocity (``GnssEpoch.v_n`` and ``vel_cov`` None) and
        ``gnss/vel`` is neither published nor recorded.
    reported_pos_sigma_h, reported_pos_sigma_v : float or None
        The position 1-sigma the receiver *reports* (NavSatFix covariance), m. None:
        the total of the white and Markov errors, :attr:`pos_sigma` (honest in size,
        though a white covariance says nothing of the correlation). A consumer
        receiver reports about its white noise: give that value to make the reported
        covariance optimistic in size as well.
    """

    rate_hz: float = 1.0
    pos_sigma_h: float = 1.0
    pos_sigma_v: float = 2.0
    vel_sigma: float = 0.05
    pos_markov_sigma: float = 0.0
    pos_markov_tau_s: float = 300.0
    vel_markov_sigma: float = 0.0
    vel_markov_tau_s: float = 60.0
    outages: tuple = ()
    outlier_prob: float = 0.0
    outlier_scale: float = 10.0
    velocity: bool = True
    reported_pos_sigma_h: float = None
    reported_pos_sigma_v: float = None

    def with_(self, **kw):
        """Return a copy with some fields changed."""
        return replace(self, **kw)

    @property
    def pos_sigma(self):
        """Total 1-sigma position error per ENU axis, m (what a receiver reports)."""
        h = np.hypot(self.pos_sigma_h, self.pos_markov_sigma)
        return np.array([h, h, np.hypot(self.pos_sigma_v, self.pos_markov_sigma)])

    @property
    def reported_pos_sigma(self):
        """Position 1-sigma per ENU axis the receiver reports, m (:attr:`pos_sigma` unless set)."""
        tot = self.pos_sigma
        h = tot[0] if self.reported_pos_sigma_h is None else self.reported_pos_sigma_h
        v = tot[2] if self.reported_pos_sigma_v is None else self.reported_pos_sigma_v
        return np.array([h, h, v], dtype=float)

    @property
    def vel_sigma_enu(self):
        """Total 1-sigma velocity error per ENU axis, m/s."""
        return np.full(3, np.hypot(self.vel_sigma, self.vel_markov_sigma))


@dataclass
class GnssEpoch:
    """Measurements at times ``t`` (N,).

    ``lat``, ``lon``, ``h`` (N,) measured position (rad, rad, m); ``v_n`` (N, 3)
    measured ENU velocity, None from a receiver without velocity
    (``GnssSpec.velocity`` False); ``pos_err_m`` (N, 3) the ENU position error actually
    added; ``fix`` (N,) bool; ``outlier`` (N,) bool; ``pos_cov`` and ``vel_cov``
    (3,) diagonal ENU variances the receiver reports (``vel_cov`` None without velocity).
    """

    t: np.ndarray
    lat: np.ndarray
    lon: np.ndarray
    h: np.ndarray
    v_n: np.ndarray
    pos_err_m: np.ndarray
    fix: np.ndarray
    outlier: np.ndarray
    pos_cov: np.ndarray
    vel_cov: np.ndarray


class GnssErrors:
    """Stateful GNSS error generator (keeps the Markov states between calls)."""

    def __init__(self, spec, rng):
        self.spec = spec
        self.rng = rng
        self._pm = spec.pos_markov_sigma * rng.standard_normal(3)
        self._vm = spec.vel_markov_sigma * rng.standard_normal(3)
        self._t_last = None

    def _markov_step(self, x, sigma, tau, dt):
        if sigma == 0.0:
            return x
        phi = np.exp(-dt / tau)
        return phi * x + sigma * np.sqrt(1.0 - phi * phi) * self.rng.standard_normal(3)

    def measure(self, t, pos, v_n, noise_scale=None):
        """Measurements at times ``t`` (N,) from true ``pos`` (N, 3) and ``v_n`` (N, 3).

        ``noise_scale`` (N,), optional, multiplies the white-noise sigmas (a receiver
        whose noise changes without its reported covariance changing).
        """
        s, rng = self.spec, self.rng
        n = len(t)
        pe = np.empty((n, 3))
        ve = np.empty((n, 3))
        outlier = rng.random(n) < s.outlier_prob if s.outlier_prob > 0 else np.zeros(n, bool)
        white_p = np.array([s.pos_sigma_h, s.pos_sigma_h, s.pos_sigma_v])
        for k in range(n):
            dt = 0.0 if self._t_last is None else t[k] - self._t_last
            self._t_last = t[k]
            self._pm = self._markov_step(self._pm, s.pos_markov_sigma, s.pos_markov_tau_s, dt)
            self._vm = self._markov_step(self._vm, s.vel_markov_sigma, s.vel_markov_tau_s, dt)
            scale = s.outlier_scale if outlier[k] else 1.0
            if noise_scale is not None:
                scale *= noise_scale[k]
            pe[k] = self._pm + scale * white_p * rng.standard_normal(3)
            ve[k] = self._vm + scale * s.vel_sigma * rng.standard_normal(3)
        R_M, R_N = earth.radii(pos[:, 0])
        lat = pos[:, 0] + pe[:, 1] / (R_M + pos[:, 2])
        lon = pos[:, 1] + pe[:, 0] / ((R_N + pos[:, 2]) * np.cos(pos[:, 0]))
        h = pos[:, 2] + pe[:, 2]
        fix = np.ones(n, bool)
        for a, b in s.outages:
            fix &= ~((t >= a) & (t < b))
        # the velocity errors are drawn either way: the position errors of a seed do not
        # depend on whether the receiver delivers a velocity
        vel, vel_cov = (v_n + ve, s.vel_sigma_enu ** 2) if s.velocity else (None, None)
        return GnssEpoch(t=np.asarray(t, float), lat=lat, lon=lon, h=h, v_n=vel,
                         pos_err_m=pe, fix=fix, outlier=outlier,
                         pos_cov=s.reported_pos_sigma ** 2, vel_cov=vel_cov)


def heading_measurements(t, yaw_true, sigma, rate_hz, rng, t_start=0.0):
    """Simulate an external heading source (a GNSS compass): its epochs at ``rate_hz``.

    ``t`` (N,) and ``yaw_true`` (N,) rad: the vehicle's true yaw at the IMU samples;
    ``sigma`` rad, white (a GNSS compass's noise over a 1 s epoch); ``rng`` a numpy
    Generator. Returns a namespace with ``t`` (M,) (multiples of the period from
    ``t_start``, within the samples), ``yaw`` (M,) rad wrapped into (-pi, pi] and ``var``
    (M,) rad^2 (the variance the source reports).
    """
    period = 1.0 / float(rate_hz)
    k0 = int(np.ceil((max(t_start, t[0]) + 1e-9) / period))
    tk = np.arange(k0, int(np.floor(t[-1] / period)) + 1) * period
    idx = np.clip(np.searchsorted(t, tk - 1e-9), 0, len(t) - 1)
    yaw = np.unwrap(yaw_true)[idx] + sigma * rng.standard_normal(len(tk))
    yaw = np.pi - np.mod(np.pi - yaw, 2.0 * np.pi)
    return SimpleNamespace(t=t[idx], yaw=yaw, var=np.full(len(tk), float(sigma) ** 2))
