"""rosbag2-compatible MCAP writer: chunks, indexes, summary (the file
``ros2 bag record -s mcap`` writes in Jazzy; profile details in :mod:`.rosbag2_profile`).

Messages go into chunks (zstd by default, as rosbag2's MCAP storage; lz4 or none on
request; CRC over the uncompressed records), each chunk followed by its Message Index
records; :meth:`Rosbag2McapWriter.finish` adds the ``rosbag2`` Metadata record, Data End and
the summary (schemas, channels, Statistics, Chunk Indexes, Metadata Index, Summary
Offsets, Footer with the summary CRC).  Schema and Channel records are written straight
into the data section when a topic is added, so a file cut short by a crash still
describes every channel.  Chunks are closed when they reach ``chunk_size`` bytes, when
:meth:`flush` is called and, with ``max_chunk_interval_s``, when the open chunk is older
than that: a killed process loses at most the open chunk.

:meth:`Rosbag2McapWriter.write_batches` writes whole arrays of messages of several topics
(:class:`.cdr_arrays.MessageBatch`) merged by log time into chunks: every reader then sees
the messages in log-time order across channels.  The chunk assembly is written by hand
(not with the ``mcap`` package's Writer) because chunks are built as numpy buffers: a
per-message Python call caps throughput near 10^5 messages per second.
"""

from __future__ import annotations

import os
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import lz4.frame
import numpy as np
import zstandard

from gyro_attitude import __version__
from gyro_attitude.io import cdr_arrays
from gyro_attitude.io.mcap_records import (
    MAGIC,
    MESSAGE_FIXED,
    OP_CHANNEL,
    OP_CHUNK_INDEX,
    OP_MESSAGE,
    OP_METADATA_INDEX,
    OP_SCHEMA,
    OP_STATISTICS,
    RECORD_HEADER,
    chunk_index_record,
    chunk_record_head,
    crc32,
    data_end_record,
    footer_head,
    header_record,
    message_index_record,
    metadata_index_record,
    schema_record,
    statistics_record,
    summary_offset_record,
)
from gyro_attitude.io.rosbag2_profile import (
    PROFILE,
    Rosbag2Topic,
    bag_directory_file,
    full_type_name,
    normalize_topic,
    ros2_schema_record,
    rosbag2_metadata,
    rosbag2_metadata_record,
    write_bag_metadata_yaml,
)

__all__ = ["Rosbag2McapWriter", "normalize_topic", "COMPRESSIONS", "DEFAULT_COMPRESSION"]

COMPRESSIONS = ("", "zstd", "lz4")
DEFAULT_COMPRESSION = "zstd"
DEFAULT_CHUNK_SIZE = 768 * 1024  # libmcap's default, used by rosbag2
_U64_MAX = 2**64 - 1
# Array paths: chunks being built, compressed or written at once (buffer slots), and the
# threads that build and compress them.
_PIPELINE_DEPTH = 4
_BUILD_THREADS = 2


@dataclass
class _OpenChunk:
    buf: bytearray = field(default_factory=bytearray)
    start: int = _U64_MAX
    end: int = 0
    index: dict[int, list] = field(default_factory=dict)  # channel -> [(log_time, offset)]
    opened_at: float = 0.0


def _zstd_compress(records) -> bytes:
    return zstandard.ZstdCompressor(level=1).compress(records)


def merge_offsets(logs: list[np.ndarray], sizes: list[int]) -> list[np.ndarray]:
    """Where every element of several log-time-sorted sequences starts in their merged
    stream, an element of sequence c taking ``sizes[c]`` units (bytes; 1 gives merged
    positions).  The merge is stable, a sequence listed earlier going first among equal
    times: an element's start counts the elements of every other sequence before it, found
    by binary search (O(N log N), without sorting the concatenation)."""
    k = len(logs)
    if k > 1 and all(lc.shape == logs[0].shape and np.array_equal(lc, logs[0]) for lc in logs):
        # Same log times in every sequence (a replay's outputs): a plain round robin.
        stride = sum(sizes)
        return [np.arange(logs[0].shape[0], dtype=np.int64) * stride + sum(sizes[:c])
                for c in range(k)]
    out = []
    for c, lc in enumerate(logs):
        start = np.arange(lc.shape[0], dtype=np.int64) * sizes[c]
        for d, ld in enumerate(logs):
            if d != c:
                before = np.searchsorted(ld, lc, side="right" if d < c else "left")
                start += before * np.int64(sizes[d])
        out.append(start)
    return out


