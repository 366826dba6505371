"""Generic filter cores: CKF and SRCKF (seed 000), UKF, strong tracking, Sage-Husa.

Checked against an independent implementation (filterpy 2.0, test-only dependency), the
linear Kalman filter, and each other; every filter class against the interface the
alignment engines use (:class:`~sins_align_ros.filters.base.GaussianFilter`).
"""
import numpy as np
import pytest

from sins_align_ros.filters import kf
from sins_align_ros.filters.adaptive import SageHusa, StrongTracking
from sins_align_ros.filters.cubature import (batched, chol_lower, ckf_predict, ckf_update,
                                             cubature_points, srckf_predict, srckf_update, tria,
                                             tria_lapack)
from sins_align_ros.filters.ukf import ukf_predict, ukf_update
from sins_align_ros import compiled as compilation
from tolerance import assert_roundoff, roundoff

DT = 0.1
#: Round-off of one predict + update of the small filters here, counted for the
#: comparisons of two implementations (test/tolerance.py): the points or F P F^T (two
#: n-term dot products deep, n <= 4: ~16), the moments (a 2n-point weighted sum, ~16), the
#: m x m innovation solve (~10) and K H P / the Joseph form (~16); sin, cos, atan2 and hypot
#: in the models (~10): rounded up to 100. The filters are stable, (I - K H) F shrinks an
#: error carried from earlier steps, so after N steps the chain is at most N x STEP_OPS.
STEP_OPS = 100


def fx(x):
    """A nonlinear 4-state model: a turning, drag-affected body in 2D."""
    px, py, v, h = x
    return np.array([px + v * np.cos(h) * DT, py + v * np.sin(h) * DT,
                     v - 0.05 * v * abs(v) * DT, h + 0.3 * np.sin(v) * DT])


def hx(x):
    """Range and bearing from the origin."""
    return np.array([np.hypot(x[0], x[1]), np.arctan2(x[1], x[0])])


def scenario(seed=0, steps=40):
    rng = np.random.default_rng(seed)
    x = np.array([10.0, 5.0, 2.0, 0.3])
    zs = []
    for _ in range(steps):
        x = fx(x) + rng.normal(0, [0.01, 0.01, 0.02, 0.005])
        zs.append(hx(x) + rng.normal(0, [0.1, 0.01]))
    Q = np.diag([0.01, 0.01, 0.02, 0.005]) ** 2
    R = np.diag([0.1, 0.01]) ** 2
    return zs, Q, R


X0 = np.array([9.5, 5.5, 1.8, 0.25])
P0 = np.diag([1.0, 1.0, 0.25, 0.04])


def test_tria_and_cubature_points():
    rng = np.random.default_rng(1)
    A = rng.normal(size=(4, 9))
    S = tria(A)
    assert np.allclose(S, np.tril(S)) and np.all(np.diag(S) >= 0)
    assert S @ S.T == pytest.approx(A @ A.T)
    xi = cubature_points(3)
    assert xi.shape == (3, 6) and np.allclose(xi @ xi.T / 6, np.eye(3))


@pytest.mark.parametrize('n,k', [(10, 30), (13, 39), (2, 22), (13, 13)])
def test_tria_compiled_householder_equals_lapack_qr(n, k):
    """The compiled Tria (issue 22) against LAPACK's, rows of very different scales."""
    rng = np.random.default_rng(24)
    A = rng.normal(size=(n, k)) * 10.0 ** rng.integers(-6, 2, (n, 1))
    S, ref = tria(A), tria_lapack(A)
    assert np.array_equal(S, np.tril(S)) and np.all(np.diag(S) >= 0)
    # k Householder reflections of k-term dot products (LAPACK's and ours, in other orders),
    # each row relative to the largest entry: 2 k^2 operations on the chain
    assert_roundoff(S, ref, 2 * k * k, np.abs(ref).max())


