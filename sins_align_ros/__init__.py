"""sins_align_ros: initial alignment of a strapdown inertial navigation system for ROS 2.

Layers (see DESIGN.md): ``sim`` and ``nav`` at the bottom, then ``filters``,
``models``, ``align``, ``io``, ``cli`` and finally ``ros``. Only ``ros`` imports
rclpy or message packages.
"""

__version__ = '0.1.0'
