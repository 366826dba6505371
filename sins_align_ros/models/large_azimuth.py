"""Large-azimuth error model of seed 000 (eq. 1-6), 10 states, and our 13-state extension.

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

13 states (not in seed 000): ``x[10:13] = nab``, the accelerometer bias in body axes
(FLU, m/s^2, measured minus true specific force), a random constant. It enters the
velocity error through the computed attitude: the computed specific force is
``C~_b_n (f_b + nab) = C_n^n' f_n + C~_b_n nab``, so

    dV'  += C~_b_n nab          (east, north rows)
    nab' = 0

Seed 000's 10-state model has no accelerometer bias: on a still or straight-running
base a bias is indistinguishable from a tilt of bias / g, but once the vehicle turns
the bias turns with it in the navigation frame while a tilt does not, and the 10-state
filter takes the difference for heading (bench/results/moving_base_integrity.md).
"""
import math

import numpy as np

from .. import compiled
from ..nav import earth, kernels

N_STATES = 10
#: states with the accelerometer bias (module docstring)
N_STATES_ACCEL = 13
LABELS = ('dVE', 'dVN', 'dpE', 'dpN', 'phiE', 'phiN', 'phiU', 'epsE', 'epsN', 'epsU',
          'nabX', 'nabY', 'nabZ')


def _cos_sin(a):
    """``(cos a, sin a)`` of a float; NaN for a non-finite ``a`` as numpy gives (math raises)."""
    if not math.isfinite(a):
        return math.nan, math.nan
    return math.cos(a), math.sin(a)


def C_n_nprime(phi):
    """``C_n^n'`` of seed 000 eq. 2 in the package convention (see module docstring)."""
    pe, pn, pu = map(float, phi)
    c, s = _cos_sin(pu)
    return np.array([[c, s, -pn],
                     [-s, c, pe],
                     [pn * c + pe * s, pn * s - pe * c, 1.0]])


def derivative(x, f_n, v_n, lat, h, C_b_n=None):
    """Continuous-time ``x'`` at specific force ``f_n`` and velocity ``v_n`` (ENU, (3,)).

    ``x`` is one state (10,) or (13,), or a batch of states as columns (10 or 13, N),
    e.g. all cubature points at once; the result has the same shape. ``lat`` (rad),
    ``h`` (m) are the navigation position; ``C_b_n`` (3, 3) the computed attitude
    (13 states only: it turns the body-axis accelerometer bias into ENU); noise terms
    are not included.
    """
    x = np.asarray(x, dtype=float)
    dvE, dvN, dpN = x[0], x[1], x[3]
    pe, pn, pu = x[4], x[5], x[6]
    R_M, R_N = earth.radii(lat)
    Rm, Rn = R_M + h, R_N + h
    sl, cl = np.sin(lat), np.cos(lat)
    dlat = dpN / Rm
    w_ie = earth.w_ie_n(lat)
    w_in = w_ie + earth.w_en_n(lat, h, v_n)
    a = 2.0 * w_ie + (w_in - w_ie)                 # 2 w_ie + w_en
    # b = 2 dw_ie + dw_en (per state)
    b0 = -dvN / Rm
    b1 = -2.0 * earth.OMEGA_IE * sl * dlat + dvE / Rn
    b2 = (2.0 * earth.OMEGA_IE * cl * dlat + dvE * np.tan(lat) / Rn
          + v_n[0] * dlat / (Rn * cl ** 2))
    c, s = np.cos(pu), np.sin(pu)
    cm1 = c - 1.0
    fE, fN, fU = f_n

    out = np.zeros_like(x)
    # (C_n^n' - I) f_n - a x dV - b x V (east, north rows)
    out[0] = cm1 * fE + s * fN - pn * fU + a[2] * dvN - (b1 * v_n[2] - b2 * v_n[1])
    out[1] = -s * fE + cm1 * fN + pe * fU - a[2] * dvE - (b2 * v_n[0] - b0 * v_n[2])
    out[2] = dvE
    out[3] = dvN
    # (I - C_n^n') w_in + dw_in - eps, with dw_in = dw_ie + dw_en
    wE, wN, wU = w_in
    dwie = earth.OMEGA_IE * dlat
    out[4] = -(cm1 * wE + s * wN - pn * wU) + b0 - x[7]
    out[5] = -(-s * wE + cm1 * wN + pe * wU) - dwie * sl + dvE / Rn - x[8]
    out[6] = (-((pn * c + pe * s) * wE + (pn * s - pe * c) * wN) + dwie * cl
              + dvE * np.tan(lat) / Rn + v_n[0] * dlat / (Rn * cl ** 2) - x[9])
    if len(x) == N_STATES_ACCEL:                   # + C~_b_n nab; the bias is constant
        C = np.asarray(C_b_n, dtype=float)
        out[0] += C[0, 0] * x[10] + C[0, 1] * x[11] + C[0, 2] * x[12]
        out[1] += C[1, 0] * x[10] + C[1, 1] * x[11] + C[1, 2] * x[12]
    return out


