"""The one module that owns frame and attitude conventions.

Conventions (docs/contracts.md, a contract):

* navigation frame ENU (x east, y north, z up);
* body frame FLU (REP-103: x forward, y left, z up) everywhere inside the
  package and on ROS topics. The seeds and PSINS use RFU bodies (x right,
  y forward, z up); aerospace texts use FRD. Convert at the edges with the
  matrices below;
* attitude is the rotation body -> ENU, ``C_b_n`` (a 3x3 DCM, ``v_n = C_b_n @ v_b``)
  or the quaternion ``q_b_n`` stored ``(x, y, z, w)`` as on ROS messages and in
  scipy;
* Euler angles follow REP-103: ``C_b_n = Rz(yaw) @ Ry(pitch) @ Rx(roll)``
  (fixed axes x-y-z, roll first). With an FLU body, yaw 0 points the nose east,
  positive yaw turns it towards north (CCW seen from above) and **positive
  pitch is nose down**, positive roll is right side down;
* navigation heading (human reports only) is clockwise from north in
  [0, 360) deg: ``heading = 90 deg - yaw``;
* PSINS attitude ``[pitch, roll, yaw]`` (RFU body, yaw CCW from north, pitch
  nose up) relates to REP-103 by ``C_flu_enu = C_rfu_enu @ C_FLU_TO_RFU``.

Shapes: functions accept a single angle triple (3,) or a stack (N, 3); DCMs are
(3, 3) or (N, 3, 3); quaternions (4,) or (N, 4). Angle units (``DEG``, ``ARCMIN``,
``ARCSEC``) are :mod:`sins_align_ros.units`'s.
"""
import math

import numpy as np

from .. import compiled
from . import kernels

# --- fixed frame changes (vector components) --------------------------------
#: v_flu = C_RFU_TO_FLU @ v_rfu  (right-forward-up body -> forward-left-up body)
C_RFU_TO_FLU = np.array([[0.0, 1.0, 0.0],
                         [-1.0, 0.0, 0.0],
                         [0.0, 0.0, 1.0]])
#: v_rfu = C_FLU_TO_RFU @ v_flu
C_FLU_TO_RFU = C_RFU_TO_FLU.T
#: v_frd = C_FLU_TO_FRD @ v_flu (and back, it is its own inverse)
C_FLU_TO_FRD = np.diag([1.0, -1.0, -1.0])
#: v_ned = C_ENU_TO_NED @ v_enu (and back, it is its own inverse)
C_ENU_TO_NED = np.array([[0.0, 1.0, 0.0],
                         [1.0, 0.0, 0.0],
                         [0.0, 0.0, -1.0]])


# --- small-vector algebra ----------------------------------------------------
def skew(v):
    """Return the cross-product matrix ``[v x]``, (3, 3) or (N, 3, 3).

    ``skew(a) @ b == np.cross(a, b)``.
    """
    v = np.asarray(v, dtype=float)
    S = np.zeros(v.shape[:-1] + (3, 3))
    S[..., 0, 1] = -v[..., 2]
    S[..., 0, 2] = v[..., 1]
    S[..., 1, 0] = v[..., 2]
    S[..., 1, 2] = -v[..., 0]
    S[..., 2, 0] = -v[..., 1]
    S[..., 2, 1] = v[..., 0]
    return S


def _rotation_x(a):
    """``Rx(a)`` (..., 3, 3) of angles (...) rad."""
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(c), np.zeros_like(c)
    return np.stack([np.stack([o, z, z], -1), np.stack([z, c, -s], -1),
                     np.stack([z, s, c], -1)], -2)


def _rotation_y(a):
    """``Ry(a)`` (..., 3, 3) of angles (...) rad."""
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(c), np.zeros_like(c)
    return np.stack([np.stack([c, z, s], -1), np.stack([z, o, z], -1),
                     np.stack([-s, z, c], -1)], -2)


def _rotation_z(a):
    """``Rz(a)`` (..., 3, 3) of angles (...) rad."""
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(c), np.zeros_like(c)
    return np.stack([np.stack([c, -s, z], -1), np.stack([s, c, z], -1),
                     np.stack([z, z, o], -1)], -2)


