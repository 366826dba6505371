"""Messages the alignment node publishes, built from pipeline output rows."""
import math

from geometry_msgs.msg import Vector3Stamped
from nav_msgs.msg import Odometry

from .conversions import set_quaternion, set_vector3


def imu_message(src, out, k=-1, euler=None):
    """``imu/data``: the input message ``src``'s header and rates plus row ``k``'s attitude.

    Until the attitude is known the orientation is marked unknown (REP-145:
    ``orientation_covariance[0] = -1``). Returns ``(Imu, Vector3Stamped or None)``: the
    REP-103 Euler angles (rad) when the attitude is known. The Imu is ``src`` itself
    with its orientation fields set (a received message is the callback's to keep;
    building a new one cost a quarter of the node's time at 1 kHz); ``euler``, if
    given, is the Vector3Stamped to fill (else a new one).
    """
    m = src
    q = out.q[k]
    if not math.isfinite(q[0]):          # NaN: no attitude yet
        m.orientation.x = m.orientation.y = m.orientation.z = 0.0
        m.orientation.w = 1.0
        m.orientation_covariance = [-1.0] + [0.0] * 8
        return m, None
    set_quaternion(m.orientation, q)
    m.orientation_covariance = out.P_phi[k].ravel()
    e = Vector3Stamped() if euler is None else euler
    e.header = src.header
    set_vector3(e.vector, out.euler[k])
    return m, e


def odometry_message(stamp, frame_id, child_frame_id, odo):
    """``~/odom`` from an :class:`~sins_align_ros.align.odometry.Odometry` sample."""
    o = Odometry()
    o.header.stamp = stamp
    o.header.frame_id = frame_id
    o.child_frame_id = child_frame_id
    set_vector3(o.pose.pose.position, odo.position)
    set_quaternion(o.pose.pose.orientation, odo.q)
    o.pose.covariance = [float(v) for v in odo.pose_cov.ravel()]
    set_vector3(o.twist.twist.linear, odo.v_b)
    set_vector3(o.twist.twist.angular, odo.w_b)
    o.twist.covariance = [float(v) for v in odo.twist_cov.ravel()]
    return o
