"""Robust streaming reader for MCAP files (rosbag2 profile), tolerant of damage.

The reader walks the top-level records of the data section in file order (it needs no
summary), so it also reads files a crash left without summary or footer.  Chunks are
decompressed and CRC-checked one at a time (memory stays at one chunk); each chunk comes
with the Message Index records that follow it, which the array decoders use to find the
message records without walking them in Python.

Damage (truncation, a corrupted chunk, a record longer than the file, a non-MCAP or
empty file) stops the walk.  Everything complete before the damage has been yielded by
then; ``on_damage="raise"`` (default) raises :class:`McapDamagedError` afterwards,
``"warn"`` records the reason in :attr:`McapStreamReader.damage` and stops quietly.
Record lengths are checked against the file size before anything is allocated, and
decompression is capped at the chunk's declared size (itself capped by
``max_chunk_bytes``), so a corrupted length cannot exhaust memory.
"""

from __future__ import annotations

import io
import os
import struct
import zlib
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from gyro_attitude.io.mcap_records import (
    CHUNK_FIXED,
    MAGIC,
    MESSAGE_FIXED,
    OP_CHANNEL,
    OP_CHUNK,
    OP_DATA_END,
    OP_FOOTER,
    OP_HEADER,
    OP_MESSAGE,
    OP_MESSAGE_INDEX,
    OP_METADATA,
    OP_SCHEMA,
    RECORD_HEADER,
    BodyReader,
)

__all__ = [
    "McapDamagedError",
    "SchemaInfo",
    "ChannelInfo",
    "RawChunk",
    "RawMessage",
    "McapStreamReader",
    "resolve_mcap_path",
    "topic_matches",
    "match_topic",
    "iter_chunk_records",
    "iter_chunk_messages",
]


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


def topic_matches(topic: str, wanted: str) -> bool:
    """Topic equality ignoring a leading ``/`` (rosbag2 stores fully qualified names)."""
    return topic.lstrip("/") == wanted.lstrip("/")


def match_topic(recorded: list[str], wanted: str) -> str | None:
    """The recorded topic ``wanted`` names: equal up to a leading ``/``, or, for a relative
    name, the one recorded topic ending in ``/<wanted>`` (any namespace).  None if none;
    ValueError when a relative name fits several namespaces."""
    exact = [t for t in recorded if topic_matches(t, wanted)]
    if exact:
        return exact[0]
    if wanted.startswith("/"):
        return None
    ends = sorted({t for t in recorded if t.endswith("/" + wanted)})
    if len(ends) > 1:
        raise ValueError(f"topic {wanted!r} is ambiguous: {ends}; give the full name")
    return ends[0] if ends else None


def resolve_mcap_path(path) -> Path:
    """A ``.mcap`` file, or a rosbag2 bag directory holding exactly one ``.mcap`` file."""
    p = Path(path)
    if p.is_dir():
        files = sorted(p.glob("*.mcap"))
        if len(files) != 1:
            raise ValueError(f"bag directory {p} holds {len(files)} .mcap files, expected 1")
        return files[0]
    if not p.exists():
        raise ValueError(f"no such file: {p}")
    return p


@dataclass
class _State:
    schemas: dict[int, SchemaInfo] = field(default_factory=dict)
    channels: dict[int, ChannelInfo] = field(default_factory=dict)


