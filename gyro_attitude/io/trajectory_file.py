"""Pose files and topics read into a :class:`~gyro_attitude.core.trajectory.PoseSeries`.

Formats (``timestamp`` in seconds, positions in m in the Earth-fixed local ENU frame at the
scene's origin, ``q`` = qx qy qz qw mapping body vectors into that frame):

- **TUM** text: ``timestamp tx ty tz qx qy qz qw`` per line, whitespace separated, ``#``
  comments and blank lines ignored;
- **CSV** with a header naming the same columns (any order, extra columns ignored; a
  leading ``#`` of the header is allowed);
- a rosbag2 **MCAP** topic (file, or bag directory with one ``.mcap``) of
  ``nav_msgs/msg/Odometry`` (pose.pose), ``geometry_msgs/msg/PoseStamped`` or
  ``tf2_msgs/msg/TFMessage`` (the transforms whose ``child_frame_id`` is the one asked
  for), stamped by the message header, read with the project's reader
  (:class:`~gyro_attitude.io.mcap_reader.McapStreamReader`) in log-time order.

Timestamps are read as exact decimals (an epoch of 1.7e9 s keeps its nanoseconds, which a
float would round to 0.2 µs). Every error is one line naming the file and the line or
message; :func:`~gyro_attitude.core.trajectory.check_poses` then refuses unsorted,
repeated or NaN stamps, non-unit quaternions, a single pose and long gaps.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import stat
from decimal import Decimal, InvalidOperation
from pathlib import Path

import numpy as np

from gyro_attitude.core.trajectory import (
    PoseSeries,
    TrajectoryMotion,
    TrajectoryRequest,
)

__all__ = [
    "read_poses",
    "read_tum",
    "read_csv",
    "read_pose_topic",
    "resolve_trajectory",
    "POSE_TYPES",
    "MAX_POSE_FILE_BYTES",
    "MAX_POSES",
]

#: Largest pose text file read (bytes): a day of 120 Hz poses in TUM is ~0.7 GB.
MAX_POSE_FILE_BYTES = 2 << 30
#: Most poses in one trajectory (a day at 120 Hz is 1.04e7).
MAX_POSES = 50_000_000
#: Rows of a text pose file held as strings at a time (:class:`_Rows`).
TEXT_BLOCK_ROWS = 65_536
COLUMNS = ("timestamp", "tx", "ty", "tz", "qx", "qy", "qz", "qw")
POSE_TYPES = ("nav_msgs/msg/Odometry", "geometry_msgs/msg/PoseStamped", "tf2_msgs/msg/TFMessage")


#: Stamps a pose may carry (ns): the int32 seconds of a ROS ``builtin_interfaces/Time``
#: (the IMU is stamped in the poses' time base), up to 2038-01-19.
MAX_STAMP_NS = (2**31 - 1) * 1_000_000_000


def _stamp_ns(text: str, where: str) -> int:
    whole, dot, frac = text.partition(".")
    if (whole.isascii() and whole.isdigit() and frac.isascii() and (not frac or frac.isdigit())
            and len(frac) <= 9 and len(whole) < 12):
        # the common "seconds.fraction" form, exactly, without Decimal's cost
        ns = int(whole) * 1_000_000_000 + int(frac.ljust(9, "0") or 0)
    else:
        ns = _stamp_decimal(text, where)
    if not 0 <= ns <= MAX_STAMP_NS:
        raise ValueError(f"{where}: timestamp {text[:40]} s is outside [0, {MAX_STAMP_NS // 10**9}]"
                         " s (the int32 seconds of a ROS stamp)")
    return ns


def _stamp_decimal(text: str, where: str) -> int:
    try:
        d = Decimal(text)
    except InvalidOperation:
        raise ValueError(f"{where}: timestamp {text[:40]!r} is not a number") from None
    if not d.is_finite():
        raise ValueError(f"{where}: timestamp {text[:40]!r} is not finite")
    if d.adjusted() > 12:  # beyond any stamp (an exponent of 1e999999999 overflows Decimal's
        return -1          # arithmetic): refused by the caller
    return int((d * 1_000_000_000).to_integral_value())


def _number(text: str, where: str, column: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise ValueError(f"{where}: {column} {text[:40]!r} is not a number") from None


def _open_text(path: Path):
    try:
        st = path.stat()
    except OSError as exc:
        raise ValueError(f"{path}: cannot read: {exc.strerror or exc}") from None
    if not stat.S_ISREG(st.st_mode):
        # a FIFO would block on open, /dev/zero stream NULs without end
        raise ValueError(f"{path}: not a regular file (a pipe or device): give the pose file")
    size = st.st_size
    if size > MAX_POSE_FILE_BYTES:
        raise ValueError(f"{path}: {size} bytes is more than a pose file may hold "
                         f"({MAX_POSE_FILE_BYTES})")
    try:
        # utf-8-sig: a byte-order mark (Windows editors, Excel CSV) is not part of line 1
        return open(path, encoding="utf-8-sig", newline="")
    except OSError as exc:
        raise ValueError(f"{path}: cannot read: {exc.strerror or exc}") from None


def _read_lines(path: Path):
    """``(line number, text)`` of a UTF-8 text file, one line at a time."""
    with _open_text(path) as f:
        try:
            yield from enumerate(f, 1)
        except UnicodeDecodeError as exc:
            raise ValueError(f"{path}: not a text file (byte 0x{exc.object[exc.start]:02x} "
                             "is not UTF-8)") from None


def read_tum(path) -> PoseSeries:
    """A TUM trajectory file (module docstring)."""
    path = Path(path)
    rows = _Rows(path)
    for i, line in _read_lines(path):
        body = line.split("#", 1)[0].strip()
        if not body:
            continue
        parts = body.replace(",", " ").split()
        if len(parts) != 8:
            raise ValueError(f"{path}: line {i}: {len(parts)} values, expected 8 "
                             f"({' '.join(COLUMNS)})")
        rows.add(i, parts[0], parts[1:])
    return rows.series()


class _Rows:
    """The rows of a text pose file, converted to numbers a block of
    :data:`TEXT_BLOCK_ROWS` at a time: as Python strings a row takes ~14x its numbers
    (0.9 GB for a file of 1 M poses, whose arrays are 64 MB), so only one block of them
    is held. numpy converts a block's numbers at once; only when that fails is each row
    converted alone, to name the first bad one."""

    def __init__(self, path: Path):
        self.path = path
        self.count = 0
        self._lines: list[int] = []
        self._stamps: list[str] = []
        self._values: list[list[str]] = []
        self._t: list[np.ndarray] = []
        self._a: list[np.ndarray] = []
        self._labels: list[str] = []

    def add(self, line: int, stamp: str, values: list[str]) -> None:
        """One pose: its line number, stamp text and the 7 numbers' texts (COLUMNS order)."""
        self._lines.append(line)
        self._stamps.append(stamp)
        self._values.append(values)
        self.count += 1
        if self.count > MAX_POSES:
            raise ValueError(f"{self.path}: more than {MAX_POSES} poses")
        if len(self._lines) >= TEXT_BLOCK_ROWS:
            self._convert()

    def _convert(self) -> None:
        if not self._lines:
            return
        path, values = self.path, self._values
        labels = [f"line {i}" for i in self._lines]
        try:
            a = np.array(values, dtype=np.float64).reshape(-1, 7)
        except ValueError:
            for row, where in zip(values, labels, strict=True):
                for x, c in zip(row, COLUMNS[1:], strict=True):
                    _number(x, f"{path}: {where}", c)
            raise
        t = np.array([_stamp_ns(x, f"{path}: {where}")
                      for x, where in zip(self._stamps, labels, strict=True)],
                     dtype=np.int64).reshape(-1)
        self._t.append(t)
        self._a.append(a)
        self._labels += labels
        self._lines, self._stamps, self._values = [], [], []

    def series(self) -> PoseSeries:
        self._convert()
        t = np.concatenate(self._t) if self._t else np.zeros(0, dtype=np.int64)
        a = np.concatenate(self._a) if self._a else np.zeros((0, 7))
        return PoseSeries(t, a[:, :3], a[:, 3:], tuple(self._labels), str(self.path))


