"""Hostile MCAP files: decompression bombs, forged sizes and counts, mutated files.

Each must end in a clear error or be read as damaged, within seconds and with bounded
memory (tracemalloc follows numpy's and the decompressors' Python-visible buffers), through
the reader, the array reader and the replay pipeline."""

from __future__ import annotations

import io
import struct
import time
import tracemalloc

import numpy as np
import pytest
import zstandard
from mcap.reader import make_reader

from gyro_attitude.io.cdr_arrays import imu_batch, quaternion_stamped_batch
from gyro_attitude.io.imu_fast import read_imu_arrays, read_topic_arrays
from gyro_attitude.io.mcap_reader import McapDamagedError, McapStreamReader
from gyro_attitude.io.mcap_records import (
    MAGIC,
    OP_CHUNK,
    OP_CHUNK_INDEX,
    OP_STATISTICS,
    RECORD_HEADER,
    chunk_record_head,
    data_end_record,
    footer_head,
    header_record,
)
from gyro_attitude.io.mcap_writer import Rosbag2McapWriter
from gyro_attitude.io.rosbag2_profile import Rosbag2Topic, ros2_schema_record
from gyro_attitude.offline.replay import replay_file

IMU = "sensor_msgs/msg/Imu"
QS = "geometry_msgs/msg/QuaternionStamped"
FUZZ_CASES = 32
MiB = 1024 * 1024


