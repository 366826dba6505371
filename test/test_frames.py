"""Frame and attitude conventions (REP-103, navigation heading, PSINS, RFU/FRD/NED)."""
import numpy as np
import pytest

from sins_align_ros.nav import frames as fr
from sins_align_ros import compiled as compilation
from sins_align_ros.units import DEG
from tolerance import assert_roundoff, roundoff

# Operation counts for the round-off bounds (test/tolerance.py): a DCM from Euler angles is
# 3 sin/cos pairs (2 each) and two 3x3 products (5 each) per entry, ~15; a quaternion from
# Euler angles, half-angle sin/cos (2) and a product of three terms summed 4 ways (~6), ~10;
# one way through a quaternion or a DCM and back, with atan2/asin (2), ~20 to 30.
N_DCM = 20          # euler_to_dcm, rotvec_to_dcm, scipy's as_matrix (with a margin of 5)
N_ROUND_TRIP = 30   # Euler/rotation vector -> DCM or quaternion -> back
#: a 3x3 SVD (LAPACK): 2 Householder reflections a side (~6 operations on an entry each),
#: then implicit-QR sweeps, ~2 per singular value, of 2 rotations (3 operations each): ~60;
#: ``U @ Vt`` 5 more; rounded up
N_SVD = 80
#: the compiled polar factor: up to 12 Newton-Schulz steps ``X (3I - X^T X) / 2`` (two 3x3
#: products, ~12 operations); rounding along the rotation (tangent) direction is not damped
#: by later steps, so the chain is the sum over the steps
N_NEWTON_SCHULZ = 12 * 12


def nose(euler):
    """The body x axis (forward) in ENU."""
    return fr.euler_to_dcm(euler) @ np.array([1.0, 0.0, 0.0])


def test_rep103_yaw_zero_points_east_and_positive_yaw_turns_north():
    assert nose([0, 0, 0]) == pytest.approx([1, 0, 0])
    # cos(pi/2) = 6e-17, not 0: the DCM's chain plus the matrix-vector product (5)
    assert_roundoff(nose([0, 0, 90 * DEG]), [0, 1, 0], N_DCM + 5, scale=1.0)


def test_rep103_positive_pitch_is_nose_down_and_positive_roll_right_side_down():
    assert nose([0, 10 * DEG, 0])[2] < 0
    left = fr.euler_to_dcm([10 * DEG, 0, 0]) @ np.array([0.0, 1.0, 0.0])
    assert left[2] > 0   # left side up = right side down


def test_euler_dcm_quaternion_round_trips():
    rng = np.random.default_rng(4)
    e = rng.uniform([-np.pi, -1.5, -np.pi], [np.pi, 1.5, np.pi], size=(100, 3))
    # roll and yaw are atan2 of entries of size cos(pitch), pitch is asin(C20) whose
    # derivative is 1 / cos(pitch): an entry's round-off is amplified by 1 / cos(pitch)
    cond = 1.0 / np.cos(e[:, 1:2])
    assert_roundoff(fr.dcm_to_euler(fr.euler_to_dcm(e)), e, N_ROUND_TRIP, 1.0, cond)
    assert_roundoff(fr.quat_to_euler(fr.euler_to_quat(e)), e, N_ROUND_TRIP, 1.0, cond)
    q = fr.dcm_to_quat(fr.euler_to_dcm(e))
    assert np.all(q[:, 3] >= 0)
    # Shepperd's branch divides by its largest |4 q_i| >= 1: a gain of at most 1
    assert_roundoff(fr.quat_to_dcm(q), fr.euler_to_dcm(e), N_DCM + N_ROUND_TRIP, 1.0)


def test_closed_forms_agree_with_scipy_rotation():
    """The module's closed forms (no scipy at import: 0.16 s of every start) against
    scipy's Rotation, an independent implementation, on one and on stacked inputs."""
    from scipy.spatial.transform import Rotation
    rng = np.random.default_rng(21)
    e = rng.uniform([-np.pi, -1.5, -np.pi], [np.pi, 1.5, np.pi], size=(200, 3))
    ref = Rotation.from_euler('xyz', e)
    # unit-size entries on both sides; each side's chain is N_DCM
    assert_roundoff(fr.euler_to_dcm(e), ref.as_matrix(), N_DCM, 1.0)
    assert_roundoff(fr.euler_to_dcm(e[0]), ref[0].as_matrix(), N_DCM, 1.0)
    assert_roundoff(fr.euler_to_quat(e), ref.as_quat(), N_DCM, 1.0)
    q = ref.as_quat() * rng.uniform(0.5, 2.0, (200, 1))     # any norm
    # the scaling, the norm (4 squares summed, a sqrt) and the division: 7 more
    assert_roundoff(fr.quat_to_dcm(q), ref.as_matrix(), N_DCM + 7, 1.0)
    assert_roundoff(fr.quat_to_euler(q[3]), e[3], N_ROUND_TRIP, 1.0, 1.0 / np.cos(e[3, 1]))
    for angle in (1e-12, 1e-7, 1e-3, 1.0, 3.14159):        # series, general, near pi
        v = rng.normal(size=(50, 3))
        v *= angle / np.linalg.norm(v, axis=1, keepdims=True)
        C = Rotation.from_rotvec(v).as_matrix()
        assert_roundoff(fr.rotvec_to_dcm(v), C, N_DCM, 1.0)
        # the rotation vector comes from the DCM's skew part, entries of size sin(angle)
        # formed from products relative to their own size: an error relative to the angle
        # (scipy's DCM: N_DCM, then the quaternion, atan2 and division: N_ROUND_TRIP)
        assert_roundoff(fr.dcm_to_rotvec(C), v, N_DCM + N_ROUND_TRIP, angle)
        assert_roundoff(fr.dcm_to_rotvec(C[0]), v[0], N_DCM + N_ROUND_TRIP, angle)
    att = rng.uniform([-1.5, -np.pi, -np.pi], [1.5, np.pi, np.pi], size=(50, 3))
    psins = Rotation.from_euler('ZXY', att[:, [2, 0, 1]]).as_matrix() @ fr.C_FLU_TO_RFU
    assert_roundoff(fr.psins_att_to_dcm(att), psins, N_DCM, 1.0)   # a permutation is exact
    # what is unknown stays unknown (scipy raises on a zero quaternion)
    assert np.isnan(fr.quat_to_euler([0.0, 0.0, 0.0, 0.0])).all()
    assert np.isnan(fr.quat_to_euler(np.full((2, 4), np.nan))).all()
    assert np.isnan(fr.dcm_to_euler(np.full((3, 3), np.nan))).all()


