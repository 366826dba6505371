"""cli layer of sins_align_ros (no ROS imports).

The tools' processes limit the BLAS thread pools to one thread unless the user chose
otherwise (:func:`sins_align_ros.single_thread_blas`), before numpy is imported: on
import of this layer (which the tools' entry points import first), so a program that
imports ``sins_align_ros.cli`` gets the setting too, for itself and its children.
"""
from .. import single_thread_blas

single_thread_blas()