def rotvec_to_dcm(phi):
    """DCM ``exp([phi x])`` of a rotation vector ``phi`` (rad), (..., 3) -> (..., 3, 3).

    Rodrigues: ``I + sin(a)/a [phi x] + (1 - cos a)/a^2 [phi x]^2``, ``a = |phi|``, with
    the Taylor series of both factors below 1e-4 rad.
    """
    phi = np.asarray(phi, dtype=float)
    if phi.ndim == 1:                    # one vector: the same formula on scalars
        x, y, z = phi.tolist()
        a2 = x * x + y * y + z * z
        a = math.sqrt(a2)
        k1 = 1.0 - a2 / 6.0 if a < 1e-4 else math.sin(a) / a
        k2 = 0.5 - a2 / 24.0 if a < 1e-4 else (1.0 - math.cos(a)) / a2
        return np.array([[1.0 - k2 * (y * y + z * z), k2 * x * y - k1 * z, k2 * x * z + k1 * y],
                         [k2 * x * y + k1 * z, 1.0 - k2 * (x * x + z * z), k2 * y * z - k1 * x],
                         [k2 * x * z - k1 * y, k2 * y * z + k1 * x, 1.0 - k2 * (x * x + y * y)]])
    a2 = np.sum(phi * phi, axis=-1)[..., None, None]
    a = np.sqrt(a2)
    small = a < 1e-4
    with np.errstate(divide='ignore', invalid='ignore'):
        k1 = np.where(small, 1.0 - a2 / 6.0, np.sin(a) / a)
        k2 = np.where(small, 0.5 - a2 / 24.0, (1.0 - np.cos(a)) / a2)
    S = skew(phi)
    return np.eye(3) + k1 * S + k2 * (S @ S)


def dcm_to_rotvec(C):
    """Rotation vector (rad) of a DCM, (..., 3, 3) -> (..., 3); angle in [0, pi].

    Through the quaternion (:func:`dcm_to_quat`, ``w >= 0``): ``phi = v 2 atan2(|v|, w) /
    |v|``, the factor's series ``2 / w (1 - |v|^2 / (3 w^2))`` for ``|v| < 1e-6``.
    """
    q = dcm_to_quat(C)
    v, w = q[..., :3], q[..., 3]
    n = np.linalg.norm(v, axis=-1)
    with np.errstate(divide='ignore', invalid='ignore'):
        k = np.where(n < 1e-6, 2.0 / w * (1.0 - n * n / (3.0 * w * w)),
                     2.0 * np.arctan2(n, w) / n)
    return v * k[..., None]


def orthonormalize(C):
    """Nearest orthonormal matrix to ``C`` (polar decomposition).

    For a (3, 3) within :data:`~.kernels.POLAR_MAX_DEPARTURE` of orthonormal (an attitude
    after a filter's feedback, the mean attitude over an interval) the compiled
    Newton-Schulz iteration (:func:`~.kernels.polar_factor`) when the kernels are;
    otherwise the SVD's ``U V^T``. The two agree to round-off (test_frames.py).
    """
    C = np.asarray(C, dtype=float)
    if compiled.COMPILED and C.shape == (3, 3):
        out = np.empty((3, 3))
        if kernels.polar_factor(np.ascontiguousarray(C), out):
            return out
    U, _, Vt = np.linalg.svd(C)
    return U @ Vt


#: departure from orthonormality (largest ``|C^T C - I|`` entry) below which one
#: Newton-Schulz step reaches round-off in :func:`reorthonormalize`
NEWTON_SCHULZ_MAX = 1e-8
_I3 = np.eye(3)


def reorthonormalize(C):
    """Nearest orthonormal matrix to a nearly orthonormal ``C`` (3, 3): its polar factor.

    For an attitude that is a product of rotations (a filter's feedback ``C_n'^n C_b^n'``),
    orthonormal but for round-off. Compiled: :func:`orthonormalize`. Otherwise, with
    ``E = C^T C - I``: ``C`` itself when ``|E| < 1e-15``; one Newton-Schulz step
    ``C (I - E / 2)`` when ``|E|`` is within :data:`NEWTON_SCHULZ_MAX` (the step squares
    the departure, ``3/4 |E|^2``, to round-off); else the SVD.
    """
    if compiled.COMPILED:
        return orthonormalize(C)
    E = C.T @ C - _I3
    err = np.abs(E).max()
    if err < 1e-15:
        return C
    if err < NEWTON_SCHULZ_MAX:
        return C - 0.5 * (C @ E)
    return orthonormalize(C)


