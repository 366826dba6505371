"""What the GNSS velocities and the gyros say about the GNSS lever arm.

An antenna ``l`` (body axes, m) from the IMU moves about it at ``C (w x l)``; on a ship
rolling 5 deg every 8 s a mast-top antenna 18 m up sways at about 1 m/s, twenty times a
receiver's velocity noise. Told no arm, every filter reads that sway as velocity noise
(the self-check widens it) and, worse, as information: the sway is in phase with the
roll rate, and the filter settles a tilt 17 sigma off (``test_installation``). So the
coarse window's GNSS velocities are fitted to the IMU's view of the motion *and* a
lever arm, and an arm the data show beyond doubt replaces the configured one (said so).

The fit (a standard GNSS/INS calibration idea, here on the coarse window with no
attitude yet): in the initial body frame b0 the IMU's velocity is its specific-force
integral ``u(t)`` (:func:`~sins_align_ros.nav.coarse.velocity_integral_b0`) up to a
rotation, gravity's integral and slow bias terms; the antenna adds
``C_b^b0 (w x l) = sum_k l_k C_b^b0 (w x e_k)``, linear in ``l``. Levelled by gravity's
integral, the ENU velocity is ``V = R(psi) u + R(psi) B l + smooth``. The second
differences remove the smooth part (as in :func:`~.gnss_noise_check.motion_free_velocity_sigma`);
for each heading ``psi`` on a 1-deg grid ``l`` is the least-squares solution, and the
heading with the smallest clipped sum of squares wins (clipped, so a GNSS outlier does not
choose it). The rows beyond 4 sigma and their neighbours are then dropped and ``l``
refitted; its covariance is the sandwich form for the second differences' correlated
noise (variance ``6 s^2``, lag-one correlation -2/3).

The sign: where the IMU itself hardly translates, the horizontal rows fit ``l`` at
``psi`` exactly as well as ``-l`` at ``psi + 180 deg``. The vertical rows (weight
:data:`UP_WEIGHT`) settle it when the arm has a horizontal part (the pitch and roll move
such an antenna up and down, whatever the heading); an arm straight up the mast leaves it
open (:attr:`ArmFit.ambiguous`), and the self-check then takes the antenna above the IMU.
"""
import math
from dataclasses import dataclass

import numpy as np

from ...nav.coarse import arm_velocity_b0, velocity_integral_b0

#: fewest GNSS velocities in the coarse window for a fit
MIN_FIXES = 20
#: heading grid of the fit (deg)
GRID_DEG = 1.0
#: rows beyond this many sigma (and their neighbours) are left out of the refit
OUTLIER_SIGMAS = 4.0
#: relative margin above the best vectorised grid score within which headings are fitted
#: again one by one (:func:`_grid_scores` agrees with the one-by-one fit to round-off)
_PRESELECT_TOL = 1e-6
#: weight of the vertical rows: a receiver's vertical velocity noise taken as twice the
#: horizontal
UP_WEIGHT = 0.5
#: the heading half a turn away fits within this factor of the best (its arm the
#: opposite): the arm's sign is not known
AMBIGUITY_RATIO = 2.0


@dataclass
class ArmFit:
    """Outcome of :func:`fit_lever_arm`.

    ``delta`` (3,) m: the arm the data show beyond the configured one (body axes);
    ``cov`` (3, 3) m^2 its covariance; ``chi2`` ``delta^T cov^-1 delta``; ``noise``
    the receiver's horizontal velocity noise 1-sigma left after the fit (m/s);
    ``rate_rms`` the RMS body rate over the window (rad/s); ``ambiguous``: ``-delta``
    fits nearly as well (with the heading half a turn away).
    """

    delta: np.ndarray
    cov: np.ndarray
    chi2: float
    noise: float
    rate_rms: float
    ambiguous: bool = False


def levelling(up_b0):
    """Rotation (3, 3) that takes the direction ``up_b0`` (3,) to the z axis."""
    z = up_b0 / np.linalg.norm(up_b0)
    x = np.cross([0.0, 1.0, 0.0], z) if abs(z[1]) < 0.9 else np.cross([1.0, 0.0, 0.0], z)
    x /= np.linalg.norm(x)
    return np.array([x, np.cross(z, x), z])


def _rotation(psi):
    c, s = math.cos(psi), math.sin(psi)
    return np.array([[c, s], [-s, c]])


