"""Loosely coupled GNSS/INS error models: seed 001's 15 states and seed 003's 18 states.

Errors are computed minus true, in this package's conventions: ENU navigation frame,
FLU body, misalignment ``phi`` with ``C~_b_n = (I - [phi x]) C_b_n`` (the seeds use
RFU bodies: the sensor-error states are body-axis vectors, a fixed relabelling).

15 states (seed 001 eq. 2)::

    x = [phi_E phi_N phi_U | dV_E dV_N dV_U | dp_E dp_N dp_U | eps_x eps_y eps_z |
         nab_x nab_y nab_z]

18 states (seed 003 eq. 28): the same with the gyro error split into a random constant
``eps_b`` and a first-order Markov part ``eps_r``::

    x = [phi | dV | dp | eps_b | eps_r | nab]

Position error in metres east, north, up (``dp_E = (R_N + h) cos L dlambda``,
``dp_N = (R_M + h) dL``, ``dp_U = dh``) instead of the seeds' ``(dL, dlambda, dh)`` in
radians: the same model under the diagonal change of variables :func:`D_pos` (then
the position measurement is a plain difference in metres and the covariance is well
conditioned). The transition of the Markov states over an interval is exact;
the rest is the classical phi-angle model (seed 001 eq. 1 with Qin, *Inertial
navigation*, ch. 4; seed 003 eq. 16-22)::

    phi' = -w_in x phi + dw_in - C_b_n eps
    dV'  = f_n x phi - (2 w_ie + w_en) x dV + V x (2 dw_ie + dw_en) + dg + C_b_n nab
    dp'  = dV + (transport terms)
    eps_r' = -eps_r / tau_g + w_g,   nab' = -nab / tau_a + w_a   (seed 001 eq. 2, seed 003
                                                                 eq. 23-25)

Seed 003 also models the receiver's position and velocity errors as Markov
processes (eq. 26-27) but its state (eq. 28) has 18 entries: they enter here as the
measurement noise R (a receiver's errors over a 1 s epoch are close to white).

For the unscented filter of seed 003 :func:`derivative18` keeps the attitude and
velocity equations nonlinear in ``phi`` (the large-misalignment form of
:mod:`.large_misalignment`, seed 004 eq. 3), so a heading error of tens of degrees
after coarse alignment is propagated without linearisation error; its Jacobian at
zero is :func:`F_matrix` (tested).

Measurement (seed 001 sec. 1, seed 003 eq. 30-36): ``z = [p_INS - p_GNSS (m, ENU),
v_INS - v_GNSS (m/s, ENU)] = H x + v`` with ``H`` selecting ``dp`` and ``dV``.
"""
import math

import numpy as np

from . import large_misalignment as lm
from .. import compiled
from ..nav import earth, kernels
from ..nav.frames import skew

I_PHI, I_V, I_P = slice(0, 3), slice(3, 6), slice(6, 9)
#: 15 states: gyro (Markov) and accelerometer (Markov) errors
I_EPS15, I_NAB15 = slice(9, 12), slice(12, 15)
#: 18 states: constant gyro drift, Markov gyro drift, Markov accelerometer error
I_EPSB, I_EPSR, I_NAB18 = slice(9, 12), slice(12, 15), slice(15, 18)
LABELS15 = ('phiE', 'phiN', 'phiU', 'dVE', 'dVN', 'dVU', 'dpE', 'dpN', 'dpU',
            'epsx', 'epsy', 'epsz', 'nabx', 'naby', 'nabz')
LABELS18 = LABELS15[:9] + ('epsbx', 'epsby', 'epsbz', 'epsrx', 'epsry', 'epsrz',
                           'nabx', 'naby', 'nabz')
#: measurement rows in the state: position E, N, U then velocity E, N, U
MEAS_STATES = np.array([6, 7, 8, 3, 4, 5])


def D_pos(lat, h):
    """``(3, 3)`` mapping the seeds' ``(dL, dlambda, dh)`` to our ``(dp_E, dp_N, dp_U)`` in m."""
    R_M, R_N = earth.radii(lat)
    return np.array([[0.0, (R_N + h) * math.cos(lat), 0.0],
                     [R_M + h, 0.0, 0.0],
                     [0.0, 0.0, 1.0]])


