"""Numpy-only core: knows nothing of ROS or files."""