# --- REP-103 Euler angles ----------------------------------------------------
def euler_to_dcm(euler):
    """``C_b_n`` from REP-103 ``[roll, pitch, yaw]`` (rad); (3,) -> (3, 3), (N, 3) -> (N, 3, 3)."""
    euler = np.asarray(euler, dtype=float)
    return _rotation_z(euler[..., 2]) @ _rotation_y(euler[..., 1]) @ _rotation_x(euler[..., 0])


def dcm_to_euler(C_b_n):
    """REP-103 ``[roll, pitch, yaw]`` (rad) of ``C_b_n``; yaw in (-pi, pi].

    Closed form for ``C = Rz(y) Ry(p) Rx(r)``: ``r = atan2(C21, C22)``,
    ``p = -asin(C20)``, ``y = atan2(C10, C00)`` (vectorised, (..., 3, 3) -> (..., 3)).
    """
    C = np.asarray(C_b_n, dtype=float)
    if C.ndim == 2:                      # scalar fast path (live node, one sample)
        return np.array([math.atan2(C[2, 1], C[2, 2]),
                         -math.asin(C[2, 0] if not abs(C[2, 0]) > 1.0  # NaN stays NaN
                                    else math.copysign(1.0, C[2, 0])),
                         math.atan2(C[1, 0], C[0, 0])])
    roll = np.arctan2(C[..., 2, 1], C[..., 2, 2])
    pitch = -np.arcsin(np.clip(C[..., 2, 0], -1.0, 1.0))
    yaw = np.arctan2(C[..., 1, 0], C[..., 0, 0])
    return np.stack([roll, pitch, yaw], axis=-1)


def euler_to_quat(euler):
    """Quaternion ``(x, y, z, w)`` body -> ENU from REP-103 Euler angles (rad).

    The product ``q_z(yaw) q_y(pitch) q_x(roll)`` of the elementary quaternions, in
    closed form (the sign is the product's: ``w`` may be negative).
    """
    e = np.asarray(euler, dtype=float) * 0.5
    cr, sr = np.cos(e[..., 0]), np.sin(e[..., 0])
    cp, sp = np.cos(e[..., 1]), np.sin(e[..., 1])
    cy, sy = np.cos(e[..., 2]), np.sin(e[..., 2])
    return np.stack([sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy,
                     cr * cp * sy - sr * sp * cy, cr * cp * cy + sr * sp * sy], axis=-1)


def quat_to_euler(q):
    """REP-103 Euler angles (rad) from quaternion ``(x, y, z, w)`` body -> ENU, any norm.

    ``dcm_to_euler(quat_to_dcm(q))``; NaN for a NaN or zero quaternion.
    """
    return dcm_to_euler(quat_to_dcm(q))


def quat_to_yaw(q):
    """REP-103 yaw (rad) of quaternion ``(x, y, z, w)`` body -> ENU; NaN for a zero quaternion.

    ``atan2(2 (w z + x y), w^2 + x^2 - y^2 - z^2)``: the yaw of ``Rz(y) Ry(p) Rx(r)``, the
    same as :func:`dcm_to_euler`'s, for any norm.
    """
    x, y, z, w = (float(v) for v in q)
    if x * x + y * y + z * z + w * w == 0.0:
        return float('nan')
    return math.atan2(2.0 * (w * z + x * y), w * w + x * x - y * y - z * z)


def dcm_to_quat(C_b_n):
    """Quaternion ``(x, y, z, w)`` of ``C_b_n``, sign chosen with w >= 0.

    Shepperd's method, vectorised over (..., 3, 3); the input must be orthonormal.
    """
    C = np.asarray(C_b_n, dtype=float)
    if C.ndim == 2:
        return _dcm_to_quat_one(C.ravel().tolist())
    shape = C.shape[:-2]
    C = C.reshape(-1, 3, 3)
    tr = C[:, 0, 0] + C[:, 1, 1] + C[:, 2, 2]
    k = np.argmax(np.stack([tr, C[:, 0, 0], C[:, 1, 1], C[:, 2, 2]], axis=-1), axis=-1)
    with np.errstate(divide='ignore', invalid='ignore'):
        # w largest (the common case) for every row, then the rows of the other cases
        s0 = np.sqrt(np.maximum(1.0 + tr, 0.0)) * 2.0
        q = np.stack([(C[:, 2, 1] - C[:, 1, 2]) / s0, (C[:, 0, 2] - C[:, 2, 0]) / s0,
                      (C[:, 1, 0] - C[:, 0, 1]) / s0, 0.25 * s0], axis=-1)
        for case in range(1, 4):                  # x, y or z largest: those rows only
            rows = np.flatnonzero(k == case)
            if len(rows):
                q[rows] = _shepperd(C[rows], case)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(q[:, 3:4] < 0.0, -q, q).reshape(shape + (4,))


