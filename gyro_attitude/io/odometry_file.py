"""The carrier velocity of a ``nav_msgs/msg/Odometry`` topic in a recording, for the transport
rate (``replay --odometry-topic``): each message's linear velocity in its ``header.frame_id``
(REP-105, :func:`gyro_attitude.core.attitude.nav_frame.odometry_velocity`), stamped by its
header, in log-time order as the node receives them.

Odometry carries two strings before its fixed part, so it is decoded message by message here
(plain ``struct``: an odometry topic runs at tens to hundreds of Hz, not the Imu's kHz).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

import numpy as np

from gyro_attitude.core.attitude.nav_frame import odometry_velocity
from gyro_attitude.io.mcap_reader import McapStreamReader, resolve_mcap_path

__all__ = ["OdometryVelocities", "decode_odometry", "read_odometry_velocities"]

ODOMETRY_TYPE = "nav_msgs/msg/Odometry"
_LE, _BE = b"\x00\x01", b"\x00\x00"  # CDR encapsulation kinds (little, big endian)


def _string(data: bytes, pos: int, order: str) -> tuple[str, int]:
    pos = (pos + 3) & ~3
    (n,) = struct.unpack_from(order + "I", data, pos)
    pos += 4
    if n == 0 or pos + n > len(data):
        raise ValueError("a string runs past the message")
    return data[pos:pos + n - 1].decode("utf-8", "replace"), pos + n


def decode_odometry(data: bytes) -> tuple[int, str, str, np.ndarray, np.ndarray]:
    """``(stamp_ns, frame_id, child_frame_id, orientation (4,), linear velocity (3,))`` of a
    CDR-serialized Odometry; ValueError when the bytes are not one."""
    data = bytes(data)
    if len(data) < 12 or data[:2] not in (_LE, _BE):
        raise ValueError("not a CDR message")
    order = "<" if data[:2] == _LE else ">"
    body = data[4:]
    try:
        sec, nsec = struct.unpack_from(order + "iI", body, 0)
        frame_id, pos = _string(body, 8, order)
        child, pos = _string(body, pos, order)
        pos = (pos + 7) & ~7
        pose = struct.unpack_from(order + "7d", body, pos)
        pos += 8 * (7 + 36)
        linear = struct.unpack_from(order + "3d", body, pos)
    except struct.error:
        raise ValueError("truncated Odometry message") from None
    return (sec * 1_000_000_000 + nsec, frame_id, child, np.array(pose[3:7]),
            np.array(linear))


@dataclass
class OdometryVelocities:
    """``stamp_ns`` (N,) and ``velocity`` (N, 3) in the messages' frame; ``skipped`` counts the
    messages that could not be used (their first reason in ``detail``)."""

    topic: str
    stamp_ns: np.ndarray
    velocity: np.ndarray
    skipped: int
    detail: str


def read_odometry_velocities(path, topic: str) -> OdometryVelocities:
    """Every usable Odometry message of ``topic``; ValueError naming the topic when it is
    absent, of another type, or holds no usable message."""
    path = resolve_mcap_path(path)
    reader = McapStreamReader(path, on_damage="warn")
    t, v = [], []
    skipped, detail, name = 0, "", None
    for msg in reader.iter_messages([topic], log_time_order=True):
        if name is None:
            name = msg.channel.topic
            if msg.channel.type_name != ODOMETRY_TYPE:
                raise ValueError(f"{path}: topic {name} has type "
                                 f"{msg.channel.type_name or 'unknown'}, not {ODOMETRY_TYPE}")
        try:
            stamp, frame, child, q, lin = decode_odometry(msg.data)
            v.append(odometry_velocity(lin, q, child, frame))
            t.append(stamp)
        except ValueError as exc:
            skipped += 1
            detail = detail or f"message at log time {msg.log_time} ns: {exc}"
    if name is None:
        known = sorted({c.topic for c in reader.channels.values()})
        raise ValueError(f"{path}: no messages on odometry topic {topic!r} (topics: "
                         f"{', '.join(known) or 'none'})")
    if not t:
        raise ValueError(f"{path}: no usable message on {name}: {detail}")
    return OdometryVelocities(name, np.array(t, dtype=np.int64),
                              np.array(v, dtype=np.float64).reshape(-1, 3), skipped, detail)
