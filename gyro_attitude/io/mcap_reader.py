"""The one MCAP reader (any profile), tolerant of damage and of hostile sizes and counts.

The reader walks the top-level records of the data section in file order (it needs no
summary), so it also reads files a crash left without summary or footer.  Chunks are
decompressed and CRC-checked one at a time (memory stays at one chunk); each chunk comes
with the Message Index records that follow it, which the array decoders
(:mod:`gyro_attitude.io.imu_fast`) use to find message records without walking them.

Descriptive records are parsed by the ``mcap`` package (:func:`.mcap_records.parse_record`).
Chunk decompression, Message Index parsing and the message walk are here, measured: the
``mcap`` package decompresses to whatever size a chunk declares (a 137 kB file declaring
4 GiB of zeros costs 4 GiB and a minute); its plain read loop builds one Python object per
record (606 k messages of the replay benchmark file: 4.3 s, against 1.2 s for this reader
with the array decoders, same run); its Message Index parser loops per entry (12 000
entries: 14 ms, against 0.12 ms with numpy here).

Hostile sizes: every declared length is checked against the bytes that are really there
before anything is allocated; a chunk's uncompressed size must be at most
``max_chunk_bytes`` and at most :data:`MAX_COMPRESSION_RATIO` times its compressed size,
and decompression stops at the declared size.  Counts from the summary are checked against
what the file's bytes can hold.

Read-ahead: ``iter_chunks(read_ahead=n)`` reads, decompresses and CRC-checks up to ``n``
chunks ahead in a worker thread (file reads, zstd/lz4 and the CRC release the GIL) while the
caller decodes the current one; the chunks, the damage records and the errors reach the caller
in the same order as without read-ahead.

Damage: an empty or non-MCAP file raises :class:`McapDamagedError` at once.  Damage inside
the file (a corrupt chunk, CRC mismatch, bad message index, unparsable record, message on
an unknown channel) is skipped and recorded in :attr:`McapStreamReader.damages`; truncation
ends the walk.  With ``on_damage="raise"`` (default) the first damage raises after
everything before it was yielded; with ``"warn"`` the reader keeps everything readable.
"""

from __future__ import annotations

import functools
import heapq
import io
import os
import struct
import threading
from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import lz4.frame
import numpy as np
import zstandard

from gyro_attitude.io.mcap_records import (
    CHUNK_FIXED,
    FOOTER_BODY,
    MAGIC,
    MESSAGE_FIXED,
    MIN_MESSAGE_RECORD,
    OP_ATTACHMENT,
    OP_CHANNEL,
    OP_CHUNK,
    OP_CHUNK_INDEX,
    OP_DATA_END,
    OP_FOOTER,
    OP_HEADER,
    OP_MESSAGE,
    OP_MESSAGE_INDEX,
    OP_METADATA,
    OP_SCHEMA,
    OP_STATISTICS,
    RECORD_HEADER,
    RecordParseError,
    crc32,
    parse_record,
)
from gyro_attitude.io.strict_yaml import load_yaml

__all__ = [
    "McapDamagedError",
    "SchemaInfo",
    "ChannelInfo",
    "RawChunk",
    "RawMessage",
    "SummaryInfo",
    "McapStreamReader",
    "resolve_mcap_path",
    "recorded_topics",
    "bag_files",
    "UnorderedBagError",
    "topic_matches",
    "match_topic",
    "iter_chunk_records",
    "iter_chunk_messages",
    "DEFAULT_MAX_CHUNK_BYTES",
    "MAX_COMPRESSION_RATIO",
]

# A chunk may not declare more uncompressed bytes than this (rosbag2 writes 768 KiB chunks,
# this package 4 MiB; one large message makes a larger chunk, hence the margin).
DEFAULT_MAX_CHUNK_BYTES = 256 * 1024 * 1024
# Read-ahead starts another chunk only while less than this waits for the caller.
READ_AHEAD_BYTES = 32 * 1024 * 1024
# Uncompressed / compressed size of one chunk.  Real recordings stay far below (Imu chunks
# of this package: ~4x with zstd; a chunk of identical messages ~300x); zstd's own limit
# for zeros is ~32000x, which is what a decompression bomb uses.
MAX_COMPRESSION_RATIO = 1000
# The summary section is read whole: a legitimate one holds ~100 bytes per chunk.
MAX_SUMMARY_BYTES = 64 * 1024 * 1024


# A file that ends at a record boundary without Data End and footer: what a writer killed
# mid-recording leaves (every record before it is whole).
UNFINISHED = "file ends without Data End and footer (truncated, or writer killed)"


