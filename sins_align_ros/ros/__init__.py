"""ROS 2 layer: rclpy nodes and message conversion only.

The nodes do small-matrix numerics at IMU rate; a multi-threaded BLAS only adds
threads that spin between calls (measured: a whole core at 200 Hz), so its
thread pools are limited to one thread unless the user chose otherwise. This
must run before numpy is imported, hence here.
"""
import os

for _var in ('OPENBLAS_NUM_THREADS', 'OMP_NUM_THREADS', 'MKL_NUM_THREADS'):
    os.environ.setdefault(_var, '1')
