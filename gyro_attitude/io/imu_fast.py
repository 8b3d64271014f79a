"""Fast array reading of Imu and QuaternionStamped topics from MCAP files.

Fast path: for each chunk, the Message Index gives the offsets of a topic's message
records; with one frame_id the records have one fixed layout
(:func:`gyro_attitude.io.cdr_arrays.message_record_dtype`), so the chunk is read as a
numpy structured array — a zero-copy strided view when the records are evenly spaced
(one topic per chunk, or topics interleaved regularly), else a gather.  Each record is
checked (opcode, record length, channel, CDR little-endian header, frame_id length and
bytes); anything irregular (another frame_id, big-endian CDR, another size) is decoded
per message by rclpy's deserializer instead.  Chunks without a usable index (a file cut
short by a crash) are walked record by record in Python to find the offsets, then decoded
the same way.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from gyro_attitude.io import cdr_arrays
from gyro_attitude.io.cdr_arrays import IMU_TYPE, MAGNETIC_FIELD_TYPE, QUATERNION_STAMPED_TYPE
from gyro_attitude.io.mcap_reader import (
    McapStreamReader,
    bag_files,
    iter_chunk_records,
    match_topic,
)
from gyro_attitude.io.mcap_records import MESSAGE_FIXED, OP_MESSAGE, RECORD_HEADER

__all__ = [
    "ImuArrays",
    "MagneticFieldArrays",
    "QuaternionArrays",
    "read_imu_arrays",
    "read_magnetic_field_arrays",
    "read_quaternion_stamped_arrays",
    "read_topic_arrays",
    "deserialized",
]

_FIELDS = {type_name: dict(fields) for type_name, fields in cdr_arrays.BODY_FIELDS.items()}


@dataclass
class _TopicArrays:
    topic: str
    stamp_ns: np.ndarray
    log_time_ns: np.ndarray
    publish_time_ns: np.ndarray
    frame_id: str
    frame_ids: set[str]
    fast_messages: int
    fallback_messages: int
    damage: str | None

    def __len__(self) -> int:
        return int(self.stamp_ns.shape[0])

    def in_log_time_order(self, empty=np.empty):
        """These messages in log-time order, file order among equal log times: the order
        ``ros2 bag play`` and ``mcap_player`` deliver them (the one order rule of replay and
        player). ``self`` when already in that order (no copy); else the reordered columns
        come from ``empty(shape, dtype)`` (e.g. :meth:`.spool.Spool.empty`)."""
        log = self.log_time_ns
        if log.size < 2 or not (log[1:] < log[:-1]).any():
            return self
        order = np.argsort(log, kind="stable")
        changes = {}
        done: dict[int, np.ndarray] = {}  # an array shared by two fields stays shared
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if isinstance(v, np.ndarray) and v.ndim >= 1 and v.shape[0] == log.size \
                    and v.strides[0] != 0:  # a broadcast constant row stays as it is
                if id(v) not in done:
                    done[id(v)] = np.take(v, order, axis=0, out=empty(v.shape, v.dtype))
                changes[f.name] = done[id(v)]
        return dataclasses.replace(self, **changes)


@dataclass
class ImuArrays(_TopicArrays):
    """All messages of one ``sensor_msgs/msg/Imu`` topic as arrays, in file order
    (:meth:`in_log_time_order` gives them as a player delivers them).

    ``stamp_ns`` header stamps, ``log_time_ns``/``publish_time_ns`` MCAP times (int64 ns;
    the same array for both when every message's are equal, as recorders write them);
    ``orientation`` (N, 4) x, y, z, w; ``angular_velocity`` (N, 3) rad/s;
    ``linear_acceleration`` (N, 3) m/s²; covariances (N, 9) row-major -- when every
    message carries the same covariance (what IMU drivers publish), a read-only broadcast
    view of that row, which costs no memory.  ``frame_id`` is the first message's;
    ``frame_ids`` all seen.  ``damage`` is None for an intact file,
    else what stopped the read (with ``on_damage="warn"``).
    """

    orientation: np.ndarray = field(default=None)
    orientation_covariance: np.ndarray = field(default=None)
    angular_velocity: np.ndarray = field(default=None)
    angular_velocity_covariance: np.ndarray = field(default=None)
    linear_acceleration: np.ndarray = field(default=None)
    linear_acceleration_covariance: np.ndarray = field(default=None)


@dataclass
class QuaternionArrays(_TopicArrays):
    """All messages of one ``geometry_msgs/msg/QuaternionStamped`` topic (x, y, z, w)."""

    quaternion: np.ndarray = field(default=None)


@dataclass
class MagneticFieldArrays(_TopicArrays):
    """All messages of one ``sensor_msgs/msg/MagneticField`` topic: ``magnetic_field`` (N, 3)
    tesla, ``magnetic_field_covariance`` (N, 9)."""

    magnetic_field: np.ndarray = field(default=None)
    magnetic_field_covariance: np.ndarray = field(default=None)


_ARRAY_CLASSES = {IMU_TYPE: ImuArrays, QUATERNION_STAMPED_TYPE: QuaternionArrays,
                  MAGNETIC_FIELD_TYPE: MagneticFieldArrays}


class _Collector:
    def __init__(self, topic: str, type_name: str, fields=None, empty=np.empty):
        self.topic = topic
        self.empty = empty  # allocator of the recording-length columns
        self.type_name = type_name
        all_fields = _FIELDS[type_name]
        if fields is None:
            self.fields = dict(all_fields)
        else:
            unknown = sorted(set(fields) - set(all_fields))
            if unknown:
                raise ValueError(f"{type_name} has no array fields {unknown}; have "
                                 f"{sorted(all_fields)}")
            self.fields = {k: v for k, v in all_fields.items() if k in fields}
        self.parts: list[dict[str, np.ndarray]] = []
        self.out: dict[str, np.ndarray] | None = None  # preallocated (count from summary)
        self.pos = 0
        # Covariance columns are held as one row while every message repeats it (bit for
        # bit): writing 2 x 9 doubles per message into fresh memory was a third of the read.
        self.constant: dict[str, np.ndarray | None] = {
            k: None for k in self.fields if k.endswith("_covariance")}
        self.frame_ids: list[str] = []
        self.fast = 0
        self.fallback = 0
        self._dtypes: dict[str, np.dtype] = {}

    def dtype(self, frame: str, itemsize: int | None = None) -> np.dtype:
        key = (frame, itemsize)
        if key not in self._dtypes:
            self._dtypes[key] = cdr_arrays.message_record_dtype(self.type_name, frame, itemsize)
        return self._dtypes[key]

    def preallocate(self, count: int) -> None:
        """Size the output for ``count`` messages (from the file's summary statistics):
        chunks are then copied straight into place, with no final concatenation."""
        try:
            out = {k: self.empty(count, np.int64)
                   for k in ("stamp_ns", "log_time_ns", "publish_time_ns")}
            for name, width in self.fields.items():
                if name not in self.constant:
                    out[name] = self.empty((count, width), np.float64)
        except OSError:
            # no room for what the summary declares (a disk-backed allocator): the chunks
            # are read as parts, and joined for what they really hold
            return
        self.out = out

    def _room(self, m: int) -> bool:
        if self.out is not None and self.pos + m > len(self.out["stamp_ns"]):
            # The summary's count was wrong (or stale): keep what is in place as a part.
            part = {k: v[:self.pos] for k, v in self.out.items()}
            for name, row in self.constant.items():
                if name not in part:
                    part[name] = self._repeat(name, row, self.pos)
            self.parts.append(part)
            self.out = None
        return self.out is not None

    def _repeat(self, name: str, row, m: int) -> np.ndarray:
        """``row`` as ``m`` rows (a read-only view; no row yet only when ``m`` is 0)."""
        return np.broadcast_to(np.zeros(self.fields[name]) if row is None else row,
                               (m, self.fields[name]))

    def _still_constant(self, name: str, column: np.ndarray) -> bool:
        """Whether ``column`` (m, w) repeats the held row of a constant-candidate field;
        when it does not, the field is materialized from here on (never again held)."""
        if name not in self.constant:
            return False
        row = self.constant[name]
        if row is None:  # the first rows of this topic: hold the first one
            row = self.constant[name] = np.array(column[0], dtype=np.float64)
        bits = row.view(np.uint64)
        if (np.asarray(column, dtype=np.float64).view(np.uint64) == bits).all():
            return True
        # Per message from here on: the rows so far are the held row (parts hold it as
        # views, which result() concatenates).
        del self.constant[name]
        if self.out is not None:
            full = self.empty((len(self.out["stamp_ns"]), self.fields[name]), np.float64)
            full[:self.pos] = row
            self.out[name] = full
        return False

    def add_records(self, recs: np.ndarray) -> None:
        m = len(recs)
        if self._room(m):
            sl = slice(self.pos, self.pos + m)
            o = self.out
            o["stamp_ns"][sl] = recs["sec"]
            o["stamp_ns"][sl] *= 1_000_000_000
            o["stamp_ns"][sl] += recs["nanosec"]
            o["log_time_ns"][sl] = recs["log_time"]
            o["publish_time_ns"][sl] = recs["publish_time"]
            for name in self.fields:
                if not self._still_constant(name, recs[name]):
                    o[name][sl] = recs[name]
            self.pos += m
        else:
            part = {
                "stamp_ns": cdr_arrays.join_stamp(recs["sec"], recs["nanosec"]),
                "log_time_ns": recs["log_time"].astype(np.int64),
                "publish_time_ns": recs["publish_time"].astype(np.int64),
            }
            for name in self.fields:
                part[name] = (self._repeat(name, self.constant[name], m)
                              if self._still_constant(name, recs[name])
                              else np.array(recs[name], dtype=np.float64))
            self.parts.append(part)
        self.fast += m

    def _add_part(self, part: dict[str, np.ndarray]) -> None:
        m = len(part["stamp_ns"])
        for name in list(self.constant):
            if m and self._still_constant(name, part[name]):
                part[name] = self._repeat(name, self.constant[name], m)
        if self._room(m):
            for k, v in self.out.items():
                v[self.pos:self.pos + m] = part[k]
            self.pos += m
        else:
            self.parts.append(part)

    def add_messages(self, msgs: list[tuple[int, int, bytes]]) -> list[str]:
        """Per-message fallback: rclpy deserialization of (log_time, publish_time, data).
        Messages that do not deserialize are left out; returns what was wrong with them."""
        if self.type_name == IMU_TYPE:
            from sensor_msgs.msg import Imu as msg_type
        elif self.type_name == MAGNETIC_FIELD_TYPE:
            from sensor_msgs.msg import MagneticField as msg_type
        else:
            from geometry_msgs.msg import QuaternionStamped as msg_type
        cols: dict[str, list] = {k: [] for k in ("stamp_ns", "log_time_ns", "publish_time_ns",
                                                 *_FIELDS[self.type_name])}
        bad: list[str] = []
        for log, pub, data in msgs:
            m, problem = deserialized(data, msg_type, self.topic, self.type_name, log)
            if problem is not None:
                bad.append(problem)
                continue
            cols["stamp_ns"].append(m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec)
            cols["log_time_ns"].append(log)
            cols["publish_time_ns"].append(pub)
            self.frame_ids.append(m.header.frame_id)
            for name in _FIELDS[self.type_name]:
                cols[name].append(_message_field(m, name))
        part = {k: np.asarray(v, dtype=np.int64) for k, v in cols.items()
                if k in ("stamp_ns", "log_time_ns", "publish_time_ns")}
        for name, width in self.fields.items():
            part[name] = np.asarray(cols[name], dtype=np.float64).reshape(-1, width)
        self._add_part(part)
        self.fallback += len(msgs) - len(bad)
        return bad

    def result(self, damage: str | None):
        keys = ("stamp_ns", "log_time_ns", "publish_time_ns", *self.fields)
        out = {}
        if self.out is not None and self.parts:  # cannot happen: _room() empties out first
            raise AssertionError("preallocated output and parts at once")
        for k in keys:
            if k in self.constant:  # the same row in every message
                n = self.pos if self.out is not None else sum(len(p[k]) for p in self.parts)
                out[k] = self._repeat(k, self.constant[k], n)
            elif self.out is not None:
                out[k] = self.out[k][:self.pos]
            elif self.parts:
                out[k] = _concatenated([p[k] for p in self.parts], self.empty)
            else:
                width = self.fields.get(k)
                out[k] = np.zeros((0,) if width is None else (0, width),
                                  np.int64 if width is None else np.float64)
        if np.array_equal(out["publish_time_ns"], out["log_time_ns"]):
            # what recorders usually write: one array for both (8 bytes a message less)
            out["publish_time_ns"] = out["log_time_ns"]
        cls = _ARRAY_CLASSES[self.type_name]
        return cls(topic=self.topic, frame_id=self.frame_ids[0] if self.frame_ids else "",
                   frame_ids=set(self.frame_ids), fast_messages=self.fast,
                   fallback_messages=self.fallback, damage=damage, **out)


def _concatenated(parts: list[np.ndarray], empty) -> np.ndarray:
    """``np.concatenate(parts)`` into an array from ``empty(shape, dtype)``."""
    shape = (sum(len(p) for p in parts), *parts[0].shape[1:])
    return np.concatenate(parts, out=empty(shape, parts[0].dtype))


def deserialized(data, msg_type, topic: str, type_name: str, log_time: int):
    """``(message, None)``, or ``(None, why)`` when ``data`` does not deserialize as
    ``msg_type`` (a truncated or foreign CDR payload): the one rule of replay and player,
    which skip such a message and name it."""
    from rclpy.serialization import deserialize_message  # lazy: no rclpy at io top

    try:
        return deserialize_message(data, msg_type), None
    except Exception as exc:  # rclpy raises plain exceptions on bad CDR
        return None, (f"{topic}: message at log time {log_time} does not deserialize as "
                      f"{type_name} ({str(exc).splitlines()[0][:80]})")


def _message_field(msg, name: str) -> tuple:
    """A message's array field as a flat tuple (vectors as x, y, z[, w])."""
    value = getattr(msg, name)
    if hasattr(value, "x"):
        return ((value.x, value.y, value.z, value.w) if hasattr(value, "w")
                else (value.x, value.y, value.z))
    return tuple(value)


def _frame_at(records: bytes, off: int) -> str | None:
    """frame_id of the CDR-LE message record at ``off`` (None when it does not parse)."""
    p = off + cdr_arrays.MESSAGE_RECORD_PREFIX
    if p + 16 > len(records) or bytes(records[p:p + 4]) != cdr_arrays.CDR_LE_HEADER:
        return None
    n = int.from_bytes(records[p + 12:p + 16], "little")
    if n < 1 or p + 16 + n > len(records) or records[p + 16 + n - 1] != 0:
        return None
    try:
        return bytes(records[p + 16:p + 16 + n - 1]).decode("utf-8")
    except UnicodeDecodeError:
        return None


def _decode_chunk_channel(col: _Collector, records: bytes, offsets: np.ndarray,
                          cid: int) -> list[str]:
    """Decode the records of channel ``cid`` at ``offsets`` (ascending) of one chunk;
    returns the damage found (records that are not messages, messages that do not decode),
    which is left out."""
    if offsets.size == 0:
        return []
    frame = _frame_at(records, int(offsets[0]))
    ok = np.zeros(offsets.size, dtype=bool)
    recs = None
    if frame is not None:
        dtype = col.dtype(frame)
        size = dtype.itemsize
        inside = offsets + size <= len(records)
        steps = np.diff(offsets)
        if inside.all() and (offsets.size == 1 or (steps[0] >= size and (steps == steps[0]).all())):
            # Evenly spaced records: a zero-copy strided view over the chunk.
            stride = int(steps[0]) if offsets.size > 1 else size
            recs = np.ndarray((offsets.size,), dtype=dtype, buffer=records,
                              offset=int(offsets[0]), strides=(stride,))
        else:
            # Gather rows through a sliding-window view: one fancy index per record.
            buf = np.frombuffer(records, dtype=np.uint8)
            safe = np.where(inside, offsets, 0)
            if len(buf) >= size:
                rows = np.lib.stride_tricks.sliding_window_view(buf, size)[safe]
                recs = np.ascontiguousarray(rows).view(dtype).reshape(-1)
            else:
                recs = np.zeros(offsets.size, dtype)
        fb = frame.encode("utf-8") + b"\x00"
        ok = (inside & (recs["opcode"] == OP_MESSAGE) & (recs["record_length"] == size - 9)
              & (recs["channel_id"] == cid)
              & (recs["encapsulation"] == cdr_arrays.CDR_LE_HEADER_U32)
              & (recs["frame_id_len"] == len(fb)) & (recs["frame_id"] == fb[:-1]))
    if ok.all():
        col.add_records(recs)
        col.frame_ids.append(frame)
        return []
    damage: list[str] = []
    # Irregular records (or a mix): keep the file order, regular ones still array-wide.
    start = 0
    n = offsets.size
    while start < n:
        stop = start
        while stop < n and ok[stop] == ok[start]:
            stop += 1
        if ok[start]:
            col.add_records(recs[start:stop])
            col.frame_ids.append(frame)
        else:
            msgs = []
            for off in offsets[start:stop].tolist():
                if off + RECORD_HEADER.size + MESSAGE_FIXED.size > len(records):
                    damage.append(f"{col.topic}: message index points past the chunk end")
                    continue
                op, length = RECORD_HEADER.unpack_from(records, off)
                body = off + RECORD_HEADER.size
                if op != OP_MESSAGE or length < MESSAGE_FIXED.size \
                        or body + length > len(records):
                    damage.append(f"{col.topic}: message index points at a record that is "
                                  f"not a message of this chunk (offset {off})")
                    continue
                msg_cid, _, log, pub = MESSAGE_FIXED.unpack_from(records, body)
                if msg_cid != cid:
                    damage.append(f"{col.topic}: message index points at a message of "
                                  f"channel {msg_cid} (offset {off})")
                    continue
                msgs.append((log, pub, bytes(records[body + MESSAGE_FIXED.size:
                                                     body + length])))
            damage.extend(col.add_messages(msgs))
        start = stop
    return damage


def read_topic_arrays(path, topics: dict[str, str], *, on_damage: str = "raise",
                      validate_crc: bool = True,
                      progress: Callable[[int, int], None] | None = None,
                      required: bool = True, fields: dict | None = None,
                      empty=np.empty) -> dict:
    """Read several fixed-layout topics in one pass: ``{topic: type_name}`` -> arrays.

    ``path`` an MCAP file or a rosbag2 bag directory (a split bag's files are read in the
    order its ``metadata.yaml`` lists them, as rosbag2 does, and joined).
    ``type_name`` is ``sensor_msgs/msg/Imu`` or ``geometry_msgs/msg/QuaternionStamped``.
    A relative topic name also matches the one recorded topic ending in ``/<name>`` (any
    namespace).  A topic recorded with another type raises ValueError naming both types;
    a topic absent from the file raises ValueError when ``required`` (else it is left out).
    ``progress(bytes_done, bytes_total)`` is called after each chunk.  ``fields``
    (``{topic: names}``) limits what is extracted for a topic (others come back None);
    stamps and times are always read.  ``empty(shape, dtype)`` allocates the columns of a
    topic's length (default ``np.empty``; :meth:`.spool.Spool.empty` keeps them on disk).
    """
    for t, ty in topics.items():
        if ty not in _FIELDS:
            raise ValueError(f"no array reader for {ty!r} (topic {t}); have {sorted(_FIELDS)}")
    if isinstance(path, bytes | bytearray | memoryview):
        return _read_file_arrays(path, topics, on_damage, validate_crc, progress, required,
                                 fields, empty)
    files = bag_files(path)
    if len(files) == 1:
        return _read_file_arrays(files[0], topics, on_damage, validate_crc, progress,
                                 required, fields, empty)
    sizes = [f.stat().st_size for f in files]
    parts: dict[str, list] = {}
    for k, f in enumerate(files):
        done = sum(sizes[:k])

        def part_progress(n, _total, done=done):
            progress(done + n, sum(sizes))

        got = _read_file_arrays(f, topics, on_damage, validate_crc,
                                None if progress is None else part_progress, False, fields,
                                empty)
        for t, a in got.items():
            parts.setdefault(t, []).append(a)
    missing = [t for t in topics if t not in parts]
    if required and missing:
        raise ValueError(f"{path}: no topic {missing[0]!r} in any of its {len(files)} files")
    return {t: _joined(p, empty) for t, p in parts.items()}


def _joined(parts: list, empty=np.empty):
    """One topic's arrays of several files, in file order."""
    if len(parts) == 1:
        return parts[0]
    first = parts[0]
    changes = {}
    joined = {}
    for f in dataclasses.fields(first):
        vals = [getattr(p, f.name) for p in parts]
        if not isinstance(vals[0], np.ndarray):
            continue
        if all(v.ndim == 2 and v.strides[0] == 0 and len(v) for v in vals) and \
                all(np.array_equal(v[0], vals[0][0]) for v in vals):
            n = sum(len(v) for v in vals)  # one constant row in every file: keep it so
            changes[f.name] = np.broadcast_to(vals[0][0], (n, vals[0].shape[1]))
        else:
            key = tuple(id(v) for v in vals)  # log and publish times: one array stays one
            if key not in joined:
                joined[key] = _concatenated(vals, empty)
            changes[f.name] = joined[key]
    return dataclasses.replace(
        first, frame_ids=set().union(*(p.frame_ids for p in parts)),
        fast_messages=sum(p.fast_messages for p in parts),
        fallback_messages=sum(p.fallback_messages for p in parts),
        damage=next((p.damage for p in parts if p.damage), None), **changes)


def _read_file_arrays(path, topics, on_damage, validate_crc, progress, required, fields,
                      empty=np.empty):
    reader = McapStreamReader(path, validate_crc=validate_crc, on_damage=on_damage,
                              reuse_buffers=True)
    total = reader.size
    fields = fields or {}
    collectors = {t: _Collector(t, ty, fields.get(t), empty) for t, ty in topics.items()}
    by_channel: dict[int, _Collector | None] = {}

    def collector_for(cid: int) -> _Collector | None:
        if cid not in by_channel:
            ch = reader.channels.get(cid)
            col = None
            if ch is not None:
                recorded = [c.topic for c in reader.channels.values()]
                for t, c in collectors.items():
                    if match_topic(recorded, t) == ch.topic:
                        if ch.type_name != c.type_name:
                            raise ValueError(f"topic {ch.topic} holds {ch.type_name or '?'}"
                                             f" messages, expected {c.type_name}")
                        if ch.message_encoding != "cdr":
                            raise ValueError(f"topic {ch.topic} has message encoding "
                                             f"{ch.message_encoding!r}, expected 'cdr'")
                        c.topic = ch.topic
                        col = c
            by_channel[cid] = col
        return by_channel[cid]

    summary = reader.summary()
    if summary is not None and summary.message_counts:
        # Pre-size the outputs from the summary's counts, only as far as the declared chunk
        # bytes could hold such messages (a forged count must not allocate).
        recorded = [ch.topic for ch in summary.channels.values()]
        for t, c in collectors.items():
            topic = match_topic(recorded, t)
            cids = [cid for cid, ch in summary.channels.items() if ch.topic == topic]
            count = sum(summary.message_counts.get(cid, 0) for cid in cids)
            if topic is not None and count * c.dtype("").itemsize <= summary.uncompressed_bytes:
                c.preallocate(count)
    # two chunks read ahead: their file reads, decompression and CRC overlap the decoding
    for chunk in reader.iter_chunks(read_ahead=2):
        index = chunk.message_index
        if index is None:
            # No usable index: walk the records once to find each channel's offsets (the
            # reader has cut the chunk at its last whole record).
            offs = _walk_offsets(chunk.records)
            index = {cid: np.stack([np.zeros(len(o), np.uint64), np.asarray(o, np.uint64)], 1)
                     for cid, o in offs.items()}
        for cid, entries in index.items():
            col = collector_for(cid)
            if col is None:
                continue
            offsets = np.sort(entries[:, 1].astype(np.int64), kind="stable")
            for what in _decode_chunk_channel(col, chunk.records, offsets, cid):
                reader._damaged(what, chunk.file_offset)
        if progress is not None:
            progress(chunk.file_offset + 1, total)
    if progress is not None:
        progress(total, total)
    out = {}
    recorded = [ch.topic for ch in reader.channels.values()]
    for t, c in collectors.items():
        if match_topic(recorded, t) is None:
            if required:
                have = sorted(ch.topic for ch in reader.channels.values())
                raise ValueError(f"{reader.path}: no topic {t!r}; topics: {have}")
            continue
        out[t] = c.result(reader.damage)
    return out


def _walk_offsets(records: bytes) -> dict[int, list[int]]:
    """Offsets of every Message record in a chunk, per channel (Python walk)."""
    out: dict[int, list[int]] = {}
    for opcode, pos, body, _ in iter_chunk_records(records):
        if opcode == OP_MESSAGE:
            cid = int.from_bytes(records[body:body + 2], "little")
            out.setdefault(cid, []).append(pos)
    return out


def read_imu_arrays(path, topic: str = "imu/data_raw", *, on_damage: str = "raise",
                    validate_crc: bool = True, progress=None) -> ImuArrays:
    """Every ``sensor_msgs/msg/Imu`` message of ``topic`` as :class:`ImuArrays`."""
    return read_topic_arrays(path, {topic: IMU_TYPE}, on_damage=on_damage,
                             validate_crc=validate_crc, progress=progress)[topic]


def read_quaternion_stamped_arrays(path, topic: str = "truth/attitude", *,
                                   on_damage: str = "raise", validate_crc: bool = True,
                                   progress=None) -> QuaternionArrays:
    """Every ``geometry_msgs/msg/QuaternionStamped`` message of ``topic``."""
    return read_topic_arrays(path, {topic: QUATERNION_STAMPED_TYPE}, on_damage=on_damage,
                             validate_crc=validate_crc, progress=progress)[topic]


def read_magnetic_field_arrays(path, topic: str = "imu/mag", *, on_damage: str = "raise",
                               validate_crc: bool = True, progress=None) -> MagneticFieldArrays:
    """Every ``sensor_msgs/msg/MagneticField`` message of ``topic``."""
    return read_topic_arrays(path, {topic: MAGNETIC_FIELD_TYPE}, on_damage=on_damage,
                             validate_crc=validate_crc, progress=progress)[topic]
