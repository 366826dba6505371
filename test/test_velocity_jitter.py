"""A vibrating chassis's velocity jitter: measured, and added to the GNSS velocity noise.

Vibration is bounded in velocity: the mechanized velocity carries it at every GNSS epoch as
an error that does not accumulate (the simulator's ``ROBOT_VIBRATION``: 0.05 m/s per axis,
correlated over 0.05 s). The self-check measures it from the specific-force integral
(``gnss_noise_check.velocity_jitter``) and, where it is at least the GNSS velocity sigma, widens
``imu_velocity_jitter_mps``; the engines add its variance to the velocity rows' noise (the
ASCKF has it lent beside its Sage-Husa R, ``epoch_noise.py``).
"""
import math

import numpy as np

from sins_align_ros.align import params as prm
from sins_align_ros.align.inputs.gnss_fix import GnssFix
from sins_align_ros.align.stages.gnss_noise_check import (JITTER_CHUNK_S, JITTER_COUNTED,
                                                          _velocity_jitter, ar1_product,
                                                          gm_shares,
                                                          kept_share, velocity_jitter)
from sins_align_ros.align.engines.moving import MovingBaseAlignment
from sins_align_ros.align.stages.self_check import SelfCheck
from sins_align_ros.sim.imu import ImuErrors, ImuSpec
from sins_align_ros.units import DEG, UG

RATE = 30.0
DT = 1.0 / RATE
G = 9.8


def _still(spec, seconds, seed=7):
    """A still IMU's increments through ``spec``'s errors: ``(t, dtheta, dv, dt)``."""
    n = int(round(seconds * RATE))
    errors = ImuErrors(spec, np.random.default_rng(seed))
    dth, dv = errors.apply(np.zeros((n, 3)), np.tile([0.0, 0.0, G * DT], (n, 1)), DT)
    return DT * np.arange(1, n + 1), dth, dv, np.full(n, DT)


def _expected(Phi, m, K):
    """Mean, and the bound on the median's departure from it, of the per-piece statistic.

    ``Phi`` (m, m) the correlation of one axis's velocity over a piece, unit variance. The
    statistic of a piece is ``sum over 2 axes x^T M x / (2 (m - 3))``, ``M = I - H`` the
    quadratic fit's residual projector: mean ``tr(M Phi) / (m - 3)``, variance
    ``tr((M Phi)^2) / (m - 3)^2`` (two independent Gaussian axes). Its median over ``K``
    independent pieces departs from the mean by the skew of a scaled chi-square of
    ``nu = 2 mean^2 / var`` degrees of freedom (``2 / (3 nu)`` of it) plus 4 standard
    errors of a median (``1.2533 sd / sqrt(K)``).
    """
    t = DT * np.arange(m)
    A = np.column_stack([np.ones(m), t, t * t])
    M = np.eye(m) - A @ np.linalg.pinv(A)
    MP = M @ Phi
    mean = np.trace(MP) / (m - 3)
    sd = math.sqrt(np.trace(MP @ MP)) / (m - 3)
    nu = 2.0 * mean ** 2 / sd ** 2
    return mean, mean * 2.0 / (3.0 * nu) + 4.0 * 1.2533 * sd / math.sqrt(K)


