"""The streaming reader: real rosbag2 files, and damaged files (truncation at every byte,
corrupted chunks, wrong/empty/non-MCAP files, fuzzing)."""

from __future__ import annotations

import time

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from mcap.reader import make_reader

from gyro_attitude.io.imu_fast import read_topic_arrays
from gyro_attitude.io.mcap_reader import McapDamagedError, McapStreamReader
from gyro_attitude.io.mcap_writer import Rosbag2McapWriter

IMU = "sensor_msgs/msg/Imu"
QS = "geometry_msgs/msg/QuaternionStamped"


def _mcap_messages(path):
    """(topic, log_time, data) by the mcap package's reader (independent oracle)."""
    with open(path, "rb") as f:
        return [(ch.topic, m.log_time, m.data)
                for _, ch, m in make_reader(f, validate_crcs=True).iter_messages(
                    log_time_order=False)]


@pytest.mark.parametrize("name", ["only_topics.mcap", "talker/talker.mcap", "talker"])
def test_reads_real_rosbag2_files(reference_dir, name):
    path = reference_dir / name
    reader = McapStreamReader(path)
    ours = [(m.channel.topic, m.log_time, m.data) for m in reader.iter_messages()]
    mcap_path = path if path.is_file() else path / "talker.mcap"
    assert sorted(ours) == sorted(_mcap_messages(mcap_path))
    assert reader.profile == "ros2" and reader.complete and reader.damage is None
    assert len(ours) == (7 if name == "only_topics.mcap" else 20)
    if name == "only_topics.mcap":
        assert [n for n, _ in reader.metadata] == ["rosbag2", "rosbag2"]


@pytest.fixture(scope="module")
def small_file(tmp_path_factory):
    """~4 kB: Imu and QuaternionStamped in several small chunks, one zstd."""
    path = tmp_path_factory.mktemp("small") / "small.mcap"
    rng = np.random.default_rng(20)
    n = 8
    t = 10**9 + np.arange(n, dtype=np.int64) * 10**6
    with Rosbag2McapWriter(path, chunk_size=700) as wr:
        wr.add_topic("imu/data_raw", IMU)
        wr.add_topic("truth/attitude", QS)
        wr.write_imu_array("imu/data_raw", t, rng.normal(size=(n, 3)), frame_id="i")
        wr.write_quaternion_stamped_array("truth/attitude", t, [0, 0, 0, 1.0])
    return path


def _chunk_ends(path):
    """Per chunk: (end offset incl. its message index, messages in it), by mcap's summary."""
    with open(path, "rb") as f:
        idx = make_reader(f).get_summary().chunk_indexes
    return [(c.chunk_start_offset + c.chunk_length, c.chunk_start_offset + c.chunk_length
             + c.message_index_length) for c in idx]


def test_truncated_at_every_byte(small_file, tmp_path):
    raw = small_file.read_bytes()
    full = [(m.channel.topic, m.log_time, m.data)
            for m in McapStreamReader(small_file).iter_messages()]
    full_imu = read_topic_arrays(small_file, {"imu/data_raw": IMU})["imu/data_raw"]
    chunk_ends = _chunk_ends(small_file)
    data_end = raw.rfind(b"\x0f\x04\x00\x00\x00\x00\x00\x00\x00")  # Data End record
    assert data_end > 0
    start = time.monotonic()
    # In memory (the same code path as files; a file system write per cut would dominate).
    for cut in range(len(raw)):
        cut_path = raw[:cut]
        if cut < 8:  # nothing of the file is there: refused whatever on_damage says
            with pytest.raises(McapDamagedError, match="empty file|inside the MCAP magic"):
                list(McapStreamReader(cut_path, on_damage="warn").iter_messages())
            continue
        reader = McapStreamReader(cut_path, on_damage="warn")
        got = [(m.channel.topic, m.log_time, m.data) for m in reader.iter_messages()]
        # Everything readable is a prefix of the file's messages ...
        assert got == full[:len(got)], cut
        # ... and no complete chunk before the cut is lost.
        n_complete = sum(1 for end, _ in chunk_ends if end <= cut)
        assert len(got) >= sum(_msgs_in_chunk(small_file, k) for k in range(n_complete)), cut
        intact = cut >= data_end + 13
        assert (reader.damage is None) == intact, cut
        if not intact:
            with pytest.raises(McapDamagedError):
                list(McapStreamReader(cut_path).iter_messages())
            if cut >= 8:
                imu = read_topic_arrays(cut_path, {"imu/data_raw": IMU}, on_damage="warn",
                                        required=False).get("imu/data_raw")
                if imu is not None:
                    k = len(imu)
                    np.testing.assert_array_equal(imu.angular_velocity,
                                                  full_imu.angular_velocity[:k])
    assert time.monotonic() - start < 60
    # And a few real truncated files.
    for cut in (chunk_ends[0][1], data_end, data_end + 13):
        p = tmp_path / "cut.mcap"
        p.write_bytes(raw[:cut])
        reader = McapStreamReader(p, on_damage="warn")
        assert len(list(reader.iter_messages())) > 0
        assert (reader.damage is None) == (cut == data_end + 13)