def _design(e, B):
    """Second differences of the residual ``e`` (N, 3) and the basis ``B`` (N, 3, 3).

    Returns ``d`` (3 (N-2),) and ``D`` (3 (N-2), 3): the east rows, the north rows and
    the up rows times :data:`UP_WEIGHT`.
    """
    w = (1.0, 1.0, UP_WEIGHT)
    d = np.diff(e, n=2, axis=0) * w
    D = np.diff(B, n=2, axis=0) * np.array(w)[:, None]
    return d.T.reshape(-1), np.vstack([D[:, a, :] for a in range(3)])


def _clipped_fit(d, D):
    """Least squares ``d ~ D l``: returns ``(l, score)``.

    The score is a sum of squares with each residual clipped at
    :data:`OUTLIER_SIGMAS` robust sigmas (an outlier counts, but as one row).
    """
    sol = np.linalg.lstsq(D, d, rcond=None)[0]
    r = d - D @ sol
    c = OUTLIER_SIGMAS * np.median(np.abs(r)) / 0.6745
    return sol, float(np.sum(np.minimum(r * r, c * c)))


def _grid_scores(V, U_l, B0, grid, rows=100_000):
    """Clipped sums of squares (G,) of the fit at each heading of ``grid`` (G,), vectorised.

    The same fit as ``_clipped_fit(*_design(*rotated(psi)))`` of :func:`fit_lever_arm`
    (``V``, ``U_l`` (N, 3), ``B0`` (N, 3, 3)), equal to round-off: the second differences
    are taken before the rotation (both linear), and ``l`` solves the least squares by a
    QR factorisation per heading. At most ``rows`` residuals are held at a time.
    """
    w = np.array([1.0, 1.0, UP_WEIGHT])
    dV = np.diff(V, n=2, axis=0).T                         # (3, M): axis a, epoch
    dU = np.diff(U_l, n=2, axis=0).T
    dB = np.diff(B0, n=2, axis=0).transpose(1, 0, 2)       # (3, M, 3): axis a, epoch, k
    out = np.empty(len(grid))
    step = max(1, rows // (3 * dV.shape[1]))
    for g0 in range(0, len(grid), step):
        c = np.cos(grid[g0:g0 + step])[:, None]                     # (G, 1)
        s = np.sin(grid[g0:g0 + step])[:, None]
        # e = V - U_l R3 and D = R3^T B0 per heading (R3: _rotation in the E-N block)
        d = np.stack(np.broadcast_arrays(dV[0] - (dU[0] * c - dU[1] * s),
                                         dV[1] - (dU[0] * s + dU[1] * c),
                                         dV[2] - dU[2] + 0.0 * c), axis=1)  # (G, 3, M)
        c, s = c[..., None], s[..., None]
        D = np.stack(np.broadcast_arrays(dB[0] * c - dB[1] * s, dB[0] * s + dB[1] * c,
                                         dB[2] + 0.0 * c), axis=1)         # (G, 3, M, 3)
        d = (d * w[:, None]).reshape(len(c), -1)                    # (G, 3M)
        D = (D * w[:, None, None]).reshape(len(c), -1, 3)           # (G, 3M, 3)
        Qf, Rf = np.linalg.qr(D)
        sol = np.linalg.solve(Rf, np.einsum('gri,gr->gi', Qf, d)[..., None])
        r = d - (D @ sol)[..., 0]
        clip = OUTLIER_SIGMAS * np.median(np.abs(r), axis=1) / 0.6745
        out[g0:g0 + step] = np.sum(np.minimum(r * r, (clip * clip)[:, None]), axis=1)
    return out


def _difference_covariance(n):
    """Covariance (n, n) of ``n`` second differences of unit white noise."""
    S = 6.0 * np.eye(n)
    i = np.arange(n - 1)
    S[i, i + 1] = S[i + 1, i] = -4.0
    j = np.arange(n - 2)
    S[j, j + 2] = S[j + 2, j] = 1.0
    return S


def fit_lever_arm(t_v, V, window, arm_b):
    """Fit the lever arm beyond ``arm_b`` to the GNSS velocities of the coarse window.

    ``t_v`` (N,) stamps and ``V`` (N, 3) ENU velocities of the fixes (the antenna's);
    ``window`` the coarse window ``(t, dtheta, dv, dt)`` (vehicle frame); ``arm_b`` (3,)
    the configured arm (m). Returns an :class:`ArmFit`, or None with fewer than
    :data:`MIN_FIXES` velocities in the window or no rotation to fit to.
    """
    tt, dth, dvv, dts = window
    inside = (t_v >= tt[0]) & (t_v <= tt[-1])
    if np.count_nonzero(inside) < MIN_FIXES:
        return None
    t = t_v[inside]
    C_bb0, u_b0 = velocity_integral_b0(dth, dvv)
    arm_b = np.asarray(arm_b, dtype=float)
    if np.any(arm_b):
        u_b0 = u_b0 + arm_velocity_b0(C_bb0, dth, dts, arm_b)

    def at_fixes(Y):
        return np.column_stack([np.interp(t, tt, Y[:, i]) for i in range(3)])

    U = at_fixes(u_b0)
    L = levelling(U[-1] - U[0])
    U_l = U @ L.T
    B0 = np.stack([at_fixes(arm_velocity_b0(C_bb0, dth, dts, e_k)) @ L.T
                   for e_k in np.eye(3)], axis=-1)                    # (N, 3, 3) levelled
    V = V[inside]

    def rotated(psi):
        R3 = np.eye(3)
        R3[:2, :2] = _rotation(psi)
        return V - U_l @ R3, np.einsum('nak,ab->nbk', B0, R3)

    if np.linalg.matrix_rank(_design(*rotated(0.0))[1]) < 3:
        return None
    grid = np.radians(np.arange(0.0, 360.0, GRID_DEG))
    fits = {}

    def fit(i):                     # heading i's clipped fit, as the grid's selection has it
        if i not in fits:
            fits[i] = _clipped_fit(*_design(*rotated(grid[i])))
        return fits[i]

    scores = _grid_scores(V, U_l, B0, grid)
    # the vectorised scores only preselect: headings within round-off of the best are
    # scored again one by one, so the choice is exactly the one-by-one fit's
    # (relative to the best and, for a best near 0, to the largest: round-off of the QR
    # and of lstsq differ by more than the best score's own digits there)
    near = np.flatnonzero(scores <= scores.min() * (1.0 + _PRESELECT_TOL)
                          + _PRESELECT_TOL * scores.max())
    k = int(near[np.argmin([fit(i)[1] for i in near])])
    k_opp = (k + len(grid) // 2) % len(grid)
    ambiguous = fit(k_opp)[1] < AMBIGUITY_RATIO * fit(k)[1]
    e, B = rotated(grid[k])
    d, D = _design(e, B)
    m = len(d) // 3
    r = d - D @ fit(k)[0]
    s = np.median(np.abs(r[:2 * m])) / 0.6745
    big = np.abs(r) > OUTLIER_SIGMAS * s
    big = big[:m] | big[m:2 * m] | big[2 * m:]
    spoilt = big | np.r_[big[1:], False] | np.r_[False, big[:-1]]
    if np.count_nonzero(~spoilt) < MIN_FIXES // 2:
        return None
    keep = np.r_[~spoilt, ~spoilt, ~spoilt]
    Dk, dk = D[keep], d[keep]
    sol = np.linalg.lstsq(Dk, dk, rcond=None)[0]
    n_h = 2 * np.count_nonzero(~spoilt)
    noise = float(np.median(np.abs(dk - Dk @ sol)[:n_h]) / 0.6745 / math.sqrt(6.0))
    # sandwich covariance with the second differences' correlation, per axis (the up rows
    # carry their weight: a receiver's vertical noise taken as 1 / UP_WEIGHT times)
    S = np.zeros((3 * m, 3 * m))
    for a in range(3):
        S[a * m:(a + 1) * m, a * m:(a + 1) * m] = _difference_covariance(m)
    S = S[np.ix_(keep, keep)] * noise ** 2
    A = np.linalg.pinv(Dk.T @ Dk) @ Dk.T
    cov = A @ S @ A.T
    chi2 = float(sol @ np.linalg.solve(cov, sol))
    rate_rms = float(np.sqrt(np.mean(np.sum((dth / dts[:, None]) ** 2, axis=1))))
    return ArmFit(sol, cov, chi2, noise, rate_rms, bool(ambiguous))
