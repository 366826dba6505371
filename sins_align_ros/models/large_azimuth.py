"""10-state large-azimuth error model of seed 000 (eq. 1-6), in this package's conventions.

State ``x = [dV_E, dV_N, dp_E, dp_N, phi_E, phi_N, phi_U, eps_E, eps_N, eps_U]``:
horizontal velocity error (m/s), horizontal position error (m, east and north;
seed 000 uses latitude/longitude errors, metres keep the filter well scaled),
misalignment (rad) and gyro drift (rad/s) resolved in the *computed* navigation
frame n' — the frame the mechanization works in. With that choice the drift term
is exactly ``-eps`` even for a 180 deg heading error; drift resolved in the true
frame would enter as ``-C_n^n' eps^n`` (checked numerically in test_models.py).

Misalignment convention (the package's, seed 002 eq. 3): the computed attitude is
``C~_b_n = C_n^n' C_b_n`` with ``C_n^n' = I - [phi x]`` for small angles. For a
large heading error and small tilts (seed 000 eq. 1-2, to first order in the tilts)

    C_n^n' = [[ cU,  sU, -phi_N],
              [-sU,  cU,  phi_E],
              [phi_N cU + phi_E sU, phi_N sU - phi_E cU, 1]]

with ``cU = cos(phi_U)``, ``sU = sin(phi_U)``. Seed 000 prints the heading terms
with the opposite sign to its own tilt terms; here both follow ``I - [phi x]``,
and a test checks the model against the mechanization it describes.

Dynamics (seed 000 eq. 3-4 in this convention, vertical channel ignored):

    dV'   = (C_n^n' - I) f_n - (2 w_ie + w_en) x dV - (2 dw_ie + dw_en) x V + accel noise
    dp'   = dV (east, north)
    phi'  = (I - C_n^n') w_in + dw_in - eps^n' + gyro noise
    eps'  = 0

Measurement: GNSS position difference ``z = [dp_E, dp_N]`` (linear, eq. 6), and
optionally GNSS velocity ``[dV_E, dV_N]``.
"""
import numpy as np

from ..nav import earth

N_STATES = 10
LABELS = ('dVE', 'dVN', 'dpE', 'dpN', 'phiE', 'phiN', 'phiU', 'epsE', 'epsN', 'epsU')


def C_n_nprime(phi):
    """``C_n^n'`` of seed 000 eq. 2 in the package convention (see module docstring)."""
    pe, pn, pu = phi
    c, s = np.cos(pu), np.sin(pu)
    return np.array([[c, s, -pn],
                     [-s, c, pe],
                     [pn * c + pe * s, pn * s - pe * c, 1.0]])


def derivative(x, f_n, v_n, lat, h):
    """Continuous-time ``x'`` (10,) at specific force ``f_n`` and velocity ``v_n`` (ENU).

    ``lat`` (rad), ``h`` (m) are the navigation position; noise terms are not included.
    """
    dv = np.array([x[0], x[1], 0.0])
    dlat = x[3] / (earth.radii(lat)[0] + h)
    phi = x[4:7]
    eps = x[7:10]
    R_M, R_N = earth.radii(lat)
    w_ie = earth.w_ie_n(lat)
    w_en = earth.w_en_n(lat, h, v_n)
    w_in = w_ie + w_en
    dw_ie = earth.OMEGA_IE * np.array([0.0, -np.sin(lat) * dlat, np.cos(lat) * dlat])
    dw_en = np.array([-dv[1] / (R_M + h), dv[0] / (R_N + h),
                      dv[0] * np.tan(lat) / (R_N + h)
                      + v_n[0] * dlat / ((R_N + h) * np.cos(lat) ** 2)])
    C = C_n_nprime(phi)
    dv_dot = ((C - np.eye(3)) @ f_n - np.cross(2.0 * w_ie + w_en, dv)
              - np.cross(2.0 * dw_ie + dw_en, v_n))
    phi_dot = (np.eye(3) - C) @ w_in + dw_ie + dw_en - eps
    out = np.zeros(N_STATES)
    out[0:2] = dv_dot[:2]
    out[2:4] = x[0:2]
    out[4:7] = phi_dot
    return out


def propagate(x, f_n, v_n, lat, h, dt, substeps=1):
    """Discrete transition ``f(x)`` over ``dt`` by classical Runge-Kutta (seed 000 eq. 6)."""
    step = dt / substeps
    for _ in range(substeps):
        k1 = derivative(x, f_n, v_n, lat, h)
        k2 = derivative(x + 0.5 * step * k1, f_n, v_n, lat, h)
        k3 = derivative(x + 0.5 * step * k2, f_n, v_n, lat, h)
        k4 = derivative(x + step * k3, f_n, v_n, lat, h)
        x = x + step / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    return x


def H_position():
    """Measurement matrix of the GNSS position difference (2, 10)."""
    H = np.zeros((2, N_STATES))
    H[0, 2] = H[1, 3] = 1.0
    return H


def misalignment_of(C_est, C_true):
    """``phi`` (3,) of a computed attitude in this model's parametrisation.

    Inverts ``C_n^n' = C_est C_true^T`` to first order in the tilts, exactly in heading.
    """
    A = np.asarray(C_est) @ np.asarray(C_true).T
    # A[0,2] = -phi_N, A[1,2] = phi_E; the bottom row gives the same to first order
    return np.array([A[1, 2], -A[0, 2], np.arctan2(A[0, 1], A[0, 0])])
