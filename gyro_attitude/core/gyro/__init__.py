"""Gimballed gyro dynamics: single-gimbal rate gyro (``rate_gyro``), two-gimbal free gyro (``free_gyro``)."""
