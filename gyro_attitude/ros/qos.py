"""QoS profiles of the gyro_attitude topics and the one QoS adaptation rule of recorder and
player."""

from __future__ import annotations

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from gyro_attitude.io.qos import qos_profile

__all__ = ["imu_qos", "offered_profiles", "adapted_qos"]


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


def offered_profiles(endpoint_infos) -> list[dict]:
    """The publishers' offered QoS (``get_publishers_info_by_topic``) as rosbag2 profile dicts
    (:func:`gyro_attitude.io.qos.qos_profile`: policies by name, durations as (sec, nsec))."""
    profiles = []
    for info in endpoint_infos:
        q = info.qos_profile
        profiles.append(qos_profile(
            history=int(q.history), depth=int(q.depth), reliability=int(q.reliability),
            durability=int(q.durability), deadline=_sec_nsec(q.deadline),
            lifespan=_sec_nsec(q.lifespan), liveliness=int(q.liveliness),
            liveliness_lease_duration=_sec_nsec(q.liveliness_lease_duration),
            avoid_ros_namespace_conventions=bool(q.avoid_ros_namespace_conventions)))
    return profiles


def _sec_nsec(duration) -> tuple[int, int]:
    return divmod(int(duration.nanoseconds), 1_000_000_000)


def adapted_qos(profiles: list[dict], depth: int) -> QoSProfile:
    """QoS that matches every offered profile (rosbag2's adaptation rule), keep-last ``depth``.

    Used both to subscribe to live publishers (recorder) and to republish recorded ones
    (player): reliable only if every profile is reliable, transient-local only if every one
    is; otherwise best effort / volatile, which any publisher or subscriber accepts.
    ``profiles`` are dicts with policy names (:func:`offered_profiles`,
    :func:`gyro_attitude.io.qos.parse_qos_profiles`). None known (a bag written by mcap_ros2
    or Foxglove tools has no ``offered_qos_profiles``) gives rosbag2's default profile,
    reliable and volatile: a reliable publisher matches best-effort and reliable
    subscribers alike.
    """
    reliable = not profiles or all(p["reliability"] == "reliable" for p in profiles)
    transient = bool(profiles) and all(p["durability"] == "transient_local" for p in profiles)
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST, depth=int(depth),
        reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if transient else DurabilityPolicy.VOLATILE)