class McapDamagedError(ValueError):
    """The file is not MCAP, or is damaged at ``offset`` (what precedes it was readable)."""

    def __init__(self, message: str, offset: int | None = None):
        super().__init__(message)
        self.offset = offset


@dataclass(frozen=True)
class SchemaInfo:
    id: int
    name: str
    encoding: str
    data: bytes


@dataclass(frozen=True)
class ChannelInfo:
    id: int
    schema_id: int
    topic: str
    message_encoding: str
    metadata: dict
    schema: SchemaInfo | None

    @property
    def type_name(self) -> str:
        return self.schema.name if self.schema is not None else ""


@dataclass
class RawChunk:
    """One chunk's uncompressed records; ``message_index`` maps channel id -> (k, 2) uint64
    ``(log_time, offset)`` rows, or is None when the index records are missing or damaged.
    Messages written outside any chunk come as a RawChunk with ``loose=True``."""

    records: bytes
    message_start_time: int
    message_end_time: int
    message_index: dict[int, np.ndarray] | None
    file_offset: int
    loose: bool = False


@dataclass(frozen=True)
class RawMessage:
    channel: ChannelInfo
    sequence: int
    log_time: int
    publish_time: int
    data: bytes


@dataclass
class SummaryInfo:
    """What an intact summary section says, checked against the file size.

    ``message_counts``: {channel id: count} from Statistics, only counts the file's bytes can
    hold; ``chunk_starts``: (file offset, message_start_time) of every chunk from the Chunk
    Indexes; ``uncompressed_bytes``: total declared uncompressed chunk bytes (each
    declaration capped as the reader caps it)."""

    channels: dict[int, ChannelInfo] = field(default_factory=dict)
    message_counts: dict[int, int] = field(default_factory=dict)
    chunk_starts: list[tuple[int, int]] = field(default_factory=list)
    uncompressed_bytes: int = 0


def topic_matches(topic: str, wanted: str) -> bool:
    """Topic equality ignoring a leading ``/`` (rosbag2 stores fully qualified names)."""
    return topic.lstrip("/") == wanted.lstrip("/")


def match_topic(recorded: list[str], wanted: str) -> str | None:
    """The recorded topic ``wanted`` names: for a full name (``/imu``) the topic equal to it;
    for a relative name (``imu``) the one recorded topic equal to it up to the leading ``/``
    or ending in ``/<wanted>`` (any namespace).  None if none; ValueError when a relative
    name fits several topics (``/imu`` and ``/robot/imu`` alike: which one was meant
    cannot depend on which channel a file happens to define first)."""
    if wanted.startswith("/"):
        return next((t for t in recorded if topic_matches(t, wanted)), None)
    fits = sorted({t for t in recorded if topic_matches(t, wanted)
                   or t.endswith("/" + wanted)})
    if len(fits) > 1:
        raise ValueError(f"topic {wanted!r} is ambiguous: {fits}; give the full name")
    return fits[0] if fits else None


def recorded_topics(path, *, scan: bool = False) -> dict[str, str] | None:
    """``{topic: type name}`` of a recording (a file or a bag directory's files) from the
    summaries; a file without a usable summary is walked chunk by chunk when ``scan`` (its
    Channel records are in the chunks), else the answer is None (not known without a pass
    over the data)."""
    out: dict[str, str] = {}
    for f in bag_files(path):
        reader = McapStreamReader(f, on_damage="warn")
        summary = reader.summary()
        if summary is not None and summary.channels:
            channels = summary.channels.values()
        elif scan:
            for _ in reader.iter_chunks():
                pass
            channels = reader.channels.values()
        else:
            return None
        out.update({c.topic: c.type_name for c in channels})
    return out


class UnorderedBagError(ValueError):
    """A directory of several ``.mcap`` files and no ``metadata.yaml``: one split bag whose
    order is lost, or separate recordings (``files``: their paths, sorted).  A command that
    takes several recordings adds how to give them so."""

    def __init__(self, directory: Path, files: list[Path]):
        self.directory, self.files = directory, files
        names = ", ".join(f.name for f in files[:3])
        if len(files) > 3:
            names += f" and {len(files) - 3} more"
        super().__init__(
            f"{directory} holds {len(files)} .mcap files ({names}) and no metadata.yaml "
            f"saying they are one bag and in what order: give one of them, or write a split "
            f"bag's metadata.yaml (ros2 bag reindex {directory} -s mcap)")