@pytest.mark.skipif(not compilation.COMPILED, reason='numba not installed or switched off')
@pytest.mark.parametrize('fading', [False, True])
def test_compiled_square_root_ckf_equals_its_numpy_reference(fading, monkeypatch):
    """The compiled SRCKF moments (issue 22) against the numpy lines they replace.

    13 states of very different scales, 4 measurements, a nonlinear transition and
    measurement; a singular innovation covariance raises as numpy's solve does.
    """
    rng = np.random.default_rng(22)
    n, m = 13, 4
    scale = 10.0 ** rng.integers(-6, 1, n)
    A = rng.normal(size=(n, n)) * scale[:, None]
    S = np.linalg.cholesky(A @ A.T + np.diag(scale ** 2))
    x = rng.normal(size=n) * scale
    B = np.eye(n) + 0.1 * rng.normal(size=(n, n)) * scale[:, None] / scale[None, :]
    f = batched(lambda X: B @ X + 0.01 * np.sin(X / scale[:, None]) * scale[:, None])
    H = rng.normal(size=(m, n)) / scale[None, :]
    h = batched(lambda X: H @ X + 0.05 * (X[:m] / scale[:m, None]) ** 2)
    SQ, SR = np.diag(0.1 * scale), np.diag(rng.uniform(0.1, 1.0, m))
    z, fade = rng.normal(size=m), (rng.uniform(1.0, 2.0, n) if fading else None)
    fast = srckf_predict(x, S, f, SQ, fade), srckf_update(x, S, z, h, SR)
    monkeypatch.setattr(compilation, 'COMPILED', False)
    ref = srckf_predict(x, S, f, SQ, fade), srckf_update(x, S, z, h, SR)
    pairs = [*zip(ref[0], fast[0]), *zip(ref[1][:2], fast[1][:2])]
    pairs += [(getattr(ref[1][2], k), getattr(fast[1][2], k))
              for k in ('y', 'z_pred', 'Pzz', 'Pxz', 'K', 'eta', 'chi', 'Szz', 'w')]
    # the NIS solves the m x m innovation covariance: its conditioning enters
    cond = np.linalg.cond(ref[1][2].Pzz)
    assert_roundoff(fast[1][2].nis(), kf.nis(ref[1][2].y, ref[1][2].Pzz), STEP_OPS,
                    cond=cond)
    for a, b in pairs:
        assert a.shape == b.shape
        # one predict and one update of 13 states: 2n = 26-point sums and Tria's
        # Householder reflections over 2n + n columns (2 x 39^2 / 13 per state ~ 240):
        # ~300 operations, relative to the largest entry, solved through Pzz
        assert_roundoff(b, a, 300, np.abs(a).max(), cond)
    monkeypatch.setattr(compilation, 'COMPILED', True)
    with pytest.raises(np.linalg.LinAlgError):
        srckf_update(x, S, z, batched(lambda X: np.zeros((m, X.shape[1]))), np.zeros((m, m)))
    for compiled in (True, False):        # shapes that disagree: ValueError on both paths
        monkeypatch.setattr(compilation, 'COMPILED', compiled)
        with pytest.raises(ValueError):
            srckf_update(x, S, z[:-1], h, SR)
        with pytest.raises(ValueError):
            srckf_update(x, S, z, h, SR[:-1, :-1])
        with pytest.raises(ValueError):
            srckf_predict(x, S, batched(lambda X: X[:-1]), SQ)
        with pytest.raises(ValueError):
            srckf_predict(x, S, f, SQ, np.ones(n - 1))


