"""Frame and attitude conventions (REP-103, navigation heading, PSINS, RFU/FRD/NED)."""
import numpy as np
import pytest

from sins_align_ros.nav import frames as fr
from sins_align_ros.nav import kernels
from sins_align_ros.units import DEG


def nose(euler):
    """The body x axis (forward) in ENU."""
    return fr.euler_to_dcm(euler) @ np.array([1.0, 0.0, 0.0])


def test_rep103_yaw_zero_points_east_and_positive_yaw_turns_north():
    assert nose([0, 0, 0]) == pytest.approx([1, 0, 0])
    assert nose([0, 0, 90 * DEG]) == pytest.approx([0, 1, 0], abs=1e-12)


def test_rep103_positive_pitch_is_nose_down_and_positive_roll_right_side_down():
    assert nose([0, 10 * DEG, 0])[2] < 0
    left = fr.euler_to_dcm([10 * DEG, 0, 0]) @ np.array([0.0, 1.0, 0.0])
    assert left[2] > 0   # left side up = right side down


def test_euler_dcm_quaternion_round_trips():
    rng = np.random.default_rng(4)
    e = rng.uniform([-np.pi, -1.5, -np.pi], [np.pi, 1.5, np.pi], size=(100, 3))
    assert fr.dcm_to_euler(fr.euler_to_dcm(e)) == pytest.approx(e, abs=1e-12)
    assert fr.quat_to_euler(fr.euler_to_quat(e)) == pytest.approx(e, abs=1e-12)
    q = fr.dcm_to_quat(fr.euler_to_dcm(e))
    assert np.all(q[:, 3] >= 0)
    assert fr.quat_to_dcm(q) == pytest.approx(fr.euler_to_dcm(e), abs=1e-12)


def test_closed_forms_agree_with_scipy_rotation():
    """The module's closed forms (no scipy at import: 0.16 s of every start) against
    scipy's Rotation, an independent implementation, on one and on stacked inputs."""
    from scipy.spatial.transform import Rotation
    rng = np.random.default_rng(21)
    e = rng.uniform([-np.pi, -1.5, -np.pi], [np.pi, 1.5, np.pi], size=(200, 3))
    ref = Rotation.from_euler('xyz', e)
    assert fr.euler_to_dcm(e) == pytest.approx(ref.as_matrix(), abs=1e-14)
    assert fr.euler_to_dcm(e[0]) == pytest.approx(ref[0].as_matrix(), abs=1e-14)
    assert fr.euler_to_quat(e) == pytest.approx(ref.as_quat(), abs=1e-14)
    q = ref.as_quat() * rng.uniform(0.5, 2.0, (200, 1))     # any norm
    assert fr.quat_to_dcm(q) == pytest.approx(ref.as_matrix(), abs=1e-14)
    assert fr.quat_to_euler(q[3]) == pytest.approx(e[3], abs=1e-12)
    for angle in (1e-12, 1e-7, 1e-3, 1.0, 3.14159):        # series, general, near pi
        v = rng.normal(size=(50, 3))
        v *= angle / np.linalg.norm(v, axis=1, keepdims=True)
        C = Rotation.from_rotvec(v).as_matrix()
        assert fr.rotvec_to_dcm(v) == pytest.approx(C, abs=1e-15)
        assert fr.dcm_to_rotvec(C) == pytest.approx(v, abs=1e-12 * max(angle, 1e-3))
        assert fr.dcm_to_rotvec(C[0]) == pytest.approx(v[0], abs=1e-12 * max(angle, 1e-3))
    att = rng.uniform([-1.5, -np.pi, -np.pi], [1.5, np.pi, np.pi], size=(50, 3))
    psins = Rotation.from_euler('ZXY', att[:, [2, 0, 1]]).as_matrix() @ fr.C_FLU_TO_RFU
    assert fr.psins_att_to_dcm(att) == pytest.approx(psins, abs=1e-14)
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
    assert fr.attitude_error(C_est, C) == pytest.approx(phi, rel=1e-12)


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
        assert np.allclose(sig[k], want, rtol=1e-5, atol=1e-9)
        assert np.allclose(fr.euler_sigma_one(euler[k], P[k].tolist()), sig[k], rtol=1e-12)
        cov = fr.euler_cov_from_phi_cov(euler[k], P[k])
        assert np.allclose(np.sqrt(np.clip(np.diag(cov), 0.0, None)), sig[k], rtol=1e-12)


@pytest.mark.parametrize('departure', [0.0, 1e-15, 1e-12, 1e-9, 1e-6, 1e-2, 0.1, 0.3])
@pytest.mark.parametrize('compiled', [False, True])
def test_orthonormalize_is_the_svd_polar_factor_to_round_off(departure, compiled, monkeypatch):
    """Both functions, compiled (Newton-Schulz) or not, against the SVD's ``U V^T``."""
    if compiled and not kernels.COMPILED:
        pytest.skip('numba not installed or switched off')
    monkeypatch.setattr(kernels, 'COMPILED', compiled)
    rng = np.random.default_rng(7)
    for k in range(50):
        C = fr.rotvec_to_dcm(rng.normal(0.0, 1.0, 3)) + rng.normal(0.0, departure, (3, 3))
        if k == 0:
            C = C @ np.diag([1.0, 1.0, -1.0])           # a reflection's factor too
        U, _, Vt = np.linalg.svd(C)
        for R in (fr.reorthonormalize(C), fr.orthonormalize(C)):
            assert np.abs(R - U @ Vt).max() < 2e-14
            assert np.abs(R.T @ R - np.eye(3)).max() < 2e-15
    for bad in (np.full((3, 3), np.nan), np.diag([np.inf] * 3), np.diag([1.0, 1.0, np.nan])):
        with pytest.raises(np.linalg.LinAlgError):       # as the SVD: never a silent NaN
            fr.orthonormalize(bad)
