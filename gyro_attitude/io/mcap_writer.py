"""rosbag2-compatible MCAP writer (the files ``ros2 bag record -s mcap`` writes in Jazzy).

What goes into the file (compared against real rosbag2 output in the tests):

* header profile ``ros2``; one Schema per message type, encoding ``ros2msg``, data built
  from the installed ``.msg`` files exactly as rosbag2 builds it (:mod:`.ros2_schema`);
* one Channel per topic, message encoding ``cdr``, metadata ``offered_qos_profiles``
  (rosbag2 version-9 YAML, :mod:`.qos`) and ``topic_type_hash`` (``RIHS01_...``);
* messages in chunks (optionally zstd or lz4 compressed, CRC over the uncompressed
  records), each chunk followed by its Message Index records;
* a ``rosbag2`` Metadata record with ``serialized_metadata`` (rosbag2's metadata YAML),
  Data End with the data-section CRC, and the summary: schemas, channels, Statistics,
  Chunk Indexes, Metadata Index, Summary Offsets, Footer (with the summary CRC);
* optionally a bag directory: ``<dir>/<dir>_0.mcap`` plus ``metadata.yaml`` (version 9).

Schema and Channel records are written straight into the data section (outside chunks)
when a topic is added, so a file cut short by a crash still describes every channel.
Chunks are closed when they reach ``chunk_size`` bytes, when :meth:`flush` is called and,
with ``max_chunk_interval_s``, when the open chunk is older than that: a killed process
loses at most the open chunk.

The chunk assembly is written by hand (not with the ``mcap`` package's Writer) because
the array paths (:meth:`write_imu_array`, :meth:`write_quaternion_stamped_array`) build
whole chunks as one numpy structured array: a per-message Python call would cap
throughput near 10^5 messages per second.
"""

from __future__ import annotations

import struct
import time
import zlib
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from gyro_attitude import __version__
from gyro_attitude.io import cdr_arrays
from gyro_attitude.io.mcap_records import (
    CHUNK_FIXED,
    MAGIC,
    MESSAGE_FIXED,
    OP_CHANNEL,
    OP_CHUNK,
    OP_CHUNK_INDEX,
    OP_DATA_END,
    OP_FOOTER,
    OP_HEADER,
    OP_MESSAGE,
    OP_MESSAGE_INDEX,
    OP_METADATA,
    OP_METADATA_INDEX,
    OP_SCHEMA,
    OP_STATISTICS,
    OP_SUMMARY_OFFSET,
    RECORD_HEADER,
    pack_bytes32,
    pack_str,
    pack_str_map,
    record,
)
from gyro_attitude.io.qos import DEFAULT_QOS_YAML, parse_qos_profiles
from gyro_attitude.io.ros2_schema import full_msg_definition, normalize_type_name, type_hash

__all__ = ["Rosbag2McapWriter", "normalize_topic", "COMPRESSIONS"]

COMPRESSIONS = ("", "zstd", "lz4")
DEFAULT_CHUNK_SIZE = 768 * 1024  # libmcap's default, used by rosbag2
_U64_MAX = 2**64 - 1


def normalize_topic(topic: str) -> str:
    """Fully qualified topic name as rosbag2 stores it (leading ``/``)."""
    if not isinstance(topic, str) or not topic.strip("/"):
        raise ValueError(f"topic name must be a non-empty string, got {topic!r}")
    return topic if topic.startswith("/") else "/" + topic


@dataclass
class _Channel:
    id: int
    topic: str
    type_name: str
    schema_id: int
    qos_yaml: str
    type_hash: str
    count: int = 0
    sequence: int = 0


@dataclass
class _OpenChunk:
    buf: bytearray = field(default_factory=bytearray)
    start: int = _U64_MAX
    end: int = 0
    index: dict[int, list] = field(default_factory=dict)  # channel -> [(log_time, offset)]
    opened_at: float = 0.0


