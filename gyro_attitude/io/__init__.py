"""File I/O: rosbag2-compatible MCAP. No rclpy import at module top."""
