"""Seed 002 error models: structure (eq. 6, 16), observability (eq. 9-10), and agreement
of the linear model with the mechanization it describes."""
import numpy as np
import pytest
from scipy.linalg import expm

from sins_align_ros.filters import kf
from sins_align_ros.models import large_azimuth as la
from sins_align_ros.models.stationary import StationaryModel, limits
from sins_align_ros.nav import earth
from sins_align_ros.nav.frames import attitude_error, euler_to_dcm, rotvec_to_dcm
from sins_align_ros.nav.mechanization import StationaryStrapdown
from sins_align_ros.sim.imu import ImuSimulator, ImuSpec, specific_force_n
from sins_align_ros.sim.trajectory import Trajectory
from sins_align_ros.units import ARCMIN, DEG, DPH, DPSH, UG
from tolerance import assert_roundoff

LAT = 34.0 * DEG


def observability_rank(F, H):
    n = F.shape[0]
    obs = np.vstack([H @ np.linalg.matrix_power(F, k) for k in range(n)])
    return np.linalg.matrix_rank(obs, tol=1e-9 * np.abs(obs).max())


def test_reduced7_is_seed002_eq16():
    g = 9.8
    F = StationaryModel('reduced7').F(np.eye(3), LAT, g)
    wN, wU = earth.OMEGA_IE * np.cos(LAT), earth.OMEGA_IE * np.sin(LAT)
    expected = np.zeros((7, 7))
    expected[0, 3] = -g
    expected[1, 2] = g
    expected[2, 3], expected[2, 4] = wU, -wN
    expected[3, 2], expected[3, 5] = -wU, -1.0
    expected[4, 2], expected[4, 6] = wN, -1.0
    assert F == pytest.approx(expected)


def test_observability_ranks():
    """Seed 002 eq. 10: the 12-state model has rank 9; the reduced model is observable."""
    C = euler_to_dcm([0.01, -0.02, 0.7])
    m12 = StationaryModel('stationary12')
    F12 = m12.F(C, LAT, 9.8)
    assert observability_rank(F12, m12.H()) == 9
    m7 = StationaryModel('reduced7')
    assert observability_rank(m7.F(C, LAT, 9.8), m7.H()) == 7


@pytest.mark.parametrize('name', ['stationary12', 'stationary10', 'reduced7'])
def test_linear_model_predicts_the_mechanization_errors(name):
    """Propagate a misalignment and biases with expm(F T) and with the mechanization."""
    m = StationaryModel(name)
    traj = Trajectory(34.0, 75.0, 100.0, heading_deg=30.0)
    a_b = np.array([50.0, -80.0, 30.0]) * UG
    eps_b = np.array([0.02, -0.01, 0.03]) * DPH
    spec = ImuSpec(gyro_bias_dph=eps_b / DPH, accel_bias_ug=a_b / UG)
    sim = ImuSimulator(traj, spec, 100.0)
    e0, _, p0 = sim.initial_truth()
    chunk = sim.next_chunk(6000)                       # 60 s
    C_true = euler_to_dcm(e0)
    phi0 = np.array([2e-4, -3e-4, 2e-3])
    mech = StationaryStrapdown(rotvec_to_dcm(-phi0) @ C_true, *p0,
                               coriolis=m.mech.coriolis, hold_vertical=m.mech.hold_vertical)
    out = mech.run(chunk.dtheta, chunk.dv, 0.01)
    g = earth.gravity(p0[0], p0[2])
    x0 = np.zeros(m.n)
    x0[m.i_phi] = phi0
    a_n, e_n = C_true @ a_b, C_true @ eps_b
    if name == 'stationary12':
        x0[6:9], x0[9:12] = a_b, eps_b
    elif name == 'stationary10':
        x0[5:7], x0[7:10] = a_b[:2], eps_b
    else:
        x0[5:7] = e_n[1:]
    x = expm(m.F(C_true, p0[0], g) * 60.0) @ x0
    if name == 'reduced7':                             # eq. 15: a_E, a_N, eps_E are absent
        x = x.copy()
        x[0] += a_n[0] * 60.0
        x[1] += a_n[1] * 60.0
    err = attitude_error(out['C_b_n'][-1], euler_to_dcm(chunk.euler[-1]))
    v = out['v_n'][-1][m.meas]
    assert v == pytest.approx(x[m.i_v], rel=0.02, abs=2e-4)
    tol = 0.05 * np.abs(x[m.i_phi]) + (3e-5 if name == 'reduced7' else 2e-6)
    assert np.all(np.abs(err - x[m.i_phi]) < tol)


def test_discretize_matches_closed_form_for_a_random_walk():
    F = np.zeros((1, 1))
    Phi, Qd = kf.discretize(F, np.eye(1), np.eye(1) * 4.0, 0.5)
    assert Phi == pytest.approx(np.eye(1)) and Qd == pytest.approx(np.array([[2.0]]))
    F = np.array([[0.0, 1.0], [0.0, 0.0]])            # integrated random walk
    Phi, Qd = kf.discretize(F, np.array([[0.0], [1.0]]), np.eye(1), 2.0)
    assert Qd == pytest.approx(np.array([[8 / 3, 2.0], [2.0, 2.0]]))


def test_kalman_update_is_the_textbook_scalar_case():
    x, P = np.array([1.0]), np.array([[4.0]])
    x2, P2, y, S = kf.update(x, P, np.array([3.0]), np.eye(1), np.array([[1.0]]))
    assert x2 == pytest.approx([1.0 + 0.8 * 2.0]) and P2 == pytest.approx(np.array([[0.8]]))
    assert kf.nis(y, S) == pytest.approx(4.0 / 5.0)