def _zeros_frame(n_bytes: int) -> bytes:
    """One zstd frame of ``n_bytes`` zeros (its header declares the size), built by
    streaming so the zeros are never in memory at once."""
    out = zstandard.ZstdCompressor(level=3).compressobj(size=n_bytes)
    block = bytes(MiB)
    parts = [out.compress(block) for _ in range(n_bytes // MiB)]
    parts.append(out.compress(bytes(n_bytes % MiB)))
    parts.append(out.flush())
    return b"".join(parts)


def _bomb_file(path, declared: int, frame: bytes) -> None:
    """Header, Imu schema + channel, one zstd chunk declaring ``declared`` bytes, Data End."""
    ch = Rosbag2Topic.create(1, "/imu/data_raw", IMU, 1, None)
    chunk = chunk_record_head(0, 10, declared, 0, "zstd", len(frame)) + frame
    path.write_bytes(MAGIC + header_record("ros2", "bomb") + ros2_schema_record(1, IMU)
                     + ch.channel_record() + chunk + data_end_record(0)
                     + footer_head(0, 0) + b"\0\0\0\0" + MAGIC)


def _bounded(fn, *, seconds: float, peak_bytes: int):
    tracemalloc.start()
    start = time.monotonic()
    try:
        return fn()
    finally:
        elapsed = time.monotonic() - start
        _, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        assert elapsed < seconds, f"took {elapsed:.1f} s"
        assert peak < peak_bytes, f"peak {peak / MiB:.0f} MiB"


@pytest.fixture(scope="module")
def big_zero_frame():
    return _zeros_frame(4 * 1024 * MiB)  # 4 GiB of zeros: ~137 kB


def test_four_gib_of_declared_zeros_is_refused_in_seconds(tmp_path, big_zero_frame):
    assert len(big_zero_frame) < 200_000
    path = tmp_path / "bomb.mcap"
    _bomb_file(path, 4 * 1024 * MiB, big_zero_frame)
    reader = McapStreamReader(path, on_damage="warn")
    _bounded(lambda: list(reader.iter_messages()), seconds=5, peak_bytes=20 * MiB)
    assert "chunk declares 4294967296 uncompressed bytes" in reader.damage
    with pytest.raises(ValueError, match="has no messages; .*damaged at byte"):
        _bounded(lambda: replay_file(path, tmp_path / "o.mcap"), seconds=5,
                 peak_bytes=20 * MiB)
    assert not (tmp_path / "o.mcap").exists()
    # Under the hard cap but far beyond any real compression ratio: refused as well.
    _bomb_file(path, 200 * MiB, big_zero_frame)
    reader = McapStreamReader(path, on_damage="warn")
    _bounded(lambda: list(reader.iter_messages()), seconds=5, peak_bytes=20 * MiB)
    assert "more than 1000x" in reader.damage


def test_frame_larger_than_its_declared_chunk_stops_at_the_declaration(tmp_path):
    """The chunk declares a believable 64 kB, the zstd frame inside holds 256 MiB: the
    decompression must stop just past 64 kB (zstd's decompress() would allocate the
    frame's own 256 MiB)."""
    path = tmp_path / "liar.mcap"
    _bomb_file(path, 64_000, _zeros_frame(256 * MiB))
    reader = McapStreamReader(path, on_damage="warn")
    _bounded(lambda: list(reader.iter_messages()), seconds=5, peak_bytes=8 * MiB)
    assert "decompressed to 64001 bytes, declares 64000" in reader.damage


@pytest.fixture()
def good_file(tmp_path):
    path = tmp_path / "good.mcap"
    n = 3000
    t = 10**9 + np.arange(n, dtype=np.int64) * 10**6
    with Rosbag2McapWriter(path, chunk_size=64 * 1024) as w:
        w.add_topic("imu/data_raw", IMU)
        w.write_imu_array("imu/data_raw", t, np.tile([0.0, 0.0, 0.1], (n, 1)))
    return path


def _summary_record_offsets(data: bytes, opcode: int) -> list[int]:
    with io.BytesIO(data) as f:
        s = make_reader(f).get_summary()
    assert s is not None
    out = []
    pos = struct.unpack_from("<Q", data, len(data) - 8 - 20)[0]  # footer summary_start
    while pos < len(data) - 8 - 29:
        op, length = RECORD_HEADER.unpack_from(data, pos)
        if op == opcode:
            out.append(pos)
        pos += RECORD_HEADER.size + length
    return out


def test_forged_statistics_count_allocates_nothing_big(tmp_path, good_file):
    data = bytearray(good_file.read_bytes())
    [stats] = _summary_record_offsets(bytes(data), OP_STATISTICS)
    body = stats + RECORD_HEADER.size
    struct.pack_into("<Q", data, body, 2**39)  # total message count
    counts = body + 8 + 2 + 4 * 4 + 8 + 8 + 4
    struct.pack_into("<Q", data, counts + 2, 2**39)  # channel 1: 8 TiB worth of Imu arrays
    for ci in _summary_record_offsets(bytes(data), OP_CHUNK_INDEX):  # and huge chunk sizes
        length = RECORD_HEADER.unpack_from(data, ci)[1]
        struct.pack_into("<Q", data, ci + RECORD_HEADER.size + length - 8, 2**40)
    forged = tmp_path / "forged.mcap"
    forged.write_bytes(bytes(data))
    assert McapStreamReader(good_file).summary().message_counts == {1: 3000}
    assert McapStreamReader(forged).summary().message_counts == {}  # not believed
    expected = read_imu_arrays(good_file)
    got = _bounded(lambda: read_imu_arrays(forged), seconds=5, peak_bytes=40 * MiB)
    np.testing.assert_array_equal(got.angular_velocity, expected.angular_velocity)
    result = _bounded(lambda: replay_file(forged, tmp_path / "o.mcap"), seconds=10,
                      peak_bytes=60 * MiB)
    assert result.messages == 3000


def _mutations(raw: bytes, rng: np.random.Generator, chunk_offsets: list[int]):
    """Seeded hostile variants: truncations, byte flips, forged record lengths, forged
    chunk sizes and message-index counts."""
    n = len(raw)
    kind = rng.integers(5)
    data = bytearray(raw)
    if kind == 0:
        return bytes(data[:rng.integers(0, n)])
    if kind == 1:
        for pos in rng.integers(0, n, size=rng.integers(1, 8)):
            data[pos] ^= int(rng.integers(1, 256))
        return bytes(data)
    huge = [2**63 - 1, 2**40, 2**32 + 5, n, n + 1, 0, 1, 7]
    value = huge[rng.integers(len(huge))]
    if kind == 2:  # a record length somewhere
        pos = int(rng.choice(chunk_offsets)) + 1
        struct.pack_into("<Q", data, pos, value)
    elif kind == 3:  # a chunk's uncompressed size or compressed length
        c = int(rng.choice(chunk_offsets))
        field = (9 + 16) if rng.integers(2) else (9 + 28 + 4 + 4)  # usize, or records length
        struct.pack_into("<Q", data, c + field, value)
    else:  # the entries length of a message index
        c = int(rng.choice(chunk_offsets))
        length = RECORD_HEADER.unpack_from(raw, c)[1]
        mi = c + RECORD_HEADER.size + length
        if mi + 15 < n:
            struct.pack_into("<I", data, mi + RECORD_HEADER.size + 2, value & 0xFFFFFFFF)
    return bytes(data)


def _fuzz_source(tmp_path):
    """A 400-message Imu + truth file in ~40 small chunks, and its chunk offsets."""
    src = tmp_path / "src.mcap"
    n = 400
    t = 10**9 + np.arange(n, dtype=np.int64) * 10**6
    with Rosbag2McapWriter(src, chunk_size=4000) as w:
        w.add_topic("imu/data_raw", IMU)
        w.add_topic("truth/attitude", QS)
        w.write_batches([imu_batch("imu/data_raw", t, np.tile([0.1, 0.0, 0.2], (n, 1))),
                         quaternion_stamped_batch("truth/attitude", t[::10], [0, 0, 0, 1.0])])
    raw = src.read_bytes()
    chunk_offsets = []
    pos = len(MAGIC)
    while pos < len(raw):
        op, length = RECORD_HEADER.unpack_from(raw, pos)
        if op == OP_CHUNK:
            chunk_offsets.append(pos)
        if op == 0x0F:
            break
        pos += RECORD_HEADER.size + length
    assert len(chunk_offsets) > 5
    return raw, chunk_offsets


def _outcome(fn):
    try:
        return ("ok", fn())
    except (McapDamagedError, ValueError) as exc:
        return (type(exc).__name__, str(exc))


def test_read_ahead_gives_what_the_plain_walk_gives(tmp_path, monkeypatch):
    """Chunks prepared ahead by the worker thread reach the caller with the same records,
    indexes, damage records (in the same order, also interleaved with the caller's own decode
    damage) and errors as the plain walk, on seeded mutated files, in both damage modes."""
    raw, chunk_offsets = _fuzz_source(tmp_path)
    rng = np.random.default_rng(77)
    path = tmp_path / "m.mcap"

    def walk(ahead, mode):
        reader = McapStreamReader(path, on_damage=mode, reuse_buffers=True)
        got = []
        try:
            for c in reader.iter_chunks(read_ahead=ahead):
                idx = None if c.message_index is None else {
                    k: v.tolist() for k, v in c.message_index.items()}
                got.append((bytes(c.records), idx, c.file_offset))
        except McapDamagedError as exc:
            got.append(("raised", str(exc)))
        return got, reader.damages, sorted(reader.channels)

    real_iter = McapStreamReader.iter_chunks
    for case in range(60):
        path.write_bytes(_mutations(raw, rng, chunk_offsets) if case else raw)
        for mode in ("warn", "raise"):
            assert walk(2, mode) == walk(0, mode), (case, mode)
        # through the array reader: the caller's own damage records interleave the same way
        monkeypatch.setattr(McapStreamReader, "iter_chunks",
                            lambda self, read_ahead=0: real_iter(self, 0))
        plain = _outcome(lambda: read_topic_arrays(path, {"imu/data_raw": IMU}, on_damage="warn",
                                                   required=False))
        monkeypatch.setattr(McapStreamReader, "iter_chunks", real_iter)
        ahead = _outcome(lambda: read_topic_arrays(path, {"imu/data_raw": IMU}, on_damage="warn",
                                                   required=False))
        assert plain[0] == ahead[0], case
        if plain[0] != "ok":
            assert plain == ahead, case
        elif "imu/data_raw" in plain[1]:
            a, b = plain[1]["imu/data_raw"], ahead[1]["imu/data_raw"]
            assert a.damage == b.damage, case
            np.testing.assert_array_equal(a.angular_velocity, b.angular_velocity)
            np.testing.assert_array_equal(a.stamp_ns, b.stamp_ns)


def test_read_ahead_damage_is_recorded_when_the_caller_gets_there(tmp_path):
    """Damage the worker finds ahead (a CRC mismatch in a later chunk) is recorded after what
    the caller records while it decodes an earlier chunk, as in the plain walk."""
    raw, chunk_offsets = _fuzz_source(tmp_path)
    data = bytearray(raw)
    c = chunk_offsets[3]
    struct.pack_into("<I", data, c + RECORD_HEADER.size + 24, 12345)  # chunk 3's CRC
    path = tmp_path / "m.mcap"
    path.write_bytes(bytes(data))
    orders = []
    for ahead in (0, 2):
        reader = McapStreamReader(path, on_damage="warn")
        for k, _ in enumerate(reader.iter_chunks(read_ahead=ahead)):
            if k == 1:
                time.sleep(0.3)  # the worker is now past chunk 3
                reader._damaged("what the caller found in chunk 1", 0)
        orders.append(reader.damages)
    assert orders[0] == orders[1]
    assert "caller" in orders[0][0] and "CRC" in orders[0][1]


@pytest.mark.parametrize(("budget", "ahead"), [(1, 1), (1 << 30, 2)])
def test_read_ahead_holds_what_its_budget_allows(tmp_path, monkeypatch, budget, ahead):
    """The worker runs at most ``read_ahead`` chunks ahead of the caller, and only one
    when a chunk already waiting is over READ_AHEAD_BYTES (huge chunks: two in memory)."""
    import gyro_attitude.io.mcap_reader as mr

    raw, _ = _fuzz_source(tmp_path)
    path = tmp_path / "m.mcap"
    path.write_bytes(raw)
    monkeypatch.setattr(mr, "READ_AHEAD_BYTES", budget)
    produced = []
    real_walk = McapStreamReader._walk_chunks

    def counting_walk(self):
        for chunk in real_walk(self):
            produced.append(chunk)
            yield chunk

    monkeypatch.setattr(McapStreamReader, "_walk_chunks", counting_walk)
    leads = []
    for k, _ in enumerate(McapStreamReader(path).iter_chunks(read_ahead=2)):
        time.sleep(0.02)  # the worker goes as far ahead as it may
        leads.append(len(produced) - (k + 1))
    assert max(leads) == ahead and min(leads) >= 0


def test_read_ahead_worker_stops_when_the_caller_does(tmp_path):
    """Leaving the loop early (or an error in the caller) joins the worker thread."""
    import threading

    raw, _ = _fuzz_source(tmp_path)
    path = tmp_path / "m.mcap"
    path.write_bytes(raw)
    before = threading.active_count()
    it = McapStreamReader(path).iter_chunks(read_ahead=2)
    next(it)
    assert threading.active_count() == before + 1
    it.close()
    assert threading.active_count() == before


def test_fuzz_reader_arrays_and_replay(tmp_path):
    """FUZZ_CASES seeded mutations (~20 s idle): never a traceback other than the documented
    ValueError family, never a hang, bounded memory."""
    raw, chunk_offsets = _fuzz_source(tmp_path)
    rng = np.random.default_rng(2024)
    cases = 0
    outcomes = {"read": 0, "damaged": 0, "refused": 0}
    tracemalloc.start()
    try:
        while cases < FUZZ_CASES:  # a fixed count: the same cases whatever the load
            data = _mutations(raw, rng, chunk_offsets)
            path = tmp_path / "m.mcap"
            path.write_bytes(data)
            start = time.monotonic()
            try:
                reader = McapStreamReader(path, on_damage="warn")
                list(reader.iter_messages())
                list(McapStreamReader(path, on_damage="warn").iter_messages(
                    log_time_order=True))
                read_topic_arrays(path, {"imu/data_raw": IMU, "truth/attitude": QS},
                                  on_damage="warn", required=False)
                out = tmp_path / "o.mcap"
                r = replay_file(path, out, force=True)
                outcomes["damaged" if r.input_damage else "read"] += 1
            except (McapDamagedError, ValueError) as exc:
                assert str(exc) and "\n" not in str(exc)
                outcomes["refused"] += 1
            assert time.monotonic() - start < 10, "a mutated file took too long"  # shared machine
            cases += 1
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert all(outcomes.values()), outcomes
    assert peak < 64 * MiB, f"peak {peak / MiB:.0f} MiB"


def test_descriptive_record_with_a_field_cut_short_is_damage():
    """A Schema whose data length says more than the record holds: damage, not a
    silently truncated schema."""
    from gyro_attitude.io.mcap_records import RecordParseError, parse_record, schema_record

    rec = schema_record(1, "pkg/msg/T", "ros2msg", b"0123456789")
    body = bytearray(rec[RECORD_HEADER.size:])
    struct.pack_into("<I", body, 2 + 4 + 9 + 4 + 7, 1000)  # data length: 1000 bytes
    with pytest.raises(RecordParseError, match="overruns"):
        parse_record(0x03, bytes(body))
    assert parse_record(0x03, rec[RECORD_HEADER.size:]).data == b"0123456789"
    assert parse_record(0x03, rec[RECORD_HEADER.size:] + b"pad").data == b"0123456789"


def _late_channel_file(tmp_path):
    """Imu on ``/robot/imu/data_raw`` from the first chunk; ``/imu/data_raw`` defined (by
    mcap's own writer, which puts Channel records inside chunks) two chunks later."""
    from mcap.writer import CompressionType, Writer

    from gyro_attitude.io.rosbag2_profile import full_msg_definition

    src = tmp_path / "src.mcap"
    with Rosbag2McapWriter(src) as w:
        w.add_topic("imu/data_raw", IMU)
        w.write_imu_array("imu/data_raw", np.arange(1, 3), [[1.0, 0, 0], [2.0, 0, 0]])
    robot_cdr, own_cdr = (m.data for m in McapStreamReader(src).iter_messages())
    path = tmp_path / "late.mcap"
    with open(path, "wb") as f:
        w = Writer(f, chunk_size=2000, compression=CompressionType.NONE)  # ~5 Imu a chunk
        w.start("ros2", "test")
        sid = w.register_schema(IMU, "ros2msg", full_msg_definition(IMU).encode())
        robot = w.register_channel("/robot/imu/data_raw", "cdr", sid)
        for k in range(7):
            w.add_message(robot, 10**9 + k, robot_cdr, 10**9 + k)
        own = w.register_channel("/imu/data_raw", "cdr", sid)
        for k in range(7, 30):
            w.add_message(own if k % 2 else robot, 10**9 + k, own_cdr if k % 2 else robot_cdr,
                          10**9 + k)
        w.finish()
    return path


def test_read_ahead_shows_the_caller_only_the_channels_it_has_reached(tmp_path, monkeypatch):
    """Channels (and schemas) the worker registers ahead become visible when the caller gets
    to their chunk: a slow caller sees the same channels at each chunk as the plain walk, and
    the array reader picks the same channels (not a result that depends on timing)."""
    path = _late_channel_file(tmp_path)

    def seen(ahead):
        reader = McapStreamReader(path)
        out = []
        for c in reader.iter_chunks(read_ahead=ahead):
            time.sleep(0.05)  # a busy caller: the worker is as far ahead as it may go
            out.append((c.file_offset, sorted(ch.topic for ch in reader.channels.values())))
        return out

    assert seen(2) == seen(0)
    assert seen(0)[0][1] == ["/robot/imu/data_raw"]

    real_iter = McapStreamReader.iter_chunks

    def slow(self, read_ahead=0):
        for c in real_iter(self, read_ahead):
            time.sleep(0.05)
            yield c

    monkeypatch.setattr(McapStreamReader, "iter_chunks",
                        lambda self, read_ahead=0: real_iter(self, 0))
    plain = _outcome(lambda: read_imu_arrays(path))
    monkeypatch.setattr(McapStreamReader, "iter_chunks", slow)
    ahead = _outcome(lambda: read_imu_arrays(path))
    assert plain[0] == ahead[0]
    if plain[0] == "ok":
        np.testing.assert_array_equal(plain[1].angular_velocity, ahead[1].angular_velocity)
    else:
        assert plain == ahead


def test_topic_matched_by_its_namespace_until_the_exact_one_appears_is_refused(tmp_path):
    """``imu/data_raw`` names ``/robot/imu/data_raw`` until ``/imu/data_raw`` is defined later
    in the file: the reader must not interleave the two recordings into one series."""
    path = _late_channel_file(tmp_path)
    with pytest.raises(ValueError, match=r"ambiguous: \['/imu/data_raw', '/robot/imu/data_raw'\]"
                                         r"; give the full name"):
        read_imu_arrays(path)
    own = read_imu_arrays(path, "/imu/data_raw")  # the full names still read
    robot = read_imu_arrays(path, "/robot/imu/data_raw")
    assert (len(own), len(robot)) == (12, 7 + 11)  # odd k of 7..29 are own
    assert (own.angular_velocity[:, 0] == 2.0).all() and (robot.angular_velocity[:, 0] == 1.0).all()


@pytest.mark.parametrize("layout", ["late_channel", "both_upfront", "no_summary"])
def test_ambiguous_relative_topic_is_refused_whatever_the_chunk_layout(tmp_path, layout):
    """``imu/data_raw`` fits ``/imu/data_raw`` and ``/robot/imu/data_raw``: refused naming
    both, whether the second channel is defined two chunks later, before any message, or in
    a file without summary; the full names read (replay, player and allan share the rule)."""
    from gyro_attitude.io.mcap_reader import match_topic

    if layout == "late_channel":
        path = _late_channel_file(tmp_path)
    else:
        path = tmp_path / f"{layout}.mcap"
        w = Rosbag2McapWriter(path, chunk_size=2000)
        w.add_topic("/robot/imu/data_raw", IMU)
        w.add_topic("/imu/data_raw", IMU)
        for topic in ("/robot/imu/data_raw", "/imu/data_raw"):
            w.write_imu_array(topic, 10**9 + np.arange(20), np.zeros((20, 3)))
        if layout == "no_summary":
            w.flush()
            w.abandon()
        else:
            w.finish()
    with pytest.raises(ValueError, match=r"'imu/data_raw' is ambiguous: \['/imu/data_raw', "
                                         r"'/robot/imu/data_raw'\]; give the full name"):
        read_imu_arrays(path, on_damage="warn")
    with pytest.raises(ValueError, match="ambiguous"):
        match_topic(["/imu/data_raw", "/robot/imu/data_raw"], "imu/data_raw")
    assert match_topic(["/imu/data_raw", "/robot/imu/data_raw"], "/imu/data_raw") == \
        "/imu/data_raw"
    assert len(read_imu_arrays(path, "/imu/data_raw", on_damage="warn")) > 0