def propagate(x, f_n, v_n, lat, h, dt, substeps=1, C_b_n=None):
    """Discrete transition ``f(x)`` over ``dt`` by classical Runge-Kutta (seed 000 eq. 6).

    ``x`` (10,) or (13,), or a batch (10 or 13, N) of column states; ``C_b_n`` the
    computed attitude over ``dt`` (13 states, :func:`derivative`). Compiled
    (:func:`_rk4_columns`) when the kernels are; :func:`propagate_reference` otherwise,
    and a test keeps the two equal to round-off.
    """
    if not compiled.COMPILED:
        return propagate_reference(x, f_n, v_n, lat, h, dt, substeps, C_b_n)
    x = np.asarray(x, dtype=float)
    X = np.ascontiguousarray(x.reshape(len(x), -1))
    C = _NO_ATTITUDE if C_b_n is None else np.ascontiguousarray(C_b_n, dtype=float)
    out = np.empty_like(X)
    _rk4_columns(X, float(lat), float(h), np.asarray(f_n, dtype=float),
                 np.asarray(v_n, dtype=float), C, float(dt), int(substeps), out)
    return out.reshape(x.shape)


#: the attitude argument of the compiled transition for 10 states (not read)
_NO_ATTITUDE = np.zeros((3, 3))


@compiled.jit
def _terms(lat, h, f_n, v_n):
    """Return the position-dependent constants of :func:`_derivative_column` (17,).

    ``R_M + h, R_N + h, sin L, cos L, tan L, a (3), w_in (3), f_n (3), v_n (3)`` with
    ``a = 2 w_ie + w_en`` (:func:`~sins_align_ros.nav.earth.radii`,
    :func:`~sins_align_ros.nav.earth.w_ie_n`, :func:`~sins_align_ros.nav.earth.w_en_n`).
    """
    sl, cl = np.sin(lat), np.cos(lat)
    R_M, R_N = kernels._radii(lat)
    tl = np.tan(lat)
    w_en = (-v_n[1] / (R_M + h), v_n[0] / (R_N + h), v_n[0] * tl / (R_N + h))
    w_ie = (0.0, earth.OMEGA_IE * cl, earth.OMEGA_IE * sl)
    terms = np.empty(17)
    terms[0], terms[1], terms[2], terms[3], terms[4] = R_M + h, R_N + h, sl, cl, tl
    for i in range(3):
        w_in = w_ie[i] + w_en[i]
        terms[5 + i] = 2.0 * w_ie[i] + (w_in - w_ie[i])
        terms[8 + i] = w_in
        terms[11 + i] = f_n[i]
        terms[14 + i] = v_n[i]
    return terms


@compiled.jit
def _derivative_column(x, k, terms, C):
    """:func:`derivative` of one state ``x`` (n,) into ``k`` (n,), scalar arithmetic.

    ``terms``: ``R_M + h, R_N + h, sin L, cos L, tan L, a (3), w_in (3), f_n (3), v_n (3)``
    with ``a = 2 w_ie + w_en`` (:func:`propagate` builds them).
    """
    Rm, Rn, sl, cl, tl = terms[0], terms[1], terms[2], terms[3], terms[4]
    a2 = terms[7]
    wE, wN, wU = terms[8], terms[9], terms[10]
    fE, fN, fU = terms[11], terms[12], terms[13]
    vE, vN, vU = terms[14], terms[15], terms[16]
    dvE, dvN, dpN = x[0], x[1], x[3]
    pe, pn, pu = x[4], x[5], x[6]
    dlat = dpN / Rm
    b0 = -dvN / Rm
    b1 = -2.0 * earth.OMEGA_IE * sl * dlat + dvE / Rn
    b2 = 2.0 * earth.OMEGA_IE * cl * dlat + dvE * tl / Rn + vE * dlat / (Rn * cl ** 2)
    c, s = np.cos(pu), np.sin(pu)
    cm1 = c - 1.0
    k[0] = cm1 * fE + s * fN - pn * fU + a2 * dvN - (b1 * vU - b2 * vN)
    k[1] = -s * fE + cm1 * fN + pe * fU - a2 * dvE - (b2 * vE - b0 * vU)
    k[2] = dvE
    k[3] = dvN
    dwie = earth.OMEGA_IE * dlat
    k[4] = -(cm1 * wE + s * wN - pn * wU) + b0 - x[7]
    k[5] = -(-s * wE + cm1 * wN + pe * wU) - dwie * sl + dvE / Rn - x[8]
    k[6] = (-((pn * c + pe * s) * wE + (pn * s - pe * c) * wN) + dwie * cl
            + dvE * tl / Rn + vE * dlat / (Rn * cl ** 2) - x[9])
    for i in range(7, len(x)):
        k[i] = 0.0
    if len(x) == N_STATES_ACCEL:
        k[0] += C[0, 0] * x[10] + C[0, 1] * x[11] + C[0, 2] * x[12]
        k[1] += C[1, 0] * x[10] + C[1, 1] * x[11] + C[1, 2] * x[12]