def test_limits():
    tilt, head, noise = limits(LAT, 100 * UG, 0.01 * DPH, 0.001 * DPSH, 540.0)
    assert tilt / ARCMIN == pytest.approx(0.3441, rel=1e-3)   # 100 ug
    assert head / ARCMIN == pytest.approx(2.757, rel=1e-3)    # 0.01 deg/h at 34 deg
    assert noise / ARCMIN == pytest.approx(0.712, rel=1e-2)


@pytest.mark.parametrize('case,heading_err_deg', [('static', 90.0), ('sway', 180.0),
                                                  ('underway', 30.0)])
def test_large_azimuth_model_predicts_the_mechanization_errors(case, heading_err_deg):
    """Seed 000 eq. 1-4: 60 s of propagation against the full mechanization, large heading."""
    from sins_align_ros.nav.mechanization import Strapdown
    from sins_align_ros.sim.presets import SEED000_SWAY
    traj = {'static': Trajectory(45.78, 126.67, 0.0, heading_deg=45.0),
            'sway': Trajectory(45.78, 126.67, 0.0, heading_deg=45.0, sway=SEED000_SWAY),
            'underway': Trajectory(45.78, 126.67, 0.0, heading_deg=45.0, speed=8.0,
                                   sway=SEED000_SWAY)}[case]
    eps_b = np.array([0.3, -0.2, 0.5]) * DPH if case == 'static' else np.zeros(3)
    sim = ImuSimulator(traj, ImuSpec(gyro_bias_dph=eps_b / DPH), 100.0)
    e0, v0, p0 = sim.initial_truth()
    c = sim.next_chunk(6000)
    phi0 = np.array([0.03, 0.03, heading_err_deg]) * DEG
    A0 = la.C_n_nprime(phi0)
    out = Strapdown(A0 @ euler_to_dcm(e0), v0, *p0).run(c.dtheta, c.dv, 0.01)
    x = np.zeros(la.N_STATES)
    x[4:7] = phi0
    x[7:10] = A0 @ euler_to_dcm(e0) @ eps_b          # drift in the computed frame
    for k in range(9, 6000, 10):                       # 10 Hz model steps, truth at mid-step
        km = traj.kinematics(c.t[k] - 0.05)
        lat, h, v = c.pos[k, 0], c.pos[k, 2], km.v_n[0]
        f_n = specific_force_n(km, lat, h)[0]
        x = la.propagate(x, f_n, v, lat, h, 0.1)
    dv = out['v_n'][-1, :2] - c.v_n[-1, :2]
    dp = earth.local_offset_m(*c.pos[-1], *out['pos'][-1])[:2]
    phi = la.misalignment_of(out['C_b_n'][-1], euler_to_dcm(c.euler[-1]))
    assert x[0:2] == pytest.approx(dv, rel=0.01, abs=2e-3)
    assert x[2:4] == pytest.approx(dp, rel=0.01, abs=0.05)
    assert x[4:7] == pytest.approx(phi, abs=2e-5)
    assert np.abs(dv).max() > 0.3                      # the errors are large: a real check


@pytest.mark.parametrize('n', [10, 13])
def test_large_azimuth_compiled_transition_equals_the_numpy_reference(n):
    """The compiled RK4 of the cubature points (issue 22) against the numpy one."""
    rng = np.random.default_rng(23)
    scale = np.array([0.5, 0.5, 10, 10, 0.01, 0.01, 2.5, 1e-6, 1e-6, 1e-6, 1e-3, 1e-3, 1e-3])
    X = rng.normal(size=(n, 2 * n)) * scale[:n, None]
    f_n, v_n = np.array([0.3, -0.2, 9.8]), np.array([5.0, 3.0, 0.1])
    C = np.asfortranarray(euler_to_dcm([0.1, 0.05, 0.7]))           # any memory layout
    for sub in (1, 3):
        ref = la.propagate_reference(X, f_n, v_n, 0.8, 10.0, 1.0, sub, C)
        # sub steps of the model's matrix product (10-term dot products, 20 operations)
        # and the attitude C (~20), on terms up to g = 9.8 x the state (as test_moving's)
        scale = 10.0 * np.abs(X).max()
        assert_roundoff(la.propagate(X, f_n, v_n, 0.8, 10.0, 1.0, sub, C), ref,
                        40 * sub, scale)
        assert_roundoff(la.propagate(X[:, 3], f_n, v_n, 0.8, 10.0, 1.0, sub, C), ref[:, 3],
                        40 * sub, scale)


def test_reset_jacobian_is_the_error_left_by_a_feedback():
    """After the attitude is corrected by C_n^n'(phi_hat)^T the error is J dphi: heading kept.

    A heading error of 3 deg with tilt corrections of 1-2 mrad: the old transform
    (C_n^n'(phi_hat)^T) put 1e-3 x 0.05 rad of heading into the tilts; the error the
    feedback really leaves has tilts of second order (1e-6 rad) only.
    """
    phi_hat = np.array([1e-3, -2e-3, 0.6])
    for dphi in (np.array([0.0, 0.0, 0.05]), np.array([2e-4, -1e-4, 0.0]),
                 np.array([3e-4, 1e-4, -0.02])):
        C_left = la.C_n_nprime(phi_hat).T @ la.C_n_nprime(phi_hat + dphi)
        left = la.misalignment_of(C_left, np.eye(3))
        J = la.reset_jacobian(phi_hat)
        np.testing.assert_allclose(left, J @ dphi, atol=3e-6)
        old = la.C_n_nprime(phi_hat).T @ dphi
        if dphi[2] != 0.0:
            assert np.max(np.abs(old[:2] - left[:2])) > 10 * 3e-6
