"""How the sensors sit on the vehicle: the IMU mounting rotation and the GNSS lever arm.

Both are given in the vehicle frame ``v`` (FLU, REP-103 ``base_link``); the filters
work in it: the IMU increments are turned into it at input (:meth:`Installation.to_vehicle`)
and every GNSS epoch is moved from the antenna to the IMU before a filter sees it
(:meth:`Installation.fix_to_imu`), so every filter and the coarse stage share one
treatment.

Lever arm ``l_v`` (3,) m, antenna relative to the IMU. With ``C_v_n`` the attitude and
``w_nv_v`` the vehicle's rate against the navigation frame::

    p_ant = p_imu + C_v_n l_v                      (position, ENU metres)
    v_ant = v_imu + C_v_n (w_nv_v x l_v)           (velocity, ENU)

(the usual lever-arm relations of GNSS/INS integration, not from the seeds, which put the
antenna at the IMU; ``w_nv_v`` is taken as the gyro rate: the Earth and transport rates
add below 1e-4 rad/s, 2 mm/s on a 20 m arm.)

Where we differ from a filter that models the arm in its measurement matrix: the
attitude's uncertainty enters as measurement noise, not as information. The correction
uses the filter's current attitude, and the error that attitude may have is added to the
epoch's variances, per ENU axis, from the misalignment covariance ``P_phi``::

    d p = -(C l) x phi = [C l x] phi   ->   var_p = diag([a x] P_phi [a x]^T), a = C l

and the same with ``a = C (w x l)`` for the velocity. This keeps every filter's model as
its seed writes it, and cannot make a filter more confident than it was without the
arm; it gives up the heading information that a swinging arm carries (a ship's sway
moves a mast-top antenna by about 1 m/s), which the filters here find from the
accelerations anyway.
"""
import math
from collections import deque
from copy import copy
from dataclasses import replace

import numpy as np

from ...nav import earth
from ...nav.coarse import arm_velocity_b0, body_attitude_increments
from ...nav.frames import euler_to_dcm, skew
from ...units import DEG

#: how long the arm speeds of recent samples are kept (:meth:`Installation.speed_since`), s
SPEED_MEMORY_S = 5.0


def _cross_var(a, P):
    """Per-axis variance (3,) of ``a x phi`` for misalignment covariance ``P`` (3, 3)."""
    A = skew(a)
    return np.maximum(np.einsum('ij,jk,ik->i', A, P, A), 0.0)


