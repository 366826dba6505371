"""Coarse alignment: analytic double-vector and inertial-frame (i0) alignment.

Both return ``C_b_n`` (FLU body -> ENU) at the end of the data window.

* :func:`analytic` — TRIAD on the mean specific force (= -gravity) and the mean
  angular rate (= Earth rate) of a still IMU (Titterton & Weston sec. 10.3).
  Disturbance of the base corrupts the mean rate directly.
* :func:`inertial_frame` — the i0 method: the body attitude change since the
  start is integrated from the gyros in the inertial frame, so any rotation of
  the base (sway, people walking on a vehicle) is followed exactly; the
  specific force integrated in that frame is matched against the gravity
  integral, which turns with the Earth in the inertial frame fixed at t0. The
  unknown constant rotation between the frames is the Wahba (SVD) solution over
  all epochs. Translational motion must average out (sway, heave), or be
  supplied as velocity change (``dv_n``, e.g. from GNSS).
* :func:`detect_motion` — used by ``coarse_method: auto`` to pick between them.
"""
import numpy as np

from . import earth, kernels
from .frames import orthonormalize


def _triad(a_b, b_b, a_n, b_n):
    """DCM ``C_b_n`` with ``a_n = C a_b`` exactly and ``b`` matched as well as possible."""
    def basis(a, b):
        r1 = a / np.linalg.norm(a)
        r2 = np.cross(a, b)
        r2 = r2 / np.linalg.norm(r2)
        return np.column_stack([r1, r2, np.cross(r1, r2)])
    return basis(a_n, b_n) @ basis(a_b, b_b).T


def analytic(dtheta, dv, dt, lat):
    """Double-vector (TRIAD) alignment of a still IMU.

    Parameters
    ----------
    dtheta, dv : ndarray (N, 3)
        Increments, body FLU.
    dt : float or ndarray (N,)
    lat : float
        Latitude, rad.

    Returns
    -------
    C_b_n : ndarray (3, 3)
    """
    T = np.sum(np.broadcast_to(dt, (len(dtheta),)))
    return triad(np.sum(dv, axis=0) / T, np.sum(dtheta, axis=0) / T, lat)


def triad(f_b, w_b, lat):
    """Return ``C_b_n`` (3, 3) of a still body from its mean specific force and rate (3,).

    ``f_b`` m/s^2 and ``w_b`` rad/s in body FLU, ``lat`` rad: gravity's reaction exactly
    up, the Earth rate matched as well as possible (:func:`analytic`'s attitude).
    """
    f_n = np.array([0.0, 0.0, 1.0])              # up: the specific force of a still body
    return _triad(f_b, w_b, f_n, earth.w_ie_n(lat))


def body_attitude_increments(dtheta):
    """``C_b(t_k)^{b0}`` for k = 1..N: body attitude relative to the start, (N, 3, 3).

    Uses the same coning correction as the mechanization (compiled loop,
    :func:`~.kernels.attitude_increments`).
    """
    dtheta = np.ascontiguousarray(dtheta, dtype=float)
    out = np.empty((len(dtheta), 3, 3))
    kernels.attitude_increments(dtheta, out)
    return out


def velocity_integral_b0(dtheta, dv):
    """Body attitudes and the specific-force integral in the initial body frame b0.

    Returns ``C_bb0`` (N, 3, 3) (:func:`body_attitude_increments`) and ``V_b0`` (N, 3),
    m/s: the sum of ``C_b(k-1)^b0 (dv + 0.5 dtheta x dv)`` (rotation-compensated).
    """
    C_bb0 = body_attitude_increments(dtheta)
    C_prev = np.concatenate([np.eye(3)[None], C_bb0[:-1]])
    dv_c = dv + 0.5 * np.cross(dtheta, dv)
    return C_bb0, np.cumsum(np.einsum('kij,kj->ki', C_prev, dv_c), axis=0)


def arm_velocity_b0(C_bb0, dtheta, dt, arm_b, relative=True):
    """Velocity (N, 3) in b0 of a point ``arm_b`` (3,) m from the IMU about the IMU.

    ``C_b^b0 (w x arm)`` with the rate ``w = dtheta / dt`` of each sample: what a GNSS
    antenna on a lever arm adds to the IMU's velocity, known from the gyros alone.
    ``C_bb0`` (N, 3, 3) as :func:`velocity_integral_b0` gives; ``dt`` (N,); ``relative``:
    less its first value (the change since the window's start).
    """
    L_b0 = np.einsum('kij,kj->ki', C_bb0, np.cross(dtheta / dt[:, None], arm_b))
    return L_b0 - L_b0[0] if relative else L_b0