def test_ckf_matches_filterpy_to_round_off():
    filterpy = pytest.importorskip('filterpy.kalman', reason='filterpy is a test dependency')
    zs, Q, R = scenario()
    ref = filterpy.CubatureKalmanFilter(dim_x=4, dim_z=2, dt=DT, hx=lambda x: hx(x.ravel()),
                                        fx=lambda x, dt: fx(x.ravel()))
    ref.x, ref.P, ref.Q, ref.R = X0.reshape(4, 1), P0.copy(), Q, R   # column vectors
    x, P = X0.copy(), P0.copy()
    for steps, z in enumerate(zs, 1):
        ref.predict()
        ref.update(z.reshape(2, 1))
        x, P, Xp = ckf_predict(x, P, fx, Q)
        x, P, _ = ckf_update(x, P, z, hx, R, points=Xp)   # filterpy does not re-sample
        # filterpy's order against ours, through the innovation covariance's solve
        cond = np.linalg.cond(ref.S)
        assert_roundoff(x, ref.x.ravel(), steps * STEP_OPS, np.abs(x).max(), cond)
        assert_roundoff(P, ref.P, steps * STEP_OPS, np.abs(P0).max(), cond)


def test_ukf_matches_filterpy_to_round_off():
    filterpy = pytest.importorskip('filterpy.kalman', reason='filterpy is a test dependency')
    zs, Q, R = scenario(seed=2)
    pts = filterpy.MerweScaledSigmaPoints(4, alpha=0.5, beta=2.0, kappa=0.0)
    ref = filterpy.UnscentedKalmanFilter(dim_x=4, dim_z=2, dt=DT, hx=hx,
                                         fx=lambda x, dt: fx(x), points=pts)
    ref.x, ref.P, ref.Q, ref.R = X0.copy(), P0.copy(), Q, R
    x, P = X0.copy(), P0.copy()
    for steps, z in enumerate(zs, 1):
        ref.predict()
        ref.update(z)
        x, P, Xp = ukf_predict(x, P, fx, Q, alpha=0.5)
        x, P, _, _ = ukf_update(x, P, z, hx, R, alpha=0.5)   # re-drawn points, as filterpy
        # as the CKF's; the UKF's weights (alpha 0.5: W0 = -3) add |W| sums up to 7 x
        cond = np.linalg.cond(ref.S) * 7.0
        assert_roundoff(x, ref.x, steps * STEP_OPS, np.abs(x).max(), cond)
        assert_roundoff(P, ref.P, steps * STEP_OPS, np.abs(P0).max(), cond)


def test_ckf_equals_the_linear_kalman_filter_on_a_linear_problem():
    F = np.array([[1.0, DT, 0.0], [0.0, 1.0, DT], [0.0, 0.0, 0.98]])
    H = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    Q, R = np.diag([1e-4, 1e-3, 1e-2]), np.diag([0.05, 0.2])
    rng = np.random.default_rng(3)
    x_kf = x_ckf = np.array([1.0, 0.0, 0.5])
    P_kf = P_ckf = np.eye(3)
    for steps in range(1, 31):
        z = rng.normal(size=2)
        x_kf, P_kf = kf.predict(x_kf, P_kf, F, Q)
        x_kf, P_kf, _, _ = kf.update(x_kf, P_kf, z, H, R)
        x_ckf, P_ckf, _ = ckf_predict(x_ckf, P_ckf, lambda x: F @ x, Q)
        x_ckf, P_ckf, _ = ckf_update(x_ckf, P_ckf, z, lambda x: H @ x, R)
        cond = np.linalg.cond(H @ P_kf @ H.T + R)
        assert_roundoff(x_ckf, x_kf, steps * STEP_OPS, np.abs(x_kf).max(), cond)
        assert_roundoff(P_ckf, P_kf, steps * STEP_OPS, np.abs(P_kf).max(), cond)