#: Largest bag ``metadata.yaml`` read (bytes): rosbag2's are a few kB.
MAX_BAG_METADATA_BYTES = 1 << 20


def bag_files(path) -> list[Path]:
    """The MCAP files of a recording, in the order rosbag2 reads them: a ``.mcap`` file
    itself; for a bag directory the ``relative_file_paths`` of its ``metadata.yaml`` (a
    split bag: ``<name>_0.mcap``, ``<name>_1.mcap``, ...), or without metadata its one
    ``.mcap`` file. ``ValueError`` in one line naming what is missing or wrong."""
    p = Path(path)
    if not p.is_dir():
        if not p.exists():
            raise ValueError(f"no such file: {p}")
        if not p.is_file():
            raise ValueError(f"not a regular file: {p}")
        return [p]
    meta = p / "metadata.yaml"
    if not meta.is_file():
        files = sorted(p.glob("*.mcap"))
        if len(files) > 1:
            raise UnorderedBagError(p, files)
        if len(files) != 1:
            raise ValueError(f"bag directory {p} holds 0 .mcap files and no metadata.yaml")
        return files
    try:
        with open(meta, "rb") as f:
            raw = f.read(MAX_BAG_METADATA_BYTES + 1)
        if len(raw) > MAX_BAG_METADATA_BYTES:
            raise ValueError(f"{meta}: larger than {MAX_BAG_METADATA_BYTES} bytes")
        data = load_yaml(raw.decode("utf-8"), str(meta))
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"{meta}: cannot read: {exc}") from None
    info = data.get("rosbag2_bagfile_information") if isinstance(data, dict) else None
    names = info.get("relative_file_paths") if isinstance(info, dict) else None
    if not isinstance(names, list) or not names or \
            not all(isinstance(n, str) and n for n in names):
        raise ValueError(f"{meta}: no rosbag2_bagfile_information.relative_file_paths list")
    files = []
    for name in names:
        f = p / name
        if Path(name).is_absolute() or ".." in Path(name).parts or f.suffix != ".mcap":
            raise ValueError(f"{meta}: {name!r} is not an .mcap file inside the bag directory")
        if not f.is_file():
            raise ValueError(f"{meta} lists {name}, which is not in {p}")
        files.append(f)
    return files


def resolve_mcap_path(path) -> Path:
    """A ``.mcap`` file, or a rosbag2 bag directory of one ``.mcap`` file (a split bag is
    read file by file: see :func:`bag_files`)."""
    files = bag_files(path)
    if len(files) != 1:
        raise ValueError(f"{path} is a split bag of {len(files)} files: read them with "
                         "bag_files()")
    return files[0]


def decompress_bounded(compression: str, data, size: int) -> bytes:
    """Exactly ``size`` bytes from ``data`` or ValueError; never produces more than
    ``size + 1`` bytes, whatever the compressed frame claims."""
    if compression == "":
        if len(data) != size:
            raise ValueError(f"uncompressed chunk holds {len(data)} bytes, declares {size}")
        return data
    if compression == "zstd":
        # ZstdDecompressor.decompress() allocates the frame's own content size and ignores
        # max_output_size when the frame declares one: a stream read is bounded.
        try:
            out = zstandard.ZstdDecompressor().stream_reader(
                io.BytesIO(data), read_across_frames=True).read(size + 1)
        except zstandard.ZstdError as exc:
            raise ValueError(f"zstd: {exc}") from None
    elif compression == "lz4":
        try:
            out = lz4.frame.LZ4FrameDecompressor().decompress(bytes(data), max_length=size + 1)
        except RuntimeError as exc:
            raise ValueError(f"lz4: {exc}") from None
    else:
        raise ValueError(f"unknown chunk compression {compression!r}")
    if len(out) != size:
        raise ValueError(f"chunk decompressed to {len(out)} bytes, declares {size}")
    return out


def check_declared_size(usize: int, compressed: int, compression: str,
                        max_chunk_bytes: int) -> None:
    """ValueError when a chunk's declared uncompressed size is not believable."""
    if usize > max_chunk_bytes:
        raise ValueError(f"chunk declares {usize} uncompressed bytes (limit {max_chunk_bytes})")
    if compression and usize > MAX_COMPRESSION_RATIO * compressed + 4096:
        raise ValueError(f"chunk declares {usize} uncompressed bytes from {compressed} "
                         f"compressed (more than {MAX_COMPRESSION_RATIO}x)")