def read_csv(path) -> PoseSeries:
    """A CSV pose file with a header naming the columns (module docstring)."""
    import csv

    path = Path(path)
    rows = _Rows(path)
    index = None
    with _open_text(path) as f:
        reader = csv.reader(f)
        try:
            for record in reader:
                i = reader.line_num
                if not record or not "".join(record).strip() or (
                        index is not None and record[0].lstrip().startswith("#")):
                    continue
                if index is None:
                    names = [c.strip().lstrip("#").strip().lower() for c in record]
                    missing = [c for c in COLUMNS if c not in names]
                    if missing:
                        raise ValueError(f"{path}: line {i}: the header must name the columns "
                                         f"{', '.join(COLUMNS)}; missing {', '.join(missing)}")
                    index = [names.index(c) for c in COLUMNS]
                    continue
                if len(record) <= max(index):
                    raise ValueError(f"{path}: line {i}: {len(record)} values, the header has "
                                     f"{max(index) + 1} or more")
                rows.add(i, record[index[0]].strip(), [record[j] for j in index[1:]])
        except UnicodeDecodeError as exc:
            raise ValueError(f"{path}: not a text file (byte 0x{exc.object[exc.start]:02x} "
                             "is not UTF-8)") from None
        except csv.Error as exc:
            raise ValueError(f"{path}: line {reader.line_num}: not CSV: {exc}") from None
    if index is None:
        raise ValueError(f"{path}: empty: no header line")
    return rows.series()


