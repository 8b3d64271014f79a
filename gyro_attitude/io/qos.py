"""QoS profiles as rosbag2 (Jazzy, metadata version 9) writes them into MCAP channels.

The channel metadata key ``offered_qos_profiles`` holds a YAML list with one entry per
publisher, policies spelled by name (``keep_last``, ``reliable``, ``volatile``,
``automatic``); an infinite duration is ``sec: 9223372036, nsec: 854775807``.  Plain
Python values only: the ROS layer converts rclpy QoS objects (see
``gyro_attitude.ros.mcap_recorder_node``).
"""

from __future__ import annotations

from gyro_attitude.io.strict_yaml import load_yaml

__all__ = [
    "INFINITE_DURATION",
    "qos_profile",
    "qos_profiles_yaml",
    "parse_qos_profiles",
    "DEFAULT_QOS_YAML",
]

# rmw's "infinite" duration as rosbag2 serializes it: RMW_DURATION_INFINITE split in sec/nsec.
INFINITE_DURATION = (9223372036, 854775807)

_HISTORY = ("system_default", "keep_last", "keep_all", "unknown")
_RELIABILITY = ("system_default", "reliable", "best_effort", "unknown", "best_available")
_DURABILITY = ("system_default", "transient_local", "volatile", "unknown", "best_available")
_LIVELINESS = ("system_default", "automatic", "manual_by_node", "manual_by_topic", "unknown",
               "best_available")


def _policy(value, names: tuple[str, ...], what: str) -> str:
    """Accept a policy name or its rmw enum integer; return the name rosbag2 writes."""
    if isinstance(value, str):
        v = value.strip().lower()
        if v in names:
            return v
    elif isinstance(value, int) and not isinstance(value, bool) and 0 <= value < len(names):
        return names[value]
    raise ValueError(f"QoS {what} {value!r} is not one of {names} (or their rmw integers)")


def _duration(value, what: str) -> tuple[int, int]:
    if value is None:
        return INFINITE_DURATION
    if isinstance(value, dict):
        value = (value.get("sec", 0), value.get("nsec", 0))
    try:
        sec, nsec = (int(value[0]), int(value[1]))
    except (TypeError, ValueError, IndexError) as exc:
        raise ValueError(f"QoS {what} must be (sec, nsec), got {value!r}") from exc
    if sec < 0 or nsec < 0:
        raise ValueError(f"QoS {what} (sec, nsec) must not be negative: {value!r}")
    if nsec > 999_999_999 or sec >= 2**31 - 1:
        # Older rosbag2 wrote "infinite" as (2147483647, 4294967295); Jazzy writes
        # RMW_DURATION_INFINITE split as (9223372036, 854775807).  Both mean infinite.
        return INFINITE_DURATION
    return sec, nsec


def qos_profile(
    history="keep_last",
    depth: int = 10,
    reliability="reliable",
    durability="volatile",
    deadline=None,
    lifespan=None,
    liveliness="automatic",
    liveliness_lease_duration=None,
    avoid_ros_namespace_conventions: bool = False,
) -> dict:
    """One QoS profile as a dict in rosbag2's key order (durations ``None`` = infinite)."""
    if int(depth) < 0:
        raise ValueError(f"QoS depth must be >= 0, got {depth}")
    out = {
        "history": _policy(history, _HISTORY, "history"),
        "depth": int(depth),
        "reliability": _policy(reliability, _RELIABILITY, "reliability"),
        "durability": _policy(durability, _DURABILITY, "durability"),
    }
    for key, val in (("deadline", deadline), ("lifespan", lifespan)):
        sec, nsec = _duration(val, key)
        out[key] = {"sec": sec, "nsec": nsec}
    out["liveliness"] = _policy(liveliness, _LIVELINESS, "liveliness")
    sec, nsec = _duration(liveliness_lease_duration, "liveliness_lease_duration")
    out["liveliness_lease_duration"] = {"sec": sec, "nsec": nsec}
    out["avoid_ros_namespace_conventions"] = bool(avoid_ros_namespace_conventions)
    return out


def qos_profiles_yaml(profiles: list[dict]) -> str:
    """Serialize profiles (dicts from :func:`qos_profile`) like rosbag2's yaml-cpp emitter."""
    lines: list[str] = []
    for p in profiles:
        p = qos_profile(**p)  # validates and orders the keys
        first = True
        for key, val in p.items():
            lead = "- " if first else "  "
            first = False
            if isinstance(val, dict):
                lines.append(f"{lead}{key}:")
                lines.append(f"    sec: {val['sec']}")
                lines.append(f"    nsec: {val['nsec']}")
            elif isinstance(val, bool):
                lines.append(f"{lead}{key}: {'true' if val else 'false'}")
            else:
                lines.append(f"{lead}{key}: {val}")
    return "\n".join(lines)


def parse_qos_profiles(text: str) -> list[dict]:
    """Parse an ``offered_qos_profiles`` string (version 9 names or older integers)."""
    if not text or not text.strip():
        return []
    data = load_yaml(text, "offered_qos_profiles")
    if not isinstance(data, list):
        raise ValueError(f"offered_qos_profiles is not a YAML list: {text[:80]!r}")
    out = []
    for item in data:
        if not isinstance(item, dict):
            raise ValueError(f"offered_qos_profiles entry is not a mapping: {item!r}")
        try:
            out.append(qos_profile(**item))
        except TypeError:  # a key qos_profile has no argument for
            raise ValueError(f"offered_qos_profiles entry has unknown keys: "
                             f"{sorted(map(str, item))}") from None
    return out


DEFAULT_QOS_YAML = qos_profiles_yaml([qos_profile()])