def inertial_frame(dtheta, dv, dt, lat, h=0.0, dv_n=None, n_epochs=50, arm_b=None,
                   epochs=None):
    """Inertial-frame (i0) coarse alignment, tolerant of sway and disturbance.

    Parameters
    ----------
    dtheta, dv : ndarray (N, 3)
        Increments, body FLU.
    dt : float or ndarray (N,)
    lat, h : float
        Latitude (rad) and height (m).
    dv_n : ndarray (N, 3) or None
        Velocity change in ENU since the start at each sample (moving base with
        velocity aiding); None for a base at rest on average.
    n_epochs : int
        Number of epochs used in the Wahba fit.
    arm_b : ndarray (3,) or None
        ``dv_n`` is the velocity of a point this far from the IMU (body axes, m): a GNSS
        antenna on a lever arm. Its velocity about the IMU, ``C_b^b0 (w x arm)`` in b0, is
        known from the gyros alone, so it is added to the specific-force side, where the
        unknown attitude does not touch it: ``V_b0 + dL_b0 = C_i0^b0 (G_i0 + dV_i0)``.
    epochs : ndarray of int or None
        Samples to fit at (default ``n_epochs`` from the first tenth of the window on);
        the fit then uses the differences from the first of them, so that ``dv_n`` need
        only be right at these samples (a velocity measured there, not interpolated).

    Returns
    -------
    C_b_n : ndarray (3, 3)
        Attitude at the end of the window.
    """
    n = len(dtheta)
    dt = np.broadcast_to(np.asarray(dt, dtype=float), (n,))
    t = np.cumsum(dt)
    C_bb0, V_b0 = velocity_integral_b0(dtheta, dv)
    if dv_n is not None and arm_b is not None and np.any(arm_b):
        V_b0 = V_b0 + arm_velocity_b0(C_bb0, dtheta, dt, arm_b)
    u, a = _earth_axis(lat), earth.OMEGA_IE * t
    V_i0 = gravity_integral_i0(t, lat, h)
    if dv_n is not None:
        # velocity change expressed in i0: sum of C_n^i0 d(v_n) (small-rotation form)
        dvn = np.diff(np.vstack([np.zeros(3), dv_n]), axis=0)
        Rz = _rotations(u, a)
        V_i0 = V_i0 + np.cumsum(np.einsum('kij,kj->ki', Rz, dvn), axis=0)
    if epochs is None:
        idx = np.unique(np.linspace(n // 10, n - 1, n_epochs).astype(int))
        B = np.einsum('ki,kj->ij', V_b0[idx], V_i0[idx])   # sum of b0 (x) i0 pairs
    else:
        idx = np.asarray(epochs, dtype=int)
        B = np.einsum('ki,kj->ij', V_b0[idx[1:]] - V_b0[idx[0]], V_i0[idx[1:]] - V_i0[idx[0]])
    U, _, Vt = np.linalg.svd(B)
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))])
    C_i0_b0 = U @ D @ Vt                                    # V_b0 = C_i0_b0 @ V_i0
    C_n_i0_end = _rotations(u, a[-1:])[0]
    return orthonormalize(C_n_i0_end.T @ C_i0_b0.T @ C_bb0[-1])


def attitude_at_start(C_b_n_end, dtheta, dt, lat, w_en=None):
    """Return the attitude (3, 3) at a window's start from the one at its end.

    ``C_b_n(t0) = C_n(end)^n(t0) C_b_n(end) C_b(end)^b0``: the body's own turn over the
    window from the gyros (``dtheta`` (N, 3), :func:`body_attitude_increments`) and the
    navigation frame's with the Earth, ``Omega T`` about its axis (``dt`` (N,) or a float,
    ``lat`` rad), and over the ground, ``w_en T`` (``w_en`` (3,) rad/s, the mean transport
    rate, :func:`~.earth.w_en_n`; None: a base that does not translate; 3.4' per axis over
    60 s at 150 m/s, seed 001's flight). For :func:`inertial_frame`'s attitude on such a
    base this is its fit at the start, ``C_i0^b0`` transposed, exactly (the same
    increments turned it to the end).
    """
    n = len(dtheta)
    T = float(np.sum(np.broadcast_to(np.asarray(dt, dtype=float), (n,))))
    C_bb0 = body_attitude_increments(dtheta)
    theta = earth.OMEGA_IE * T * _earth_axis(lat)
    if w_en is not None:
        theta = theta + np.asarray(w_en, dtype=float) * T
    angle = float(np.linalg.norm(theta))
    C_n_i0_end = _rotations(theta / angle, np.array([angle]))[0] if angle > 0.0 else np.eye(3)
    return orthonormalize(C_n_i0_end @ np.asarray(C_b_n_end) @ C_bb0[-1].T)


def _earth_axis(lat):
    """Earth's rotation axis in ENU at latitude ``lat`` (rad), unit (3,)."""
    return np.array([0.0, np.cos(lat), np.sin(lat)])