def _shepperd(C, case):
    """Shepperd's quaternion (M, 4) of DCMs (M, 3, 3) whose x (1), y (2) or z (3) is largest."""
    if case == 1:
        s = np.sqrt(np.maximum(1.0 + C[:, 0, 0] - C[:, 1, 1] - C[:, 2, 2], 0.0)) * 2.0
        return np.stack([0.25 * s, (C[:, 0, 1] + C[:, 1, 0]) / s,
                         (C[:, 0, 2] + C[:, 2, 0]) / s, (C[:, 2, 1] - C[:, 1, 2]) / s], -1)
    if case == 2:
        s = np.sqrt(np.maximum(1.0 - C[:, 0, 0] + C[:, 1, 1] - C[:, 2, 2], 0.0)) * 2.0
        return np.stack([(C[:, 0, 1] + C[:, 1, 0]) / s, 0.25 * s,
                         (C[:, 1, 2] + C[:, 2, 1]) / s, (C[:, 0, 2] - C[:, 2, 0]) / s], -1)
    s = np.sqrt(np.maximum(1.0 - C[:, 0, 0] - C[:, 1, 1] + C[:, 2, 2], 0.0)) * 2.0
    return np.stack([(C[:, 0, 2] + C[:, 2, 0]) / s, (C[:, 1, 2] + C[:, 2, 1]) / s,
                     0.25 * s, (C[:, 1, 0] - C[:, 0, 1]) / s], -1)


def _dcm_to_quat_one(c):
    """Shepperd's method on one row-major DCM (9 floats), scalar arithmetic."""
    c00, c01, c02, c10, c11, c12, c20, c21, c22 = c
    tr = c00 + c11 + c22
    k = max(range(4), key=(tr, c00, c11, c22).__getitem__)
    if k == 0:
        s = 2.0 * math.sqrt(max(1.0 + tr, 0.0))
        q = ((c21 - c12) / s, (c02 - c20) / s, (c10 - c01) / s, 0.25 * s)
    elif k == 1:
        s = 2.0 * math.sqrt(max(1.0 + c00 - c11 - c22, 0.0))
        q = (0.25 * s, (c01 + c10) / s, (c02 + c20) / s, (c21 - c12) / s)
    elif k == 2:
        s = 2.0 * math.sqrt(max(1.0 - c00 + c11 - c22, 0.0))
        q = ((c01 + c10) / s, 0.25 * s, (c12 + c21) / s, (c02 - c20) / s)
    else:
        s = 2.0 * math.sqrt(max(1.0 - c00 - c11 + c22, 0.0))
        q = ((c02 + c20) / s, (c12 + c21) / s, 0.25 * s, (c10 - c01) / s)
    n = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    sign = -1.0 if q[3] < 0.0 else 1.0
    return np.array([sign * q[0] / n, sign * q[1] / n, sign * q[2] / n, sign * q[3] / n])


def quat_to_dcm(q):
    """``C_b_n`` (..., 3, 3) of quaternion ``(x, y, z, w)`` (..., 4), normalised first.

    NaN for a NaN or zero quaternion.
    """
    q = np.asarray(q, dtype=float)
    with np.errstate(divide='ignore', invalid='ignore'):
        q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    xx, yy, zz = x * x, y * y, z * z
    xy, xz, yz, wx, wy, wz = x * y, x * z, y * z, w * x, w * y, w * z
    return np.stack([
        np.stack([1.0 - 2.0 * (yy + zz), 2.0 * (xy - wz), 2.0 * (xz + wy)], -1),
        np.stack([2.0 * (xy + wz), 1.0 - 2.0 * (xx + zz), 2.0 * (yz - wx)], -1),
        np.stack([2.0 * (xz - wy), 2.0 * (yz + wx), 1.0 - 2.0 * (xx + yy)], -1)], -2)


