"""bench/tilt_limit.py's ideal-estimator covariance against the closed form of a still IMU."""
import math

import numpy as np

from conftest import load_bench
from sins_align_ros.nav import earth
from sins_align_ros.sim.gnss import GnssSpec
from sins_align_ros.sim.imu import ImuSpec
from sins_align_ros.sim.trajectory import Trajectory
from sins_align_ros.units import DEG, UG
from tolerance import roundoff


def _tilt_limit():
    """Return bench/tilt_limit.py as a module."""
    return load_bench('tilt_limit')


def test_still_tilt_sigma_tends_to_accel_bias_over_g():
    """A still, level IMU: the tilt the ideal filter reaches is the accelerometer bias / g.

    At rest the specific force is ``(0, 0, g)``: ``dV_E' = -g phi_N + nab_E``, and a tilt
    ``d`` with a bias ``g d`` moves nothing the positions show. With the prior
    ``phi_N ~ N(0, s_p^2)``, ``nab_E ~ N(0, s_b^2)`` and the combination
    ``a = -g phi_N + nab_E`` known exactly, ``Var(phi_N) = L = 1 / (1 / s_p^2 + g^2 / s_b^2)``
    (just below ``(s_b / g)^2``: ``s_p`` = 2 deg, ``s_b / g`` = 5 mg). At the equator the
    north tilt has no other tie (the vertical Earth rate that turns tilt against bias
    elsewhere, and the east tilt's gyrocompass tie with heading through the north Earth
    rate, both vanish or do not touch it), so ``L`` is a lower bound, exact up to what the
    finite data leave of ``a``: ``Var(phi_N) = L + beta^2 Var(a(T)) / g^2`` with
    ``beta = s_p^2 / (s_p^2 + s_b^2 / g^2)``. The gyro bias (10 deg/h) makes the east
    channel's position a cubic in time; ``Var(a(T))`` is that of ``p''(T)`` of a least-squares
    cubic through the 750 positions (0.5 m, 2.5 Hz, 300 s): 1.06e-9 (m/s^2)^2, a relative
    excess of the sigma of 2.2e-7. The bound takes twice that (the Schuler loop bends the
    cubic by ``(w_s T)^2 / 2`` = 7 % over 300 s). Below: round-off of the 9000-step
    recursion (15 states; each step a few products of length 15).
    """
    tl = _tilt_limit()
    T, rate, gnss_rate, sigma_p = 300.0, 30.0, 2.5, 0.5
    truth = tl.truth_of(Trajectory(0.0, 10.0, 0.0, heading_deg=30.0, name='static'), rate, T)
    spec = ImuSpec(gyro_bias_dph=10.0, accel_bias_ug=5000.0)
    gnss = GnssSpec(rate_hz=gnss_rate, pos_sigma_h=sigma_p, pos_sigma_v=sigma_p)
    res = tl.run(truth, spec, gnss, (T,), prior=(2.0, 10.0))
    g = earth.gravity(0.0, 0.0)
    s_b, s_p = 5000.0 * UG, 2.0 * DEG
    L = 1.0 / (1.0 / s_p ** 2 + g ** 2 / s_b ** 2)
    beta = s_p ** 2 / (s_p ** 2 + s_b ** 2 / g ** 2)
    t = np.arange(1, int(T * gnss_rate) + 1) / gnss_rate
    B = np.stack([np.ones_like(t), t, t ** 2, t ** 3], axis=1)
    c = np.array([0.0, 0.0, 2.0, 6.0 * T])                       # p''(T)
    var_a = sigma_p ** 2 * c @ np.linalg.solve(B.T @ B, c)
    excess = 0.5 * beta ** 2 * var_a / (g ** 2 * L)               # relative, on the sigma
    ratio = res.phi[-1, 1] / math.sqrt(L)
    low = roundoff(int(T * rate) * 3 * 15)                       # n_ops: steps x products
    assert 1.0 - low <= ratio <= 1.0 + 2.0 * excess + low, (ratio - 1.0, excess)