def gravity_integral_i0(t, lat, h):
    """Integral of gravity from 0 to each ``t`` (N,) s in the frame i0, (N, 3) m/s.

    i0 is ENU at the window's start, fixed in inertial space: the up vector turns about
    the Earth axis ``u`` at the Earth rate, ``C_n(t)^i0 = exp(W t [u x])``; closed form.
    """
    u, up, W = _earth_axis(lat), np.array([0.0, 0.0, 1.0]), earth.OMEGA_IE
    a = W * t
    par = np.dot(u, up) * u
    return earth.gravity(lat, h) * (np.outer(t, par) + np.outer(np.sin(a) / W, up - par)
                                    + np.outer((1.0 - np.cos(a)) / W, np.cross(u, up)))


def velocity_change_n(dtheta, dv, dt, lat, h, C_b_n_end, arm_b=None):
    """ENU velocity change since the window's start that the IMU implies (N, 3), m/s.

    The inverse of :func:`inertial_frame`'s relation ``V_b0 = C_i0^b0 (G_i0 + dV_i0)``
    for a known attitude ``C_b_n_end`` (3, 3) at the window's end: ``dV_i0 = C_b0^i0
    V_b0 - G_i0``, turned back to ENU sample by sample. With ``arm_b`` (3,) m, body axes,
    the change is the velocity of that point (a GNSS antenna), as :func:`inertial_frame`
    takes it. Inputs as :func:`inertial_frame`'s.
    """
    n = len(dtheta)
    dt = np.broadcast_to(np.asarray(dt, dtype=float), (n,))
    t = np.cumsum(dt)
    C_bb0, V_b0 = velocity_integral_b0(dtheta, dv)
    if arm_b is not None and np.any(arm_b):
        V_b0 = V_b0 + arm_velocity_b0(C_bb0, dtheta, dt, arm_b)
    Rz = _rotations(_earth_axis(lat), earth.OMEGA_IE * t)     # C_n(t)^i0
    # C_b0^i0 = C_n_end^i0 C_b_n_end C_b0^b_end
    C_b0_i0 = Rz[-1] @ np.asarray(C_b_n_end, dtype=float) @ C_bb0[-1].T
    G_i0 = gravity_integral_i0(t, lat, h)
    dV_i0 = V_b0 @ C_b0_i0.T - G_i0
    steps = np.diff(np.vstack([np.zeros(3), dV_i0]), axis=0)
    return np.cumsum(np.einsum('kji,kj->ki', Rz, steps), axis=0)


def _rotations(u, angles):
    """Rodrigues rotations about unit axis ``u`` by ``angles`` (N,), (N, 3, 3)."""
    K = np.array([[0.0, -u[2], u[1]], [u[2], 0.0, -u[0]], [-u[1], u[0], 0.0]])
    s = np.sin(angles)[:, None, None]
    c = (1.0 - np.cos(angles))[:, None, None]
    return np.eye(3)[None] + s * K[None] + c * (K @ K)[None]


def detect_motion(dtheta, dv, dt, gyro_noise=0.0, accel_noise=0.0):
    """Decide whether the base moves (sways, is disturbed) during the window.

    Compares the scatter of 1-s means of the angular rate and of the specific
    force direction with what sensor noise alone would give: ``gyro_noise``
    (rad/sqrt(s), the ARW) and ``accel_noise`` (m/s^2/sqrt(Hz), the VRW). The
    base is "moving" when either scatter exceeds 5x its noise level, with floors
    of 0.2 x Earth rate and 20 micro-rad of tilt that a quiet base never reaches.

    Returns
    -------
    moving : bool
    rate_scatter : float
        RMS scatter of the 1-s mean angular rate, rad/s.
    tilt_scatter : float
        RMS scatter of the 1-s mean specific-force direction, rad.
    """
    n = len(dtheta)
    dt = float(np.mean(np.broadcast_to(dt, (n,))))
    m = max(1, int(round(1.0 / dt)))
    k = n // m
    if k < 2:
        return False, 0.0, 0.0
    T = m * dt
    w = dtheta[:k * m].reshape(k, m, 3).sum(axis=1) / T
    f = dv[:k * m].reshape(k, m, 3).sum(axis=1) / T
    u = f / np.linalg.norm(f, axis=1, keepdims=True)
    rate_scatter = float(np.sqrt(np.mean(np.sum((w - w.mean(axis=0)) ** 2, axis=1))))
    tilt_scatter = float(np.sqrt(np.mean(np.sum((u - u.mean(axis=0)) ** 2, axis=1))))
    g = np.linalg.norm(f.mean(axis=0))
    rate_thr = max(0.2 * earth.OMEGA_IE, 5.0 * np.sqrt(3.0 / T) * gyro_noise)
    tilt_thr = max(20e-6, 5.0 * np.sqrt(2.0 / T) * accel_noise / g)
    moving = bool(rate_scatter > rate_thr or tilt_scatter > tilt_thr)
    return moving, rate_scatter, tilt_scatter