class McapStreamReader:
    """Walk an MCAP file's data section.

    Parameters
    ----------
    path: ``.mcap`` file, bag directory, or the file's bytes (tests, in-memory data).
    validate_crc: check chunk CRCs (a mismatch is damage).
    on_damage: ``"raise"`` or ``"warn"`` (see module docstring).
    max_chunk_bytes: refuse chunks that declare more uncompressed bytes than this.
    reuse_buffers: read every compressed chunk into one reused buffer (saves an allocation
        and its page faults per chunk).
    """

    def __init__(self, path, *, validate_crc: bool = True, on_damage: str = "raise",
                 max_chunk_bytes: int = DEFAULT_MAX_CHUNK_BYTES, reuse_buffers: bool = False):
        if on_damage not in ("raise", "warn"):
            raise ValueError(f"on_damage must be 'raise' or 'warn', got {on_damage!r}")
        if isinstance(path, bytes | bytearray | memoryview):
            self._buffer: bytes | None = bytes(path)
            self.path = Path("<memory>")
        else:
            self._buffer = None
            self.path = resolve_mcap_path(path)
        self.validate_crc = validate_crc
        self.on_damage = on_damage
        self.max_chunk_bytes = int(max_chunk_bytes)
        self.reuse_buffers = bool(reuse_buffers)
        self._chunk_buf = bytearray()
        self.profile: str | None = None
        self.library: str | None = None
        self.metadata: list[tuple[str, dict]] = []
        self.attachment_count = 0
        self.damages: list[str] = []
        self.complete = False  # Data End seen
        self.schemas: dict[int, SchemaInfo] = {}
        self.channels: dict[int, ChannelInfo] = {}
        self.size = (len(self._buffer) if self._buffer is not None
                     else os.path.getsize(self.path))
        self._read_ahead_thread: int | None = None  # ident of the read-ahead worker
        # what the worker found ahead of the caller (damage records, schemas, channels...),
        # applied in file order when the caller gets there: at every chunk the caller sees
        # what the plain walk shows (which channels exist decides which topics match)
        self._read_ahead_pending: list[Callable[[], None]] = []

    @property
    def damage(self) -> str | None:
        """The damage found so far in one line (None for an intact file)."""
        if not self.damages:
            return None
        more = len(self.damages) - 1
        return self.damages[0] + (f" (and {more} more damaged place{'s' * (more > 1)})"
                                  if more else "")

    def _open(self):
        return open(self.path, "rb") if self._buffer is None else io.BytesIO(self._buffer)

    # ---------------------------------------------------------------- walking
    def _damaged(self, what: str, offset: int) -> None:
        msg = f"{self.path}: damaged at byte {offset}: {what}"
        if threading.get_ident() == self._read_ahead_thread:
            self._read_ahead_pending.append(functools.partial(self.damages.append, msg))
        else:
            self.damages.append(msg)
        if self.on_damage == "raise":
            raise McapDamagedError(msg, offset)

    def _check_magic(self, f) -> None:
        if self.size == 0:
            raise McapDamagedError(f"{self.path}: empty file", 0)
        magic = f.read(len(MAGIC))
        if magic != MAGIC:
            if MAGIC.startswith(magic):
                raise McapDamagedError(f"{self.path}: damaged at byte {len(magic)}: file "
                                       f"ends inside the MCAP magic", len(magic))
            raise McapDamagedError(f"{self.path}: not an MCAP file (bad magic)", 0)

    def iter_chunks(self, read_ahead: int = 0) -> Iterator[RawChunk]:
        """Yield the chunks (and loose messages) of the data section in file order;
        ``read_ahead`` > 0: up to that many chunks prepared ahead by a worker thread, which
        starts the next one only while less than :data:`READ_AHEAD_BYTES` wait for the
        caller (so huge chunks are held at most two at a time)."""
        if read_ahead <= 0 or self._read_ahead_thread is not None:
            yield from self._walk_chunks()
            return
        # (kind, item, what was found before it) in file order; kind "chunk", "end", "error"
        ready: deque = deque()
        held = [0]  # uncompressed bytes in `ready`
        cond = threading.Condition()
        stop = threading.Event()

        def push(kind, item) -> None:
            found, self._read_ahead_pending = self._read_ahead_pending, []
            with cond:
                ready.append((kind, item, found))
                if kind == "chunk":
                    held[0] += len(item.records)
                cond.notify_all()

        def produce() -> None:
            self._read_ahead_thread = threading.get_ident()
            walk = self._walk_chunks()
            try:
                while True:
                    with cond:
                        while ready and (len(ready) >= read_ahead
                                         or held[0] >= READ_AHEAD_BYTES):
                            if stop.is_set():
                                return
                            cond.wait(0.05)
                    if stop.is_set():
                        return
                    try:
                        chunk = next(walk)
                    except StopIteration:
                        push("end", None)
                        return
                    push("chunk", chunk)
            except BaseException as exc:  # re-raised in the caller, in order
                push("error", exc)
            finally:
                walk.close()

        worker = threading.Thread(target=produce, name="mcap_read_ahead", daemon=True)
        worker.start()
        try:
            while True:
                with cond:
                    while not ready:
                        cond.wait(0.1)
                    kind, item, found_ahead = ready.popleft()
                    if kind == "chunk":
                        held[0] -= len(item.records)
                    cond.notify_all()
                for apply in found_ahead:
                    apply()
                if kind == "chunk":
                    yield item
                elif kind == "end":
                    return
                else:
                    raise item
        finally:
            stop.set()
            worker.join()
            self._read_ahead_thread = None

    def _walk_chunks(self) -> Iterator[RawChunk]:
        size = self.size
        with self._open() as f:
            self._check_magic(f)
            pos = len(MAGIC)
            pending: RawChunk | None = None
            index: dict[int, np.ndarray] | None = None
            while True:
                head = f.read(RECORD_HEADER.size)
                if len(head) < RECORD_HEADER.size:
                    if pending is not None:  # its index may be incomplete: do not trust it
                        pending.message_index = None
                        yield from self._finish_chunk(pending)
                    self._damaged(UNFINISHED if not head else "record header cut by the end "
                                  "of the file", pos)
                    return
                opcode, length = RECORD_HEADER.unpack(head)
                body_pos = pos + RECORD_HEADER.size
                if length > size - body_pos:
                    if pending is not None:
                        pending.message_index = None
                        yield from self._finish_chunk(pending)
                    self._damaged(f"record (opcode 0x{opcode:02x}) declares {length} bytes, "
                                  f"the file has {size - body_pos} left", pos)
                    return
                if opcode == OP_MESSAGE_INDEX and pending is not None:
                    body = f.read(length)
                    if index is not None:
                        try:
                            cid, entries = _parse_message_index(body, len(pending.records))
                            index[cid] = entries
                        except ValueError as exc:
                            index = None  # walk this chunk's records instead
                            self._damaged(f"message index: {exc}", pos)
                    pos = body_pos + length
                    continue
                if pending is not None:  # a non-index record: the chunk's index is complete
                    pending.message_index = index or None
                    yield from self._finish_chunk(pending)
                    pending = None
                if opcode == OP_CHUNK:
                    body = self._read_body(f, length)
                    try:
                        pending = self._parse_chunk(body, pos)
                        index = {}
                    except ValueError as exc:
                        self._damaged(f"chunk skipped: {exc}", pos)
                elif opcode == OP_DATA_END:
                    self.complete = True
                    return
                elif opcode == OP_MESSAGE:
                    body = f.read(length)
                    if length < MESSAGE_FIXED.size:
                        self._damaged("message record too short", pos)
                    else:
                        yield RawChunk(head + body, 0, 0, None, pos, loose=True)
                elif opcode in (OP_HEADER, OP_SCHEMA, OP_CHANNEL, OP_METADATA):
                    try:
                        self._register(opcode, f.read(length))
                    except RecordParseError as exc:
                        self._damaged(str(exc), pos)
                elif opcode == OP_FOOTER:
                    self._damaged("footer inside the data section (no Data End)", pos)
                    return
                else:
                    if opcode == OP_ATTACHMENT:
                        self.attachment_count += 1
                    f.seek(length, os.SEEK_CUR)  # the spec says: skip unknown records
                pos = body_pos + length

    def _read_body(self, f, length: int):
        if not self.reuse_buffers:
            return f.read(length)
        if len(self._chunk_buf) < length:
            self._chunk_buf = bytearray(length)
        body = memoryview(self._chunk_buf)[:length]
        f.readinto(body)
        return body

    def _register(self, opcode: int, body) -> None:
        rec = parse_record(opcode, body)
        if threading.get_ident() == self._read_ahead_thread:
            self._read_ahead_pending.append(functools.partial(self._add_record, opcode, rec))
        else:
            self._add_record(opcode, rec)

    def _add_record(self, opcode: int, rec) -> None:
        if opcode == OP_HEADER:
            self.profile, self.library = rec.profile, rec.library
        elif opcode == OP_SCHEMA:
            self.schemas[rec.id] = SchemaInfo(rec.id, rec.name, rec.encoding, bytes(rec.data))
        elif opcode == OP_CHANNEL:
            self.channels[rec.id] = ChannelInfo(rec.id, rec.schema_id, rec.topic,
                                                rec.message_encoding, dict(rec.metadata),
                                                self.schemas.get(rec.schema_id))
        elif opcode == OP_METADATA:
            self.metadata.append((rec.name, dict(rec.metadata)))

    def _parse_chunk(self, body, pos: int) -> RawChunk:
        if len(body) < CHUNK_FIXED.size + 4:
            raise ValueError("chunk record too short")
        start, end, usize, crc = CHUNK_FIXED.unpack_from(body, 0)
        p = CHUNK_FIXED.size
        (n,) = struct.unpack_from("<I", body, p)
        if n > len(body) - p - 12:
            raise ValueError("compression name overruns the chunk")
        try:
            compression = bytes(body[p + 4:p + 4 + n]).decode("utf-8")
        except UnicodeDecodeError:
            raise ValueError("compression name is not UTF-8") from None
        p += 4 + n
        (clen,) = struct.unpack_from("<Q", body, p)
        p += 8
        if clen > len(body) - p:  # fewer is padding (forward compatibility)
            raise ValueError(f"records length {clen} overruns the chunk body "
                             f"({len(body) - p} bytes)")
        check_declared_size(usize, clen, compression, self.max_chunk_bytes)
        data = body[p:p + clen]
        records = decompress_bounded(compression, data, usize)
        if self.validate_crc and crc != 0 and crc32(records) != crc:
            raise ValueError("chunk CRC mismatch")
        if compression == "":
            records = bytes(records)  # detach from the reused read buffer
        return RawChunk(records, start, end, {}, pos)

    def _finish_chunk(self, chunk: RawChunk) -> Iterator[RawChunk]:
        """Register the chunk's Schema/Channel records (libmcap writes them into chunks) and
        check its index; yields the chunk unless its records are unusable."""
        try:
            others = _non_message_records(chunk.records, chunk.message_index)
        except ValueError as exc:
            if chunk.message_index is None:
                # The records themselves are broken: keep what precedes the break.
                good = _records_before_break(chunk.records)
                self._damaged(f"chunk records: {exc}", chunk.file_offset)
                chunk.records = chunk.records[:good]
                try:
                    others = _non_message_records(chunk.records, None)
                except ValueError:  # cannot happen: cut at a record boundary
                    return
            else:
                self._damaged(f"message index does not match the chunk ({exc})",
                              chunk.file_offset)
                chunk.message_index = None
                yield from self._finish_chunk(chunk)
                return
        for opcode, off, length in others:
            if opcode in (OP_SCHEMA, OP_CHANNEL):
                body = chunk.records[off + RECORD_HEADER.size:off + RECORD_HEADER.size + length]
                try:
                    self._register(opcode, body)
                except RecordParseError as exc:
                    self._damaged(f"in chunk: {exc}", chunk.file_offset)
        yield chunk

    # ---------------------------------------------------------------- messages
    def iter_messages(self, topics: list[str] | None = None, *,
                      log_time_order: bool = False) -> Iterator[RawMessage]:
        """Every message, optionally only of ``topics``; in file order, or in log-time order
        (stable: file order among equal times).  Log-time order streams chunk by chunk when
        the summary's chunk indexes say when later chunks start, else sorts in memory."""
        if not log_time_order:
            yield from self._iter_file_order(topics)
            return
        summary = self.summary()
        starts = summary.chunk_starts if summary is not None else []
        if not starts:
            yield from sorted(self._iter_file_order(topics), key=lambda m: m.log_time)
            return
        # Messages of chunk j and later are >= the least start time of chunks j..end: a
        # buffered message earlier than that can be released.  A message outside the
        # indexed chunks (loose, or the index is stale) disables releasing: sort at the end.
        offsets = [o for o, _ in starts]
        later_min = np.minimum.accumulate(np.array([s for _, s in starts], dtype=np.uint64)
                                          [::-1])[::-1]
        heap: list = []
        streaming = True
        for k, (msg, file_offset) in enumerate(self._iter_file_order(topics, with_offset=True)):
            heapq.heappush(heap, (msg.log_time, k, msg))
            if streaming:
                j = int(np.searchsorted(offsets, file_offset))
                streaming = j < len(offsets) and offsets[j] == file_offset
                bound = int(later_min[j]) if streaming else 0
                while heap and heap[0][0] < bound:
                    yield heapq.heappop(heap)[2]
        while heap:
            yield heapq.heappop(heap)[2]

    def _iter_file_order(self, topics, with_offset: bool = False):
        for chunk in self.iter_chunks():
            for cid, seq, log, pub, data in iter_chunk_messages(chunk.records):
                ch = self.channels.get(cid)
                if ch is None:
                    self._damaged(f"message on unknown channel {cid}", chunk.file_offset)
                    continue
                if topics is not None and not any(topic_matches(ch.topic, t) for t in topics):
                    continue
                msg = RawMessage(ch, seq, log, pub, data)
                yield (msg, chunk.file_offset) if with_offset else msg

    # ---------------------------------------------------------------- summary
    def summary(self) -> SummaryInfo | None:
        """The summary section of an intact file, checked (None when absent or damaged:
        it is only ever a shortcut, the data section is the truth)."""
        try:
            with self._open() as f:
                return self._read_summary(f)
        except (OSError, ValueError, IndexError, struct.error):
            return None

    def _read_summary(self, f) -> SummaryInfo | None:
        size = self.size
        foot = RECORD_HEADER.size + FOOTER_BODY.size
        if size < 2 * len(MAGIC) + foot:
            return None
        f.seek(size - len(MAGIC) - foot)
        tail = f.read(foot + len(MAGIC))
        if tail[-len(MAGIC):] != MAGIC or tail[0] != OP_FOOTER:
            return None
        summary_start, summary_offset_start, _ = FOOTER_BODY.unpack_from(tail, 9)
        end = summary_offset_start or size - len(MAGIC) - foot
        if not (len(MAGIC) < summary_start <= end <= size - len(MAGIC) - foot
                and end - summary_start <= MAX_SUMMARY_BYTES):
            return None
        f.seek(summary_start)
        buf = f.read(end - summary_start)
        out = SummaryInfo()
        schemas: dict[int, SchemaInfo] = {}
        stats = None
        pos = 0
        while pos + RECORD_HEADER.size <= len(buf):
            op, length = RECORD_HEADER.unpack_from(buf, pos)
            body = buf[pos + RECORD_HEADER.size:pos + RECORD_HEADER.size + length]
            if len(body) != length:
                return None
            if op == OP_SCHEMA:
                r = parse_record(op, body)
                schemas[r.id] = SchemaInfo(r.id, r.name, r.encoding, bytes(r.data))
            elif op == OP_CHANNEL:
                r = parse_record(op, body)
                out.channels[r.id] = ChannelInfo(r.id, r.schema_id, r.topic,
                                                 r.message_encoding, dict(r.metadata),
                                                 schemas.get(r.schema_id))
            elif op == OP_STATISTICS:
                stats = parse_record(op, body)
            elif op == OP_CHUNK_INDEX:
                r = parse_record(op, body)
                if r.chunk_start_offset + r.chunk_length > size:
                    return None
                usize = min(r.uncompressed_size, self.max_chunk_bytes)
                if r.compression:
                    usize = min(usize, MAX_COMPRESSION_RATIO * r.compressed_size + 4096)
                out.uncompressed_bytes += usize
                out.chunk_starts.append((r.chunk_start_offset, r.message_start_time))
            pos += RECORD_HEADER.size + length
        out.chunk_starts.sort()
        if stats is not None:
            # A count is believed only when the bytes can hold that many message records.
            capacity = (out.uncompressed_bytes + size) // MIN_MESSAGE_RECORD
            out.message_counts = {cid: n for cid, n in stats.channel_message_counts.items()
                                  if 0 <= n <= capacity}
        return out