def read_pose_topic(path, topic: str, child_frame_id: str | None = None) -> PoseSeries:
    """The poses of an MCAP topic of one of :data:`POSE_TYPES` (module docstring)."""
    from gyro_attitude.io.mcap_reader import McapStreamReader, resolve_mcap_path

    path = resolve_mcap_path(path)
    if not topic:
        raise ValueError(f"{path}: an MCAP trajectory needs its topic (motion.topic or "
                         "--trajectory-topic)")
    reader = McapStreamReader(path, on_damage="raise")
    t, rows, labels = [], [], []
    msg_type = None
    name = None
    k = 0
    for msg in reader.iter_messages([topic], log_time_order=True):
        name = msg.channel.topic
        k += 1
        where = f"{path}: {name} message {k} (log time {msg.log_time} ns)"
        if msg_type is None:
            type_name = msg.channel.type_name
            if type_name not in POSE_TYPES:
                raise ValueError(f"{path}: topic {name} has type {type_name or 'unknown'}; a "
                                 f"trajectory is read from {', '.join(POSE_TYPES)}")
            if type_name == POSE_TYPES[2] and not child_frame_id:
                raise ValueError(f"{path}: topic {name} is a TFMessage: say which transform "
                                 "(motion.child_frame_id or --child-frame-id)")
            msg_type = type_name
        try:
            m = _typestore().deserialize_cdr(bytes(msg.data), msg_type)
        except Exception as exc:  # the CDR decoder raises plain exceptions on bad bytes
            raise ValueError(f"{where}: does not deserialize as {msg.channel.type_name} "
                             f"({str(exc).splitlines()[0][:80]})") from None
        for stamp, pos, rot in _poses_of(m, child_frame_id):
            t.append(stamp.sec * 1_000_000_000 + stamp.nanosec)
            rows.append([pos.x, pos.y, pos.z, rot.x, rot.y, rot.z, rot.w])
            labels.append(where.split(": ", 1)[1])
        if len(t) > MAX_POSES:
            raise ValueError(f"{path}: more than {MAX_POSES} poses")
    if name is None:
        known = sorted({c.topic for c in reader.channels.values()})
        raise ValueError(f"{path}: no messages on topic {topic!r} (topics: "
                         f"{', '.join(known) or 'none'})")
    if not t and msg_type is not None and child_frame_id:
        raise ValueError(f"{path}: topic {name} has no transform with child_frame_id "
                         f"{child_frame_id!r}")
    a = np.array(rows, dtype=np.float64).reshape(-1, 7)
    return PoseSeries(np.array(t, dtype=np.int64), a[:, :3], a[:, 3:], tuple(labels), str(path))


