"""QoS profiles of the gyro_attitude topics."""

from __future__ import annotations

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

__all__ = ["imu_qos"]


def imu_qos(reliability: str = "best_effort", depth: int = 1000) -> QoSProfile:
    """Profile for ``imu/data_raw``: sensor-data style (best effort, volatile, keep last)
    by default, ``reliable`` on request.

    The depth is larger than ``qos_profile_sensor_data``'s 5: at 1 kHz a Python subscriber
    that pauses for a few milliseconds (garbage collection, a diagnostics callback) must not
    lose the samples queued meanwhile.
    """
    policies = {"best_effort": ReliabilityPolicy.BEST_EFFORT, "reliable": ReliabilityPolicy.RELIABLE}
    if reliability not in policies:
        raise ValueError(f"reliability must be one of {list(policies)}, got {reliability!r}")
    if int(depth) < 1:
        raise ValueError(f"QoS depth must be >= 1, got {depth}")
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=int(depth),
        reliability=policies[reliability],
        durability=DurabilityPolicy.VOLATILE,
    )