@compiled.jit(sig='void(f8[:, :], f8, f8, f8[:], f8[:], f8[:, :], f8, i8, f8[:, :])')
def _rk4_columns(X, lat, h, f_n, v_n, C, dt, substeps, out):
    """:func:`propagate_reference` of every column of ``X`` (n, N) into ``out`` (n, N)."""
    n, m = X.shape
    terms = _terms(lat, h, f_n, v_n)
    step = dt / substeps
    x, y = np.empty(n), np.empty(n)
    k1, k2, k3, k4 = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    for j in range(m):
        for i in range(n):
            x[i] = X[i, j]
        for _ in range(substeps):
            _derivative_column(x, k1, terms, C)
            for i in range(n):
                y[i] = x[i] + 0.5 * step * k1[i]
            _derivative_column(y, k2, terms, C)
            for i in range(n):
                y[i] = x[i] + 0.5 * step * k2[i]
            _derivative_column(y, k3, terms, C)
            for i in range(n):
                y[i] = x[i] + step * k3[i]
            _derivative_column(y, k4, terms, C)
            for i in range(n):
                x[i] = x[i] + step / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
        for i in range(n):
            out[i, j] = x[i]


@compiled.warms_up
def _first_calls():
    for n in (N_STATES, N_STATES_ACCEL):
        propagate(np.zeros((n, 2)), np.zeros(3), np.zeros(3), 0.5, 0.0, 1.0)


def propagate_reference(x, f_n, v_n, lat, h, dt, substeps=1, C_b_n=None):
    """:func:`propagate` in numpy on the whole batch, :func:`derivative` as written."""
    step = dt / substeps
    args = (f_n, v_n, lat, h, C_b_n)
    for _ in range(substeps):
        k1 = derivative(x, *args)
        k2 = derivative(x + 0.5 * step * k1, *args)
        k3 = derivative(x + 0.5 * step * k2, *args)
        k4 = derivative(x + step * k3, *args)
        x = x + step / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    return x


def reset_jacobian(phi_hat):
    """Return ``J`` (3, 3): the misalignment error after a feedback of ``phi_hat``, ``J dphi``.

    ``C_n^n'(phi) = (I - [t x]) C_z(phi_U)`` (tilts ``t`` applied after the heading,
    module docstring; seed 004's ``C_y(phi_N) C_x(phi_E) C_z(phi_U)`` is the same to
    first order in the tilts). Correcting the attitude by
    ``C_n^n'(phi_hat)^T`` leaves, for ``phi = phi_hat + dphi`` and to first order in
    ``dphi`` and the tilts, ``C_z(phi_hat_U)^T (I - [dt x]) C_z(phi_hat_U + dphi_U)
    = (I - [(C_z^T dt) x]) C_z(dphi_U)``: the heading error is unchanged and the tilt
    errors turn with the heading correction, ``J = C_z(phi_hat_U)^T``.

    Not ``C_n^n'(phi_hat)^T``, which we used before session 23 and which also mixes
    the heading error into the tilts (and back) by the tilt correction, a product of a
    correction and an error that the model does not carry. With a MEMS gyro the
    mechanization's tilts drift 3-5 arcmin between epochs (the drift stays in the
    filter), so the tilt correction had one sign at every epoch and the mixing built a
    tilt-heading correlation the data do not have; the well-measured tilt then
    "measured" the heading through it (seed 000's ship, MEMS, run 1004 of the
    integrity matrix: the CKF's heading sigma 7 deg at 400 s where a linear covariance
    recursion of the same F, Q, H and R without the mixing gave 19 deg; the heading
    ended 28 deg off).
    """
    c, s = _cos_sin(float(phi_hat[2]))
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def H_position(n_states=N_STATES):
    """Measurement matrix of the GNSS position difference (2, ``n_states``)."""
    H = np.zeros((2, n_states))
    H[0, 2] = H[1, 3] = 1.0
    return H


def misalignment_of(C_est, C_true):
    """``phi`` (3,) of a computed attitude in this model's parametrisation.

    Inverts ``C_n^n' = C_est C_true^T`` to first order in the tilts, exactly in heading.
    """
    A = np.asarray(C_est) @ np.asarray(C_true).T
    # A[0,2] = -phi_N, A[1,2] = phi_E; the bottom row gives the same to first order
    return np.array([A[1, 2], -A[0, 2], np.arctan2(A[0, 1], A[0, 0])])
