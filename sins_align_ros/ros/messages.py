"""Messages the alignment node publishes as objects, built from pipeline output rows.

``imu/data`` goes out as bytes (:mod:`.imu_wire`).
"""
from nav_msgs.msg import Odometry

from .conversions import set_quaternion, set_vector3


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