def test_square_root_ckf_equals_ckf():
    zs, Q, R = scenario(seed=4)
    x1, P = X0.copy(), P0.copy()
    x2, S = X0.copy(), chol_lower(P0)
    SQ, SR = chol_lower(Q), chol_lower(R)
    for steps, z in enumerate(zs, 1):
        x1, P, _ = ckf_predict(x1, P, fx, Q)
        x1, P, u1 = ckf_update(x1, P, z, hx, R)
        x2, S, _ = srckf_predict(x2, S, fx, SQ)
        x2, S, u2 = srckf_update(x2, S, z, hx, SR)
        # the square-root form rounds in the factors: P's round-off is relative to the
        # products S S^T, which are of P's size; Tria's reflections add ~2 (3n)^2 / n = 72
        n_ops, cond = steps * (STEP_OPS + 72), np.linalg.cond(u1.Pzz)
        assert_roundoff(x2, x1, n_ops, np.abs(x1).max(), cond)
        assert_roundoff(S @ S.T, P, n_ops, np.abs(P0).max(), cond)
        assert_roundoff(u2.Pzz, u1.Pzz, n_ops, np.abs(u1.Pzz).max(), cond)
        assert np.allclose(S, np.tril(S))


def test_fading_factors_are_one_when_consistent_and_grow_when_not():
    rng = np.random.default_rng(5)
    n, m = 4, 2
    P = np.diag([1.0, 2.0, 0.5, 0.1])
    Q = 0.01 * np.eye(n)
    H = rng.normal(size=(m, n))
    R = 0.1 * np.eye(m)
    Pxz = P @ H.T
    st = StrongTracking(alpha=np.ones(n), rho=0.95, beta=3.0)
    S = H @ P @ H.T + R
    for _ in range(200):                       # innovations as predicted: no fading
        lam = st.factors(rng.multivariate_normal(np.zeros(m), S), P, Pxz, Q, R)
    assert np.all(lam == 1.0)
    st = StrongTracking(alpha=[1.0, 2.0, 1.0, 1.0])
    for _ in range(200):                       # innovations ten times larger
        lam = st.factors(10 * rng.multivariate_normal(np.zeros(m), S), P, Pxz, Q, R)
    assert st.lambda0 > 1.0
    assert lam[1] == pytest.approx(2.0 * lam[0]) and np.all(lam > 1.0)
    assert StrongTracking.sqrt_factors(lam) == pytest.approx(np.sqrt(lam))


def test_sage_husa_tracks_a_wrong_measurement_noise():
    """Scalar random walk seen with noise 10x larger than the filter's R0."""
    rng = np.random.default_rng(6)
    q, r_true = 1e-4, 1.0
    results = {}
    for gate in (False, True):
        est = SageHusa(Q0=np.eye(1) * q, R0=np.eye(1) * 0.01, b=0.99, gate=gate, adapt_q=False)
        x_true, x, P = 0.0, np.zeros(1), np.eye(1)
        for _ in range(3000):
            x_true += rng.normal(0, np.sqrt(q))
            z = np.array([x_true + rng.normal(0, np.sqrt(r_true))])
            x, P, Xp = ckf_predict(x, P, lambda s: s, est.Q)
            x, P, upd = ckf_update(x, P, z, lambda s: s, est.R)
            est.update(upd)
        results[gate] = est
    assert results[False].R[0, 0] == pytest.approx(r_true, rel=0.3)   # eq. 39 alone
    # the seed's gate (eq. 20) learns the larger noise too, but only from large innovations
    assert results[True].R[0, 0] > 0.5 * r_true and results[True].divergence_flags > 0


def test_sage_husa_counts_the_configured_noise_as_a_memory_of_epochs():
    """The seed's weight d_1 = 1 replaces R0 by the first squared innovation; with R0
    worth 1/(1-b) epochs one small innovation moves R by about 5 %, and the estimate
    still converges to the real noise (here 10x R0) over the memory."""
    from types import SimpleNamespace
    small = SimpleNamespace(y=np.array([0.01]), K=np.zeros((1, 1)), eta=np.zeros((1, 1)),
                            Pzz=np.eye(1) * 1e-6)
    seed = SageHusa(Q0=np.eye(1), R0=np.eye(1), b=0.97, gate=False, adapt_q=False,
                    prior_epochs=0)
    ours = SageHusa(Q0=np.eye(1), R0=np.eye(1), b=0.97, gate=False, adapt_q=False)
    assert seed.update(small)[1][0, 0] == pytest.approx(1e-3)    # the floor: R0 gone
    d = 0.03 / (1.0 - 0.97 ** (1 + 1 / 0.03))                     # 0.046
    assert ours.update(small)[1][0, 0] == pytest.approx(1.0 - d + d * 1e-4)
    rng = np.random.default_rng(8)
    for _ in range(400):
        y = rng.normal(0.0, np.sqrt(10.0), 1)
        ours.update(SimpleNamespace(y=y, K=np.zeros((1, 1)), eta=np.zeros((1, 1)),
                                    Pzz=np.eye(1) * 10.0))
    assert ours.R[0, 0] == pytest.approx(10.0, rel=0.35)