class Installation:
    """The mounting rotation and lever arm of one configuration.

    ``lever_arm_m`` (3,) FLU m; ``mounting_rpy_deg`` (3,) the rotation vehicle -> IMU
    frame (the ``base_link -> imu_link`` transform) as REP-103 roll, pitch, yaw, deg.
    """

    def __init__(self, lever_arm_m=(0.0, 0.0, 0.0), mounting_rpy_deg=(0.0, 0.0, 0.0)):
        self.l_v = np.asarray(lever_arm_m, dtype=float).reshape(3)
        rpy = np.asarray(mounting_rpy_deg, dtype=float).reshape(3)
        #: rotation IMU frame -> vehicle frame (3, 3), or None for none
        self.C_s_v = None if not np.any(rpy) else euler_to_dcm(rpy * DEG)
        #: the lever arm is zero
        self.no_arm = not np.any(self.l_v)
        self._speeds = deque()

    @classmethod
    def from_params(cls, cfg):
        """Build from ``gnss_lever_arm_m`` and ``imu_mounting_rpy_deg`` of ``cfg``."""
        return cls(cfg['gnss_lever_arm_m'], cfg['imu_mounting_rpy_deg'])

    def with_lever_arm(self, lever_arm_m):
        """Return this installation with the lever arm ``lever_arm_m`` (3,) m (self if same).

        The mounting rotation and the recorded arm speeds are shared.
        """
        l_v = np.asarray(lever_arm_m, dtype=float).reshape(3)
        if np.array_equal(l_v, self.l_v):
            return self
        other = copy(self)
        other.l_v = l_v
        other.no_arm = not np.any(l_v)
        return other

    @property
    def arm_m(self):
        """Length of the lever arm, m."""
        return float(np.linalg.norm(self.l_v))

    # -- the IMU -------------------------------------------------------------------------
    def to_vehicle(self, x_s):
        """Turn vectors (N, 3) or (3,) from the IMU frame into the vehicle frame."""
        return x_s if self.C_s_v is None else x_s @ self.C_s_v.T

    def take(self, t, dtheta, dv, t_prev):
        """Return increments ``dtheta``, ``dv`` (N, 3) or (3,) in the vehicle frame.

        Records their arm speed (:meth:`recent_speed`); ``t`` their stamps, ``t_prev`` the
        stamp before the first (or None).
        """
        dtheta = self.to_vehicle(np.asarray(dtheta, dtype=float))
        self.recent_speed(t, dtheta, t_prev)
        return dtheta, self.to_vehicle(np.asarray(dv, dtype=float))

    # -- the GNSS antenna ----------------------------------------------------------------
    def arm_velocity_v(self, w_v):
        """Velocity (N, 3) or (3,) of the antenna about the IMU in the vehicle frame, m/s."""
        return np.cross(w_v, self.l_v)

    def speed_bound(self, w_v):
        """Largest antenna speed (m/s) about the IMU over rates ``w_v`` (N, 3) rad/s."""
        if self.no_arm or len(w_v) == 0:
            return 0.0
        return float(np.max(np.linalg.norm(self.arm_velocity_v(w_v), axis=1)))

    def fix_to_imu(self, fix, C_v_n, w_v, P_phi, rate_var=0.0):
        """Return GNSS epoch ``fix`` (a :class:`~.gnss_fix.GnssFix`) moved to the IMU.

        ``C_v_n`` (3, 3) the current attitude, ``w_v`` (3,) the vehicle's measured rate
        (rad/s), ``P_phi`` (3, 3) its misalignment covariance about ENU (rad^2),
        ``rate_var`` the variance per axis of the rate's error (gyro bias and noise). The
        returned fix's ``arm_var`` (6,) is what these uncertainties do to the correction
        per ENU axis, position (m^2) then velocity ((m/s)^2) (module docstring; the rate
        error adds ``rate_var |l|^2`` to each velocity axis, a bound): the filters that
        set their measurement noise add it. Unchanged without an arm.
        """
        if self.no_arm:
            return fix
        a_p = C_v_n @ self.l_v
        a_v = C_v_n @ self.arm_velocity_v(w_v)
        R_M, R_N = earth.radii(fix.lat)
        lat = fix.lat - a_p[1] / (R_M + fix.h)
        lon = fix.lon - a_p[0] / ((R_N + fix.h) * math.cos(fix.lat))
        v_n = None if fix.v_n is None else np.asarray(fix.v_n, dtype=float) - a_v
        return replace(fix, lat=lat, lon=lon, h=fix.h - a_p[2], v_n=v_n,
                       arm_var=np.r_[_cross_var(a_p, P_phi),
                                     _cross_var(a_v, P_phi) + rate_var * (self.l_v @ self.l_v)])

    def window_arm_velocity_n(self, C_v_n_end, dtheta, dt):
        """ENU velocity (N, 3) of the antenna about the IMU over a window of increments.

        ``C_v_n_end`` (3, 3) the attitude after the last of ``dtheta`` (N, 3) (vehicle
        frame) with intervals ``dt`` (N,); the attitudes before it follow from the gyros
        (the navigation frame's turn, below 0.3 deg a minute, is neglected).
        """
        C_bb0 = body_attitude_increments(dtheta)
        C_n_b0 = C_v_n_end @ C_bb0[-1].T
        return arm_velocity_b0(C_bb0, dtheta, dt, self.l_v, relative=False) @ C_n_b0.T

    def recent_speed(self, t, dtheta, t_prev):
        """Record the largest arm speed of samples ``t`` (N,), ``dtheta`` (N, 3) (vehicle).

        ``t_prev`` the stamp before the first (None: taken 10 ms before). Kept for
        :data:`SPEED_MEMORY_S` seconds; returns nothing (:meth:`speed_since` reads it).
        """
        if self.no_arm:
            return
        t = np.atleast_1d(t)
        prev = t[0] - 0.01 if t_prev is None else t_prev
        dt = np.maximum(np.diff(np.r_[prev, t]), 1e-3)
        self._speeds.append((float(t[-1]), self.speed_bound(np.atleast_2d(dtheta) / dt[:, None])))
        while self._speeds and self._speeds[0][0] < t[-1] - SPEED_MEMORY_S:
            self._speeds.popleft()

    def speed_since(self, t0):
        """Largest arm speed (m/s) recorded for samples after ``t0`` (0 without an arm)."""
        return max((s for t, s in self._speeds if t >= t0), default=0.0)
