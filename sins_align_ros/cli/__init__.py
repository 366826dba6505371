"""cli layer of sins_align_ros (no ROS imports).

The tools' processes limit the BLAS thread pools to one thread unless the user chose
otherwise (:func:`sins_align_ros.single_thread_blas`), before numpy is imported.
"""
from .. import single_thread_blas

single_thread_blas()