def _parse_message_index(body, records_len: int) -> tuple[int, np.ndarray]:
    """(channel id, (k, 2) uint64 (log_time, offset)) of one Message Index record.

    Parsed with numpy, not the ``mcap`` package's per-entry loop (100x slower, see the
    module docstring): an index holds ~10^4 entries per chunk here."""
    if len(body) < 6:
        raise ValueError("record too short")
    cid, nbytes = struct.unpack_from("<HI", body, 0)
    if nbytes > len(body) - 6 or nbytes % 16:
        raise ValueError(f"{nbytes} bytes of entries in a {len(body)}-byte record")
    entries = np.frombuffer(body, dtype="<u8", count=nbytes // 8, offset=6).reshape(-1, 2)
    if entries.shape[0] > records_len // MIN_MESSAGE_RECORD:
        raise ValueError(f"{entries.shape[0]} entries cannot fit in a {records_len}-byte chunk")
    if entries.size and int(entries[:, 1].max()) > records_len - MIN_MESSAGE_RECORD:
        raise ValueError("offset beyond the chunk")
    return cid, entries.astype(np.uint64)


def _non_message_records(records, index: dict[int, np.ndarray] | None) -> list:
    """(opcode, offset, length) of every record of a chunk that is not an indexed message.

    With an index, only the gaps between the indexed message records are walked (record
    lengths gathered array-wide); without one, every record.  ValueError when the records
    do not tile the chunk (or the index does not point at whole message records)."""
    n = len(records)
    if index is None:
        return [(op, off, length) for op, off, _, length in iter_chunk_records(records)
                if op != OP_MESSAGE]
    parts = [e[:, 1] for e in index.values() if e.size]
    offs = (np.concatenate(parts) if len(parts) > 1 else parts[0]).astype(np.int64) \
        if parts else np.zeros(0, np.int64)
    if offs.size > 1 and not (offs[1:] > offs[:-1]).all():
        offs = np.sort(offs)  # several channels, or an unordered index
        if not (offs[1:] > offs[:-1]).all():
            raise ValueError("the index lists a record twice")
    buf = np.frombuffer(records, dtype=np.uint8)
    if offs.size:
        if offs[-1] + RECORD_HEADER.size > n:
            raise ValueError("index offset beyond the chunk")
        ops = buf[offs]
        # the u64 record lengths, gathered through a sliding-window view
        lens = np.ascontiguousarray(
            np.lib.stride_tricks.sliding_window_view(buf, 8)[offs + 1]).view("<u8")[:, 0]
        if (ops != OP_MESSAGE).any() or (lens < MESSAGE_FIXED.size).any() \
                or (lens > n).any():
            raise ValueError("index points at a record that is not a message")
        ends = offs + RECORD_HEADER.size + lens.astype(np.int64)
        if (ends[:-1] > offs[1:]).any() or ends[-1] > n:
            raise ValueError("indexed message records overlap or overrun the chunk")
        gap_starts = np.concatenate([[0], ends])
        gap_ends = np.concatenate([offs, [n]])
    else:
        gap_starts, gap_ends = np.array([0]), np.array([n])
    out = []
    for g0, g1 in zip(gap_starts[gap_starts < gap_ends].tolist(),
                      gap_ends[gap_starts < gap_ends].tolist(), strict=True):
        pos = g0
        while pos < g1:
            if g1 - pos < RECORD_HEADER.size:
                raise ValueError("chunk ends inside a record header")
            op, length = RECORD_HEADER.unpack_from(records, pos)
            if length > g1 - pos - RECORD_HEADER.size:
                raise ValueError("record overruns its chunk")
            if op == OP_MESSAGE:
                # A message the index does not list: the index is incomplete.
                raise ValueError("message record missing from the index")
            out.append((op, pos, length))
            pos += RECORD_HEADER.size + length
    return out


def _records_before_break(records) -> int:
    """Length of the longest prefix of whole records (for a chunk whose records break)."""
    pos = 0
    n = len(records)
    while n - pos >= RECORD_HEADER.size:
        op, length = RECORD_HEADER.unpack_from(records, pos)
        if length > n - pos - RECORD_HEADER.size or (op == OP_MESSAGE
                                                     and length < MESSAGE_FIXED.size):
            break
        pos += RECORD_HEADER.size + length
    return pos


def iter_chunk_records(records):
    """(opcode, record_offset, body_offset, body_length) for each record of a chunk.

    Raises ValueError on a record that overruns the chunk or a Message record too short to
    hold its fixed fields.
    """
    pos = 0
    n = len(records)
    while pos < n:
        if n - pos < RECORD_HEADER.size:
            raise ValueError("chunk ends inside a record header")
        opcode, length = RECORD_HEADER.unpack_from(records, pos)
        body = pos + RECORD_HEADER.size
        if length > n - body:
            raise ValueError("record overruns its chunk")
        if opcode == OP_MESSAGE and length < MESSAGE_FIXED.size:
            raise ValueError("message record too short")
        yield opcode, pos, body, length
        pos = body + length


def iter_chunk_messages(records):
    """(channel_id, sequence, log_time, publish_time, data) for each Message record.

    A Python walk over the records: the slow, general path (the array decoders use the
    message index instead).  Raises ValueError on a record that overruns the chunk.
    """
    mv = memoryview(records)
    for opcode, _, body, length in iter_chunk_records(records):
        if opcode == OP_MESSAGE:
            cid, seq, log, pub = MESSAGE_FIXED.unpack_from(records, body)
            yield cid, seq, log, pub, bytes(mv[body + MESSAGE_FIXED.size:body + length])