def _blocks(f_n, v_n, lat, h):
    """Return the navigation blocks of the phi-angle model in the seeds' position variables.

    Returns ``Maa, Mav, Map, Mva, Mvv, Mvp, Mpv, Mpp`` (each (3, 3)), position columns
    and rows in ``(dL, dlambda, dh)``.
    """
    R_M, R_N = earth.radii(lat)
    Rm, Rn = R_M + h, R_N + h
    vE, vN = v_n[0], v_n[1]
    sL, cL = math.sin(lat), math.cos(lat)
    tL, secL = sL / cL, 1.0 / cL
    W = earth.OMEGA_IE
    w_ie = np.array([0.0, W * cL, W * sL])
    w_en = np.array([-vN / Rm, vE / Rn, vE * tL / Rn])
    # d(w_en)/d(dV), d(w_ie)/d(p), d(w_en)/d(p)
    Mav = np.array([[0.0, -1.0 / Rm, 0.0], [1.0 / Rn, 0.0, 0.0], [tL / Rn, 0.0, 0.0]])
    M1 = np.array([[0.0, 0.0, 0.0], [-W * sL, 0.0, 0.0], [W * cL, 0.0, 0.0]])
    M2 = np.array([[0.0, 0.0, vN / Rm ** 2], [0.0, 0.0, -vE / Rn ** 2],
                   [vE * secL ** 2 / Rn, 0.0, -vE * tL / Rn ** 2]])
    Maa = -skew(w_ie + w_en)
    Map = M1 + M2
    Vx = skew(v_n)
    Mva = skew(f_n)
    Mvv = Vx @ Mav - skew(2.0 * w_ie + w_en)
    Mvp = Vx @ (2.0 * M1 + M2)
    # normal gravity falls with height: the computed vertical acceleration gains 2 g / R dh
    Mvp[2, 2] += 2.0 * earth.gravity(lat, h) / math.sqrt(R_M * R_N)
    Mpv = np.array([[0.0, 1.0 / Rm, 0.0], [secL / Rn, 0.0, 0.0], [0.0, 0.0, 1.0]])
    Mpp = np.array([[0.0, 0.0, -vN / Rm ** 2], [vE * secL * tL / Rn, 0.0, -vE * secL / Rn ** 2],
                    [0.0, 0.0, 0.0]])
    return Maa, Mav, Map, Mva, Mvv, Mvp, Mpv, Mpp


def F_matrix(C_b_n, f_n, v_n, lat, h, tau_g, tau_a, n_states=15):
    """Continuous-time system matrix (n, n) (seed 001 eq. 1-2; seed 003 eq. 29).

    ``C_b_n`` (3, 3) attitude, ``f_n`` (3,) specific force in ENU, ``v_n`` (3,) ENU
    velocity, ``lat`` (rad), ``h`` (m); ``tau_g``, ``tau_a``: correlation times (s) of
    the Markov gyro and accelerometer errors (``inf``: random constants).
    ``n_states`` 15 or 18. The blocks of :func:`_blocks` under the change of position
    variables :func:`D_pos` (``M_p D^-1``, ``D M_pv``, ``D M_pp D^-1``), written out
    entry by entry in :func:`_fill_F` (a filter epoch's cost; test_navigation holds it
    to the block products).
    """
    if n_states not in (15, 18):
        raise ValueError(f'n_states must be 15 or 18, not {n_states}')
    F = np.zeros((n_states, n_states))
    _fill_F(F, compiled.kernel_array(C_b_n), compiled.kernel_array(f_n),
            compiled.kernel_array(v_n), float(lat), float(h), 1.0 / tau_g,
            1.0 / tau_a)
    return F


