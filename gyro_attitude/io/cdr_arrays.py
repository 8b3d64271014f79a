"""Array-wide CDR codec for ``sensor_msgs/msg/Imu`` and ``geometry_msgs/msg/QuaternionStamped``.

Both messages have a fixed serialized size once the header's ``frame_id`` is fixed, so a
batch of serialized messages is a numpy structured array: one record per message, the
fields at fixed byte offsets.  Layout (XCDR1, little endian, as rclpy/Fast DDS write it):

======  =====================================================================
offset  field
======  =====================================================================
0       encapsulation ``00 01 00 00`` (CDR_LE); alignment counts from offset 4
4       header.stamp.sec ``int32``; 8: header.stamp.nanosec ``uint32``
12      header.frame_id: ``uint32`` length L (including the NUL), L bytes
4+a     ``float64`` fields, a = 12 + L rounded up to a multiple of 8
======  =====================================================================

Imu doubles: orientation (x, y, z, w), orientation_covariance[9], angular_velocity[3],
angular_velocity_covariance[9], linear_acceleration[3], linear_acceleration_covariance[9].
QuaternionStamped: quaternion (x, y, z, w).

Written by hand because no library decodes CDR array-wide: per-message decoders
(rclpy, mcap-ros2-support) run at tens of thousands of messages per second in Python.
The tests check every field against rclpy's own (de)serialization.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "IMU_TYPE",
    "QUATERNION_STAMPED_TYPE",
    "CDR_LE_HEADER",
    "payload_dtype",
    "payload_size",
    "MESSAGE_RECORD_PREFIX",
    "message_record_dtype",
    "split_stamp",
    "join_stamp",
]

IMU_TYPE = "sensor_msgs/msg/Imu"
QUATERNION_STAMPED_TYPE = "geometry_msgs/msg/QuaternionStamped"
CDR_LE_HEADER = b"\x00\x01\x00\x00"
# The 4 encapsulation bytes read as one little-endian uint32.
CDR_LE_HEADER_U32 = int.from_bytes(CDR_LE_HEADER, "little")

BODY_FIELDS = {
    IMU_TYPE: (
        ("orientation", 4),
        ("orientation_covariance", 9),
        ("angular_velocity", 3),
        ("angular_velocity_covariance", 9),
        ("linear_acceleration", 3),
        ("linear_acceleration_covariance", 9),
    ),
    QUATERNION_STAMPED_TYPE: (("quaternion", 4),),
}

# MCAP Message record: opcode u8, record length u64, channel_id u16, sequence u32,
# log_time u64, publish_time u64, then the payload.
MESSAGE_RECORD_PREFIX = 1 + 8 + 2 + 4 + 8 + 8


def _frame_bytes(frame_id: str) -> bytes:
    if not isinstance(frame_id, str):
        raise ValueError(f"frame_id must be a str, got {type(frame_id).__name__}")
    b = frame_id.encode("utf-8")
    if b"\x00" in b:
        raise ValueError(f"frame_id {frame_id!r} contains a NUL byte")
    return b + b"\x00"


def _fields(type_name: str, frame_id: str, base: int) -> tuple[list, int]:
    if type_name not in BODY_FIELDS:
        raise ValueError(f"no array codec for {type_name!r}; have {sorted(BODY_FIELDS)}")
    fb = _frame_bytes(frame_id)
    n = len(fb)
    fields = [
        ("encapsulation", "<u4", base + 0),
        ("sec", "<i4", base + 4),
        ("nanosec", "<u4", base + 8),
        ("frame_id_len", "<u4", base + 12),
        ("frame_id", f"S{n}", base + 16),
    ]
    off = 4 + ((12 + n + 7) // 8) * 8  # first double, 8-aligned relative to offset 4
    for name, count in BODY_FIELDS[type_name]:
        fields.append((name, ("<f8", (count,)), base + off))
        off += 8 * count
    return fields, off


def payload_size(type_name: str, frame_id: str) -> int:
    """Serialized size in bytes (with the 4-byte encapsulation header)."""
    return _fields(type_name, frame_id, 0)[1]


def payload_dtype(type_name: str, frame_id: str) -> np.dtype:
    """Structured dtype of one serialized message (itemsize = :func:`payload_size`)."""
    fields, size = _fields(type_name, frame_id, 0)
    return _make_dtype(fields, size)


def message_record_dtype(type_name: str, frame_id: str, itemsize: int | None = None) -> np.dtype:
    """Structured dtype of one MCAP Message record carrying this message.

    ``itemsize`` > record size gives a strided view over records interleaved with others
    (the extra bytes belong to the other records).
    """
    fields, size = _fields(type_name, frame_id, MESSAGE_RECORD_PREFIX)
    prefix = [
        ("opcode", "u1", 0),
        ("record_length", "<u8", 1),
        ("channel_id", "<u2", 9),
        ("sequence", "<u4", 11),
        ("log_time", "<u8", 15),
        ("publish_time", "<u8", 23),
    ]
    size += MESSAGE_RECORD_PREFIX
    if itemsize is not None and itemsize < size:
        raise ValueError(f"itemsize {itemsize} is smaller than the record ({size} bytes)")
    return _make_dtype(prefix + fields, size if itemsize is None else itemsize)


def _make_dtype(fields: list, itemsize: int) -> np.dtype:
    return np.dtype({
        "names": [f[0] for f in fields],
        "formats": [f[1] for f in fields],
        "offsets": [f[2] for f in fields],
        "itemsize": itemsize,
    })


def split_stamp(t_ns) -> tuple[np.ndarray, np.ndarray]:
    """int64 nanoseconds -> (sec int32, nanosec uint32) as builtin_interfaces/Time.

    Negative times keep nanosec in [0, 1e9) (floor division), like rclpy's Time.to_msg.
    """
    t = np.asarray(t_ns)
    if t.dtype.kind not in "iu":
        raise ValueError(f"stamps must be integer nanoseconds, got dtype {t.dtype}")
    t = t.astype(np.int64)
    sec, nsec = np.divmod(t, 1_000_000_000)
    if sec.size and (sec.min() < -(2**31) or sec.max() >= 2**31):
        raise ValueError("stamp seconds outside the int32 range of builtin_interfaces/Time")
    return sec.astype(np.int32), nsec.astype(np.uint32)


def join_stamp(sec, nanosec) -> np.ndarray:
    """(sec, nanosec) -> int64 nanoseconds."""
    return np.asarray(sec, np.int64) * 1_000_000_000 + np.asarray(nanosec, np.int64)