def test_asckf_without_improvements_is_the_square_root_ckf():
    from sins_align_ros.filters.asckf import ASCKF
    zs, Q, R = scenario(seed=7)
    f = ASCKF(X0, P0, Q, R, fading=False, adaptive=False)
    x, S = X0.copy(), chol_lower(P0)
    for steps, z in enumerate(zs, 1):
        upd = f.step(fx, z, hx)
        x, S, _ = srckf_predict(x, S, fx, chol_lower(Q))
        x, S, _ = srckf_update(x, S, z, hx, chol_lower(R))
        # the same square-root steps in another order (the class's compiled path)
        n_ops, cond = steps * (STEP_OPS + 72), np.linalg.cond(upd.Pzz)
        assert_roundoff(f.x, x, n_ops, np.abs(x).max(), cond)
        assert_roundoff(f.P, S @ S.T, n_ops, np.abs(P0).max(), cond)


def test_asckf_fades_and_adapts_when_the_noise_is_wrong():
    """Measurement noise ten times the filter's R for a while: fading fires (at the step,
    before the R estimate has caught up), R grows."""
    from sins_align_ros.filters.asckf import ASCKF
    rng = np.random.default_rng(8)
    Q = np.diag([0.01, 0.01, 0.02, 0.005]) ** 2
    R = np.diag([0.1, 0.01]) ** 2
    x = np.array([10.0, 5.0, 2.0, 0.3])
    f_ok = ASCKF(X0, P0, Q, R, fading=True, adaptive=False)
    f_bad = ASCKF(X0, P0, Q, R, fading=True, adaptive=True, adapt_q=False)
    lam_ok, lam_bad = [], []
    for k in range(300):
        x = fx(x) + rng.normal(0, np.sqrt(np.diag(Q)))
        scale = 10.0 if 100 <= k < 200 else 1.0
        noise = rng.normal(0, np.sqrt(np.diag(R)))
        f_ok.step(fx, hx(x) + noise, hx)
        f_bad.step(fx, hx(x) + scale * noise, hx)
        if 150 <= k < 200:
            lam_ok.append(f_ok.lam.max())
        if 100 <= k < 200:
            lam_bad.append(f_bad.lam.max())
    assert np.mean(lam_ok) < 1.5
    assert max(lam_bad) > 1.0
    assert f_bad.noise.R[0, 0] > 3.0 * R[0, 0]               # learned the larger noise
    assert np.all(np.isfinite(f_bad.x)) and np.all(np.linalg.eigvalsh(f_bad.P) > 0)


def test_lag1_correlation_separates_white_from_persistent_innovations():
    from sins_align_ros.filters.asckf import lag1_correlation
    rng = np.random.default_rng(11)
    white = rng.standard_normal((2000, 2))
    r_white = [lag1_correlation(white[k:k + 11]) for k in range(0, 2000, 11)]
    # spread about 1/sqrt(L m) = 0.22 for L = 10, m = 2, whatever the scale
    assert abs(np.mean(r_white)) < 0.05 and 0.15 < np.std(r_white) < 0.3
    assert lag1_correlation(100.0 * white[:11]) == pytest.approx(lag1_correlation(white[:11]))
    drift = 0.2 * white[:11] + np.array([1.0, -0.5])          # a bias keeps its sign
    assert lag1_correlation(drift) > 0.8
    assert lag1_correlation(np.zeros((11, 2))) == 0.0