def euler_rates_to_w_nb_b(euler, euler_rate):
    """Body angular rate relative to the nav frame from REP-103 Euler rates.

    For ``C_b_n = Rz(y) Ry(p) Rx(r)`` the body rate is
    ``w_nb_b = [r' - y' sin p,  p' cos r + y' cos p sin r,  -p' sin r + y' cos p cos r]``.

    Parameters
    ----------
    euler, euler_rate : ndarray (..., 3)
        ``[roll, pitch, yaw]`` (rad) and their time derivatives (rad/s).

    Returns
    -------
    w_nb_b : ndarray (..., 3), rad/s, body axes.
    """
    euler = np.asarray(euler, dtype=float)
    euler_rate = np.asarray(euler_rate, dtype=float)
    r, p = euler[..., 0], euler[..., 1]
    dr, dp, dy = euler_rate[..., 0], euler_rate[..., 1], euler_rate[..., 2]
    sr, cr, sp, cp = np.sin(r), np.cos(r), np.sin(p), np.cos(p)
    return np.stack([dr - dy * sp,
                     dp * cr + dy * cp * sr,
                     -dp * sr + dy * cp * cr], axis=-1)


# --- navigation heading and PSINS conventions --------------------------------
def yaw_to_heading(yaw):
    """Navigation heading (rad, clockwise from north, [0, 2pi)) from REP-103 ENU yaw."""
    return np.mod(np.pi / 2.0 - np.asarray(yaw, dtype=float), 2.0 * np.pi)


def heading_to_yaw(heading):
    """REP-103 ENU yaw (rad, CCW from east, (-pi, pi]) from navigation heading (cw from north)."""
    return wrap_pi(np.pi / 2.0 - np.asarray(heading, dtype=float))


def wrap_pi(a):
    """Wrap angles to (-pi, pi]."""
    a = np.asarray(a, dtype=float)
    return np.pi - np.mod(np.pi - a, 2.0 * np.pi)


def nav_to_euler(roll, pitch_up, heading):
    """REP-103 Euler angles from roll (right side down), pitch (nose up), heading (cw from N)."""
    return np.stack(np.broadcast_arrays(roll, -np.asarray(pitch_up, dtype=float),
                                        heading_to_yaw(heading)), axis=-1)


def psins_att_to_dcm(att):
    """``C_b_n`` (FLU -> ENU) from a PSINS attitude ``[pitch, roll, yaw]`` (rad, RFU body).

    PSINS defines ``C_rfu_enu = Rz(yaw) Rx(pitch) Ry(roll)``.
    """
    att = np.asarray(att, dtype=float)
    C_rfu_enu = _rotation_z(att[..., 2]) @ _rotation_x(att[..., 0]) @ _rotation_y(att[..., 1])
    return C_rfu_enu @ C_FLU_TO_RFU


def dcm_to_psins_att(C_b_n):
    """PSINS attitude ``[pitch, roll, yaw]`` (rad, RFU body) of an FLU -> ENU DCM.

    For ``C = Rz(y) Rx(p) Ry(r)``: ``p = asin(C21)``, ``r = atan2(-C20, C22)``,
    ``y = atan2(-C01, C11)`` (PSINS ``m2att``).
    """
    C = np.asarray(C_b_n, dtype=float) @ C_RFU_TO_FLU
    pitch = np.arcsin(np.clip(C[..., 2, 1], -1.0, 1.0))
    roll = np.arctan2(-C[..., 2, 0], C[..., 2, 2])
    yaw = np.arctan2(-C[..., 0, 1], C[..., 1, 1])
    return np.stack([pitch, roll, yaw], axis=-1)


def attitude_error(C_est, C_true):
    """Small-angle attitude error ``phi`` (rad, nav axes) with ``C_est = exp(-[phi x]) C_true``.

    This is seed 002 eq. 3's platform misalignment ``C~ = (I - [phi x]) C``
    to first order, exact for large angles as a rotation vector.
    Shapes (3, 3) -> (3,), or stacked.
    """
    dC = np.asarray(C_true) @ np.swapaxes(np.asarray(C_est), -1, -2)
    return dcm_to_rotvec(dC)


def euler_error(euler_est, euler_true):
    """Difference of Euler triples with the angle wrap removed, rad."""
    return wrap_pi(np.asarray(euler_est) - np.asarray(euler_true))


