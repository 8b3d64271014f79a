"""Array-wide CDR layouts and batch builders: Imu, QuaternionStamped, Odometry, JointState.

Each of these messages has a fixed serialized size once its strings (frame ids, joint
names) and the number of joints are fixed, so a batch of serialized messages is a numpy
structured array: one record per message, the fields at fixed byte offsets
(:class:`CdrLayout` computes them).  Layout of Imu and QuaternionStamped (XCDR1, little
endian, as rclpy/Fast DDS write it):

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
QuaternionStamped: quaternion (x, y, z, w).  MagneticField:
magnetic_field (x, y, z) tesla, magnetic_field_covariance[9].  Odometry: child_frame_id, pose (position,
orientation, covariance[36]), twist (linear, angular, covariance[36]).  JointState:
name[], position[], velocity[], effort[] (sequences: uint32 count, then the elements).

:class:`MessageBatch` holds N messages of one topic as columns (what the MCAP writer
encodes chunk by chunk); :func:`imu_batch`, :func:`quaternion_stamped_batch`,
:func:`odometry_batch` and :func:`joint_state_batch` build and validate them.

Written by hand because no library decodes CDR array-wide: per-message decoders
(rclpy, mcap-ros2-support) run at tens of thousands of messages per second in Python.
The tests check every field against rclpy's own (de)serialization.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

import numpy as np

from gyro_attitude.core.attitude.validation import NO_ESTIMATE

__all__ = [
    "IMU_TYPE",
    "QUATERNION_STAMPED_TYPE",
    "ODOMETRY_TYPE",
    "MAGNETIC_FIELD_TYPE",
    "JOINT_STATE_TYPE",
    "CdrLayout",
    "ImuCdr",
    "QuaternionStampedCdr",
    "TransformCdr",
    "header_body_offset",
    "CDR_LE_HEADER",
    "MESSAGE_RECORD_PREFIX",
    "message_record_dtype",
    "split_stamp",
    "join_stamp",
    "BODY_FIELDS",
    "MessageBatch",
    "imu_batch",
    "quaternion_stamped_batch",
    "magnetic_field_batch",
    "odometry_batch",
    "joint_state_batch",
]

IMU_TYPE = "sensor_msgs/msg/Imu"
QUATERNION_STAMPED_TYPE = "geometry_msgs/msg/QuaternionStamped"
ODOMETRY_TYPE = "nav_msgs/msg/Odometry"
MAGNETIC_FIELD_TYPE = "sensor_msgs/msg/MagneticField"
JOINT_STATE_TYPE = "sensor_msgs/msg/JointState"
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
    MAGNETIC_FIELD_TYPE: (("magnetic_field", 3), ("magnetic_field_covariance", 9)),
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


class CdrLayout:
    """Field offsets of one serialized message (encapsulation header included), built
    field by field with XCDR1 alignment counted from offset 4 (after the header)."""

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
        """A CDR string (uint32 length including the NUL, the bytes); returns the bytes."""
        if not isinstance(text, str):
            raise ValueError(f"{name} must be a str, got {type(text).__name__}")
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

    def header(self, frame_id: str) -> bytes:
        """std_msgs/Header: stamp sec, nanosec, frame_id; returns the frame_id bytes."""
        self.i32("sec")
        self.u32("nanosec")
        return self.string("frame_id", frame_id)

    def size(self) -> int:
        """Serialized size: Fast DDS pads the payload to a multiple of 8 after the header
        (rclpy's serialize_message returns those bytes too)."""
        self._align(8)
        return self.off


def _fields(type_name: str, frame_id: str, base: int) -> tuple[list, int]:
    """Fields of Imu or QuaternionStamped at ``base`` and the message size."""
    if type_name not in BODY_FIELDS:
        raise ValueError(f"no array codec for {type_name!r}; have {sorted(BODY_FIELDS)}")
    _frame_bytes(frame_id)
    lay = CdrLayout()
    lay.header(frame_id)
    for name, count in BODY_FIELDS[type_name]:
        lay.doubles(name, count)
    size = lay.size()
    return [(n, f, base + o) for n, f, o in lay.fields], size


_RECORD_PREFIX_FIELDS = [
    ("opcode", "u1", 0),
    ("record_length", "<u8", 1),
    ("channel_id", "<u2", 9),
    ("sequence", "<u4", 11),
    ("log_time", "<u8", 15),
    ("publish_time", "<u8", 23),
]


def _record_dtype(payload_fields: list, payload_size: int, itemsize: int | None) -> np.dtype:
    """MCAP Message record dtype around a payload whose fields start at offset 0."""
    fields = [(n, f, MESSAGE_RECORD_PREFIX + o) for n, f, o in payload_fields]
    size = MESSAGE_RECORD_PREFIX + payload_size
    if itemsize is not None and itemsize < size:
        raise ValueError(f"itemsize {itemsize} is smaller than the record ({size} bytes)")
    return _make_dtype(_RECORD_PREFIX_FIELDS + fields, size if itemsize is None else itemsize)


def message_record_dtype(type_name: str, frame_id: str, itemsize: int | None = None) -> np.dtype:
    """Structured dtype of one MCAP Message record carrying this message (Imu or
    QuaternionStamped).

    ``itemsize`` > record size gives a strided view over records interleaved with others
    (the extra bytes belong to the other records).
    """
    fields, size = _fields(type_name, frame_id, 0)
    return _record_dtype(fields, size, itemsize)


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


def _times(value, n: int, name: str, default: np.ndarray) -> np.ndarray:
    if value is None:
        return default
    a = np.asarray(value)
    if a.shape != (n,) or a.dtype.kind not in "iu":
        raise ValueError(f"{name} must be integer ns of shape ({n},), got {a.dtype} {a.shape}")
    if n and a.min() < 0:
        raise ValueError(f"{name} must be non-negative (MCAP times are unsigned)")
    return a.astype(np.int64, copy=False)


def _rows(value, n: int, width: int, name: str, default=None) -> np.ndarray:
    if value is None:
        return np.broadcast_to(np.asarray(default, np.float64), (n, width))
    a = np.asarray(value, dtype=np.float64)
    if a.shape not in ((width,), (n, width)):
        raise ValueError(f"{name} must have shape ({n}, {width}) or ({width},), got {a.shape}")
    return np.broadcast_to(a, (n, width))


@dataclass
class MessageBatch:
    """N messages of one fixed-layout topic as columns, for chunk-wide encoding.

    ``columns`` maps payload fields to arrays of N rows: the body fields of ``type_name``
    ((N, w) float64, possibly broadcast views) and, for types with more strings or
    sequences than the header's, their constant length, count and text fields (broadcast,
    stride 0, so the writer sets them once per buffer).  ``layout`` is ``(fields, size)``
    of the payload (offsets from its start); ``None`` means the fixed Imu /
    QuaternionStamped layout of :data:`BODY_FIELDS`.  Fields in neither stay 0 (the
    padding, and zero covariances).  Times are int64 ns."""

    topic: str
    type_name: str
    frame_id: str
    stamp_ns: np.ndarray
    log_time_ns: np.ndarray
    publish_time_ns: np.ndarray
    columns: dict
    layout: tuple[list, int] | None = None

    def __len__(self) -> int:
        return int(self.stamp_ns.shape[0])

    def _payload_layout(self) -> tuple[list, int]:
        return self.layout if self.layout is not None else _fields(self.type_name,
                                                                   self.frame_id, 0)

    def record_dtype(self) -> np.dtype:
        """Structured dtype of the MCAP Message record of one message of this batch."""
        return _record_dtype(*self._payload_layout(), None)

    def payloads(self) -> np.ndarray:
        """``(N, size)`` uint8: the serialized CDR messages, one per row (for per-message
        writers and tests; the MCAP writer builds records without this copy)."""
        fields, size = self._payload_layout()
        recs = np.zeros(len(self), dtype=_make_dtype(fields, size))
        frame = _frame_bytes(self.frame_id)
        recs["encapsulation"] = CDR_LE_HEADER_U32
        recs["frame_id_len"] = len(frame)
        recs["frame_id"] = frame
        recs["sec"], recs["nanosec"] = split_stamp(self.stamp_ns)
        for name, arr in self.columns.items():
            recs[name] = arr
        return recs.view(np.uint8).reshape(len(self), size)

    def take(self, order: np.ndarray) -> MessageBatch:
        """The batch with its messages in ``order`` (a permutation)."""
        return MessageBatch(self.topic, self.type_name, self.frame_id, self.stamp_ns[order],
                            self.log_time_ns[order], self.publish_time_ns[order],
                            {k: v[order] for k, v in self.columns.items()}, self.layout)

    def constant_columns(self) -> list[str]:
        """Body fields that are one value broadcast to every message (stride 0)."""
        return [k for k, v in self.columns.items() if len(self) and v.strides[0] == 0]

    def fill(self, recs: np.ndarray, lo: int, hi: int, skip=()) -> None:
        """Write messages ``lo:hi`` into structured records (the header constants, and the
        body fields in ``skip``, are set by the caller once per buffer): stamp, times and
        the body fields."""
        sec, nsec = split_stamp(self.stamp_ns[lo:hi])
        recs["sec"] = sec
        recs["nanosec"] = nsec
        recs["log_time"] = self.log_time_ns[lo:hi]
        recs["publish_time"] = self.publish_time_ns[lo:hi]
        for name, arr in self.columns.items():
            if name not in skip:
                recs[name] = arr[lo:hi]


def _batch(topic, type_name, frame_id, stamp_ns, log_time_ns, publish_time_ns,
           columns, layout=None) -> MessageBatch:
    _frame_bytes(frame_id)
    stamps = np.asarray(stamp_ns)
    if stamps.ndim != 1 or stamps.dtype.kind not in "iu":
        raise ValueError(f"stamp_ns must be 1-D integer ns, got {stamps.dtype} {stamps.shape}")
    n = stamps.shape[0]
    split_stamp(stamps)  # range check of the seconds
    stamps = stamps.astype(np.int64, copy=False)
    log = _times(log_time_ns, n, "log_time_ns", stamps)
    if n and log.min() < 0:
        raise ValueError("log_time_ns must be non-negative (MCAP times are unsigned)")
    pub = _times(publish_time_ns, n, "publish_time_ns", log)
    return MessageBatch(topic, type_name, frame_id, stamps, log, pub, columns, layout)


def imu_batch(topic: str, stamp_ns, angular_velocity, linear_acceleration=None,
              orientation=None, *, frame_id: str = "imu_link", orientation_covariance=None,
              angular_velocity_covariance=None, linear_acceleration_covariance=None,
              log_time_ns=None, publish_time_ns=None) -> MessageBatch:
    """N ``sensor_msgs/msg/Imu`` messages from arrays.

    ``stamp_ns`` (N,) int ns -> header.stamp (and log/publish time unless given);
    ``angular_velocity`` (N, 3) rad/s; ``linear_acceleration`` (N, 3) m/s² specific force or
    None (zeros, covariance[0] = -1); ``orientation`` (N, 4) x, y, z, w or None (identity,
    covariance[0] = -1: "no estimate"); covariances (N, 9) or (9,), default all zeros
    ("unknown") for the fields that are given.
    """
    n = np.shape(stamp_ns)[0] if np.ndim(stamp_ns) == 1 else -1
    no_estimate = np.zeros(9)
    no_estimate[0] = NO_ESTIMATE  # REP-145
    columns = {
        "orientation": _rows(orientation, n, 4, "orientation", [0.0, 0.0, 0.0, 1.0]),
        "orientation_covariance": _rows(orientation_covariance, n, 9, "orientation_covariance",
                                        no_estimate if orientation is None else np.zeros(9)),
        "angular_velocity": _rows(angular_velocity, n, 3, "angular_velocity"),
        "angular_velocity_covariance": _rows(angular_velocity_covariance, n, 9,
                                             "angular_velocity_covariance", np.zeros(9)),
        "linear_acceleration": _rows(linear_acceleration, n, 3, "linear_acceleration",
                                     np.zeros(3)),
        "linear_acceleration_covariance": _rows(
            linear_acceleration_covariance, n, 9, "linear_acceleration_covariance",
            no_estimate if linear_acceleration is None else np.zeros(9)),
    }
    return _batch(topic, IMU_TYPE, frame_id, stamp_ns, log_time_ns, publish_time_ns, columns)


def quaternion_stamped_batch(topic: str, stamp_ns, quaternion, *, frame_id: str = "map",
                             log_time_ns=None, publish_time_ns=None) -> MessageBatch:
    """N ``geometry_msgs/msg/QuaternionStamped`` (x, y, z, w) messages from arrays."""
    n = np.shape(stamp_ns)[0] if np.ndim(stamp_ns) == 1 else -1
    columns = {"quaternion": _rows(quaternion, n, 4, "quaternion")}
    return _batch(topic, QUATERNION_STAMPED_TYPE, frame_id, stamp_ns, log_time_ns,
                  publish_time_ns, columns)


def magnetic_field_batch(topic: str, stamp_ns, magnetic_field, *, frame_id: str = "imu_link",
                         magnetic_field_covariance=None, log_time_ns=None,
                         publish_time_ns=None) -> MessageBatch:
    """N ``sensor_msgs/msg/MagneticField`` messages: ``magnetic_field`` (N, 3) tesla,
    covariance (N, 9) or (9,) tesla², default all zeros ("unknown", REP-145)."""
    n = _n_stamps(stamp_ns)
    columns = {"magnetic_field": _rows(magnetic_field, n, 3, "magnetic_field"),
               "magnetic_field_covariance": _rows(magnetic_field_covariance, n, 9,
                                                  "magnetic_field_covariance", np.zeros(9))}
    return _batch(topic, MAGNETIC_FIELD_TYPE, frame_id, stamp_ns, log_time_ns,
                  publish_time_ns, columns)


def _n_stamps(stamp_ns) -> int:
    return np.shape(stamp_ns)[0] if np.ndim(stamp_ns) == 1 else -1


def _constant(value, n: int, dtype: str) -> np.ndarray:
    """One value broadcast to ``n`` rows (stride 0: the writer sets it once per buffer)."""
    return np.broadcast_to(np.array(value, dtype=dtype), (max(n, 0),))


def odometry_batch(topic: str, stamp_ns, position, orientation, linear_velocity,
                   angular_velocity, *, frame_id: str = "map", child_frame_id: str = "base_link",
                   log_time_ns=None, publish_time_ns=None) -> MessageBatch:
    """N ``nav_msgs/msg/Odometry`` messages from arrays (covariances zero).

    ``position`` (N, 3) and ``orientation`` (N, 4) x, y, z, w in ``frame_id``; twist
    ``linear_velocity``, ``angular_velocity`` (N, 3) in ``child_frame_id``."""
    n = _n_stamps(stamp_ns)
    lay = CdrLayout()
    lay.header(frame_id)
    child = lay.string("child_frame_id", child_frame_id)
    lay.doubles("position", 3)
    lay.doubles("orientation", 4)
    lay.doubles("pose_covariance", 36)
    lay.doubles("linear", 3)
    lay.doubles("angular", 3)
    lay.doubles("twist_covariance", 36)
    size = lay.size()
    columns = {
        "child_frame_id_len": _constant(len(child), n, "<u4"),
        "child_frame_id": _constant(child, n, f"S{len(child)}"),
        "position": _exact_rows(position, n, 3, "position"),
        "orientation": _exact_rows(orientation, n, 4, "orientation"),
        "linear": _exact_rows(linear_velocity, n, 3, "linear_velocity"),
        "angular": _exact_rows(angular_velocity, n, 3, "angular_velocity"),
    }
    return _batch(topic, ODOMETRY_TYPE, frame_id, stamp_ns, log_time_ns, publish_time_ns,
                  columns, (lay.fields, size))


def joint_state_batch(topic: str, stamp_ns, names, positions, velocities, *,
                      frame_id: str = "", log_time_ns=None,
                      publish_time_ns=None) -> MessageBatch:
    """N ``sensor_msgs/msg/JointState`` messages (no effort) of the same joints.

    ``names``: the k >= 1 joint names; ``positions``, ``velocities`` (N, k)."""
    if isinstance(names, str) or not all(isinstance(x, str) for x in names):
        raise ValueError("joint names must be a sequence of str")
    names = list(names)
    if not names:
        raise ValueError("a JointState batch needs at least one joint name")
    n = _n_stamps(stamp_ns)
    k = len(names)
    lay = CdrLayout()
    lay.header(frame_id)
    lay.u32("name_count")
    encoded = [lay.string(f"name{i}", name) for i, name in enumerate(names)]
    lay.u32("position_count")
    lay.doubles("position", k)
    lay.u32("velocity_count")
    lay.doubles("velocity", k)
    lay.u32("effort_count")  # 0: no effort
    size = lay.size()
    columns = {"name_count": _constant(k, n, "<u4")}
    for i, b in enumerate(encoded):
        columns[f"name{i}_len"] = _constant(len(b), n, "<u4")
        columns[f"name{i}"] = _constant(b, n, f"S{len(b)}")
    columns["position_count"] = _constant(k, n, "<u4")
    columns["velocity_count"] = _constant(k, n, "<u4")
    columns["position"] = _exact_rows(positions, n, k, "positions")
    columns["velocity"] = _exact_rows(velocities, n, k, "velocities")
    return _batch(topic, JOINT_STATE_TYPE, frame_id, stamp_ns, log_time_ns, publish_time_ns,
                  columns, (lay.fields, size))


def _exact_rows(value, n: int, width: int, name: str) -> np.ndarray:
    a = np.asarray(value, dtype=np.float64)
    if a.shape != (n, width):
        raise ValueError(f"{name} must have shape ({n}, {width}), got {a.shape}")
    return a


# ---------------------------------------------------------------------------------------
# One serialized Imu read in place, serialized Imu and QuaternionStamped out: the
# attitude_integrator's per-message path at kHz rates. rclpy's deserialize_message builds a
# Python message with numpy covariance arrays, and publish() serializes one back, at tens of
# µs each; the fixed layout of these messages (above) makes both a slice and a struct call.
# Any message that is not the plain little-endian layout (another encapsulation, a length
# that does not add up, a frame_id that is not UTF-8) takes rclpy's path instead, so the
# result is the same message either way (checked byte for byte against rclpy in the tests).

def _double_slices(type_name: str) -> dict[str, slice]:
    """Each body field's slice of the message's float64 values (:data:`BODY_FIELDS` order)."""
    out, k = {}, 0
    for name, count in BODY_FIELDS[type_name]:
        out[name] = slice(k, k + count)
        k += count
    return out


_IMU_SLICES = _double_slices(IMU_TYPE)
_IMU_DOUBLES = _IMU_SLICES["linear_acceleration_covariance"].stop
_ORIENTATION_DOUBLES = _IMU_SLICES["orientation_covariance"].stop  # orientation + covariance
_U32 = struct.Struct("<I")
_STAMP = struct.Struct("<iI")
_QUATERNION = struct.Struct("<4d")
_ORIENTATION = struct.Struct(f"<{_ORIENTATION_DOUBLES}d")


def header_body_offset(frame_len: int) -> int:
    """Offset of the first float64 after a std_msgs/Header whose frame_id takes
    ``frame_len`` bytes (its NUL included): :class:`CdrLayout`'s rule (stamp at 4, the
    string's length at 12, XCDR1 alignment counted from offset 4) in one expression, for a
    per-message parse where building a layout would cost more than the message."""
    return 4 + (12 + frame_len + 7) // 8 * 8


def _plain_framing(raw: bytes, doubles: int) -> tuple[int, int] | None:
    """(frame_id length with its NUL, body offset) of a CDR_LE message made of a Header then
    exactly ``doubles`` doubles, or None when ``raw`` is not laid out so."""
    if len(raw) < 16 + 1 + doubles * 8 or raw[:4] != CDR_LE_HEADER:
        return None
    (frame_len,) = _U32.unpack_from(raw, 12)
    body = header_body_offset(frame_len)
    if frame_len < 1 or body + doubles * 8 != len(raw) or raw[15 + frame_len] != 0:
        return None
    return frame_len, body


class ImuCdr:
    """One serialized ``sensor_msgs/Imu`` read in place (:meth:`parse`), and the same bytes
    with the orientation filled in (:meth:`with_orientation`)."""

    __slots__ = ("raw", "t_ns", "frame_id", "values", "_body")

    @property
    def stamp_cdr(self) -> bytes:
        """header.stamp as serialized (sec int32, nanosec uint32), copied as is."""
        return self.raw[4:12]

    def __init__(self, raw: bytes, t_ns: int, frame_id: str, values: np.ndarray, body: int):
        self.raw = raw
        self.t_ns = t_ns
        self.frame_id = frame_id
        self.values = values  # the 37 float64 of the body, in field order
        self._body = body

    _last_frame: tuple[bytes, str] = (b"", "")  # frame_id bytes -> str, decoded once

    @classmethod
    def parse(cls, raw: bytes) -> ImuCdr | None:
        """The fields of ``raw``, or None when it is not the plain CDR_LE layout."""
        framing = _plain_framing(raw, _IMU_DOUBLES)
        if framing is None:
            return None
        frame_len, body = framing
        frame_bytes = raw[16:15 + frame_len]
        cached = cls._last_frame
        if frame_bytes == cached[0]:
            frame_id = cached[1]
        else:
            try:
                frame_id = frame_bytes.decode("utf-8")
            except UnicodeDecodeError:
                return None
            if "\x00" in frame_id:
                return None
            cls._last_frame = (frame_bytes, frame_id)
        sec, nanosec = _STAMP.unpack_from(raw, 4)
        values = np.frombuffer(raw, np.float64, _IMU_DOUBLES, body).copy()
        return cls(raw, sec * 1_000_000_000 + nanosec, frame_id, values, body)

    @property
    def angular_velocity(self) -> np.ndarray:
        return self.values[_IMU_SLICES["angular_velocity"]]

    @property
    def angular_velocity_covariance(self) -> np.ndarray:
        return self.values[_IMU_SLICES["angular_velocity_covariance"]]

    @property
    def linear_acceleration(self) -> np.ndarray:
        return self.values[_IMU_SLICES["linear_acceleration"]]

    @property
    def linear_acceleration_covariance(self) -> np.ndarray:
        return self.values[_IMU_SLICES["linear_acceleration_covariance"]]

    def with_orientation(self, x: float, y: float, z: float, w: float, covariance) -> bytes:
        """These bytes with ``orientation`` and ``orientation_covariance`` (9) replaced."""
        b = self._body
        raw = self.raw
        return raw[:b] + _ORIENTATION.pack(x, y, z, w, *covariance) + raw[b + _ORIENTATION.size:]


class QuaternionStampedCdr:
    """Serialized ``geometry_msgs/QuaternionStamped`` with one ``frame_id``."""

    __slots__ = ("_head", "_tail")

    def __init__(self, frame_id: str):
        frame = _frame_bytes(frame_id)
        body = header_body_offset(len(frame))
        head_len = 16 + len(frame)
        self._head = _U32.pack(len(frame)) + frame + b"\x00" * (body - head_len)
        self._tail = struct.Struct("<4d")

    def encode(self, stamp_cdr: bytes, x: float, y: float, z: float, w: float) -> bytes:
        """The message with header.stamp ``stamp_cdr`` (8 serialized bytes, e.g.
        :attr:`ImuCdr.stamp_cdr`) and quaternion (x, y, z, w)."""
        return CDR_LE_HEADER + stamp_cdr + self._head + self._tail.pack(x, y, z, w)

    @staticmethod
    def parse(raw: bytes) -> tuple[int, tuple[float, float, float, float]] | None:
        """(header.stamp in ns, (x, y, z, w)) of one serialized message, or None when it is
        not the plain CDR_LE layout (any frame_id)."""
        framing = _plain_framing(raw, 4)
        if framing is None:
            return None
        body = framing[1]
        sec, nanosec = _STAMP.unpack_from(raw, 4)
        return sec * 1_000_000_000 + nanosec, _QUATERNION.unpack_from(raw, body)


class TransformCdr:
    """Serialized ``tf2_msgs/TFMessage`` with one ``geometry_msgs/TransformStamped``: a
    rotation (translation zero) from the frame ``parent`` to a child frame, as a tf2
    ``TransformBroadcaster`` sends it on ``/tf`` (the bytes rclpy writes for it)."""

    __slots__ = ("_parent", "_child", "_middle", "_tail")

    def __init__(self, parent: str):
        self._parent = _frame_bytes(parent)
        self._child: str | None = None
        self._middle = b""
        self._tail = struct.Struct("<7d")

    def _middle_for(self, child: str) -> bytes:
        # XCDR1 alignment counts from the byte after the 4-byte encapsulation header: the
        # body starts with the array's length (4) and the stamp (8), so frame_id's own
        # length sits at 12
        child_b = _frame_bytes(child)
        out = _U32.pack(len(self._parent)) + self._parent
        pos = 16 + len(self._parent)
        out += b"\x00" * (-pos % 4)
        pos += -pos % 4 + 4 + len(child_b)
        out += _U32.pack(len(child_b)) + child_b
        return out + b"\x00" * (-pos % 8)  # the translation's float64s are 8-aligned

    def encode(self, stamp_cdr: bytes, child: str, x: float, y: float, z: float,
               w: float) -> bytes:
        """The message stamped ``stamp_cdr`` (8 serialized bytes, e.g.
        :attr:`ImuCdr.stamp_cdr`), child frame ``child``, rotation (x, y, z, w)."""
        if child != self._child:
            self._middle = self._middle_for(child)
            self._child = child
        return (CDR_LE_HEADER + _ONE + stamp_cdr + self._middle
                + self._tail.pack(0.0, 0.0, 0.0, x, y, z, w))


_ONE = _U32.pack(1)