def test_navigation_heading_is_clockwise_from_north():
    assert fr.yaw_to_heading(0.0) == pytest.approx(np.pi / 2)          # east
    assert fr.yaw_to_heading(np.pi / 2) == pytest.approx(0.0)          # north
    assert fr.yaw_to_heading(-np.pi / 2) == pytest.approx(np.pi)       # south
    h = np.linspace(0, 2 * np.pi, 13)[:-1]
    assert fr.yaw_to_heading(fr.heading_to_yaw(h)) == pytest.approx(h)
    e = fr.nav_to_euler(0.0, 5 * DEG, 45 * DEG)
    assert nose(e) == pytest.approx([np.sin(45 * DEG) * np.cos(5 * DEG),
                                     np.cos(45 * DEG) * np.cos(5 * DEG), np.sin(5 * DEG)])


def test_psins_attitude_conversion():
    # PSINS yaw is CCW from north with an RFU body: REP-103 yaw = PSINS yaw + 90 deg
    C = fr.psins_att_to_dcm(np.array([0.0, 0.0, -90.6]) * DEG)
    assert fr.dcm_to_euler(C)[2] == pytest.approx(-0.6 * DEG)
    # PSINS pitch is nose up: REP-103 pitch (nose down) has the opposite sign
    C = fr.psins_att_to_dcm(np.array([3.0, 2.0, 30.0]) * DEG)
    e = fr.dcm_to_euler(C)
    assert e[1] == pytest.approx(-3.0 * DEG, abs=0.05 * DEG)
    att = np.array([3.0, -2.0, 130.0]) * DEG
    assert fr.dcm_to_psins_att(fr.psins_att_to_dcm(att)) == pytest.approx(att)


def test_fixed_frame_changes():
    v_rfu = np.array([1.0, 2.0, 3.0])       # right, forward, up
    assert fr.C_RFU_TO_FLU @ v_rfu == pytest.approx([2.0, -1.0, 3.0])
    assert fr.C_FLU_TO_FRD @ np.array([2.0, -1.0, 3.0]) == pytest.approx([2.0, 1.0, -3.0])
    assert fr.C_ENU_TO_NED @ np.array([1.0, 2.0, 3.0]) == pytest.approx([2.0, 1.0, -3.0])
    for C in (fr.C_RFU_TO_FLU, fr.C_FLU_TO_FRD, fr.C_ENU_TO_NED):
        assert C @ C.T == pytest.approx(np.eye(3))


def test_euler_rates_to_body_rate_matches_finite_difference():
    def euler(t):
        return np.array([0.3 * np.sin(t), -0.2 * np.cos(1.3 * t), 1.0 + 0.5 * t])

    def euler_rate(t):
        return np.array([0.3 * np.cos(t), 0.26 * np.sin(1.3 * t), 0.5])

    t, h = 0.7, 1e-6
    C0, C1 = fr.euler_to_dcm(euler(t - h)), fr.euler_to_dcm(euler(t + h))
    w_fd = fr.dcm_to_rotvec(C0.T @ C1) / (2 * h)       # C_b_n' = C_b_n [w_nb_b x]
    w = fr.euler_rates_to_w_nb_b(euler(t), euler_rate(t))
    assert w == pytest.approx(w_fd, abs=1e-8)


