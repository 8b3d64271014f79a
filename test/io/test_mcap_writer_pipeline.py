"""write_batches' threads: errors in any of them reach the caller, without a hang or a
chunk written after the failed one; a channel fed by several batches of one call."""

from __future__ import annotations

import struct
import threading

import numpy as np
import pytest
from mcap.exceptions import EndOfFile
from mcap.records import Chunk, MessageIndex
from mcap.stream_reader import StreamReader

from gyro_attitude.io import cdr_arrays
from gyro_attitude.io.cdr_arrays import imu_batch, quaternion_stamped_batch
from gyro_attitude.io.mcap_writer import Rosbag2McapWriter

T0 = 1_700_000_000_000_000_000


def _pipeline_threads() -> list[threading.Thread]:
    return [t for t in threading.enumerate() if t.name.startswith("mcap_chunk")]


def _call_with_timeout(fn, seconds: float = 60.0) -> BaseException | None:
    """Run ``fn`` in a thread; the exception it raised (None if none); fails on a hang."""
    outcome: list = []

    def run():
        try:
            fn()
            outcome.append(None)
        except BaseException as exc:  # handed to the test
            outcome.append(exc)

    t = threading.Thread(target=run, daemon=True)
    t.start()
    t.join(seconds)
    assert not t.is_alive(), "write_batches hung"
    return outcome[0]


def _imu(n: int, topic: str = "imu") -> cdr_arrays.MessageBatch:
    t = T0 + np.arange(n, dtype=np.int64) * 1_000_000
    return imu_batch(topic, t, np.zeros((n, 3)), publish_time_ns=np.arange(n))


def test_disk_full_is_raised_in_the_caller(tmp_path):
    with pytest.raises(OSError, match="No space left"):  # unbuffered: seen at the first byte
        Rosbag2McapWriter("/dev/full")
    wr = Rosbag2McapWriter(tmp_path / "f.mcap", chunk_size=20_000, compression="")
    wr.add_topic("imu", "sensor_msgs/msg/Imu")
    wr.add_topic("imu2", "sensor_msgs/msg/Imu")
    wr._file.close()
    wr._file = open("/dev/full", "wb", buffering=0)  # the disk is full from here on
    exc = _call_with_timeout(lambda: wr.write_batches([_imu(5000), _imu(3000, "imu2")]))
    assert isinstance(exc, OSError) and exc.errno == 28  # ENOSPC
    assert _pipeline_threads() == []
    with pytest.raises(ValueError, match="already finished"):  # abandoned, not half-summarized
        wr.write_batches([_imu(3)])
    wr.finish()  # a no-op now, without an error


def test_closed_file_is_raised_in_the_caller(tmp_path):
    wr = Rosbag2McapWriter(tmp_path / "c.mcap", chunk_size=20_000)
    wr.add_topic("imu", "sensor_msgs/msg/Imu")
    wr._file.close()  # what a file closed under the writer looks like
    exc = _call_with_timeout(lambda: wr.write_batches([_imu(2000)]))
    assert isinstance(exc, ValueError) and "closed file" in str(exc)
    assert _pipeline_threads() == []


def test_error_building_a_chunk_leaves_exactly_the_chunks_before_it(tmp_path, monkeypatch):
    """A chunk whose build fails in a pool thread: the error reaches the caller and the
    file holds the chunks before it, complete, and nothing after (the chunks built or
    queued behind it are not written)."""
    n, fail_at = 3000, 1000
    real_fill = cdr_arrays.MessageBatch.fill

    def fill(self, recs, lo, hi, skip=()):
        if lo <= fail_at < hi:
            raise RuntimeError("planted failure")
        real_fill(self, recs, lo, hi, skip)

    monkeypatch.setattr(cdr_arrays.MessageBatch, "fill", fill)
    path = tmp_path / "f.mcap"
    wr = Rosbag2McapWriter(path, chunk_size=10_000, compression="")
    wr.add_topic("imu", "sensor_msgs/msg/Imu")
    exc = _call_with_timeout(lambda: wr.write_batches([_imu(n)]))
    assert isinstance(exc, RuntimeError) and str(exc) == "planted failure"
    assert _pipeline_threads() == []
    # Every chunk holds ceil(chunk_size / record size) messages (fixed-size records):
    # the file ends after the chunks before the one holding message fail_at.
    size = _imu(1).record_dtype().itemsize
    per_chunk = -(-10_000 // size)
    got = []
    with open(path, "rb") as f, pytest.raises(EndOfFile):
        for rec in StreamReader(f, skip_magic=False).records:
            if type(rec).__name__ == "Message":
                got.append(rec.publish_time)
    assert got == list(range(fail_at // per_chunk * per_chunk))


def _chunk_messages(data: bytes) -> list[tuple[int, int, int, int]]:
    """(channel id, sequence, log time, offset) of the Message records of an uncompressed
    chunk, by walking the MCAP record framing (opcode u8, length u64, body)."""
    out, pos = [], 0
    while pos < len(data):
        op, length = struct.unpack_from("<BQ", data, pos)
        if op == 0x05:
            cid, seq, log = struct.unpack_from("<HIQ", data, pos + 9)
            out.append((cid, seq, log, pos))
        pos += 9 + length
    assert pos == len(data)
    return out


def test_one_channel_fed_by_two_batches(tmp_path):
    """Two batches of the same topic in one call, irregularly interleaved: sequence numbers
    count in written order, and each chunk's Message Index of that channel lists all its
    messages (log time, offset) in file order."""
    rng = np.random.default_rng(11)
    la = np.sort(rng.integers(0, 300, size=700)).astype(np.int64) * 1000 + T0
    lb = np.sort(rng.integers(0, 300, size=500)).astype(np.int64) * 1000 + T0
    lq = T0 + np.arange(200, dtype=np.int64) * 1_500_000 // 1000
    path = tmp_path / "s.mcap"
    with Rosbag2McapWriter(path, chunk_size=9_000, compression="") as wr:
        wr.add_topic("imu", "sensor_msgs/msg/Imu")
        wr.add_topic("att", "geometry_msgs/msg/QuaternionStamped")
        wr.write_batches([_imu(3)])  # sequences continue from 3 on channel 1
        wr.write_batches([
            imu_batch("imu", la, np.zeros((la.size, 3))),
            quaternion_stamped_batch("att", lq, [0, 0, 0, 1.0]),
            imu_batch("imu", lb, np.ones((lb.size, 3)), frame_id="other_frame"),
        ])
    seqs: dict[int, list[int]] = {}
    chunks = 0
    with open(path, "rb") as f:
        pending: dict[int, list] = {}
        for rec in StreamReader(f, skip_magic=False, emit_chunks=True).records:
            if isinstance(rec, Chunk):
                assert not pending, "a chunk's Message Index records are missing"
                chunks += 1
                for cid, seq, log, off in _chunk_messages(rec.data):
                    seqs.setdefault(cid, []).append(seq)
                    pending.setdefault(cid, []).append((log, off))
            elif isinstance(rec, MessageIndex):
                assert list(rec.records) == pending.pop(rec.channel_id)
    assert not pending and chunks > 20
    assert seqs[1] == list(range(3 + 700 + 500)) and seqs[2] == list(range(200))