class Rosbag2McapWriter:
    """Write a rosbag2 (Jazzy) compatible MCAP file.

    Parameters
    ----------
    path:
        Output ``.mcap`` file, or with ``bag_directory=True`` a directory to create that
        will hold ``<name>_0.mcap`` and ``metadata.yaml`` (it must not exist or be empty).
    chunk_size:
        Close a chunk once its uncompressed records reach this many bytes.
    compression:
        ``""`` (none, rosbag2's reference files), ``"zstd"`` or ``"lz4"``.
    max_chunk_interval_s:
        Also close the open chunk (and flush the file) when a message arrives and the chunk
        is older than this; recorders call :meth:`flush` from a timer as well.
    ros_distro:
        Written into the ``rosbag2`` metadata.
    data_section_crc:
        Also compute the Data End CRC over the whole data section.  Off by default, as in
        libmcap (``enableDataCRC = false``) and so in rosbag2's files (CRC 0 = "not
        computed"); chunk CRCs and the summary CRC are always written.

    Use as a context manager, or call :meth:`finish` (idempotent).  Times are int ns;
    ``log_time`` is the receive time, ``publish_time`` the send time (defaults to log time).
    """

    def __init__(
        self,
        path,
        *,
        bag_directory: bool = False,
        chunk_size: int = DEFAULT_CHUNK_SIZE,
        compression: str = "",
        max_chunk_interval_s: float | None = None,
        ros_distro: str = "jazzy",
        data_section_crc: bool = False,
    ):
        if compression not in COMPRESSIONS:
            raise ValueError(f"compression must be one of {COMPRESSIONS}, got {compression!r}")
        if int(chunk_size) <= 0:
            raise ValueError(f"chunk_size must be positive, got {chunk_size}")
        if max_chunk_interval_s is not None and not max_chunk_interval_s > 0:
            raise ValueError(f"max_chunk_interval_s must be > 0, got {max_chunk_interval_s}")
        self.chunk_size = int(chunk_size)
        self.compression = compression
        self.max_chunk_interval_s = max_chunk_interval_s
        self.ros_distro = ros_distro
        path = Path(path)
        self.bag_directory: Path | None = None
        if bag_directory:
            if path.exists() and (not path.is_dir() or any(path.iterdir())):
                raise ValueError(f"bag directory {path} exists and is not an empty directory")
            path.mkdir(parents=True, exist_ok=True)
            self.bag_directory = path
            path = path / f"{path.name}_0.mcap"
        else:
            path.parent.mkdir(parents=True, exist_ok=True)
        self.path = path
        self._compressor = None
        if compression == "zstd":
            import zstandard

            self._compressor = zstandard.ZstdCompressor(level=1).compress
        elif compression == "lz4":
            import lz4.frame

            self._compressor = lz4.frame.compress
        self._file = open(path, "wb")  # closed in finish()
        self._pos = 0
        self._data_crc = 0
        self._crc_data = bool(data_section_crc)
        self._schemas: dict[str, tuple[int, bytes]] = {}  # type -> (id, record)
        self._channels: dict[str, _Channel] = {}
        self._channel_records: list[bytes] = []
        self._chunk_indexes: list[bytes] = []
        self._chunk = _OpenChunk()
        self._chunk_count = 0
        self._message_count = 0
        self._start = _U64_MAX
        self._end = 0
        self._finished = False
        self._emit(MAGIC)
        self._emit(record(OP_HEADER, pack_str("ros2") + pack_str(f"gyro_attitude {__version__}")))

    # ----------------------------------------------------------------- plumbing
    def _emit(self, data) -> None:
        self._file.write(data)
        if self._crc_data:
            self._data_crc = zlib.crc32(data, self._data_crc)
        self._pos += len(data)

    def _check_open(self) -> None:
        if self._finished:
            raise ValueError(f"writer for {self.path} is already finished")

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        self.finish()
        return False

    # ----------------------------------------------------------------- topics
    def add_topic(self, topic: str, type_name: str, qos_profiles_yaml: str | None = None) -> int:
        """Declare ``topic`` of ``type_name`` (``pkg/msg/Type``); returns its channel id.

        Adding the same topic again with the same type returns the existing id.
        ``qos_profiles_yaml`` is the publishers' offered QoS (rosbag2 YAML, see
        :mod:`gyro_attitude.io.qos`); default: one reliable, volatile, keep-last-10 profile.
        """
        self._check_open()
        topic = normalize_topic(topic)
        pkg, name = normalize_type_name(type_name)
        type_name = f"{pkg}/msg/{name}"
        if topic in self._channels:
            ch = self._channels[topic]
            if ch.type_name != type_name:
                raise ValueError(f"topic {topic} already added with type {ch.type_name}")
            return ch.id
        qos = DEFAULT_QOS_YAML if qos_profiles_yaml is None else qos_profiles_yaml
        parse_qos_profiles(qos)  # validate before anything reaches the file
        if type_name not in self._schemas:
            text = full_msg_definition(type_name).encode("utf-8")
            sid = len(self._schemas) + 1
            rec = record(
                OP_SCHEMA,
                struct.pack("<H", sid) + pack_str(type_name) + pack_str("ros2msg")
                + pack_bytes32(text),
            )
            self._schemas[type_name] = (sid, rec)
            self._emit(rec)
        sid = self._schemas[type_name][0]
        ch = _Channel(len(self._channels) + 1, topic, type_name, sid, qos, type_hash(type_name))
        rec = record(
            OP_CHANNEL,
            struct.pack("<HH", ch.id, sid) + pack_str(topic) + pack_str("cdr")
            + pack_str_map({"offered_qos_profiles": qos, "topic_type_hash": ch.type_hash}),
        )
        self._channels[topic] = ch
        self._channel_records.append(rec)
        self._emit(rec)
        return ch.id

    def _channel(self, topic: str) -> _Channel:
        try:
            return self._channels[normalize_topic(topic)]
        except KeyError:
            raise ValueError(f"topic {topic!r} was not added (call add_topic first)") from None

    # ----------------------------------------------------------------- messages
    def write(self, topic: str, serialized_cdr, log_time_ns: int,
              publish_time_ns: int | None = None) -> None:
        """Append one serialized (CDR) message of an added topic."""
        self._check_open()
        ch = self._channel(topic)
        log_time = int(log_time_ns)
        pub = log_time if publish_time_ns is None else int(publish_time_ns)
        if not (0 <= log_time <= _U64_MAX and 0 <= pub <= _U64_MAX):
            raise ValueError(f"log/publish time must be non-negative int ns, got {log_time}, {pub}")
        data = bytes(serialized_cdr)
        c = self._chunk
        if not c.buf:
            c.opened_at = time.monotonic()
        off = len(c.buf)
        c.buf += RECORD_HEADER.pack(OP_MESSAGE, MESSAGE_FIXED.size + len(data))
        c.buf += MESSAGE_FIXED.pack(ch.id, ch.sequence & 0xFFFFFFFF, log_time, pub)
        c.buf += data
        c.index.setdefault(ch.id, []).append((log_time, off))
        c.start = min(c.start, log_time)
        c.end = max(c.end, log_time)
        ch.sequence += 1
        ch.count += 1
        self._message_count += 1
        self._start = min(self._start, log_time)
        self._end = max(self._end, log_time)
        if len(c.buf) >= self.chunk_size:
            self._close_chunk()
        elif (self.max_chunk_interval_s is not None
              and time.monotonic() - c.opened_at >= self.max_chunk_interval_s):
            self.flush()

    def write_message(self, topic: str, msg, log_time_ns: int,
                      publish_time_ns: int | None = None) -> None:
        """Serialize a ROS message object with rclpy and :meth:`write` it."""
        from rclpy.serialization import serialize_message  # lazy: io has no rclpy at top

        self.write(topic, serialize_message(msg), log_time_ns, publish_time_ns)

    def _close_chunk(self) -> None:
        c = self._chunk
        if not c.buf:
            return
        self._write_chunk(bytes(c.buf), c.start, c.end, {
            cid: np.asarray(entries, dtype=np.uint64) for cid, entries in c.index.items()
        })
        self._chunk = _OpenChunk()

    def _write_chunk(self, records, start: int, end: int,
                     index: dict[int, np.ndarray]) -> None:
        """Chunk record + its Message Index records; remembers the Chunk Index.

        ``records``: bytes or a byte-format memoryview (the array paths pass a view of
        their record buffer to avoid a copy)."""
        crc = zlib.crc32(records)
        data = records if self._compressor is None else self._compressor(records)
        chunk_start = self._pos
        head = CHUNK_FIXED.pack(start, end, len(records), crc) + pack_str(self.compression)
        body_len = len(head) + 8 + len(data)
        self._emit(RECORD_HEADER.pack(OP_CHUNK, body_len) + head + struct.pack("<Q", len(data)))
        self._emit(data)
        chunk_length = self._pos - chunk_start
        offsets = {}
        for cid in sorted(index):
            entries = np.ascontiguousarray(index[cid], dtype="<u8").reshape(-1, 2)
            payload = entries.tobytes()
            offsets[cid] = self._pos
            self._emit(RECORD_HEADER.pack(OP_MESSAGE_INDEX, 2 + 4 + len(payload))
                       + struct.pack("<HI", cid, len(payload)) + payload)
        index_length = self._pos - chunk_start - chunk_length
        omap = b"".join(struct.pack("<HQ", cid, o) for cid, o in offsets.items())
        self._chunk_indexes.append(record(
            OP_CHUNK_INDEX,
            struct.pack("<QQQQ", start, end, chunk_start, chunk_length)
            + struct.pack("<I", len(omap)) + omap
            + struct.pack("<Q", index_length) + pack_str(self.compression)
            + struct.pack("<QQ", len(data), len(records)),
        ))
        self._chunk_count += 1

    # ----------------------------------------------------------------- array paths
    def _write_array(self, topic: str, type_name: str, frame_id: str, stamp_ns,
                     log_time_ns, publish_time_ns, fill) -> None:
        self._check_open()
        ch = self._channel(topic)
        if ch.type_name != type_name:
            raise ValueError(f"topic {ch.topic} has type {ch.type_name}, not {type_name}")
        stamps = np.asarray(stamp_ns)
        if stamps.ndim != 1:
            raise ValueError(f"stamp_ns must be 1-D, got shape {stamps.shape}")
        n = stamps.shape[0]
        sec, nsec = cdr_arrays.split_stamp(stamps)
        log = stamps.astype(np.int64) if log_time_ns is None else np.asarray(log_time_ns)
        pub = log if publish_time_ns is None else np.asarray(publish_time_ns)
        for name, arr in (("log_time_ns", log), ("publish_time_ns", pub)):
            if arr.shape != (n,) or arr.dtype.kind not in "iu":
                raise ValueError(f"{name} must be integer ns of shape ({n},), got "
                                 f"{arr.dtype} {arr.shape}")
            if n and arr.min() < 0:
                raise ValueError(f"{name} must be non-negative (MCAP times are unsigned)")
        self._close_chunk()  # keep the order: pending per-message records first
        if n == 0:
            return
        dtype = cdr_arrays.message_record_dtype(type_name, frame_id)
        rec_size = dtype.itemsize
        per_chunk = max(1, self.chunk_size // rec_size)
        frame = frame_id.encode("utf-8") + b"\x00"
        # Two record buffers, reused for every chunk (fresh pages per chunk cost page
        # faults), so that one is filled here while a worker thread CRCs, compresses and
        # writes the other: numpy's copies, zlib.crc32, the compressors and file writes all
        # release the GIL, so the two overlap on a multi-core machine.  The worker runs
        # chunks in submission order (one thread) and is the only one touching the file
        # until the last chunk is done.  Zeroed once, constant fields set once: the fields
        # cover every byte except the CDR padding after frame_id, which so stays 0.
        bufs = [np.zeros(min(n, per_chunk), dtype=dtype) for _ in range(2)]
        for b in bufs:  # the fields that are the same in every record, set once
            b["opcode"] = OP_MESSAGE
            b["record_length"] = rec_size - 9
            b["channel_id"] = ch.id
            b["encapsulation"] = cdr_arrays.CDR_LE_HEADER_U32
            b["frame_id_len"] = len(frame)
            b["frame_id"] = frame
        busy: list = [None, None]
        worker = ThreadPoolExecutor(max_workers=1, thread_name_prefix="mcap_chunk_writer")
        try:
            for i, lo in enumerate(range(0, n, per_chunk)):
                hi = min(n, lo + per_chunk)
                m = hi - lo
                if busy[i % 2] is not None:
                    busy[i % 2].result()  # that buffer is written out: reuse it
                recs = bufs[i % 2][:m]
                recs["sequence"] = (ch.sequence + np.arange(m, dtype=np.int64)) & 0xFFFFFFFF
                recs["log_time"] = log[lo:hi]
                recs["publish_time"] = pub[lo:hi]
                recs["sec"] = sec[lo:hi]
                recs["nanosec"] = nsec[lo:hi]
                fill(recs, lo, hi)
                ch.sequence += m
                ch.count += m
                lt = log[lo:hi].astype(np.uint64)
                start, end = int(lt.min()), int(lt.max())
                index = np.empty((m, 2), dtype=np.uint64)
                index[:, 0] = lt
                index[:, 1] = np.arange(m, dtype=np.uint64) * rec_size
                busy[i % 2] = worker.submit(self._write_chunk, memoryview(recs.view(np.uint8)),
                                            start, end, {ch.id: index})
                self._message_count += m
                self._start = min(self._start, start)
                self._end = max(self._end, end)
            for f in busy:
                if f is not None:
                    f.result()  # re-raises a write error here
        finally:
            worker.shutdown(wait=True)

    @staticmethod
    def _rows(value, n: int, width: int, name: str, default=None) -> np.ndarray:
        if value is None:
            return np.broadcast_to(np.asarray(default, np.float64), (n, width))
        a = np.asarray(value, dtype=np.float64)
        if a.shape not in ((width,), (n, width)):
            raise ValueError(f"{name} must have shape ({n}, {width}) or ({width},), got {a.shape}")
        return np.broadcast_to(a, (n, width))

    def write_imu_array(self, topic: str, stamp_ns, angular_velocity, linear_acceleration=None,
                        orientation=None, *, frame_id: str = "imu_link",
                        orientation_covariance=None, angular_velocity_covariance=None,
                        linear_acceleration_covariance=None, log_time_ns=None,
                        publish_time_ns=None) -> None:
        """Write N ``sensor_msgs/msg/Imu`` messages from arrays, chunk-wide.

        ``stamp_ns`` (N,) int ns -> header.stamp (and log/publish time unless given);
        ``angular_velocity`` (N, 3) rad/s; ``linear_acceleration`` (N, 3) m/s² specific
        force or None (zeros, covariance[0] = -1); ``orientation`` (N, 4) x, y, z, w or None
        (identity, covariance[0] = -1: "no estimate"); covariances (N, 9) or (9,), default
        all zeros ("unknown") for the fields that are given.
        """
        n = np.shape(stamp_ns)[0] if np.ndim(stamp_ns) == 1 else -1
        no_est = np.zeros(9)
        no_est[0] = -1.0
        cols = {
            "angular_velocity": self._rows(angular_velocity, n, 3, "angular_velocity"),
            "linear_acceleration": self._rows(linear_acceleration, n, 3, "linear_acceleration",
                                              np.zeros(3)),
            "orientation": self._rows(orientation, n, 4, "orientation", [0.0, 0.0, 0.0, 1.0]),
            "orientation_covariance": self._rows(
                orientation_covariance, n, 9, "orientation_covariance",
                no_est if orientation is None else np.zeros(9)),
            "angular_velocity_covariance": self._rows(
                angular_velocity_covariance, n, 9, "angular_velocity_covariance", np.zeros(9)),
            "linear_acceleration_covariance": self._rows(
                linear_acceleration_covariance, n, 9, "linear_acceleration_covariance",
                no_est if linear_acceleration is None else np.zeros(9)),
        }

        def fill(recs, lo, hi):
            for key, arr in cols.items():
                recs[key] = arr[lo:hi]

        self._write_array(topic, cdr_arrays.IMU_TYPE, frame_id, stamp_ns, log_time_ns,
                          publish_time_ns, fill)

    def write_quaternion_stamped_array(self, topic: str, stamp_ns, quaternion, *,
                                       frame_id: str = "map", log_time_ns=None,
                                       publish_time_ns=None) -> None:
        """Write N ``geometry_msgs/msg/QuaternionStamped`` (x, y, z, w) messages, chunk-wide."""
        n = np.shape(stamp_ns)[0] if np.ndim(stamp_ns) == 1 else -1
        quat = self._rows(quaternion, n, 4, "quaternion")

        def fill(recs, lo, hi):
            recs["quaternion"] = quat[lo:hi]

        self._write_array(topic, cdr_arrays.QUATERNION_STAMPED_TYPE, frame_id, stamp_ns,
                          log_time_ns, publish_time_ns, fill)

    # ----------------------------------------------------------------- finishing
    def flush(self) -> None:
        """Close the open chunk and push everything to the operating system."""
        if self._finished:
            return
        self._close_chunk()
        self._file.flush()

    @property
    def message_count(self) -> int:
        return self._message_count

    def topic_counts(self) -> dict[str, int]:
        return {t: ch.count for t, ch in self._channels.items()}

    def _rosbag2_metadata(self) -> dict:
        start = 0 if self._message_count == 0 else self._start
        duration = 0 if self._message_count == 0 else self._end - self._start
        name = self.path.name
        topics = []
        for ch in sorted(self._channels.values(), key=lambda c: c.topic):
            topics.append({
                "topic_metadata": {
                    "name": ch.topic,
                    "type": ch.type_name,
                    "serialization_format": "cdr",
                    "offered_qos_profiles": parse_qos_profiles(ch.qos_yaml),
                    "type_description_hash": ch.type_hash,
                },
                "message_count": ch.count,
            })
        return {
            "version": 9,
            "storage_identifier": "mcap",
            "duration": {"nanoseconds": duration},
            "starting_time": {"nanoseconds_since_epoch": start},
            "message_count": self._message_count,
            "topics_with_message_count": topics,
            "compression_format": "",
            "compression_mode": "",
            "relative_file_paths": [name],
            "files": [{
                "path": name,
                "starting_time": {"nanoseconds_since_epoch": start},
                "duration": {"nanoseconds": duration},
                "message_count": self._message_count,
            }],
            "custom_data": None,
            "ros_distro": self.ros_distro,
        }

    def finish(self) -> None:
        """Close the last chunk, write metadata, summary and footer; close the file."""
        if self._finished:
            return
        self._close_chunk()
        meta = self._rosbag2_metadata()
        meta_text = yaml.safe_dump(meta, sort_keys=False, default_flow_style=False).strip()
        meta_offset = self._pos
        meta_rec = record(OP_METADATA, pack_str("rosbag2")
                          + pack_str_map({"serialized_metadata": meta_text}))
        self._emit(meta_rec)
        self._emit(record(OP_DATA_END, struct.pack("<I", self._data_crc)))

        summary_start = self._pos
        summary = bytearray()
        groups = []  # (opcode, start, length)

        def group(opcode: int, recs: list[bytes]) -> None:
            if recs:
                groups.append((opcode, summary_start + len(summary), sum(map(len, recs))))
                for r in recs:
                    summary.extend(r)

        group(OP_SCHEMA, [rec for _, rec in sorted(self._schemas.values())])
        group(OP_CHANNEL, self._channel_records)
        counts = b"".join(struct.pack("<HQ", ch.id, ch.count) for ch in self._channels.values())
        stats = record(OP_STATISTICS, struct.pack(
            "<QHIIII", self._message_count, len(self._schemas), len(self._channels), 0, 1,
            self._chunk_count) + struct.pack(
            "<QQ", 0 if not self._message_count else self._start, self._end)
            + struct.pack("<I", len(counts)) + counts)
        group(OP_STATISTICS, [stats])
        group(OP_CHUNK_INDEX, self._chunk_indexes)
        group(OP_METADATA_INDEX, [record(OP_METADATA_INDEX, struct.pack(
            "<QQ", meta_offset, len(meta_rec)) + pack_str("rosbag2"))])
        summary_offset_start = summary_start + len(summary)
        for opcode, start, length in groups:
            summary.extend(record(OP_SUMMARY_OFFSET, struct.pack("<BQQ", opcode, start, length)))
        footer_head = RECORD_HEADER.pack(OP_FOOTER, 20) + struct.pack(
            "<QQ", summary_start, summary_offset_start)
        summary_crc = zlib.crc32(footer_head, zlib.crc32(summary))
        self._file.write(summary)
        self._file.write(footer_head + struct.pack("<I", summary_crc))
        self._file.write(MAGIC)
        self._file.close()
        self._finished = True
        if self.bag_directory is not None:
            doc = {"rosbag2_bagfile_information": meta}
            with open(self.bag_directory / "metadata.yaml", "w", encoding="utf-8") as f:
                yaml.safe_dump(doc, f, sort_keys=False, default_flow_style=False)

    def abandon(self) -> None:
        """Close the file without summary (what a crash leaves); for tests and error paths."""
        if not self._finished:
            self._file.close()
            self._finished = True


