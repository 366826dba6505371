"""ROS 2 layer: rclpy nodes and message conversion only."""