def test_whiteness_gate_leaves_a_noise_step_to_r_and_fades_a_state_jump():
    """Fading gated on the innovations' lag-1 correlation (seed 000 sec. 2.1 condition 2).

    A 10x step of the measurement noise gives white innovations: no fading, R learns it.
    A jump of the true heading (a state error the model does not know) gives
    innovations of one sign: the fading fires; a variance cap keeps P bounded.
    """
    from sins_align_ros.filters.asckf import ASCKF
    Q = np.diag([0.01, 0.01, 0.02, 0.005]) ** 2
    R = np.diag([0.1, 0.01]) ** 2

    def run(noise_scale, jump, seed, fading=True):
        rng = np.random.default_rng(seed)
        x = np.array([10.0, 5.0, 2.0, 0.3])
        f = ASCKF(X0, P0, Q, R, fading=fading, adaptive=True, adapt_q=False,
                  whiteness=(10, 0.5), var_max=np.diag(P0))
        faded = []
        for k in range(300):
            x = fx(x) + rng.normal(0, np.sqrt(np.diag(Q)))
            if k == 150:
                x[3] += jump
            scale = noise_scale if 100 <= k < 200 else 1.0
            f.step(fx, hx(x) + scale * rng.normal(0, np.sqrt(np.diag(R))), hx)
            faded.append(f.faded)
            # a cap at var_max, met to the round-off of the clip's scaling (~10 operations)
            assert np.all(np.diag(f.P) <= np.diag(P0) + roundoff(10, np.diag(P0))
                          + np.diag(Q) * 10)
        return f, x, np.array(faded)

    f, x, faded = run(10.0, 0.0, 21)
    assert faded[100:200].sum() <= 3
    assert f.noise.R[0, 0] > 3.0 * R[0, 0] or faded.sum() == 0
    f, x, faded = run(1.0, 1.0, 22)
    assert not faded[100:150].any() and faded[150:200].any()
    g, xg, _ = run(1.0, 1.0, 22, fading=False)
    assert abs(f.x[3] - x[3]) < 0.5 * abs(g.x[3] - xg[3]), (f.x[3] - x[3], g.x[3] - xg[3])


def _filters(n=4, M=2):
    """One instance of every filter the alignment engines drive, on a small linear problem."""
    from sins_align_ros.filters.asckf import ASCKF
    from sins_align_ros.filters.ckf import CKF
    from sins_align_ros.filters.linear_kf import KF
    from sins_align_ros.filters.mvbakf import MVBAKF
    from sins_align_ros.filters.ukf import UKF
    from sins_align_ros.filters.vbakf import VBAKF
    from sins_align_ros.filters.vbch import VBCH
    from sins_align_ros.filters.vbckf import VBCKF
    args = (np.zeros(n), np.eye(n), 0.01 * np.eye(n), 0.1 * np.eye(M))
    return {'CKF': CKF(*args), 'ASCKF': ASCKF(*args), 'KF': KF(*args), 'VBAKF': VBAKF(*args),
            'MVBAKF': MVBAKF(*args), 'UKF': UKF(*args), 'VBCKF': VBCKF(*args),
            'VBCH': VBCH(*args, np.eye(1, n))}


@pytest.mark.parametrize('name', ['CKF', 'ASCKF', 'KF', 'VBAKF', 'MVBAKF', 'UKF', 'VBCKF',
                                  'VBCH'])
