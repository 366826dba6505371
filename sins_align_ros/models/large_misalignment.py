"""12-state large-misalignment error model of seed 004 (eq. 3-5), in this package's conventions.

State ``x = [phi_E, phi_N, phi_U, dV_E, dV_N, dV_U, eps_x, eps_y, eps_z, nab_x, nab_y,
nab_z]`` (seed 004 eq. 4): misalignment (rad), velocity error (m/s, ENU), gyro
drift (rad/s) and accelerometer bias (m/s^2), the sensor errors in the body frame
(FLU here; seed 004 uses right-front-up, a fixed relabelling).

Misalignment (seed 004 sec. 1: the computed frame n' is the navigation frame n
turned three times): the computed attitude is ``C~_b_n = C_n^n' C_b_n`` with

    C_n^n' = C_y(phi_N) C_x(phi_E) C_z(phi_U)

(frame rotations about up, then east, then north; ``C_a(t) ~ I - t [e_a x]`` for a
small angle, so ``C_n^n' ~ I - [phi x]`` as everywhere in this package). The
derivation of eq. 3 in this convention (``A = C_n^n'``, computed quantities with a
tilde, errors measured minus true) gives

    phi'  = C_w^-1 [ (I - A) w~_in + A dw_in - C~_b_n (eps + w_g) ]
    dV'   = (I - A^T) f~_n + A^T C~_b_n (nab + w_a) - (2 w_ie + w_en) x dV - dw_en x V~
    eps'  = w_eps,  nab' = 0

with ``f~_n = C~_b_n f~_b`` the specific force the mechanization resolves, ``w~_in``
and ``V~`` its navigation rate and velocity (``w_in = w~_in - dw_in`` the true rate),
``dw_in = dw_en = [-dV_N / (R_M + h), dV_E / (R_N + h), dV_E tan(L) / (R_N + h)]``
(position errors are not states: the mechanization's position is reset to GNSS at
every epoch) and the Euler-rate matrix of the sequence above

    C_w = [[cos phi_N, 0, -sin phi_N cos phi_E],
           [0,         1,  sin phi_E],
           [sin phi_N, 0,  cos phi_N cos phi_E]]

(``w_nn'^n' = C_w phi'``). Seed 004 eq. 5 splits the right-hand side into ``f(X)``
and ``g(X) W``; the filters here need ``f`` only (the noise enters as Q).

Measurement (seed 004 eq. 4-5): ``Z = H X + V`` with ``Z`` the INS minus GNSS
velocity, ``H = [0 I 0 0]``; the auxiliary output of the H-infinity criterion is
the misalignment, ``Y = L X`` with ``L = [I 0 0 0]``.
"""
import numpy as np

from ..nav import earth

N_STATES = 12
I_PHI, I_V, I_EPS, I_NAB = slice(0, 3), slice(3, 6), slice(6, 9), slice(9, 12)
LABELS = ('phiE', 'phiN', 'phiU', 'dVE', 'dVN', 'dVU',
          'epsx', 'epsy', 'epsz', 'nabx', 'naby', 'nabz')


def C_n_nprime(phi):
    """``C_n^n'`` of misalignment ``phi`` (3,) (module docstring), (3, 3)."""
    return _C_batch(np.asarray(phi, dtype=float)[:, None])[0]


def _C_batch(phi):
    """``C_n^n'`` of each column of ``phi`` (3, N): (N, 3, 3)."""
    sE, cE = np.sin(phi[0]), np.cos(phi[0])
    sN, cN = np.sin(phi[1]), np.cos(phi[1])
    sU, cU = np.sin(phi[2]), np.cos(phi[2])
    A = np.empty((phi.shape[1], 3, 3))
    # C_y(N) C_x(E) C_z(U), multiplied out
    A[:, 0, 0] = cN * cU - sN * sE * sU
    A[:, 0, 1] = cN * sU + sN * sE * cU
    A[:, 0, 2] = -sN * cE
    A[:, 1, 0] = -cE * sU
    A[:, 1, 1] = cE * cU
    A[:, 1, 2] = sE
    A[:, 2, 0] = sN * cU + cN * sE * sU
    A[:, 2, 1] = sN * sU - cN * sE * cU
    A[:, 2, 2] = cN * cE
    return A


