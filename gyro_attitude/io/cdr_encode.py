"""Array-wide CDR encoders for ``nav_msgs/msg/Odometry`` and ``sensor_msgs/msg/JointState``.

Both have a fixed serialized size once their strings (frame ids, joint names) and the
number of joints are fixed, so N messages are one numpy structured array with the fields at
fixed byte offsets (XCDR1 little endian, alignment counted from offset 4 after the
encapsulation header, as rclpy/Fast DDS write it). Written by hand for the same reason as
:mod:`.cdr_arrays`: rclpy serializes a few ten thousand messages per second from Python.
The tests check the size against ``rclpy.serialization.serialize_message`` and every field
by deserializing with rclpy (rclpy leaves its padding bytes uninitialised; ours are 0).
"""

from __future__ import annotations

import numpy as np

from gyro_attitude.io import cdr_arrays

__all__ = ["ODOMETRY_TYPE", "JOINT_STATE_TYPE", "encode_odometry", "encode_joint_state"]

ODOMETRY_TYPE = "nav_msgs/msg/Odometry"
JOINT_STATE_TYPE = "sensor_msgs/msg/JointState"


class _Layout:
    """Builds a structured dtype field by field with CDR alignment (relative to offset 4)."""

    def __init__(self):
        self.fields: list[tuple[str, object, int]] = [("encapsulation", "<u4", 0)]
        self.off = 4

    def _align(self, n: int) -> None:
        rel = self.off - 4
        self.off = 4 + (rel + n - 1) // n * n

    def u32(self, name: str) -> None:
        self._align(4)
        self.fields.append((name, "<u4", self.off))
        self.off += 4

    def i32(self, name: str) -> None:
        self._align(4)
        self.fields.append((name, "<i4", self.off))
        self.off += 4

    def string(self, name: str, text: str) -> bytes:
        b = text.encode("utf-8")
        if b"\x00" in b:
            raise ValueError(f"{name} {text!r} contains a NUL byte")
        b += b"\x00"
        self.u32(f"{name}_len")
        self.fields.append((name, f"S{len(b)}", self.off))
        self.off += len(b)
        return b

    def doubles(self, name: str, count: int) -> None:
        self._align(8)
        self.fields.append((name, ("<f8", (count,)), self.off))
        self.off += 8 * count

    def dtype(self) -> np.dtype:
        # rclpy (Fast DDS) pads the payload to a multiple of 8 after the header; so do we.
        self._align(8)
        f = self.fields
        return np.dtype({"names": [x[0] for x in f], "formats": [x[1] for x in f],
                         "offsets": [x[2] for x in f], "itemsize": self.off})


def _rows(value, n: int, width: int, name: str) -> np.ndarray:
    a = np.asarray(value, dtype=np.float64)
    if a.shape != (n, width):
        raise ValueError(f"{name} must have shape ({n}, {width}), got {a.shape}")
    return a


def _header(lay: _Layout, frame_id: str) -> bytes:
    lay.i32("sec")
    lay.u32("nanosec")
    return lay.string("frame_id", frame_id)


def _buffer(dtype: np.dtype, stamp_ns) -> tuple[np.ndarray, int]:
    stamps = np.asarray(stamp_ns)
    if stamps.ndim != 1:
        raise ValueError(f"stamp_ns must be 1-D, got shape {stamps.shape}")
    sec, nsec = cdr_arrays.split_stamp(stamps)
    # Zeroed so the CDR padding bytes are 0, as rclpy writes them.
    recs = np.zeros(stamps.shape[0], dtype=dtype)
    recs["encapsulation"] = cdr_arrays.CDR_LE_HEADER_U32
    recs["sec"] = sec
    recs["nanosec"] = nsec
    return recs, stamps.shape[0]


def encode_odometry(stamp_ns, frame_id: str, child_frame_id: str, position, orientation,
                    linear_velocity, angular_velocity) -> np.ndarray:
    """``(N, size)`` uint8: N serialized ``nav_msgs/msg/Odometry`` (covariances zero).

    ``position`` (N, 3) in ``frame_id``; ``orientation`` (N, 4) x, y, z, w; twist
    ``linear_velocity``, ``angular_velocity`` (N, 3) in ``child_frame_id``."""
    lay = _Layout()
    frame = _header(lay, frame_id)
    child = lay.string("child_frame_id", child_frame_id)
    lay.doubles("position", 3)
    lay.doubles("orientation", 4)
    lay.doubles("pose_covariance", 36)
    lay.doubles("linear", 3)
    lay.doubles("angular", 3)
    lay.doubles("twist_covariance", 36)
    recs, n = _buffer(lay.dtype(), stamp_ns)
    recs["frame_id_len"] = len(frame)
    recs["frame_id"] = frame
    recs["child_frame_id_len"] = len(child)
    recs["child_frame_id"] = child
    recs["position"] = _rows(position, n, 3, "position")
    recs["orientation"] = _rows(orientation, n, 4, "orientation")
    recs["linear"] = _rows(linear_velocity, n, 3, "linear_velocity")
    recs["angular"] = _rows(angular_velocity, n, 3, "angular_velocity")
    return recs.view(np.uint8).reshape(n, -1)


def encode_joint_state(stamp_ns, frame_id: str, names, positions, velocities) -> np.ndarray:
    """``(N, size)`` uint8: N serialized ``sensor_msgs/msg/JointState`` (no effort).

    ``names``: the k joint names; ``positions``, ``velocities`` (N, k)."""
    names = [str(x) for x in names]
    k = len(names)
    lay = _Layout()
    frame = _header(lay, frame_id)
    lay.u32("name_count")
    encoded = [lay.string(f"name{i}", name) for i, name in enumerate(names)]
    lay.u32("position_count")
    lay.doubles("position", k)
    lay.u32("velocity_count")
    lay.doubles("velocity", k)
    lay.u32("effort_count")
    recs, n = _buffer(lay.dtype(), stamp_ns)
    recs["frame_id_len"] = len(frame)
    recs["frame_id"] = frame
    recs["name_count"] = k
    for i, b in enumerate(encoded):
        recs[f"name{i}_len"] = len(b)
        recs[f"name{i}"] = b
    recs["position_count"] = k
    recs["velocity_count"] = k
    recs["position"] = _rows(positions, n, k, "positions")
    recs["velocity"] = _rows(velocities, n, k, "velocities")
    return recs.view(np.uint8).reshape(n, -1)