def test_every_filter_has_the_declared_interface(name):
    """Each filter is a GaussianFilter: predict, step (a subset, the gate), transform, append."""
    from sins_align_ros.filters.base import GaussianFilter, Innovation
    from sins_align_ros.filters.cubature import batched
    from sins_align_ros.filters.linear_kf import linear
    f = _filters()[name]
    assert isinstance(f, GaussianFilter)
    assert f.last is None and not f.rejected and f.divergence_flags == 0
    F = np.eye(4) + 0.1 * np.eye(4, k=1)
    f.predict(linear(F))
    upd = f.step(linear(F), np.array([0.3]), batched(lambda X: X[[1]]), np.array([1]))
    assert isinstance(upd, Innovation) and upd is f.last
    assert upd.y.shape == (1,) and upd.Pzz.shape == (1, 1)
    # one m = 1 solve both ways: a division and a product
    assert_roundoff(upd.nis(), kf.nis(upd.y, upd.Pzz), 5)
    assert f.x.shape == (4,) and f.P.shape == (4, 4) and f.R.shape == (2, 2)
    f.step(linear(F), np.array([1e3, -1e3]), batched(lambda X: X[:2]), max_nis=10.0)
    assert f.rejected
    T = np.diag([1.0, -1.0, 2.0, 1.0])
    x, P = f.x.copy(), f.P.copy()
    f.transform(T)
    np.testing.assert_allclose(f.x, T @ x)
    # T P T^T, two n = 4 dot products deep (T diagonal here: fewer), in two orders
    np.testing.assert_allclose(f.P, T @ P @ T.T, rtol=0,
                               atol=roundoff(16, np.abs(T).max() ** 2 * np.abs(P).max()))
    # two random constants appended (the gyro scale-factor states): x by zeros, P by their
    # diagonal block, no cross terms, no process noise; the filter then runs on 6 states
    x, P, var = f.x.copy(), f.P.copy(), np.array([0.5, 2.0])
    f.append_states(var)
    assert f.x.shape == (6,) and f.P.shape == (6, 6) and f.Q.shape == (6, 6)
    assert np.all(f.x[:4] == x) and np.all(f.x[4:] == 0.0)
    # a square-root factor's S S^T: n = 4 products per entry
    np.testing.assert_allclose(f.P[:4, :4], P, rtol=0, atol=roundoff(8, np.abs(P).max()))
    np.testing.assert_allclose(f.P[4:, 4:], np.diag(var), rtol=0, atol=roundoff(2, var.max()))
    assert np.all(f.P[:4, 4:] == 0.0) and np.all(f.Q[4:] == 0.0) and np.all(f.Q[:, 4:] == 0.0)
    f.step(linear(np.eye(6)), np.array([0.3]), batched(lambda X: X[[1]]), np.array([1]))
    assert f.x.shape == (6,) and np.all(np.isfinite(f.P))


def test_chi2_quantile_equals_scipy_and_the_closed_forms():
    """filters.chi2 against scipy.special.chdtri (p >= 1/2) and chi2(2): -2 ln(1 - p)."""
    from scipy.special import chdtri

    from sins_align_ros.filters.chi2 import chi2_quantile, gamma_p, gamma_q
    for p in (0.5, 0.8, 0.9, 0.95, 0.99, 0.995, 0.999, 0.9999, 1 - 1e-7):
        for dof in (1, 2, 3, 4, 5, 6, 9, 12, 15, 30, 60, 120, 600, 3600):
            assert chi2_quantile(p, dof) == pytest.approx(chdtri(dof, 1 - p), rel=1e-12)
    for p in (1e-9, 1e-4, 0.3, 0.99, 1 - 1e-9):          # small p: better than 1 - p allows
        assert chi2_quantile(p, 2) == pytest.approx(-2 * np.log1p(-p), rel=1e-12)
    # P and Q from the series / continued fraction (~30 terms of 3 operations) and exp, log
    assert_roundoff(gamma_p(3.0, 2.0) + gamma_q(3.0, 2.0), 1.0, 100)
    assert_roundoff(gamma_q(1.0, 7.0), np.exp(-7.0), 100)
    with pytest.raises(ValueError):
        chi2_quantile(1.0, 3)


