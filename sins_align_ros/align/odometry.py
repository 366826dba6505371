"""The navigation filters' solution as odometry: local ENU pose and body twist.

ROS-free arithmetic behind ``~/odom``: the position becomes an ENU offset from an
origin latched at the first valid row (where fine alignment started); the velocity
is resolved in the body axes with its covariance from the velocity and attitude
errors; the angular rate is bias-corrected.
"""
from dataclasses import dataclass

import numpy as np

from ..nav import earth
from ..nav.frames import quat_to_dcm, skew


@dataclass
class Odometry:
    """One odometry sample.

    ``position`` (3,) m ENU from the origin; ``q`` (4,) x, y, z, w body FLU -> ENU;
    ``pose_cov`` (6, 6) position (m) and attitude about the ENU axes (rad);
    ``v_b`` (3,) m/s and ``w_b`` (3,) rad/s in the body axes; ``twist_cov`` (6, 6).
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

    def sample(self, out, P_nav, w_b, gyro_bias, rate_var, k=-1):
        """Return row ``k`` (default the last) of pipeline output ``out`` as :class:`Odometry`.

        ``P_nav`` (9, 9) position, velocity, misalignment covariance; ``w_b`` (3,) the
        sample's body rate (rad/s, before bias correction); ``gyro_bias`` (3,) rad/s;
        ``rate_var`` the rate noise variance per axis ((rad/s)^2). None when the row has
        no navigation solution or attitude.
        """
        nav = out.nav[k]
        q = out.q[k]
        if not (np.all(np.isfinite(nav)) and np.isfinite(q[0])):
            return None
        lat, lon, h = nav[:3]
        if self.origin is None:
            self.origin = (float(lat), float(lon), float(h))
        pos = earth.local_offset_m(*self.origin, np.array([lat]), np.array([lon]),
                                   np.array([h]))[0]
        C = quat_to_dcm(q)
        ip = np.r_[0:3, 6:9]
        v_b = C.T @ nav[3:]
        # v_b = C~^T v~ = v_b + C^T dV - C^T [v x] phi (C~ = (I - [phi x]) C)
        J = np.hstack([C.T, -C.T @ skew(nav[3:])])
        twist_cov = np.zeros((6, 6))
        twist_cov[:3, :3] = J @ P_nav[3:, 3:] @ J.T
        twist_cov[3:, 3:] = np.eye(3) * rate_var
        return Odometry(pos, q, P_nav[np.ix_(ip, ip)], v_b,
                        np.asarray(w_b, dtype=float) - gyro_bias, twist_cov)
