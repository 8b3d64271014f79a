"""ROS 2 layer: the only place rclpy and message types appear."""