@compiled.jit(sig='void(f8[:, :], f8[:, :], f8[:], f8[:], f8, f8, f8, f8)')
def _fill_F(F, C, f, v, lat, h, ig, ia):
    """Write :func:`F_matrix`'s non-zero entries into the zeroed ``F`` (15 or 18 square).

    ``ig``, ``ia``: the inverse correlation times. Position rows and columns are in
    metres (``D_pos``): ``D M_pv = I`` and the ``(dL, dlambda)`` columns scale by
    ``1 / (R_M + h)`` and ``1 / ((R_N + h) cos L)``.
    """
    R_M, R_N = kernels._radii(lat)
    Rm, Rn = R_M + h, R_N + h
    vE, vN, vU = v[0], v[1], v[2]
    sL, cL = math.sin(lat), math.cos(lat)
    tL, secL = sL / cL, 1.0 / cL
    W = earth.OMEGA_IE
    a0, a1, a2 = -vN / Rm, W * cL + vE / Rn, W * sL + vE * tL / Rn       # w_ie + w_en
    b1, b2 = a1 + W * cL, a2 + W * sL                                    # 2 w_ie + w_en
    # phi rows: -[w_in x], d(w_en)/d(dV), (d(w_ie) + d(w_en))/dp
    F[0, 1], F[0, 2], F[1, 0], F[1, 2], F[2, 0], F[2, 1] = a2, -a1, -a2, a0, a1, -a0
    F[0, 4], F[1, 3], F[2, 3] = -1.0 / Rm, 1.0 / Rn, tL / Rn
    F[1, 7] = -W * sL / Rm
    F[2, 7] = (W * cL + vE * secL * secL / Rn) / Rm
    F[0, 8], F[1, 8], F[2, 8] = vN / Rm ** 2, -vE / Rn ** 2, -vE * tL / Rn ** 2
    # dV rows: [f x], [V x] d(w_en)/d(dV) - [(2 w_ie + w_en) x], [V x] (2 d(w_ie) + d(w_en))
    F[3, 1], F[3, 2], F[4, 0], F[4, 2], F[5, 0], F[5, 1] = -f[2], f[1], f[2], -f[0], -f[1], f[0]
    F[3, 3], F[3, 4], F[3, 5] = (vN * tL - vU) / Rn, b2, -b1
    F[4, 3], F[4, 4], F[4, 5] = -vE * tL / Rn - b2, -vU / Rm, a0
    F[5, 3], F[5, 4] = vE / Rn + b1, vN / Rm - a0
    c0 = 2.0 * W * cL + vE * secL * secL / Rn
    F[3, 7] = (2.0 * W * sL * vU + vN * c0) / Rm
    F[4, 7] = -vE * c0 / Rm
    F[5, 7] = -2.0 * W * sL * vE / Rm
    F[3, 8] = (vU * vE - vN * vE * tL) / Rn ** 2
    F[4, 8] = vU * vN / Rm ** 2 + vE * vE * tL / Rn ** 2
    # normal gravity falls with height: the computed vertical acceleration gains 2 g / R dh
    F[5, 8] = (-vN * vN / Rm ** 2 - vE * vE / Rn ** 2
               + 2.0 * kernels._gravity(lat, h) / math.sqrt(R_M * R_N))
    # dp rows
    F[6, 3], F[7, 4], F[8, 5] = 1.0, 1.0, 1.0
    F[6, 7], F[6, 8], F[7, 8] = vE * tL / Rm, -vE / Rn, -vN / Rm
    # sensor errors: gyro drift(s) on the attitude, accelerometer error on the velocity
    n = F.shape[0]
    i_nab = n - 3
    for i in range(3):
        for j in range(3):
            F[i, 9 + j] = -C[i, j]
            F[3 + i, i_nab + j] = C[i, j]
            if n == 18:
                F[i, 12 + j] = -C[i, j]
        F[n - 6 + i, n - 6 + i] = -ig
        F[i_nab + i, i_nab + i] = -ia


@compiled.warms_up
def _first_calls():
    for n in (15, 18):
        F_matrix(np.eye(3), np.zeros(3), np.zeros(3), 0.5, 0.0, 1.0, 1.0, n)


def transition(F, T):
    """Discrete transition ``Phi ~ expm(F T)`` to second order, (n, n)."""
    FT = F * T
    return np.eye(len(F)) + FT + 0.5 * FT @ FT


