"""ROS 2 layer: rclpy nodes and message conversion only.

The nodes do small-matrix numerics at IMU rate: the BLAS thread pools are limited to
one thread unless the user chose otherwise (:func:`sins_align_ros.single_thread_blas`);
this must run before numpy is imported, hence here.
"""
from .. import single_thread_blas

single_thread_blas()
