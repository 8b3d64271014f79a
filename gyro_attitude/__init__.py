"""gyro_attitude: gyroscope mechanics and attitude for ROS 2 Jazzy.

Layers:
    core/  numpy only (no rclpy, no files): rotations, integrators, Earth, gyros, scenes
    io/    files: rosbag2-compatible MCAP, fast Imu decode
    ros/   the only place rclpy and message types appear
"""

__version__ = "0.1.0"