def derivative18(x, f_n, v_n, C_b_n, lat, h, tau_g, tau_a, w_b=None):
    """Noise-free ``x'`` of the 18-state model with the nonlinear attitude, (18,) or (18, N).

    Attitude and velocity rows: seed 004 eq. 3 (:func:`.large_misalignment.derivative`,
    ``phi`` the Euler-sequence misalignment) driven by ``eps_b + eps_r`` and ``nab``,
    plus the position-error terms of the linear model; position, drift and Markov rows
    as :func:`F_matrix`. Arguments as there. ``w_b`` (3,) body rate, rad/s: ``x`` then
    has 21 rows, the last three gyro scale-factor errors (random constants, not in seed
    003; :mod:`sins_align_ros.align.engines.gyro_scale`) that add ``w_b * ds`` to the drift.
    """
    x = np.asarray(x, dtype=float)
    single = x.ndim == 1
    X = x[:, None] if single else x
    eps = X[I_EPSB] + X[I_EPSR]
    if w_b is not None:
        eps = eps + np.asarray(w_b, dtype=float)[:, None] * X[18:21]
    X12 = np.vstack([X[I_PHI], X[I_V], eps, X[I_NAB18]])
    d12 = lm.derivative(X12, f_n, v_n, C_b_n, lat, h)
    _, _, Map, _, _, Mvp, Mpv, Mpp = _blocks(f_n, v_n, lat, h)
    D = D_pos(lat, h)
    Di = np.linalg.inv(D)
    dp = X[I_P]
    out = np.zeros_like(X)
    out[I_PHI] = d12[0:3] + (Map @ Di) @ dp
    out[I_V] = d12[3:6] + (Mvp @ Di) @ dp
    out[I_P] = (D @ Mpv) @ X[I_V] + (D @ Mpp @ Di) @ dp
    out[I_EPSR] = -X[I_EPSR] / tau_g
    out[I_NAB18] = -X[I_NAB18] / tau_a
    return out[:, 0] if single else out


def propagate18(x, f_n, v_n, C_b_n, lat, h, tau_g, tau_a, dt, substeps=1, w_b=None):
    """Discrete transition of :func:`derivative18` over ``dt`` by classical Runge-Kutta."""
    args = (f_n, v_n, C_b_n, lat, h, tau_g, tau_a, w_b)
    step = dt / substeps
    for _ in range(substeps):
        k1 = derivative18(x, *args)
        k2 = derivative18(x + 0.5 * step * k1, *args)
        k3 = derivative18(x + 0.5 * step * k2, *args)
        k4 = derivative18(x + step * k3, *args)
        x = x + step / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    return x


def H_matrix(n_states=15, velocity=True):
    """Measurement matrix (6 or 3, n): position E, N, U (m), then velocity E, N, U (m/s)."""
    rows = MEAS_STATES if velocity else MEAS_STATES[:3]
    H = np.zeros((len(rows), n_states))
    H[np.arange(len(rows)), rows] = 1.0
    return H


def markov_q(sigma, tau):
    """Return the driving-noise density ``2 sigma^2 / tau`` of a first-order Markov process.

    ``sigma``: its steady-state sigma, ``tau``: correlation time (0 for ``tau = inf``).
    """
    return 0.0 if not np.isfinite(tau) else 2.0 * sigma * sigma / tau


def fold_markov(sigma_const, sigma_markov, tau, tau_max=1.0e6):
    """One first-order Markov state for a random constant plus a Markov error.

    Seed 001's 15-state model has one Markov state per sensor error. The true error
    ``b + m`` (constant of sigma ``sigma_const``, Markov of ``sigma_markov`` and
    correlation time ``tau``) has the variance ``sigma_const^2 + sigma_markov^2``; the
    state keeps that variance and the Markov part's driving density
    ``2 sigma_markov^2 / tau`` (how fast the true error moves), so its correlation time
    is ``tau (sigma_const^2 + sigma_markov^2) / sigma_markov^2``, at most ``tau_max``.
    Giving the folded state the Markov part's own ``tau`` instead (a drive
    ``(sigma_const^2 + sigma_markov^2) / sigma_markov^2`` times too strong, and an
    estimate that decays to zero within ``tau`` while the constant stays) made the
    15-state filters lose the heading on a MEMS-grade flight (200 deg/h constant,
    50 deg/h Markov with 300 s: heading RMS 76 deg, VB filters kilometres off).

    Returns ``(sigma, tau_eff)``.
    """
    var = sigma_const * sigma_const + sigma_markov * sigma_markov
    if sigma_markov <= 0.0 or not np.isfinite(tau):
        return math.sqrt(var), tau_max
    return math.sqrt(var), min(tau * var / (sigma_markov * sigma_markov), tau_max)