_chunk_counts: dict = {}


def _msgs_in_chunk(path, k):
    if path not in _chunk_counts:
        counts = []
        reader = McapStreamReader(path)
        from gyro_attitude.io.mcap_reader import iter_chunk_messages

        for chunk in reader.iter_chunks():
            counts.append(sum(1 for _ in iter_chunk_messages(chunk.records)))
        _chunk_counts[path] = counts
    return _chunk_counts[path][k]


def test_corrupted_chunk_keeps_earlier_chunks(small_file, tmp_path):
    raw = bytearray(small_file.read_bytes())
    with open(small_file, "rb") as f:
        idx = make_reader(f).get_summary().chunk_indexes
    second = idx[1]
    raw[second.chunk_start_offset + second.chunk_length - 20] ^= 0xFF  # inside its records
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(bytes(raw))
    reader = McapStreamReader(bad, on_damage="warn")
    got = [(m.channel.topic, m.log_time, m.data) for m in reader.iter_messages()]
    full = [(m.channel.topic, m.log_time, m.data)
            for m in McapStreamReader(small_file).iter_messages()]
    # the damaged chunk is skipped, every other chunk read
    n0, n1 = _msgs_in_chunk(small_file, 0), _msgs_in_chunk(small_file, 1)
    assert got == full[:n0] + full[n0 + n1:] and len(idx) > 2
    assert str(second.chunk_start_offset) in reader.damage
    assert "CRC mismatch" in reader.damage or "Data corruption" in reader.damage  # zstd's own
    with pytest.raises(McapDamagedError, match="CRC mismatch|Data corruption"):
        list(McapStreamReader(bad).iter_messages())


@pytest.mark.parametrize("content, match", [
    (b"", "empty file"),
    (b"hello world, not mcap at all", "not an MCAP file"),
    (b"\x89MCA", "inside the MCAP magic"),
    (b"\x89MCAP0\r\n\x01" + (2**62).to_bytes(8, "little"),
     "damaged at byte 8: .* declares 4611686018427387904 bytes, the file has 0 left"),
    (b"\x89MCAP0\r\n\x01\x00\x00", "damaged at byte 8: record header cut"),
])
def test_bad_files_give_clear_errors(tmp_path, content, match):
    p = tmp_path / "x.mcap"
    p.write_bytes(content)
    with pytest.raises(McapDamagedError, match=match):
        list(McapStreamReader(p).iter_messages())


def test_missing_file_and_bag_dir(tmp_path):
    with pytest.raises(ValueError, match="no such file"):
        McapStreamReader(tmp_path / "nope.mcap")
    (tmp_path / "empty_bag").mkdir()
    with pytest.raises(ValueError, match="holds 0 .mcap files"):
        McapStreamReader(tmp_path / "empty_bag")


@settings(max_examples=150, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_fuzz_mutations_never_crash(small_file, tmp_path, data):
    raw = bytearray(small_file.read_bytes())
    n_mut = data.draw(st.integers(1, 6))
    for _ in range(n_mut):
        pos = data.draw(st.integers(0, len(raw) - 1))
        raw[pos] = data.draw(st.integers(0, 255))
    cut = data.draw(st.integers(0, len(raw)))
    p = tmp_path / "fuzz.mcap"
    p.write_bytes(bytes(raw[:cut]))
    start = time.monotonic()
    try:
        list(McapStreamReader(p, on_damage="warn").iter_messages())
        read_topic_arrays(p, {"imu/data_raw": IMU, "truth/attitude": QS}, on_damage="warn",
                          required=False)
    except ValueError:
        pass  # McapDamagedError or a clear ValueError (e.g. a mangled type name)
    assert time.monotonic() - start < 5.0


def test_chunk_size_cap_bounds_memory(tmp_path):
    """A chunk declaring more uncompressed bytes than max_chunk_bytes is refused before
    anything is decompressed (a corrupted or hostile size cannot exhaust memory)."""
    path = tmp_path / "z.mcap"
    with Rosbag2McapWriter(path, compression="zstd") as wr:
        wr.add_topic("imu/data_raw", IMU)
        wr.write_imu_array("imu/data_raw", np.arange(1000), np.zeros((1000, 3)))
    with pytest.raises(McapDamagedError, match="declares .* uncompressed bytes .limit 10000"):
        list(McapStreamReader(path, max_chunk_bytes=10_000).iter_messages())
    assert len(list(McapStreamReader(path).iter_messages())) == 1000
