"""MCAP record framing (https://mcap.dev/spec): opcodes, record builders and body parsers.

Every record is ``opcode u8, length u64, body``; strings are ``u32 length + UTF-8``, maps
are ``u32 byte length + pairs``.  Building is written here (the writer assembles whole
chunks from numpy buffers, which the ``mcap`` package's per-record writer cannot); parsing
of the descriptive records (Header, Schema, Channel, Metadata, Statistics, Chunk Index,
Footer, Attachment) is the ``mcap`` package's own (:func:`parse_record`), which reads the
known fields and ignores extra bytes after them (forward-compatibility padding).
"""

from __future__ import annotations

import io
import struct

from mcap import records as mcap_records
from mcap.data_stream import ReadDataStream
from mcap.exceptions import EndOfFile

try:
    # The MCAP checksum is zlib's CRC-32; ISA-L computes it with carry-less multiplies at
    # ~24 GB/s here against zlib's 2.3 GB/s (a 600 k-message replay checks ~200 MB and
    # writes ~270 MB of chunk records).  Optional: requirements.txt installs it.
    from isal import isal_zlib as _crc_impl
except ImportError:  # pragma: no cover - the same checksum, slower
    import zlib as _crc_impl

crc32 = _crc_impl.crc32

MAGIC = b"\x89MCAP0\r\n"

OP_HEADER = 0x01
OP_FOOTER = 0x02
OP_SCHEMA = 0x03
OP_CHANNEL = 0x04
OP_MESSAGE = 0x05
OP_CHUNK = 0x06
OP_MESSAGE_INDEX = 0x07
OP_CHUNK_INDEX = 0x08
OP_ATTACHMENT = 0x09
OP_ATTACHMENT_INDEX = 0x0A
OP_STATISTICS = 0x0B
OP_METADATA = 0x0C
OP_METADATA_INDEX = 0x0D
OP_SUMMARY_OFFSET = 0x0E
OP_DATA_END = 0x0F

RECORD_HEADER = struct.Struct("<BQ")
CHUNK_FIXED = struct.Struct("<QQQI")  # message_start_time, message_end_time, size, crc
MESSAGE_FIXED = struct.Struct("<HIQQ")  # channel_id, sequence, log_time, publish_time
FOOTER_BODY = struct.Struct("<QQI")  # summary_start, summary_offset_start, summary_crc
# Smallest possible Message record: header + fixed fields, empty payload.
MIN_MESSAGE_RECORD = RECORD_HEADER.size + MESSAGE_FIXED.size

_PARSERS = {
    OP_HEADER: mcap_records.Header,
    OP_FOOTER: mcap_records.Footer,
    OP_SCHEMA: mcap_records.Schema,
    OP_CHANNEL: mcap_records.Channel,
    OP_CHUNK_INDEX: mcap_records.ChunkIndex,
    OP_ATTACHMENT: mcap_records.Attachment,
    OP_ATTACHMENT_INDEX: mcap_records.AttachmentIndex,
    OP_STATISTICS: mcap_records.Statistics,
    OP_METADATA: mcap_records.Metadata,
    OP_METADATA_INDEX: mcap_records.MetadataIndex,
    OP_SUMMARY_OFFSET: mcap_records.SummaryOffset,
}


class RecordParseError(ValueError):
    """A record body does not hold the fields its opcode requires."""


def parse_record(opcode: int, body) -> mcap_records.McapRecord:
    """The ``mcap`` package's record object for one descriptive record body.

    Raises :class:`RecordParseError` when the body is too short or a string is not UTF-8.
    """
    parser = _PARSERS.get(opcode)
    if parser is None:
        raise RecordParseError(f"no parser for opcode 0x{opcode:02x}")
    stream = ReadDataStream(_ExactReads(bytes(body)))
    try:
        return parser.read(stream)
    except (EndOfFile, struct.error, UnicodeDecodeError, ValueError) as exc:
        raise RecordParseError(f"record 0x{opcode:02x} of {len(body)} bytes does not parse "
                               f"({type(exc).__name__}: a field overruns the record or is "
                               f"not UTF-8)") from None


class _ExactReads(io.BytesIO):
    """A body whose reads return exactly what is asked or raise EndOfFile: ReadDataStream
    would otherwise accept a string or byte field cut short by the end of the record."""

    def read(self, size=-1):
        data = super().read(size)
        if size is not None and size >= 0 and len(data) != size:
            raise EndOfFile()
        return data