class McapStreamReader:
    """Walk an MCAP file's data section.

    Parameters
    ----------
    path: ``.mcap`` file, bag directory, or the file's bytes (tests, in-memory data).
    validate_crc: check chunk CRCs (a mismatch is damage).
    on_damage: ``"raise"`` or ``"warn"`` (see module docstring).
    max_chunk_bytes: refuse chunks that declare more uncompressed bytes than this.
    reuse_buffers: read every uncompressed chunk into one reused buffer; a yielded
        :class:`RawChunk`'s ``records`` is then only valid until the next one is requested
        (saves an allocation and its page faults per chunk; for array readers that copy).
    """

    def __init__(self, path, *, validate_crc: bool = True, on_damage: str = "raise",
                 max_chunk_bytes: int = 1 << 30, reuse_buffers: bool = False):
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
        self.damage: str | None = None
        self.complete = False  # Data End seen
        self._state = _State()

    @property
    def size(self) -> int:
        return len(self._buffer) if self._buffer is not None else os.path.getsize(self.path)

    @property
    def channels(self) -> dict[int, ChannelInfo]:
        return self._state.channels

    @property
    def schemas(self) -> dict[int, SchemaInfo]:
        return self._state.schemas

    # ---------------------------------------------------------------- walking
    def _damaged(self, what: str, offset: int) -> None:
        msg = f"{self.path}: {what} at byte {offset}"
        self.damage = msg
        if self.on_damage == "raise":
            raise McapDamagedError(msg, offset)

    def iter_chunks(self) -> Iterator[RawChunk]:
        """Yield the chunks (and loose messages) of the data section in file order."""
        size = self.size
        with (open(self.path, "rb") if self._buffer is None else io.BytesIO(self._buffer)) as f:
            if size == 0:
                self._damaged("empty file (no MCAP magic)", 0)
                return
            magic = f.read(len(MAGIC))
            if magic != MAGIC:
                if MAGIC.startswith(magic):
                    self._damaged("file truncated inside the MCAP magic", len(magic))
                    return
                self._damaged(f"not an MCAP file (starts with {magic[:8]!r})", 0)
                return
            pos = len(MAGIC)
            pending: RawChunk | None = None
            index: dict[int, np.ndarray] | None = None
            while True:
                head = f.read(RECORD_HEADER.size)
                if len(head) < RECORD_HEADER.size:
                    if pending is not None:  # its index may be incomplete: do not trust it
                        pending.message_index = None
                        yield pending
                    what = ("file ends without Data End/footer (truncated, or writer killed)"
                            if not head else "record header truncated")
                    self._damaged(what, pos)
                    return
                opcode, length = RECORD_HEADER.unpack(head)
                body_pos = pos + RECORD_HEADER.size
                if length > size - body_pos:
                    if pending is not None:  # its index may be incomplete: do not trust it
                        pending.message_index = None
                        yield pending
                    self._damaged(f"record (opcode 0x{opcode:02x}, {length} bytes) longer "
                                  f"than the rest of the file ({size - body_pos} bytes)", pos)
                    return
                if opcode == OP_MESSAGE_INDEX and pending is not None:
                    body = f.read(length)
                    try:
                        cid, entries = _parse_message_index(body, len(pending.records))
                        index[cid] = entries
                    except (IndexError, ValueError, struct.error) as exc:
                        pending.message_index = None
                        yield pending
                        self._damaged(f"corrupt message index ({exc})", pos)
                        return
                    pos = body_pos + length
                    continue
                if pending is not None:  # a non-index record: the chunk's index is complete
                    pending.message_index = index or None
                    yield pending
                    pending = None
                if opcode == OP_CHUNK:
                    if length > self.max_chunk_bytes + 64:
                        self._damaged(f"chunk of {length} bytes exceeds max_chunk_bytes", pos)
                        return
                    if self.reuse_buffers:
                        if len(self._chunk_buf) < length:
                            self._chunk_buf = bytearray(length)
                        body = memoryview(self._chunk_buf)[:length]
                        got = f.readinto(body)
                        if got != length:
                            self._damaged("chunk truncated", pos)
                            return
                    else:
                        body = f.read(length)
                    try:
                        pending = self._parse_chunk(body, pos)
                    except (IndexError, ValueError, struct.error, zlib.error) as exc:
                        self._damaged(f"corrupt chunk ({exc})", pos)
                        return
                    index = {}
                    pos = body_pos + length
                    continue
                if opcode == OP_DATA_END:
                    self.complete = True
                    return
                if opcode == OP_MESSAGE:
                    body = f.read(length)
                    yield RawChunk(head + body, 0, 0, None, pos, loose=True)
                elif opcode in (OP_HEADER, OP_SCHEMA, OP_CHANNEL, OP_METADATA):
                    body = f.read(length)
                    try:
                        self._parse_meta_record(opcode, body)
                    except (IndexError, ValueError, struct.error, UnicodeDecodeError) as exc:
                        self._damaged(f"corrupt record 0x{opcode:02x} ({exc})", pos)
                        return
                elif opcode == OP_FOOTER:
                    self._damaged("footer inside the data section", pos)
                    return
                else:
                    f.seek(length, os.SEEK_CUR)  # the spec says: skip unknown records
                pos = body_pos + length

    def _parse_meta_record(self, opcode: int, body: bytes) -> None:
        r = BodyReader(body)
        if opcode == OP_HEADER:
            self.profile = r.string()
            self.library = r.string()
        elif opcode == OP_SCHEMA:
            sid = r.u16()
            s = SchemaInfo(sid, r.string(), r.string(), r.bytes32())
            self._state.schemas[sid] = s
        elif opcode == OP_CHANNEL:
            cid = r.u16()
            sid = r.u16()
            topic = r.string()
            enc = r.string()
            meta = r.str_map()
            self._state.channels[cid] = ChannelInfo(
                cid, sid, topic, enc, meta, self._state.schemas.get(sid))
        elif opcode == OP_METADATA:
            name = r.string()
            self.metadata.append((name, r.str_map()))

    def _parse_chunk(self, body: bytes, pos: int) -> RawChunk:
        start, end, usize, crc = CHUNK_FIXED.unpack_from(body, 0)
        r = BodyReader(body, CHUNK_FIXED.size)
        compression = r.string()
        n = r.u64()
        if n != len(body) - r.pos:
            raise ValueError(f"records length {n} does not match the chunk body")
        if usize > self.max_chunk_bytes:
            raise ValueError(f"declared uncompressed size {usize} exceeds max_chunk_bytes")
        data = body[r.pos:]
        if compression == "":
            records = data
        elif compression == "zstd":
            import zstandard

            try:
                records = zstandard.ZstdDecompressor().decompress(data, max_output_size=usize)
            except zstandard.ZstdError as exc:
                raise ValueError(f"zstd: {exc}") from exc
        elif compression == "lz4":
            import lz4.frame

            try:
                d = lz4.frame.LZ4FrameDecompressor()
                records = d.decompress(data, max_length=usize)
            except RuntimeError as exc:
                raise ValueError(f"lz4: {exc}") from exc
        else:
            raise ValueError(f"unknown chunk compression {compression!r}")
        if len(records) != usize:
            raise ValueError(f"chunk decompressed to {len(records)} bytes, declared {usize}")
        if self.validate_crc and crc != 0 and zlib.crc32(records) != crc:
            raise ValueError("chunk CRC mismatch")
        # Schema/Channel records may sit inside chunks (libmcap puts them there).
        _scan_meta_in_chunk(records, self)
        return RawChunk(records, start, end, {}, pos)

    # ---------------------------------------------------------------- messages
    def iter_messages(self, topics: list[str] | None = None) -> Iterator[RawMessage]:
        """Every message in file order (per chunk: record order), optionally by topic."""
        for chunk in self.iter_chunks():
            for cid, seq, log, pub, data in iter_chunk_messages(chunk.records):
                ch = self.channels.get(cid)
                if ch is None:
                    self._damaged(f"message on unknown channel {cid}", chunk.file_offset)
                    return
                if topics is not None and not any(topic_matches(ch.topic, t) for t in topics):
                    continue
                yield RawMessage(ch, seq, log, pub, data)


