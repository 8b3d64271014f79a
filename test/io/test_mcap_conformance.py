"""Our reader reads every valid MCAP, not only rosbag2's: the variants of Foxglove's
conformance suite (tests/conformance in foxglove/mcap: chunked or not, compression
none/lz4/zstd, with or without message indexes, chunk indexes, statistics, summary
offsets, repeated schemas and channels, attachments, metadata, schemaless channels, padding
after the known fields of records), generated here with the ``mcap`` package's writer and,
for what it cannot write (padding), rebuilt by hand.  Oracle: the ``mcap`` package's own
reader on the same (or the unpadded) file, message for message."""

from __future__ import annotations

import io
import struct

import pytest
from mcap.reader import NonSeekingReader
from mcap.writer import CompressionType, IndexType, Writer

from gyro_attitude.io.mcap_reader import McapStreamReader
from gyro_attitude.io.mcap_records import (
    MAGIC,
    OP_ATTACHMENT,
    OP_CHANNEL,
    OP_CHUNK,
    OP_DATA_END,
    OP_HEADER,
    OP_MESSAGE_INDEX,
    OP_METADATA,
    OP_SCHEMA,
    RECORD_HEADER,
    footer_head,
)


def _make(*, chunked=True, compression=CompressionType.ZSTD, index=IndexType.ALL,
          repeat=True, statistics=True, summary_offsets=True, chunk_size=300) -> bytes:
    buf = io.BytesIO()
    w = Writer(buf, chunk_size=chunk_size, compression=compression, index_types=index,
               repeat_channels=repeat, repeat_schemas=repeat, use_chunking=chunked,
               use_statistics=statistics, use_summary_offsets=summary_offsets)
    w.start(profile="", library="conformance-variant")
    sid = w.register_schema("Example", "jsonschema", b'{"type": "object"}')
    a = w.register_channel("/a", "json", sid, {"k": "v"})
    b = w.register_channel("/schemaless", "json", 0)  # schema id 0: no schema
    w.add_metadata("calibration", {"gain": "2", "unit": "rad/s"})
    w.add_attachment(create_time=5, log_time=6, name="notes.txt", media_type="text/plain",
                     data=b"attached bytes")
    c = None
    for k in range(40):
        if k == 20:  # a channel registered mid-file (inside a later chunk)
            c = w.register_channel("/late", "json", sid)
        # out of log-time order on purpose (decreasing every 7th)
        t = 1000 + 10 * k - (35 if k % 7 == 6 else 0)
        ch = (a, b, c)[k % 3] if c is not None else (a, b)[k % 2]
        w.add_message(ch, log_time=t, data=b'{"k": %d}' % k, publish_time=t + 1, sequence=k)
    w.finish()
    return buf.getvalue()


def _oracle(data: bytes) -> list[tuple]:
    reader = NonSeekingReader(io.BytesIO(data), validate_crcs=True)
    return [(ch.topic, sc.name if sc is not None else "", m.log_time, m.publish_time,
             m.sequence, m.data) for sc, ch, m in reader.iter_messages(log_time_order=False)]


def _ours(data: bytes, log_time_order=False) -> tuple[list[tuple], McapStreamReader]:
    r = McapStreamReader(data)
    msgs = [(m.channel.topic, m.channel.type_name, m.log_time, m.publish_time, m.sequence,
             m.data) for m in r.iter_messages(log_time_order=log_time_order)]
    return msgs, r


VARIANTS = {
    "zstd_all": {},
    "lz4_all": {"compression": CompressionType.LZ4},
    "uncompressed_all": {"compression": CompressionType.NONE},
    "unchunked": {"chunked": False},
    "unchunked_no_summary_extras": {"chunked": False, "statistics": False,
                                    "summary_offsets": False, "repeat": False},
    "no_indexes": {"index": IndexType.NONE},
    "chunk_index_only": {"index": IndexType.CHUNK},
    "message_index_only": {"index": IndexType.MESSAGE, "statistics": False},
    "no_repeats": {"repeat": False},
    "no_statistics_no_offsets": {"statistics": False, "summary_offsets": False},
    "one_big_chunk": {"chunk_size": 1 << 20},
}


@pytest.mark.parametrize("variant", sorted(VARIANTS))
def test_every_message_as_mcap_reads_it(variant):
    data = _make(**VARIANTS[variant])
    expected = _oracle(data)
    assert len(expected) == 40
    ours, reader = _ours(data)
    assert ours == expected
    assert reader.damage is None and reader.complete
    assert reader.metadata == [("calibration", {"gain": "2", "unit": "rad/s"})]
    assert reader.attachment_count == 1
    # log-time order: same messages, log times non-decreasing, file order among equals
    ordered, _ = _ours(data, log_time_order=True)
    assert ordered == sorted(expected, key=lambda m: m[2])


def _pad_records(data: bytes, pad: bytes = b"\x00future\x01") -> bytes:
    """The data section with ``pad`` appended to the body of every record type that may
    grow fields (Header, Schema, Channel, Chunk, Message Index, Metadata, Attachment, Data
    End); the summary dropped (its offsets would be stale), a footer without summary."""
    out = bytearray(MAGIC)
    pos = len(MAGIC)
    while True:
        op, length = RECORD_HEADER.unpack_from(data, pos)
        body = data[pos + RECORD_HEADER.size:pos + RECORD_HEADER.size + length]
        if op in (OP_HEADER, OP_SCHEMA, OP_CHANNEL, OP_CHUNK, OP_MESSAGE_INDEX, OP_METADATA,
                  OP_ATTACHMENT, OP_DATA_END):
            body = body + pad
        out += RECORD_HEADER.pack(op, len(body)) + body
        pos += RECORD_HEADER.size + length
        if op == OP_DATA_END:
            break
    out += footer_head(0, 0) + struct.pack("<I", 0) + MAGIC
    return bytes(out)


@pytest.mark.parametrize("variant", ["zstd_all", "uncompressed_all", "unchunked"])
def test_padding_after_known_fields_is_ignored(variant):
    data = _make(**VARIANTS[variant])
    padded = _pad_records(data)
    assert len(padded) > len(data) - 2000  # summary dropped, padding added
    ours, reader = _ours(padded)
    assert ours == _oracle(data)
    assert reader.damage is None and reader.complete
    assert reader.metadata == [("calibration", {"gain": "2", "unit": "rad/s"})]
