"""The navigation filters' solution as odometry: local ENU pose and body twist.

ROS-free arithmetic behind the node's ``~/odom`` (and the replay's result bag): the
position becomes an ENU offset from an origin latched at the first valid row (where
fine alignment started); the velocity is resolved in the body axes with its covariance
from the velocity and attitude errors; the angular rate is bias-corrected.
"""
from dataclasses import dataclass

import numpy as np

from ..nav import earth
from ..nav.frames import quat_to_dcm, skew


@dataclass
class Odometry:
    """Odometry samples, K of them (:meth:`OdometryFrame.samples`).

    ``position`` (K, 3) m ENU from the origin; ``q`` (K, 4) x, y, z, w body FLU -> ENU;
    ``pose_cov`` (K, 6, 6) position (m) and attitude about the ENU axes (rad);
    ``v_b`` (K, 3) m/s and ``w_b`` (K, 3) rad/s in the body axes; ``twist_cov`` (K, 6, 6).
    """

    position: np.ndarray
    q: np.ndarray
    pose_cov: np.ndarray
    v_b: np.ndarray
    w_b: np.ndarray
    twist_cov: np.ndarray


class OdometryFrame:
    """Latches the ENU origin (lat, lon rad, h m) at the first valid row."""

    def __init__(self):
        self.origin = None

    def samples(self, out, P_nav, w_b, gyro_bias, rate_var):
        """Return the rows of pipeline output ``out`` as :class:`Odometry` of arrays.

        ``P_nav`` (9, 9) position, velocity, misalignment covariance (one for every row:
        no GNSS update happens between them); ``w_b`` (K, 3) the samples' body rates
        (rad/s, before bias correction); ``gyro_bias`` (3,) rad/s; ``rate_var`` the rate
        noise variance per axis ((rad/s)^2). Returns ``(ok, odo)``: ``ok`` (K,) the rows
        with a navigation solution and attitude, ``odo`` their samples (fields with a
        leading axis of ``ok.sum()``), or ``(ok, None)`` when there is none.
        """
        nav, q = out.nav, out.q
        ok = np.isfinite(nav).all(axis=1) & np.isfinite(q[:, 0])
        if not ok.any():
            return ok, None
        nav, q = nav[ok], q[ok]
        if self.origin is None:
            self.origin = tuple(float(x) for x in nav[0, :3])
        pos = earth.local_offset_m(*self.origin, nav[:, 0], nav[:, 1], nav[:, 2])
        C_T = quat_to_dcm(q).transpose(0, 2, 1)          # (K, 3, 3) n -> b
        v_n = nav[:, 3:6]
        v_b = np.einsum('kij,kj->ki', C_T, v_n)
        # v_b = C~^T v~ = v_b + C^T dV - C^T [v x] phi (C~ = (I - [phi x]) C)
        J = np.concatenate([C_T, -C_T @ skew(v_n)], axis=2)          # (K, 3, 6)
        twist_cov = np.zeros((len(q), 6, 6))
        twist_cov[:, :3, :3] = J @ P_nav[3:, 3:] @ J.transpose(0, 2, 1)
        twist_cov[:, 3:, 3:] = np.eye(3) * rate_var
        ip = np.r_[0:3, 6:9]
        pose_cov = np.broadcast_to(P_nav[np.ix_(ip, ip)], (len(q), 6, 6))
        w = np.asarray(w_b, dtype=float)[ok] - gyro_bias
        return ok, Odometry(pos, q, pose_cov, v_b, w, twist_cov)


def odometry_bodies(odo):
    """Return the serialized bodies (K, 85) of ``nav_msgs/Odometry`` from batch ``odo``.

    ``odo``: an :class:`Odometry` of K rows. The columns
    follow the message: ``pose.pose`` position (3) and orientation (4), its covariance
    (36), ``twist.twist`` linear (3) and angular (3), its covariance (36);
    ``cdr.odometry_head(...) + row.tobytes()`` is the message.
    """
    k = len(odo.q)
    return np.concatenate([odo.position, odo.q, np.reshape(odo.pose_cov, (k, 36)), odo.v_b,
                           odo.w_b, np.reshape(odo.twist_cov, (k, 36))], axis=1)