def _parse_message_index(body: bytes, records_len: int) -> tuple[int, np.ndarray]:
    cid, nbytes = struct.unpack_from("<HI", body, 0)
    if nbytes != len(body) - 6 or nbytes % 16:
        raise ValueError(f"message index of {nbytes} bytes in a {len(body)}-byte record")
    entries = np.frombuffer(body, dtype="<u8", offset=6).reshape(-1, 2)
    if entries.size and entries[:, 1].max() >= records_len:
        raise ValueError("message index offset beyond the chunk")
    return cid, entries


def iter_chunk_records(records: bytes):
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


def iter_chunk_messages(records: bytes):
    """(channel_id, sequence, log_time, publish_time, data) for each Message record.

    A Python walk over the records: the slow, general path (the array decoders use the
    message index instead).  Raises ValueError on a record that overruns the chunk.
    """
    mv = memoryview(records)
    for opcode, _, body, length in iter_chunk_records(records):
        if opcode == OP_MESSAGE:
            cid, seq, log, pub = MESSAGE_FIXED.unpack_from(records, body)
            yield cid, seq, log, pub, bytes(mv[body + MESSAGE_FIXED.size:body + length])


def _scan_meta_in_chunk(records: bytes, reader: McapStreamReader) -> None:
    """Register Schema/Channel records found inside a chunk (cheap when there are none:
    only the first records are looked at, where writers put them)."""
    pos = 0
    n = len(records)
    while pos + RECORD_HEADER.size <= n:
        opcode, length = RECORD_HEADER.unpack_from(records, pos)
        body = pos + RECORD_HEADER.size
        if length > n - body:
            raise ValueError("record overruns its chunk")
        if opcode in (OP_SCHEMA, OP_CHANNEL):
            reader._parse_meta_record(opcode, records[body:body + length])
        else:
            return
        pos = body + length
