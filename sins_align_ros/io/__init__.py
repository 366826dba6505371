"""io layer of sins_align_ros (no ROS imports)."""