def euler_rate_inverse(phi, w):
    """``C_w^-1 w`` for columns ``phi`` (3, N) and ``w`` (3, N) (closed form), (3, N)."""
    sE, cE = np.sin(phi[0]), np.cos(phi[0])
    sN, cN = np.sin(phi[1]), np.cos(phi[1])
    rate_u = (-sN * w[0] + cN * w[2]) / cE
    return np.array([cN * w[0] + sN * w[2], w[1] - sE * rate_u, rate_u])


def derivative(x, f_n, v_n, C_b_n, lat, h):
    """Continuous-time ``x'`` (noise-free) of one state (12,) or columns (12, N).

    ``f_n`` (3,): specific force in the computed frame; ``v_n`` (3,): ENU velocity;
    ``C_b_n`` (3, 3): computed attitude (its mean over the interval: the bias terms
    are linear in it); ``lat`` (rad), ``h`` (m): position.
    """
    x = np.asarray(x, dtype=float)
    single = x.ndim == 1
    X = x[:, None] if single else x
    phi, dv = X[I_PHI], X[I_V]
    A = _C_batch(phi)
    R_M, R_N = earth.radii(lat)
    Rm, Rn = R_M + h, R_N + h
    w_ie = earth.w_ie_n(lat)
    w_in = w_ie + earth.w_en_n(lat, h, v_n)
    dw_en = np.array([-dv[1] / Rm, dv[0] / Rn, dv[0] * np.tan(lat) / Rn])
    eps_n = C_b_n @ X[I_EPS]
    nab_n = C_b_n @ X[I_NAB]
    # w_in and v_n are the mechanization's (computed velocity): the true rate is
    # w_in - dw_en, so (I - A) w~_in + A dw_en, and a x v errors as a x dV + dw_en x v~
    rhs = (w_in[:, None] - np.einsum('kij,j->ik', A, w_in) + np.einsum('kij,jk->ik', A, dw_en)
           - eps_n)
    out = np.zeros_like(X)
    out[I_PHI] = euler_rate_inverse(phi, rhs)
    a = (2.0 * w_ie + (w_in - w_ie))[:, None] - dw_en
    out[I_V] = (f_n[:, None] - np.einsum('kji,j->ik', A, f_n)
                + np.einsum('kji,jk->ik', A, nab_n)
                - np.cross(a, dv, axis=0) - np.cross(dw_en, v_n[:, None], axis=0))
    return out[:, 0] if single else out


def propagate(x, f_n, v_n, C_b_n, lat, h, dt, substeps=1):
    """Discrete transition ``f(x)`` over ``dt`` by classical Runge-Kutta.

    Shapes as :func:`derivative`.
    """
    step = dt / substeps
    for _ in range(substeps):
        k1 = derivative(x, f_n, v_n, C_b_n, lat, h)
        k2 = derivative(x + 0.5 * step * k1, f_n, v_n, C_b_n, lat, h)
        k3 = derivative(x + 0.5 * step * k2, f_n, v_n, C_b_n, lat, h)
        k4 = derivative(x + step * k3, f_n, v_n, C_b_n, lat, h)
        x = x + step / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    return x


def H_velocity():
    """Measurement matrix of the INS minus GNSS velocity (seed 004 eq. 5), (3, 12)."""
    H = np.zeros((3, N_STATES))
    H[:, I_V] = np.eye(3)
    return H


def L_attitude():
    """Auxiliary output matrix of the H-infinity criterion: the misalignment, (3, 12)."""
    L = np.zeros((3, N_STATES))
    L[:, I_PHI] = np.eye(3)
    return L


def misalignment_of(C_est, C_true):
    """``phi`` (3,) with ``C_n^n'(phi) = C_est C_true^T`` (exact inverse of :func:`C_n_nprime`)."""
    A = np.asarray(C_est) @ np.asarray(C_true).T
    phi_e = np.arcsin(np.clip(A[1, 2], -1.0, 1.0))
    phi_n = np.arctan2(-A[0, 2], A[2, 2])
    phi_u = np.arctan2(-A[1, 0], A[1, 1])
    return np.array([phi_e, phi_n, phi_u])