@functools.lru_cache(maxsize=1)
def _typestore():
    """rosbags' bundled Jazzy message types: decodes the three pose types without a ROS
    install (tf2_msgs is not among the pinned ROS wheels) and without rclpy."""
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_JAZZY)


def _poses_of(m, child_frame_id):
    """(stamp, position, rotation) of one message (several or none for a TFMessage)."""
    if hasattr(m, "transforms"):
        for tf in m.transforms:
            if tf.child_frame_id.lstrip("/") == (child_frame_id or "").lstrip("/"):
                yield tf.header.stamp, tf.transform.translation, tf.transform.rotation
        return
    pose = m.pose.pose if hasattr(m.pose, "pose") else m.pose
    yield m.header.stamp, pose.position, pose.orientation


def _format_of(path: Path, fmt: str | None) -> str:
    if fmt:
        return fmt
    if path.suffix.lower() == ".mcap" or path.is_dir():
        return "mcap"
    return "csv" if path.suffix.lower() == ".csv" else "tum"


def read_poses(path, fmt: str | None = None, topic: str | None = None,
               child_frame_id: str | None = None) -> PoseSeries:
    """Poses from ``path`` in format ``fmt`` (default: from the extension)."""
    path = Path(path)
    if not path.exists():
        raise ValueError(f"trajectory file not found: {path}")
    fmt = _format_of(path, fmt)
    if fmt == "mcap":
        return read_pose_topic(path, topic, child_frame_id)
    if path.is_dir():
        raise ValueError(f"{path}: is a directory, not a {fmt.upper()} pose file")
    return read_csv(path) if fmt == "csv" else read_tum(path)


def resolve_trajectory(spec, base_dir=None, file=None, **options):
    """``spec`` (a SceneSpec) with its trajectory read and fitted.

    ``file`` (``simulate --trajectory``) puts that file under the scene whatever its motion
    was; otherwise ``motion.file`` is read, relative to ``base_dir`` (the scene file's
    directory). ``options`` (``topic``, ``child_frame_id``, ``format``,
    ``position_sigma_m``, ``attitude_sigma_rad``) override the scene's. The IMU is then
    stamped in the poses' own time base: ``start_time_ns`` is the first pose's stamp and
    ``duration_s`` the span they cover.
    """
    req = spec.motion if isinstance(spec.motion, TrajectoryRequest) else TrajectoryRequest()
    if file is not None:
        req = TrajectoryRequest(**{**vars(req), "file": str(file)})
    elif not isinstance(spec.motion, TrajectoryRequest):
        return spec
    given = {k: v for k, v in options.items() if v is not None}
    if given:
        req = TrajectoryRequest(**{**vars(req), **given})
    if req.file is None:
        raise ValueError("motion.file: required value is missing (or give --trajectory)")
    path = Path(req.file)
    if file is None and not path.is_absolute() and base_dir is not None:
        path = Path(base_dir) / path
    poses = read_poses(path, req.format, req.topic, req.child_frame_id)
    ea = spec.earth
    motion = TrajectoryMotion(poses, (ea.latitude_rad, ea.longitude_rad, ea.height_m),
                              req.position_sigma_m, req.attitude_sigma_rad, req.max_gap_s)
    span = motion.span_s
    if not math.isfinite(span) or span <= 0.0:
        raise ValueError(f"{path}: the poses cover no time")
    return dataclasses.replace(spec, motion=motion, motion_type="trajectory",
                               start_time_ns=motion.t0_ns, duration_s=span)
