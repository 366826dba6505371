"""Messages the alignment node publishes, built from pipeline output rows."""
import math

from geometry_msgs.msg import Vector3Stamped
from nav_msgs.msg import Odometry
from sensor_msgs.msg import Imu

from .conversions import set_quaternion, set_vector3


def imu_message(src, out, k=-1):
    """``imu/data``: the input message ``src``'s header and rates plus row ``k``'s attitude.

    Until the attitude is known the orientation is marked unknown (REP-145:
    ``orientation_covariance[0] = -1``). Returns ``(Imu, Vector3Stamped or None)``: the
    REP-103 Euler angles (rad) when the attitude is known.
    """
    m = Imu()
    m.header = src.header
    m.angular_velocity = src.angular_velocity
    m.angular_velocity_covariance = src.angular_velocity_covariance
    m.linear_acceleration = src.linear_acceleration
    m.linear_acceleration_covariance = src.linear_acceleration_covariance
    q = out.q[k]
    if not math.isfinite(q[0]):          # NaN: no attitude yet
        m.orientation_covariance[0] = -1.0
        return m, None
    set_quaternion(m.orientation, q)
    m.orientation_covariance = [float(v) for v in out.P_phi[k].ravel()]
    e = Vector3Stamped()
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