def test_sqrt_psd_roots_definite_semidefinite_and_diagonal_matrices():
    """L L^T = A for every kind of A the filters give it (a negative round-off clipped)."""
    from sins_align_ros.filters.cubature import sqrt_psd
    rng = np.random.default_rng(5)
    B = rng.standard_normal((6, 4))
    cases = [np.diag([1e-12, 0.0, 4.0, 1e-20]),          # diagonal, a state without noise
             np.diag([1.0, -1e-30, 2.0]),                # a negative round-off variance
             B @ B.T,                                    # full, rank 4 of 6
             B @ B.T + np.eye(6)]                        # full, definite
    for A in cases:
        L = sqrt_psd(A)
        assert np.all(np.isfinite(L))
        want = A.copy()
        want[np.diag_indices(len(A))] = np.clip(np.diag(A), 0.0, None)
        # Cholesky: |L L^T - A| <= gamma_(n+1) |L| |L^T| (Higham thm 10.3), then L L^T's own
        # n-term dot products: 2 (n + 1) operations on |L| |L^T|
        LL = np.abs(L) @ np.abs(L).T
        assert np.all(np.abs(L @ L.T - want) <= roundoff(2 * (len(A) + 1), LL))
    assert np.array_equal(sqrt_psd(np.diag([4.0, 9.0])), np.linalg.cholesky(np.diag([4.0, 9.0])))


def test_asckf_takes_a_semi_definite_covariance():
    """P set to a rank-deficient matrix (a state held at zero variance): no LinAlgError, a
    lower-triangular root whose product is P to round-off (an eigen-root of a 4x4 matrix of
    entries up to 1: a few hundred eps), where Cholesky alone raised (ground matrix run)."""
    from sins_align_ros.filters.asckf import ASCKF
    rng = np.random.default_rng(3)
    A = rng.normal(size=(4, 2))
    P = A @ A.T                                    # rank 2
    P[3, :] = P[:, 3] = 0.0                        # and a held state
    with pytest.raises(np.linalg.LinAlgError):
        np.linalg.cholesky(P)
    f = ASCKF(np.zeros(4), np.eye(4), np.eye(4) * 1e-6, np.eye(2))
    f.P = P
    assert np.allclose(np.triu(f.S, 1), 0.0)
    np.testing.assert_allclose(f.S @ f.S.T, P, rtol=0, atol=500 * np.finfo(float).eps
                               * np.abs(P).max())


@pytest.mark.parametrize('which', ['kf', 'ukf'])
def test_consider_states_keep_their_estimate_and_an_exact_covariance(which):
    """A Schmidt consider state: measured through its correlation with a measured one, it
    keeps its estimate and variance; the measured state gets the optimal update; the
    cross-covariance shrinks by (1 - k). Closed form for x = (a, b), z = a + v:
    ``k = P_aa / (P_aa + R)``, ``P_aa' = P_aa R / (P_aa + R)``, ``P_ab' = (1 - k) P_ab``."""
    from sins_align_ros.filters.linear_kf import KF, linear
    from sins_align_ros.filters.ukf import UKF
    P0 = np.array([[4.0, 1.2], [1.2, 1.0]])
    R = np.array([[1.0]])
    z = np.array([2.0])
    cls = KF if which == 'kf' else UKF
    f = cls(np.zeros(2), P0, np.zeros((2, 2)), R)
    f.consider = np.array([False, True])
    hx = batched(lambda X: X[:1])
    f.step(linear(np.eye(2)), z, hx)
    k = 4.0 / 5.0
    assert f.x[1] == 0.0
    assert_roundoff(f.x[0], k * 2.0, 10)
    assert_roundoff(f.P[0, 0], 4.0 * 1.0 / 5.0, 20)
    assert_roundoff(f.P[0, 1], (1.0 - k) * 1.2, 20)
    assert_roundoff(f.P[1, 1], 1.0, 20)
    # without it, b takes the optimal gain P_ab / (P_aa + R)
    g = cls(np.zeros(2), P0, np.zeros((2, 2)), R)
    g.step(linear(np.eye(2)), z, hx)
    assert_roundoff(g.x[1], 1.2 / 5.0 * 2.0, 10)