def test_jitter_reads_the_vibrations_bounded_velocity():
    """Vibration only (the robot's 1.5 m/s^2 per sample, 0.05 s): the Gauss-Markov velocity
    ``sigma_x = A dt / sqrt(2 (1 - phi))`` (sim/imu.py, 0.051 m/s), the share the quadratic
    over a 2-s piece takes given back (:func:`kept_share`), to the median's spread."""
    spec = ImuSpec(vibration_accel_mps2=1.5, vibration_tau_s=0.05)
    seconds = 300.0
    t, dth, dv, dts = _still(spec, seconds)
    phi = math.exp(-DT / spec.vibration_tau_s)
    sigma_x = spec.vibration_accel_mps2 * DT / math.sqrt(2.0 * (1.0 - phi))
    m = int(round(JITTER_CHUNK_S * RATE))
    lag = np.abs(np.subtract.outer(np.arange(m), np.arange(m)))
    mean, tol = _expected(phi ** lag, m, int(seconds * RATE) // m)
    j = velocity_jitter(dth, dv, dts)
    # the median's spread of the white-share reading (mean, tol), in units of its own mean
    assert abs(j ** 2 / sigma_x ** 2 - 1.0) <= tol / mean


def test_white_accelerometer_noise_is_no_jitter():
    """A MEMS accelerometer's white noise (350 ug/sqrt(Hz)) integrates to a random walk of
    ``q sqrt(dt)`` per sample; over a 2-s piece the quadratic leaves
    ``q^2 dt tr(M Sigma) / (m - 3)`` (``Sigma_ij = min(i, j) + 1``), a few mm/s: a tenth of
    an RTK receiver's 0.02 m/s and less, so it never counts."""
    q = 350.0 * UG
    seconds = 300.0
    t, dth, dv, dts = _still(ImuSpec(accel_vrw_ug_rthz=350.0), seconds)
    m = int(round(JITTER_CHUNK_S * RATE))
    i = np.arange(m)
    mean, tol = _expected(np.minimum.outer(i, i) + 1.0, m, int(seconds * RATE) // m)
    j = velocity_jitter(dth, dv, dts)
    assert abs(j ** 2 / (q * q * DT) - mean) <= tol
    assert j < 0.1 * JITTER_COUNTED * 0.02


def _cfg(**kw):
    cfg = prm.defaults()
    cfg.update(kw)
    return cfg


def test_the_self_check_counts_a_jitter_at_least_the_gnss_velocity_noise():
    """The robot's jitter (0.05 m/s) widens ``imu_velocity_jitter_mps`` against RTK's 0.02 m/s
    velocity noise (said in a finding), not against a consumer receiver's 0.1, nor beyond
    what is configured already (within NOISE_RATIO); the figure is there in every case."""
    window = _still(ImuSpec(vibration_accel_mps2=1.5, vibration_tau_s=0.05), 60.0)
    j = velocity_jitter(*window[1:])
    for vel, told, widened in ((0.02, 0.0, True), (0.1, 0.0, False), (0.02, 0.04, False)):
        out = SelfCheck()
        _velocity_jitter(out, _cfg(gnss_vel_sigma_mps=vel, imu_velocity_jitter_mps=told),
                         window, [])
        assert out.figures['velocity_jitter_mps'] == j
        assert ('imu_velocity_jitter_mps' in out.widened) == widened
        assert any('imu_velocity_jitter_mps widened' in f for f in out.findings) == widened
    # the receiver's reported velocity noise is what the filter takes (kf told defaults)
    out = SelfCheck()
    _velocity_jitter(out, _cfg(fine_filter='kf'), window, [np.array([4e-4, 4e-4])])
    assert out.widened['imu_velocity_jitter_mps'] == j


def _engine(adaptive, jitter):
    """A 13-state seed 000 engine (ASCKF, or CKF whose R the engine sets) measuring velocity."""
    P0 = np.diag(np.r_[[0.01] * 2, [1e-4] * 2, [(1.0 * DEG) ** 2] * 3, [1e-10] * 3])
    R = np.diag([4e-4, 4e-4, 4e-4, 4e-4])
    eng = MovingBaseAlignment(np.eye(3), np.array([1.0, 0.0, 0.0]), 0.6, 0.0, 0.0, P0,
                              np.zeros(10), R, use_velocity=True, square_root=adaptive,
                              fading=False, adaptive=adaptive, accel_bias=5e-3 * 9.8)
    eng.velocity_jitter_var = jitter ** 2
    return eng


def test_the_jitter_goes_to_the_velocity_rows_and_is_lent_to_the_asckf():
    """Where the engine sets R (CKF) the velocity rows get ``jitter^2`` on top of the
    receiver's; the ASCKF has it lent for its update (``R_lent``: used with its Sage-Husa R, never
    estimated into it), the loan ended after the update; no jitter: nothing lent (as before)."""
    fix = GnssFix(0.2, 0.6, 0.0, 0.0, np.array([1.0, 0.0, 0.0]))
    j = 0.0625                                   # 2^-4 m/s: j^2 exact
    ckf = _engine(False, j)
    ckf._set_epoch_noise(fix)
    np.testing.assert_array_equal(np.diag(ckf.kf.R), [4e-4, 4e-4, 4e-4 + j * j, 4e-4 + j * j])
    # (4e-4 + j^2) - j^2: two roundings at the scale of 4e-4 + j^2
    assert abs(ckf.receiver_velocity_var() - 4e-4) <= 2.0 * np.finfo(float).eps * (4e-4 + j * j)
    asckf = _engine(True, j)
    np.testing.assert_array_equal(asckf._lend_arm_noise(fix), [0.0, 0.0, j * j, j * j])
    asckf._return_arm_noise()
    for _ in range(6):
        asckf.step_imu(np.zeros(3), np.array([0.0, 0.0, 9.8 * 0.01]), 0.01)
    m = asckf.mech
    seen = []
    orig = asckf.kf.step

    def step(*args, **kw):
        seen.append(None if asckf.kf.R_lent is None else asckf.kf.R_lent.copy())
        return orig(*args, **kw)
    asckf.kf.step = step
    asckf.update(GnssFix(0.06, m.lat, m.lon, m.h, m.v_n.copy()), 0.06)
    np.testing.assert_array_equal(seen[0], [0.0, 0.0, j * j, j * j])
    assert asckf.kf.R_lent is None
    assert _engine(True, 0.0)._lend_arm_noise(fix) is None


def gm_velocity(rng, sigma, tau, n, dt):
    """A Gauss-Markov velocity jitter (n + 1, 3), horizontal only, stationary from the start."""
    phi = math.exp(-dt / tau)
    v = np.zeros((n + 1, 3))
    v[0, :2] = rng.normal(0.0, sigma, 2)
    w = rng.normal(0.0, sigma * math.sqrt(1.0 - phi * phi), (n, 2))
    for k in range(n):
        v[k + 1, :2] = phi * v[k, :2] + w[k]
    return v


def test_a_jitter_correlated_over_its_pieces_is_read_whole():
    """A jitter correlated over 0.3 s is read at its sigma, not at what a 2-s quadratic leaves.

    60 s at 200 Hz: 30 pieces of 2 s, each holding about 2 s / (2 x 0.3 s) = 3.3 independent
    values per axis, 6.7 over both: a piece's mean square spreads by sqrt(2 / 6.7) = 0.55,
    the median of 30 by 1.25 x 0.55 / sqrt(30) = 0.13 in variance, 0.063 in sigma; 3 of
    those bound the reading. Read as white noise (the share m - 3) it came out at about two
    thirds of its sigma (0.07 for a 0.109 m/s jitter), far outside that bound.
    """
    rng = np.random.default_rng(11)
    dt, n, sigma = 1.0 / 200.0, 12000, 0.1
    for tau in (0.3, 0.05):
        v = gm_velocity(rng, sigma, tau, n, dt)
        dvv = np.diff(v, axis=0) + np.array([0.0, 0.0, 9.8]) * dt
        j = velocity_jitter(np.zeros((n, 3)), dvv, np.full(n, dt))
        assert abs(j / sigma - 1.0) < 3 * 0.063, (tau, j)


def test_the_kept_share_is_the_gauss_markov_expectation():
    """gm_shares against the mean over draws of a Gauss-Markov residual after a quadratic."""
    rng = np.random.default_rng(12)
    m, phi, draws = 60, 0.9, 4000
    t = np.arange(m, dtype=float)
    A = np.column_stack([np.ones(m), t, t * t])
    Q = np.linalg.qr(A)[0]
    x = np.zeros((draws, m))
    x[:, 0] = rng.normal(size=draws)
    for k in range(1, m):
        x[:, k] = phi * x[:, k - 1] + math.sqrt(1 - phi * phi) * rng.normal(size=draws)
    r = x - (x @ Q) @ Q.T
    tr, lag1 = gm_shares(phi, Q)
    ss = np.sum(r * r, axis=1)
    # the sample mean of `draws` sums: its standard error, 4 of them as the bound
    assert abs(np.mean(ss) - tr) < 4 * np.std(ss) / math.sqrt(draws)
    lag = np.sum(r[:, 1:] * r[:, :-1], axis=1)
    assert abs(np.mean(lag) - lag1) < 4 * np.std(lag) / math.sqrt(draws)
    assert gm_shares(0.0, Q)[0] == m - 3
    assert kept_share(Q, -1.0, 0.99) == m - 3        # white residuals: the white share exactly


def test_the_ar1_product_is_the_dense_one():
    """gm_shares' ``C Q`` by two first-order recursions (ar1_product) equals the dense
    product with ``C_ij = phi^|i - j|`` to round-off, for a basis of a quadratic fit and a
    random one (seeded), at a correlation near white and one near a random walk."""
    m = 300
    t = np.arange(m) * 0.01
    rng = np.random.default_rng(46)
    for Q in (np.linalg.qr(np.column_stack([np.ones(m), t, t * t]))[0],
              rng.standard_normal((m, 4))):
        for phi in (0.1, 0.999):
            i = np.arange(m)
            C = phi ** np.abs(np.subtract.outer(i, i))
            np.testing.assert_allclose(ar1_product(phi, Q), C @ Q, rtol=1e-9,
                                       atol=1e-9 * np.abs(C @ Q).max())