class _MergedChunks:
    """The chunks of one :meth:`Rosbag2McapWriter.write_batches` call: where each message
    goes (byte offset, chunk, sequence number), all computed up front from the batches'
    log times, so that any thread can build any chunk."""

    def __init__(self, batches: list[cdr_arrays.MessageBatch], channels: list[Rosbag2Topic],
                 chunk_size: int):
        self.batches = batches
        self.channel_ids = [ch.id for ch in channels]
        self.dtypes = [b.record_dtype() for b in batches]
        self.constants = [frozenset(b.constant_columns()) for b in batches]
        sizes = [dt.itemsize for dt in self.dtypes]
        # Byte offset of every message in the merged stream, per batch.
        offsets = merge_offsets([b.log_time_ns for b in batches], sizes)
        self.offsets = offsets
        self.total = sum(len(b) for b in batches)
        total_bytes = sum(len(b) * size for b, size in zip(batches, sizes, strict=True))
        # Chunk boundaries: a chunk closes once it reaches chunk_size, i.e. it ends before
        # the first message starting at or after its start + chunk_size (its own first
        # message starts before that, so every chunk holds at least one message).
        # ranges[c][i]: index in batch c of its first message in chunk i.
        chunk_bytes = [0]
        ranges = [[0] for _ in batches]
        while chunk_bytes[-1] < total_bytes:
            target = chunk_bytes[-1] + chunk_size
            nxt = total_bytes
            for off, r in zip(offsets, ranges, strict=True):
                k = int(np.searchsorted(off, target, side="left"))
                r.append(k)
                if k < off.shape[0]:
                    nxt = min(nxt, int(off[k]))
            chunk_bytes.append(nxt)
        self.chunk_bytes = np.asarray(chunk_bytes, dtype=np.int64)
        self.chunk_count = len(chunk_bytes) - 1
        self.ranges = [np.asarray(r, dtype=np.int64) for r in ranges]
        self.max_bytes = int(np.diff(self.chunk_bytes).max())
        self.caps = [min(len(b), self.max_bytes // dt.itemsize + 1)
                     for b, dt in zip(batches, self.dtypes, strict=True)]
        # Sequence numbers count per channel in merged order: a batch alone on its channel
        # numbers its messages base + index (one counting column, sliced per chunk); a
        # channel fed by several batches numbers each message by its rank among them.
        self.counting = np.arange(max(self.caps), dtype=np.uint32)
        self.sequence_base: list[int] = []
        self.sequences: list[np.ndarray | None] = []
        for bi, ch in enumerate(channels):
            shared = [bj for bj, other in enumerate(channels) if other is ch]
            base = ch.sequence
            if len(shared) == 1:
                self.sequence_base.append(base)
                self.sequences.append(None)
                continue
            rank = np.arange(len(batches[bi]), dtype=np.int64)
            for bj in shared:
                if bj != bi:  # messages of the other batch before each (offsets are distinct)
                    rank += np.searchsorted(offsets[bj], offsets[bi])
            self.sequence_base.append(0)
            self.sequences.append(((rank + (base & 0xFFFFFFFF)) & 0xFFFFFFFF)
                                  .astype(np.uint32))
        self.start = min(int(b.log_time_ns[0]) for b in batches)
        self.end = max(int(b.log_time_ns[-1]) for b in batches)

    def new_buffers(self) -> tuple[list[np.ndarray], np.ndarray | None]:
        """One slot: a record buffer per batch (zeroed, its constant fields set once: they
        cover every byte except the CDR padding after frame_id, which so stays 0) and,
        with several batches, the buffer their records are merged into."""
        recs = []
        for b, cid, dt, cap, constants in zip(self.batches, self.channel_ids, self.dtypes,
                                             self.caps, self.constants, strict=True):
            r = np.zeros(cap, dtype=dt)
            frame = b.frame_id.encode("utf-8") + b"\x00"
            r["opcode"] = OP_MESSAGE
            r["record_length"] = dt.itemsize - RECORD_HEADER.size
            r["channel_id"] = cid
            r["encapsulation"] = cdr_arrays.CDR_LE_HEADER_U32
            r["frame_id_len"] = len(frame)
            r["frame_id"] = frame
            for name in constants:
                r[name] = b.columns[name][0]
            recs.append(r)
        merged = np.zeros(self.max_bytes, dtype=np.uint8) if len(self.batches) > 1 else None
        return recs, merged

    def build(self, i: int, buffers) -> tuple[memoryview, int, int, dict[int, np.ndarray]]:
        """Chunk ``i`` into a slot's buffers: (records, start, end, message index)."""
        rec_bufs, merged = buffers
        byte0 = int(self.chunk_bytes[i])
        nbytes = int(self.chunk_bytes[i + 1]) - byte0
        index: dict[int, list] = {}
        start, end = _U64_MAX, 0
        records = None
        for bi, b in enumerate(self.batches):
            lo, hi = int(self.ranges[bi][i]), int(self.ranges[bi][i + 1])
            m = hi - lo
            if m == 0:
                continue
            recs = rec_bufs[bi][:m]
            seq = self.sequences[bi]
            if seq is None:
                # uint32 addition wraps modulo 2^32, as MCAP's sequence field does
                np.add(self.counting[:m], np.uint32((self.sequence_base[bi] + lo) & 0xFFFFFFFF),
                       out=recs["sequence"])
            else:
                recs["sequence"] = seq[lo:hi]
            b.fill(recs, lo, hi, skip=self.constants[bi])
            offs = self.offsets[bi][lo:hi] - byte0
            lt = b.log_time_ns[lo:hi]
            start, end = min(start, int(lt[0])), max(end, int(lt[-1]))
            entries = np.empty((m, 2), dtype=np.uint64)
            entries[:, 0] = lt
            entries[:, 1] = offs
            index.setdefault(self.channel_ids[bi], []).append(entries)
            raw = recs.view(np.uint8).reshape(m, -1)
            if merged is None:
                records = memoryview(raw.reshape(-1))  # one topic: records in place
                continue
            # Scatter whole records to their merged byte offsets.
            out = merged[:nbytes]
            steps = np.diff(offs)
            if m > 1 and (steps == steps[0]).all():
                # evenly interleaved: one strided copy
                np.ndarray((m, raw.shape[1]), np.uint8, buffer=out, offset=int(offs[0]),
                           strides=(int(steps[0]), 1))[:] = raw
            else:
                # one row copy per record through a sliding-window view
                win = np.lib.stride_tricks.sliding_window_view(out, raw.shape[1],
                                                               writeable=True)
                win[offs] = raw
            records = memoryview(out)
        merged_index = {}
        for cid, parts in index.items():
            if len(parts) == 1:
                merged_index[cid] = parts[0]
            else:  # a channel fed by several batches: its entries in file order
                e = np.concatenate(parts)
                merged_index[cid] = e[np.argsort(e[:, 1], kind="stable")]
        return records, start, end, merged_index


class Rosbag2McapWriter:
    """Write a rosbag2 (Jazzy) compatible MCAP file.

    Parameters
    ----------
    path:
        Output ``.mcap`` file, or with ``bag_directory=True`` a directory to create that
        will hold ``<name>_0.mcap`` and ``metadata.yaml`` (it must not exist or be empty).
        Safe replacement of an existing file is the caller's business
        (:mod:`gyro_attitude.io.safe_output`).
    chunk_size:
        Close a chunk once its uncompressed records reach this many bytes.
    compression:
        ``"zstd"`` (default, as rosbag2's MCAP storage), ``"lz4"`` or ``""`` (none).
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
        compression: str = DEFAULT_COMPRESSION,
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
            self.bag_directory = path
            path = bag_directory_file(path)
        else:
            path.parent.mkdir(parents=True, exist_ok=True)
        self.path = path
        self._compressor = None
        if compression == "zstd":
            # A ZstdCompressor must not be shared by threads: one context per chunk.
            self._compressor = _zstd_compress
        elif compression == "lz4":
            self._compressor = lz4.frame.compress
        # Unbuffered: every byte written has left the process when _emit returns, so after
        # a write error (a full disk) the file holds exactly what _pos says, and the last
        # whole record can be found without guessing what a buffer still held.
        self._file = open(path, "wb", buffering=0)  # closed in finish()
        self._pos = 0
        self._whole_pos = 0  # end of the last whole record on disk (see salvage)
        self._whole_counts: dict[int, int] = {}  # channel id -> messages in whole chunks
        self._data_crc = 0
        self._crc_data = bool(data_section_crc)
        self._schemas: dict[str, tuple[int, bytes]] = {}  # type -> (id, record)
        self._channels: dict[str, Rosbag2Topic] = {}
        self._channel_records: list[bytes] = []
        self._chunk_indexes: list[bytes] = []
        self._chunk = _OpenChunk()
        self._chunk_count = 0
        self._message_count = 0
        self._start = _U64_MAX
        self._end = 0
        self._finished = False
        self._emit(MAGIC)
        self._emit(header_record(PROFILE, f"gyro_attitude {__version__}"))
        self._whole_pos = self._pos

    # ----------------------------------------------------------------- plumbing
    def _emit(self, data) -> None:
        view = memoryview(data).cast("B")
        while view:  # a raw write may write less than asked (a disk filling up)
            view = view[self._file.write(view):]
        if self._crc_data:
            self._data_crc = crc32(data, self._data_crc)
        self._pos += len(data)

    def _check_open(self) -> None:
        if self._finished:
            raise ValueError(f"writer for {self.path} is already finished")

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        if exc_type is None:
            self.finish()
        else:
            self.abandon()  # an error mid-way: no summary that would pass for complete
        return False

    # ----------------------------------------------------------------- topics
    def add_topic(self, topic: str, type_name: str, qos_profiles_yaml: str | None = None, *,
                  recorded_schema: tuple[str, bytes, str] | None = None) -> int:
        """Declare ``topic`` of ``type_name`` (``pkg/msg/Type``); returns its channel id.

        Adding the same topic again with the same type returns the existing id.
        ``qos_profiles_yaml`` is the publishers' offered QoS (rosbag2 YAML, see
        :mod:`gyro_attitude.io.qos`); default: one reliable, volatile, keep-last-10 profile.
        ``recorded_schema`` ``(encoding, data, type_hash)``: a topic copied from a recording
        keeps its recorded schema and type hash (the message package need not be installed).
        """
        self._check_open()
        topic = normalize_topic(topic)
        type_name = full_type_name(type_name)
        if topic in self._channels:
            ch = self._channels[topic]
            if ch.type_name != type_name:
                raise ValueError(f"topic {topic} already added with type {ch.type_name}")
            return ch.id
        schema_id = (self._schemas[type_name][0] if type_name in self._schemas
                     else len(self._schemas) + 1)
        if recorded_schema is None:
            ch = Rosbag2Topic.create(len(self._channels) + 1, topic, type_name, schema_id,
                                     qos_profiles_yaml)
        else:
            ch = Rosbag2Topic.recorded(len(self._channels) + 1, topic, type_name, schema_id,
                                       qos_profiles_yaml, recorded_schema[2])
        if type_name not in self._schemas:
            rec = (ros2_schema_record(schema_id, type_name) if recorded_schema is None
                   else schema_record(schema_id, type_name, *recorded_schema[:2]))
            self._schemas[type_name] = (schema_id, rec)
            self._emit(rec)
        rec = ch.channel_record()
        self._channels[topic] = ch
        self._channel_records.append(rec)
        self._emit(rec)
        self._whole_pos = self._pos
        return ch.id

    def _channel(self, topic: str) -> Rosbag2Topic:
        try:
            return self._channels[normalize_topic(topic)]
        except KeyError:
            raise ValueError(f"topic {topic!r} was not added (call add_topic first)") from None

    # ----------------------------------------------------------------- messages
    def write(self, topic: str, serialized_cdr, log_time_ns: int,
              publish_time_ns: int | None = None) -> None:
        """Append one serialized (CDR) message of an added topic (call in log-time order)."""
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

    def _prepare_chunk(self, records) -> tuple[int, object]:
        """(CRC of the uncompressed records, the bytes to store): thread-safe."""
        crc = crc32(records)
        return crc, records if self._compressor is None else self._compressor(records)

    def _write_chunk(self, records, start: int, end: int,
                     index: dict[int, np.ndarray], prepared=None) -> None:
        """Chunk record + its Message Index records; remembers the Chunk Index.

        ``records``: bytes or a byte-format memoryview (the array paths pass a view of
        their record buffer to avoid a copy); ``prepared``: what :meth:`_prepare_chunk`
        returned for them, if it already ran elsewhere."""
        crc, data = self._prepare_chunk(records) if prepared is None else prepared
        chunk_start = self._pos
        self._emit(chunk_record_head(start, end, len(records), crc, self.compression,
                                     len(data)))
        self._emit(data)
        chunk_length = self._pos - chunk_start
        offsets = {}
        counts = {}
        for cid in sorted(index):
            entries = np.ascontiguousarray(index[cid], dtype="<u8").reshape(-1, 2)
            offsets[cid] = self._pos
            counts[cid] = entries.shape[0]
            self._emit(message_index_record(cid, entries.tobytes()))
        self._whole_pos = self._pos
        for cid, n in counts.items():
            self._whole_counts[cid] = self._whole_counts.get(cid, 0) + n
        self._chunk_indexes.append(chunk_index_record(
            start, end, chunk_start, chunk_length, offsets,
            self._pos - chunk_start - chunk_length, self.compression, len(data),
            len(records)))
        self._chunk_count += 1

    # ----------------------------------------------------------------- array paths
    def write_batches(self, batches: list[cdr_arrays.MessageBatch]) -> None:
        """Write message batches of several topics, merged by log time into chunks.

        Within a batch, messages keep their order among equal log times (a batch out of
        log-time order is sorted, stably); among batches, an earlier one goes first at
        equal times.  Sequence numbers count per channel in written order.  An error
        while the chunks are written (disk full, interrupt) is re-raised here after the
        threads have stopped; the file is then abandoned (closed without summary, as a
        crash leaves it: the chunks before the failed one are complete).
        """
        self._check_open()
        batches = [b for b in batches if len(b)]
        for b in batches:
            ch = self._channel(b.topic)
            if ch.type_name != b.type_name:
                raise ValueError(f"topic {ch.topic} has type {ch.type_name}, not {b.type_name}")
        self._close_chunk()  # keep the order: pending per-message records first
        if not batches:
            return
        for i, b in enumerate(batches):
            if (b.log_time_ns[1:] < b.log_time_ns[:-1]).any():
                batches[i] = b.take(np.argsort(b.log_time_ns, kind="stable"))
        channels = [self._channel(b.topic) for b in batches]
        plan = _MergedChunks(batches, channels, self.chunk_size)
        # Each chunk is built (records filled, indexed, merged), CRC'd and compressed by
        # one of a pool of threads into one of a few reused buffer slots (fresh pages per
        # chunk cost page faults), and written, in chunk order, by one writer thread (the
        # only one touching the file until the last chunk is done).  numpy's copies and
        # ufuncs, the CRC, the compressors and file writes release the GIL, so chunks are
        # built and written at once on a multi-core machine; this thread only hands out
        # chunks and waits for a slot to come free (chunk i reuses the slot of chunk
        # i - slots once that one is written).
        slots = _PIPELINE_DEPTH
        buffers: list = [None] * slots
        busy: list = [None] * slots
        stop = threading.Event()  # set on failure: queued chunks are no longer written

        def build(i: int) -> tuple:
            slot = i % slots
            if buffers[slot] is None:
                buffers[slot] = plan.new_buffers()
            records, start, end, index = plan.build(i, buffers[slot])
            return records, start, end, index, self._prepare_chunk(records)

        def write(built) -> None:
            if stop.is_set():
                return
            try:
                records, start, end, index, prepared = built.result()
                self._write_chunk(records, start, end, index, prepared)
            except BaseException:
                stop.set()
                raise

        builders = ThreadPoolExecutor(max_workers=_BUILD_THREADS,
                                      thread_name_prefix="mcap_chunk_build")
        writer = ThreadPoolExecutor(max_workers=1, thread_name_prefix="mcap_chunk_writer")
        try:
            for i in range(plan.chunk_count):
                slot = i % slots
                if busy[slot] is not None:
                    busy[slot].result()  # that slot's chunk is written: reuse the slot
                busy[slot] = writer.submit(write, builders.submit(build, i))
            for f in busy:
                if f is not None:
                    f.result()  # re-raises a write error here
        except BaseException:
            stop.set()
            writer.shutdown(wait=True, cancel_futures=True)
            builders.shutdown(wait=True, cancel_futures=True)
            self.abandon()
            raise
        writer.shutdown(wait=True)
        builders.shutdown(wait=True)
        for b, ch in zip(batches, channels, strict=True):
            ch.sequence += len(b)
            ch.count += len(b)
        self._message_count += plan.total
        self._start = min(self._start, plan.start)
        self._end = max(self._end, plan.end)

    def write_imu_array(self, topic: str, stamp_ns, angular_velocity, linear_acceleration=None,
                        orientation=None, **kwargs) -> None:
        """Write N ``sensor_msgs/msg/Imu`` messages from arrays (arguments of
        :func:`.cdr_arrays.imu_batch`); to interleave with other topics use
        :meth:`write_batches`."""
        self.write_batches([cdr_arrays.imu_batch(topic, stamp_ns, angular_velocity,
                                                 linear_acceleration, orientation, **kwargs)])

    def write_quaternion_stamped_array(self, topic: str, stamp_ns, quaternion, **kwargs) -> None:
        """Write N ``geometry_msgs/msg/QuaternionStamped`` (x, y, z, w) messages from arrays
        (arguments of :func:`.cdr_arrays.quaternion_stamped_batch`)."""
        self.write_batches([cdr_arrays.quaternion_stamped_batch(topic, stamp_ns, quaternion,
                                                                **kwargs)])

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
        return rosbag2_metadata(list(self._channels.values()), self.path.name,
                                self._message_count, self._start, self._end, self.ros_distro)

    def finish(self) -> None:
        """Close the last chunk, write metadata, summary and footer; close the file."""
        if self._finished:
            return
        self._close_chunk()
        meta = self._rosbag2_metadata()
        meta_offset = self._pos
        meta_rec = rosbag2_metadata_record(meta)
        self._emit(meta_rec)
        self._emit(data_end_record(self._data_crc))

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
        group(OP_STATISTICS, [statistics_record(
            self._message_count, len(self._schemas), len(self._channels), 0, 1,
            self._chunk_count, 0 if not self._message_count else self._start, self._end,
            {ch.id: ch.count for ch in self._channels.values()})])
        group(OP_CHUNK_INDEX, self._chunk_indexes)
        group(OP_METADATA_INDEX, [metadata_index_record(meta_offset, len(meta_rec), "rosbag2")])
        summary_offset_start = summary_start + len(summary)
        for opcode, start, length in groups:
            summary.extend(summary_offset_record(opcode, start, length))
        foot = footer_head(summary_start, summary_offset_start)
        summary_crc = crc32(foot, crc32(summary))
        self._file.write(summary)
        self._file.write(foot + summary_crc.to_bytes(4, "little"))
        self._file.write(MAGIC)
        self._file.close()
        self._finished = True
        if self.bag_directory is not None:
            write_bag_metadata_yaml(self.bag_directory, meta)

    @property
    def whole_message_count(self) -> int:
        """Messages in the chunks wholly written so far (what :meth:`salvage` keeps)."""
        return sum(self._whole_counts.values())

    def salvage(self) -> int:
        """After a write error (a full disk): end the file after its last whole record and
        close it; returns the messages kept.

        The file is cut back to the end of the last chunk written whole (with its message
        indexes), then ended by Data End and a Footer saying "no summary" (50 bytes; the cut
        freed at least the failed chunk's bytes): a valid MCAP that every reader reads from
        the start. If even that cannot be written, the file stays cut there, which the
        package's reader recovers as an unfinished recording. A bag directory also gets its
        ``metadata.yaml`` when there is room for it.
        """
        self.abandon()
        tail = data_end_record(0) + footer_head(0, 0) + bytes(4) + MAGIC  # CRC 0: none
        try:
            fd = os.open(self.path, os.O_WRONLY)
        except OSError:
            return self.whole_message_count
        try:
            os.ftruncate(fd, self._whole_pos)
            try:
                view = memoryview(tail)
                while view:
                    view = view[os.pwrite(fd, view, self._whole_pos + len(tail) - len(view)):]
                os.fsync(fd)
            except OSError:
                os.ftruncate(fd, self._whole_pos)
        except OSError:
            pass  # cannot even cut it: the reader recovers the whole chunks at its start
        finally:
            os.close(fd)
        if self.bag_directory is not None:
            for ch in self._channels.values():
                ch.count = self._whole_counts.get(ch.id, 0)
            self._message_count = self.whole_message_count
            try:
                write_bag_metadata_yaml(self.bag_directory, self._rosbag2_metadata())
            except OSError:
                pass  # no room: the .mcap alone is a readable bag directory
        return self.whole_message_count

    def abandon(self) -> None:
        """Close the file without summary (what a crash leaves); for tests and error paths."""
        if not self._finished:
            self._finished = True
            try:
                self._file.close()
            except OSError:
                pass  # the buffered tail could not be written (disk full): given up anyway