def phi_to_euler_jacobian(euler):
    """``d(euler)/d(phi)`` (3, 3) for a nav-frame perturbation ``C -> exp([phi x]) C``.

    For ``C_b_n = Rz(y) Ry(p) Rx(r)`` a nav-frame rotation ``phi`` maps to Euler
    changes through ``phi = E d(euler)`` with ``E = [Rz Ry e_x, Rz e_y, e_z]``.
    Singular at pitch = +-90 deg (gimbal lock).
    """
    r, p, y = euler
    cy, sy, cp, sp = np.cos(y), np.sin(y), np.cos(p), np.sin(p)
    E = np.array([[cy * cp, -sy, 0.0],
                  [sy * cp, cy, 0.0],
                  [-sp, 0.0, 1.0]])
    return np.linalg.inv(E)


def euler_sigma_one(euler, P_phi):
    """1-sigma of REP-103 Euler angles (3,) for one attitude, scalar arithmetic.

    Same result as ``sqrt(diag(euler_cov_from_phi_cov(euler, P_phi)))``.
    """
    _, p, y = euler
    cy, sy, cp, sp = math.cos(y), math.sin(y), math.cos(p), math.sin(p)
    P = P_phi
    rows = ((cy / cp, sy / cp, 0.0), (-sy, cy, 0.0), (cy * sp / cp, sy * sp / cp, 1.0))
    out = []
    for a, b, c in rows:
        v = (a * (a * P[0][0] + b * P[0][1] + c * P[0][2])
             + b * (a * P[1][0] + b * P[1][1] + c * P[1][2])
             + c * (a * P[2][0] + b * P[2][1] + c * P[2][2]))
        out.append(math.sqrt(v) if v > 0.0 else 0.0)
    return np.array(out)


def euler_sigma(euler, P_phi):
    """1-sigma of REP-103 Euler angles (N, 3) from ``euler`` (N, 3) and ``P_phi`` (N, 3, 3).

    ``sqrt(diag(euler_cov_from_phi_cov(euler, P_phi)))`` row by row (negative round-off
    variances give 0), without forming the (N, 3, 3) product: the quadratic form of each
    row of the Jacobian, elementwise (a replay's 120,000 rows in a few ms).
    """
    p, y = euler[:, 1], euler[:, 2]
    cy, sy, cp, sp = np.cos(y), np.sin(y), np.cos(p), np.sin(p)
    P = [[P_phi[:, i, j] for j in range(3)] for i in range(3)]
    rows = ((cy / cp, sy / cp, 0.0), (-sy, cy, 0.0), (cy * sp / cp, sy * sp / cp, 1.0))
    out = np.empty((len(euler), 3))
    for k, (a, b, c) in enumerate(rows):
        v = (a * (a * P[0][0] + b * P[0][1] + c * P[0][2])
             + b * (a * P[1][0] + b * P[1][1] + c * P[1][2])
             + c * (a * P[2][0] + b * P[2][1] + c * P[2][2]))
        out[:, k] = np.sqrt(np.clip(v, 0.0, None))
    return out


def euler_cov_from_phi_cov(euler, P_phi):
    """Covariance of REP-103 Euler angles from a nav-frame misalignment covariance.

    ``euler`` (3,) or (N, 3); ``P_phi`` (3, 3) or (N, 3, 3); returns (3, 3) or (N, 3, 3).
    """
    euler = np.asarray(euler, dtype=float)
    if euler.ndim == 1:
        return euler_cov_from_phi_cov(euler[None], P_phi)[0]
    p, y = euler[:, 1], euler[:, 2]
    if np.ndim(P_phi) == 2:
        P_phi = np.broadcast_to(P_phi, (len(euler), 3, 3))
    cy, sy, cp, sp = np.cos(y), np.sin(y), np.cos(p), np.sin(p)
    # closed-form inverse of E = [[cy cp, -sy, 0], [sy cp, cy, 0], [-sp, 0, 1]]
    J = np.zeros((len(euler), 3, 3))
    J[:, 0, 0] = cy / cp
    J[:, 0, 1] = sy / cp
    J[:, 1, 0] = -sy
    J[:, 1, 1] = cy
    J[:, 2, 0] = cy * sp / cp
    J[:, 2, 1] = sy * sp / cp
    J[:, 2, 2] = 1.0
    return np.einsum('kij,kjl,kml->kim', J, P_phi, J)
