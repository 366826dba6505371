"""Serialized bodies of the messages the alignment node publishes at the IMU rate.

``imu/data`` is built in :mod:`.imu_wire` (the input's bytes with the attitude);
``~/odom`` here.
"""
import numpy as np


def odometry_bodies(odo):
    """Return the serialized bodies (K, 85) of ``nav_msgs/Odometry`` from batch ``odo``.

    ``odo``: an :class:`~sins_align_ros.ros.odometry.Odometry` of K rows. The columns
    follow the message: ``pose.pose`` position (3) and orientation (4), its covariance
    (36), ``twist.twist`` linear (3) and angular (3), its covariance (36);
    ``cdr.odometry_head(...) + row.tobytes()`` is the message.
    """
    k = len(odo.q)
    return np.concatenate([odo.position, odo.q, np.reshape(odo.pose_cov, (k, 36)), odo.v_b,
                           odo.w_b, np.reshape(odo.twist_cov, (k, 36))], axis=1)