def test_attitude_error_is_seed002_eq3_platform_misalignment():
    C = fr.euler_to_dcm([0.1, -0.2, 1.0])
    phi = np.array([1e-3, -2e-3, 5e-3])
    C_est = (np.eye(3) - fr.skew(phi)) @ C
    assert fr.attitude_error(fr.orthonormalize(C_est), C) == pytest.approx(phi, rel=1e-4)
    C_est = fr.rotvec_to_dcm(-phi) @ C
    # phi (5e-3) is read off C_est C^T, whose unit-size products leave absolute round-off:
    # the DCMs (N_DCM), their product (5) and the rotation vector (N_ROUND_TRIP)
    assert_roundoff(fr.attitude_error(C_est, C), phi, 2 * N_DCM + 5 + N_ROUND_TRIP, 1.0)


def test_wrap_pi():
    assert fr.wrap_pi(np.array([3 * np.pi, -3 * np.pi + 0.1, 0.2])) == pytest.approx(
        [np.pi, -np.pi + 0.1, 0.2])


def test_euler_sigma_is_the_propagated_covariance_of_a_small_nav_frame_rotation():
    """sigma(euler) = sqrt(diag(J P J^T)), J the numerical d(euler)/d(phi) of C -> exp(phi) C."""
    rng = np.random.default_rng(7)
    euler = np.column_stack([rng.uniform(-3, 3, 40), rng.uniform(-1.4, 1.4, 40),
                             rng.uniform(-3, 3, 40)])
    A = rng.standard_normal((40, 3, 3)) * 1e-3
    P = A @ A.transpose(0, 2, 1)
    P[0] = np.diag([1e-6, -1e-20, 1e-6])            # a negative round-off variance: 0, not NaN
    sig = fr.euler_sigma(euler, P)
    h = 1e-7
    for k in range(40):
        C = fr.euler_to_dcm(euler[k])
        J = np.column_stack([fr.wrap_pi(fr.dcm_to_euler(fr.rotvec_to_dcm(h * e) @ C) - euler[k])
                             / h for e in np.eye(3)])
        want = np.sqrt(np.clip(np.diag(J @ P[k] @ J.T), 0.0, None))
        assert np.allclose(sig[k], want, rtol=1e-5, atol=1e-9)   # finite difference, h=1e-7
        # the scalar path and the vectorised one, two orders of one sum: the Jacobian (the
        # inverse of a 3x3 E with det cos(pitch), ~10 operations, conditioned 1 / cos(pitch)),
        # J P J^T (two 3-term dot products, 10), the sqrt; the variance's operands are
        # (|J| |P| |J|^T)_kk, its round-off reaches sigma through
        # |sqrt(a) - sqrt(b)| <= |a - b| / max(sqrt(a) + sqrt(b), sqrt(|a - b|))
        Jabs = np.abs(fr.phi_to_euler_jacobian(euler[k]))
        dvar = roundoff(20, np.diag(Jabs @ np.abs(P[k]) @ Jabs.T), 1.0 / np.cos(euler[k, 1]))
        bound = dvar / np.maximum(sig[k], np.sqrt(dvar))
        assert np.all(np.abs(fr.euler_sigma_one(euler[k], P[k].tolist()) - sig[k]) <= bound)
        cov = fr.euler_cov_from_phi_cov(euler[k], P[k])
        assert np.all(np.abs(np.sqrt(np.clip(np.diag(cov), 0.0, None)) - sig[k]) <= bound)


@pytest.mark.parametrize('departure', [0.0, 1e-15, 1e-12, 1e-9, 1e-6, 1e-2, 0.1, 0.3])
@pytest.mark.parametrize('compiled', [False, True])
def test_orthonormalize_is_the_svd_polar_factor_to_round_off(departure, compiled, monkeypatch):
    """Both functions, compiled (Newton-Schulz) or not, against the SVD's ``U V^T``."""
    if compiled and not compilation.COMPILED:
        pytest.skip('numba not installed or switched off')
    monkeypatch.setattr(compilation, 'COMPILED', compiled)
    rng = np.random.default_rng(7)
    for k in range(50):
        C = fr.rotvec_to_dcm(rng.normal(0.0, 1.0, 3)) + rng.normal(0.0, departure, (3, 3))
        if k == 0:
            C = C @ np.diag([1.0, 1.0, -1.0])           # a reflection's factor too
        U, s, Vt = np.linalg.svd(C)
        # the polar factor moves by at most 2 / (s_2 + s_3) times a perturbation of C
        # (Higham, Functions of Matrices, thm 8.9), whose round-off is relative to s_1;
        # either side is the SVD or the Newton-Schulz steps, plus the SVD's own
        cond = 2.0 * s[0] / (s[1] + s[2])
        for R in (fr.reorthonormalize(C), fr.orthonormalize(C)):
            assert_roundoff(R, U @ Vt, N_NEWTON_SCHULZ + N_SVD, 1.0, cond)
            # orthonormal to round-off whatever the conditioning: products of reflections
            # and rotations (the SVD), or steps stopped below 1e-15 = 4.5 EPS (the compiled
            # path); then R^T R's own 3-term dot products (5)
            assert_roundoff(R.T @ R, np.eye(3), N_SVD + 5, 1.0)
    for bad in (np.full((3, 3), np.nan), np.diag([np.inf] * 3), np.diag([1.0, 1.0, np.nan])):
        with pytest.raises(np.linalg.LinAlgError):       # as the SVD: never a silent NaN
            fr.orthonormalize(bad)