# ------------------------------------------------------------------ building
def pack_str(s: str) -> bytes:
    b = s.encode("utf-8")
    return struct.pack("<I", len(b)) + b


def pack_bytes32(b: bytes) -> bytes:
    return struct.pack("<I", len(b)) + b


def pack_str_map(d: dict[str, str]) -> bytes:
    body = b"".join(pack_str(k) + pack_str(v) for k, v in d.items())
    return struct.pack("<I", len(body)) + body


def record(opcode: int, body: bytes) -> bytes:
    return RECORD_HEADER.pack(opcode, len(body)) + body


def header_record(profile: str, library: str) -> bytes:
    return record(OP_HEADER, pack_str(profile) + pack_str(library))


def schema_record(schema_id: int, name: str, encoding: str, data: bytes) -> bytes:
    return record(OP_SCHEMA, struct.pack("<H", schema_id) + pack_str(name) + pack_str(encoding)
                  + pack_bytes32(data))


def channel_record(channel_id: int, schema_id: int, topic: str, message_encoding: str,
                   metadata: dict[str, str]) -> bytes:
    return record(OP_CHANNEL, struct.pack("<HH", channel_id, schema_id) + pack_str(topic)
                  + pack_str(message_encoding) + pack_str_map(metadata))


def chunk_record_head(start: int, end: int, uncompressed_size: int, crc: int,
                      compression: str, compressed_size: int) -> bytes:
    """Everything of a Chunk record before its (compressed) records."""
    head = CHUNK_FIXED.pack(start, end, uncompressed_size, crc) + pack_str(compression)
    return (RECORD_HEADER.pack(OP_CHUNK, len(head) + 8 + compressed_size) + head
            + struct.pack("<Q", compressed_size))


def message_index_record(channel_id: int, entries_le_u64: bytes) -> bytes:
    """``entries_le_u64``: (log_time, offset) pairs as little-endian uint64 bytes."""
    return (RECORD_HEADER.pack(OP_MESSAGE_INDEX, 2 + 4 + len(entries_le_u64))
            + struct.pack("<HI", channel_id, len(entries_le_u64)) + entries_le_u64)


def chunk_index_record(start: int, end: int, chunk_offset: int, chunk_length: int,
                       index_offsets: dict[int, int], index_length: int, compression: str,
                       compressed_size: int, uncompressed_size: int) -> bytes:
    omap = b"".join(struct.pack("<HQ", cid, o) for cid, o in index_offsets.items())
    return record(OP_CHUNK_INDEX, struct.pack("<QQQQ", start, end, chunk_offset, chunk_length)
                  + struct.pack("<I", len(omap)) + omap + struct.pack("<Q", index_length)
                  + pack_str(compression) + struct.pack("<QQ", compressed_size,
                                                        uncompressed_size))


def metadata_record(name: str, metadata: dict[str, str]) -> bytes:
    return record(OP_METADATA, pack_str(name) + pack_str_map(metadata))


def metadata_index_record(offset: int, length: int, name: str) -> bytes:
    return record(OP_METADATA_INDEX, struct.pack("<QQ", offset, length) + pack_str(name))


def data_end_record(data_crc: int) -> bytes:
    return record(OP_DATA_END, struct.pack("<I", data_crc))


def statistics_record(message_count: int, schema_count: int, channel_count: int,
                      attachment_count: int, metadata_count: int, chunk_count: int,
                      start: int, end: int, channel_counts: dict[int, int]) -> bytes:
    counts = b"".join(struct.pack("<HQ", cid, n) for cid, n in channel_counts.items())
    return record(OP_STATISTICS, struct.pack(
        "<QHIIII", message_count, schema_count, channel_count, attachment_count,
        metadata_count, chunk_count) + struct.pack("<QQ", start, end)
        + struct.pack("<I", len(counts)) + counts)


def summary_offset_record(opcode: int, start: int, length: int) -> bytes:
    return record(OP_SUMMARY_OFFSET, struct.pack("<BQQ", opcode, start, length))


def footer_head(summary_start: int, summary_offset_start: int) -> bytes:
    """Footer record without its CRC (the summary CRC covers these bytes too)."""
    return RECORD_HEADER.pack(OP_FOOTER, FOOTER_BODY.size) + struct.pack(
        "<QQ", summary_start, summary_offset_start)
