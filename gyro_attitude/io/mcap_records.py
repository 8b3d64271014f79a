"""MCAP record layout shared by the writer and the reader (https://mcap.dev/spec).

Every record is ``opcode u8, length u64, body``; strings are ``u32 length + UTF-8``, maps
are ``u32 byte length + pairs``.  Only the records rosbag2 files use are spelled out.
"""

from __future__ import annotations

import struct

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


class BodyReader:
    """Sequential reads from one record body; ValueError (via the caller) on overrun."""

    __slots__ = ("buf", "pos")

    def __init__(self, buf, pos: int = 0):
        self.buf = buf
        self.pos = pos

    def _take(self, n: int):
        if n < 0 or self.pos + n > len(self.buf):
            raise IndexError(f"field of {n} bytes overruns the record ({len(self.buf)} bytes)")
        out = self.buf[self.pos:self.pos + n]
        self.pos += n
        return out

    def u8(self) -> int:
        return self._take(1)[0]

    def u16(self) -> int:
        return struct.unpack("<H", self._take(2))[0]

    def u32(self) -> int:
        return struct.unpack("<I", self._take(4))[0]

    def u64(self) -> int:
        return struct.unpack("<Q", self._take(8))[0]

    def string(self) -> str:
        return bytes(self._take(self.u32())).decode("utf-8")

    def bytes32(self) -> bytes:
        return bytes(self._take(self.u32()))

    def str_map(self) -> dict[str, str]:
        end = self.pos + self.u32()
        if end > len(self.buf):
            raise IndexError("map overruns the record")
        out = {}
        while self.pos < end:
            k = self.string()
            out[k] = self.string()
        return out

    def remaining(self):
        return self.buf[self.pos:]
