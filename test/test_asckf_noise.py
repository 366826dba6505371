"""The ASCKF's process noise: one Q shared with its Sage-Husa estimator, a lent Q that
reaches the prediction and is never estimated, and the engine's ``diag(Qc) T`` per interval
(issue 44: an ASCKF on MEMS ground vehicles lost the turn-rate noise the engine lent it)."""
import numpy as np

from sins_align_ros.align.inputs.gnss_fix import GnssFix
from sins_align_ros.align.engines.moving import MovingBaseAlignment
from sins_align_ros.filters.asckf import ASCKF
from sins_align_ros.filters.cubature import batched
from sins_align_ros.units import DEG, DPH, UG


def _walk_filter(q0, r, adaptive=True):
    """A scalar random walk measured directly: ASCKF (estimating R only), no fading."""
    return ASCKF(np.zeros(1), np.eye(1), q0 * np.eye(1), r * np.eye(1), fading=False,
                 adaptive=adaptive, adapt_q=False)


def test_a_lent_process_noise_is_predicted_with_and_not_kept_in_q():
    """Closed form (a linear model: the cubature rule is exact): P- = P + Q + Q_lent; after
    the update Q is still Q (the estimator does not take the loan, nor drop an external
    setting of Q at the update, which the estimator's own copy did before)."""
    kf = _walk_filter(0.5, 1.0)
    kf.Q = 2.0 * np.eye(1)                  # set from outside (a consistency inflation)
    kf.Q_lent = 3.0 * np.eye(1)
    upd = kf.step(batched(lambda X: X), np.array([0.0]), batched(lambda X: X))
    P_pred = 1.0 + 2.0 + 3.0
    # innovation covariance P- + R; the update's variance P- R / (P- + R)
    assert np.isclose(upd.Pzz[0, 0], P_pred + 1.0, rtol=1e-12)
    assert np.isclose(kf.P[0, 0], P_pred * 1.0 / (P_pred + 1.0), rtol=1e-12)
    assert np.array_equal(kf.Q, 2.0 * np.eye(1)) and np.array_equal(kf.noise.Q, kf.Q)


def test_a_random_walk_driven_by_the_lent_noise_is_covered_by_the_sigma():
    """Seeded truth: x_k = x_(k-1) + w, w ~ N(0, q0 + q_lent), z = x + v. With the loan the
    normalised squared error averages 1 (1000 epochs: 3 standard errors of a chi-square(1)
    mean are 3 sqrt(2/1000) = 0.13); with the loan lost it is q_lent / q0 times too large."""
    rng = np.random.default_rng(44)
    q0, q_lent, r, n = 0.01, 0.5, 0.1, 1000
    kf = _walk_filter(q0, r, adaptive=False)     # R known: the test is of Q
    kf.x[:] = rng.normal()
    x = kf.x[0] + rng.normal()                    # P0 = 1
    e2 = []
    for _ in range(n):
        x += rng.normal(scale=np.sqrt(q0 + q_lent))
        kf.Q_lent = q_lent * np.eye(1)
        kf.step(batched(lambda X: X), np.array([x + rng.normal(scale=np.sqrt(r))]),
                batched(lambda X: X))
        kf.Q_lent = None
        e2.append((kf.x[0] - x) ** 2 / kf.P[0, 0])
    assert abs(np.mean(e2) - 1.0) < 3.0 * np.sqrt(2.0 / n)


def test_seed000_engine_gives_its_asckf_diag_qc_t_and_takes_the_loan_back():
    """Engine with the ASCKF (R estimated, Q not): each GNSS interval's Q is ``diag(Qc) T``
    as for every filter (not ``Qc * 1 s`` at any rate), the turn-rate noise is lent for
    the step and gone after it, and Q never goes negative (the velocity rows did:
    -3.3e-6 after 2100 RTK epochs)."""
    P0 = np.diag(np.r_[[0.1 ** 2] * 2, [0.02 ** 2] * 2, [(0.5 * DEG) ** 2] * 2,
                       (5.0 * DEG) ** 2, [(10.0 * DPH) ** 2] * 3])
    Qc = np.r_[[1e-6] * 2, 0.0, 0.0, [1e-9] * 3, [1e-14] * 3]
    eng = MovingBaseAlignment(np.eye(3), np.zeros(3), 0.5, 2.0, 0.0, P0, Qc,
                              np.eye(2) * 0.02 ** 2, accel_bias=300 * UG)
    assert eng.adaptive and not eng.own_Q
    E = np.diag(np.r_[[4e-6] * 2, 0.0, 0.0, [2e-8] * 3, [0.0] * 6])
    eng._rotation_noise = lambda T: E
    eng._force_noise = lambda T: None     # (the mechanization's 9.8 vs gravity: not tested)
    seen = []
    step = eng.kf.step
    eng.kf.step = lambda *a, **k: (seen.append(eng.kf._Q_used().copy()), step(*a, **k))[1]
    dv = np.array([0.0, 0.0, 9.8 * 0.01])
    for k in range(1, 11):
        for _ in range(20):                       # 0.2 s at 100 Hz, at rest
            eng.step_imu(np.zeros(3), dv, 0.01)
        eng.update(GnssFix(0.2 * k, 0.5, 2.0, 0.0), 0.2 * k)
        # T: twenty 0.01 s intervals summed (round-off far below the 1e-12 asked)
        assert np.allclose(seen[-1], np.diag(np.r_[Qc, [0.0] * 3]) * 0.2 + E, rtol=1e-12,
                           atol=0.0)
        assert eng.kf.Q_lent is None and np.all(np.diag(eng.kf.Q) >= 0.0)
