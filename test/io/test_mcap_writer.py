"""The writer's files, read back by independent readers: mcap (CRCs), mcap-ros2-support,
rosbags; byte equality of the array paths with rclpy's serialization."""

from __future__ import annotations

import struct
import zlib

import numpy as np
import pytest
import rclpy.serialization as rclpy_serialization
import yaml
from geometry_msgs.msg import QuaternionStamped
from mcap.reader import make_reader
from mcap.records import DataEnd, Footer
from mcap.stream_reader import StreamReader
from mcap_ros2.decoder import DecoderFactory
from sensor_msgs.msg import Imu
from std_msgs.msg import String

from gyro_attitude.io.cdr_arrays import imu_batch, quaternion_stamped_batch
from gyro_attitude.io.imu_fast import read_imu_arrays, read_quaternion_stamped_arrays
from gyro_attitude.io.mcap_writer import Rosbag2McapWriter
from gyro_attitude.io.qos import DEFAULT_QOS_YAML, qos_profile, qos_profiles_yaml


def random_unit_quaternions(rng, n):
    q = rng.normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)

def _imu_msg(t_ns, frame, w, a, q=None, cov=None):
    m = Imu()
    m.header.stamp.sec, m.header.stamp.nanosec = divmod(int(t_ns), 1_000_000_000)
    m.header.frame_id = frame
    m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z = map(float, w)
    m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z = map(float, a)
    if q is None:
        m.orientation_covariance[0] = -1.0
    else:
        m.orientation.x, m.orientation.y, m.orientation.z, m.orientation.w = map(float, q)
    if cov is not None:
        m.angular_velocity_covariance = [float(c) for c in cov]
    return m


def _write_sample(path, rng, compression="", n=50, chunk_size=3000):
    t = 1_700_000_000_000_000_000 + np.arange(n, dtype=np.int64) * 5_000_000 + 7
    w = rng.normal(size=(n, 3))
    a = rng.normal(size=(n, 3))
    q = random_unit_quaternions(rng, n)
    with Rosbag2McapWriter(path, compression=compression, chunk_size=chunk_size) as wr:
        wr.add_topic("imu/data_raw", "sensor_msgs/msg/Imu")
        wr.add_topic("/chatter", "std_msgs/msg/String",
                     qos_profiles_yaml([qos_profile(reliability="best_effort", depth=5)]))
        wr.add_topic("truth/attitude", "geometry_msgs/msg/QuaternionStamped")
        for i in range(3):
            wr.write_message("chatter", String(data=f"hello {i}"), int(t[0]) - 10 + i)
        wr.write_imu_array("imu/data_raw", t, w, a, frame_id="imu_link")
        wr.write_quaternion_stamped_array("truth/attitude", t, q, frame_id="enu")
    return t, w, a, q


@pytest.mark.parametrize("compression", ["", "zstd", "lz4"])
def test_mcap_and_mcap_ros2_read_back(tmp_path, compression):
    rng = np.random.default_rng(1)
    path = tmp_path / "a.mcap"
    t, w, a, q = _write_sample(path, rng, compression)
    with open(path, "rb") as f:
        reader = make_reader(f, validate_crcs=True, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        assert reader.get_header().profile == "ros2"
        imu, truth, chat = [], [], []
        for schema, channel, message, decoded in reader.iter_decoded_messages(
                log_time_order=False):
            assert schema.encoding == "ros2msg" and channel.message_encoding == "cdr"
            {"/imu/data_raw": imu, "/truth/attitude": truth, "/chatter": chat}[
                channel.topic].append((message, decoded))
    assert [d.data for _, d in chat] == ["hello 0", "hello 1", "hello 2"]
    assert len(imu) == len(truth) == len(t)
    for k, (m, d) in enumerate(imu):
        assert m.log_time == m.publish_time == t[k]
        assert d.header.stamp.sec * 10**9 + d.header.stamp.nanosec == t[k]
        assert d.header.frame_id == "imu_link"
        assert [d.angular_velocity.x, d.angular_velocity.y, d.angular_velocity.z] == list(w[k])
        assert [d.linear_acceleration.x, d.linear_acceleration.y,
                d.linear_acceleration.z] == list(a[k])
        assert d.orientation_covariance[0] == -1.0  # "no orientation estimate"
    for k, (_, d) in enumerate(truth):
        assert [d.quaternion.x, d.quaternion.y, d.quaternion.z, d.quaternion.w] == list(q[k])
    st = summary.statistics
    assert st.message_count == 2 * len(t) + 3
    assert st.channel_count == 3 and st.schema_count == 3 and st.metadata_count == 1
    assert st.message_start_time == int(t[0]) - 10 and st.message_end_time == int(t[-1])
    assert st.chunk_count == len(summary.chunk_indexes) > 3
    assert all(ci.compression == compression for ci in summary.chunk_indexes)
    ch = {c.topic: c for c in summary.channels.values()}
    assert ch["/chatter"].metadata["offered_qos_profiles"].startswith(
        "- history: keep_last\n  depth: 5\n  reliability: best_effort")
    assert ch["/imu/data_raw"].metadata["offered_qos_profiles"] == DEFAULT_QOS_YAML
    assert ch["/imu/data_raw"].metadata["topic_type_hash"].startswith("RIHS01_")


@pytest.mark.parametrize("data_crc", [False, True])
def test_crcs_and_summary_layout(tmp_path, data_crc):
    """Data-section CRC, summary CRC and summary offsets recomputed from the raw bytes."""
    path = tmp_path / "a.mcap"
    t = np.arange(30, dtype=np.int64) * 1000
    with Rosbag2McapWriter(path, compression="zstd", chunk_size=3000,
                           data_section_crc=data_crc) as wr:
        wr.add_topic("imu/data_raw", "sensor_msgs/msg/Imu")
        wr.add_topic("chatter", "std_msgs/msg/String")
        wr.write_message("chatter", String(data="x"), 5)
        wr.write_imu_array("imu/data_raw", t, np.ones((30, 3)))
    raw = path.read_bytes()
    records = []
    with open(path, "rb") as f:
        pos = 8
        for rec in StreamReader(f, skip_magic=False, emit_chunks=True).records:
            records.append(rec)
    data_end = next(r for r in records if isinstance(r, DataEnd))
    footer = next(r for r in records if isinstance(r, Footer))
    # Data End follows the data section: its CRC covers everything before it.
    de_off = footer.summary_start - (1 + 8 + 4)
    assert raw[de_off] == 0x0F
    # 0 = "not computed", what rosbag2 (libmcap's default) writes
    assert data_end.data_section_crc == (zlib.crc32(raw[:de_off]) if data_crc else 0)
    end = len(raw) - 8 - 4  # footer's CRC field and the closing magic
    assert footer.summary_crc == zlib.crc32(raw[footer.summary_start:end])
    assert raw[-8:] == raw[:8] == b"\x89MCAP0\r\n"
    # Summary offsets point at groups of the right opcode.
    pos = footer.summary_offset_start
    groups = {}
    while raw[pos] == 0x0E:
        op, start, length = struct.unpack_from("<BQQ", raw, pos + 9)
        assert raw[start] == op
        groups[op] = length
        pos += 9 + struct.unpack_from("<Q", raw, pos + 1)[0]
    assert set(groups) == {0x03, 0x04, 0x0B, 0x08, 0x0D}


def test_rosbag2_metadata_record(tmp_path):
    path = tmp_path / "a.mcap"
    t, *_ = _write_sample(path, np.random.default_rng(3))
    with open(path, "rb") as f:
        metas = list(make_reader(f).iter_metadata())
    assert [m.name for m in metas] == ["rosbag2"]
    meta = yaml.safe_load(metas[0].metadata["serialized_metadata"])
    assert meta["version"] == 9 and meta["storage_identifier"] == "mcap"
    assert meta["message_count"] == 2 * len(t) + 3
    counts = {x["topic_metadata"]["name"]: x["message_count"]
              for x in meta["topics_with_message_count"]}
    assert counts == {"/imu/data_raw": len(t), "/truth/attitude": len(t), "/chatter": 3}
    assert meta["starting_time"]["nanoseconds_since_epoch"] == int(t[0]) - 10
    assert meta["duration"]["nanoseconds"] == int(t[-1]) - (int(t[0]) - 10)
    qos = meta["topics_with_message_count"][0]["topic_metadata"]["offered_qos_profiles"]
    assert isinstance(qos, list) and qos[0]["history"] in ("keep_last", "keep_all")


def test_rosbags_reads_file_and_bag_directory(tmp_path):
    from rosbags.highlevel import AnyReader

    rng = np.random.default_rng(4)
    t, w, a, q = _write_sample(tmp_path / "f.mcap", rng)
    bag = tmp_path / "bagdir"
    with Rosbag2McapWriter(bag, bag_directory=True) as wr:
        wr.add_topic("imu/data_raw", "sensor_msgs/msg/Imu")
        wr.write_imu_array("imu/data_raw", t, w, a)
    meta = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert meta["version"] == 9 and meta["relative_file_paths"] == ["bagdir_0.mcap"]
    for src, n_expected in ((tmp_path / "f.mcap", 2 * len(t) + 3), (bag, len(t))):
        with AnyReader([src]) as reader:
            got = []
            for con, _ts, raw in reader.messages():
                msg = reader.deserialize(raw, con.msgtype)
                if con.topic == "/imu/data_raw":
                    got.append([msg.angular_velocity.x, msg.angular_velocity.y,
                                msg.angular_velocity.z])
            assert reader.message_count == n_expected
        np.testing.assert_array_equal(np.array(got), w)


@pytest.mark.parametrize("frame", ["", "a", "abc", "imu", "imu_link", "base_link_imu0",
                                   "ünï"])
def test_array_paths_are_byte_identical_to_rclpy(tmp_path, frame):
    rng = np.random.default_rng(5)
    n = 7
    t = np.array([0, 1, 999_999_999, 10**9, 2**31 * 10**9 - 1, 5, 6], dtype=np.int64)
    w, a = rng.normal(size=(n, 3)), rng.normal(size=(n, 3))
    q = random_unit_quaternions(rng, n)
    cov = rng.normal(size=(n, 9))
    path = tmp_path / "b.mcap"
    with Rosbag2McapWriter(path) as wr:
        wr.add_topic("imu", "sensor_msgs/msg/Imu")
        wr.add_topic("imu2", "sensor_msgs/msg/Imu")
        wr.add_topic("att", "geometry_msgs/msg/QuaternionStamped")
        wr.write_imu_array("imu", t, w, a, frame_id=frame)
        wr.write_imu_array("imu2", t, w, a, q, frame_id=frame, angular_velocity_covariance=cov)
        wr.write_quaternion_stamped_array("att", t, q, frame_id=frame)
    with open(path, "rb") as f:
        msgs = {}
        for _, ch, m in make_reader(f).iter_messages(log_time_order=False):
            msgs.setdefault(ch.topic, []).append(m.data)
    # CDR padding bytes between the frame_id's NUL and the first double are unspecified
    # (rclpy leaves whatever was in its buffer; we write zeros): compare around them.
    pad_lo = 16 + len(frame.encode()) + 1
    pad_hi = 4 + (12 + len(frame.encode()) + 1 + 7) // 8 * 8

    def ser(msg):
        b = rclpy_serialization.serialize_message(msg)
        return b[:pad_lo] + b"\x00" * (pad_hi - pad_lo) + b[pad_hi:]

    # The writer puts messages in log-time order (here the stamps), stable among equals.
    for j, k in enumerate(np.argsort(t, kind="stable")):
        assert msgs["/imu"][j] == ser(_imu_msg(t[k], frame, w[k], a[k]))
        assert msgs["/imu2"][j] == ser(_imu_msg(t[k], frame, w[k], a[k], q[k], cov[k]))
        qs = QuaternionStamped()
        qs.header.stamp.sec, qs.header.stamp.nanosec = divmod(int(t[k]), 10**9)
        qs.header.frame_id = frame
        qs.quaternion.x, qs.quaternion.y, qs.quaternion.z, qs.quaternion.w = map(float, q[k])
        assert msgs["/att"][j] == ser(qs)


def test_flush_leaves_a_readable_file_without_summary(tmp_path):
    """What kill -9 leaves after a flush: all flushed chunks readable (mcap's own reader
    too, which walks the records without the summary)."""
    path = tmp_path / "c.mcap"
    wr = Rosbag2McapWriter(path)
    wr.add_topic("chatter", "std_msgs/msg/String")
    for i in range(10):
        wr.write_message("chatter", String(data=str(i)), 100 + i)
    wr.flush()
    wr.write_message("chatter", String(data="lost"), 200)  # open chunk, never flushed
    wr.abandon()
    with open(path, "rb") as f:
        got = []
        with pytest.raises(Exception):  # noqa: B017 - mcap raises its own EndOfFile
            for rec in StreamReader(f, skip_magic=False).records:
                if type(rec).__name__ == "Message":
                    got.append(rec.log_time)
    assert got == list(range(100, 110))


def test_max_chunk_interval_closes_chunks(tmp_path, monkeypatch):
    import gyro_attitude.io.mcap_writer as mw

    now = [1000.0]
    monkeypatch.setattr(mw.time, "monotonic", lambda: now[0])
    path = tmp_path / "d.mcap"
    with Rosbag2McapWriter(path, max_chunk_interval_s=1.0) as wr:
        wr.add_topic("chatter", "std_msgs/msg/String")
        for i in range(6):
            wr.write_message("chatter", String(data=str(i)), i)
            now[0] += 0.6
    # Messages at t = 0, 0.6, 1.2 | 1.8, 2.4, 3.0 s: the third finds its chunk 1.2 s old
    # and closes it; likewise the sixth.
    with open(path, "rb") as f:
        idx = make_reader(f).get_summary().chunk_indexes
    assert [(c.message_start_time, c.message_end_time) for c in idx] == [(0, 2), (3, 5)]


def test_writer_errors(tmp_path):
    with pytest.raises(ValueError, match="compression"):
        Rosbag2McapWriter(tmp_path / "x.mcap", compression="gzip")
    with Rosbag2McapWriter(tmp_path / "y.mcap") as wr:
        wr.add_topic("imu", "sensor_msgs/msg/Imu")
        assert wr.add_topic("/imu", "sensor_msgs/msg/Imu") == 1
        with pytest.raises(ValueError, match="already added with type"):
            wr.add_topic("imu", "std_msgs/msg/String")
        with pytest.raises(ValueError, match="was not added"):
            wr.write("other", b"\x00\x01\x00\x00", 1)
        with pytest.raises(ValueError, match="not sensor_msgs/msg/Imu|has type"):
            wr.add_topic("att", "geometry_msgs/msg/QuaternionStamped")
            wr.write_imu_array("att", np.arange(3), np.zeros((3, 3)))
        with pytest.raises(ValueError, match="angular_velocity must have shape"):
            wr.write_imu_array("imu", np.arange(3), np.zeros((2, 3)))
        with pytest.raises(ValueError, match="integer n"):
            wr.write_imu_array("imu", np.arange(3) * 1.0, np.zeros((3, 3)))
        with pytest.raises(ValueError, match="non-negative"):
            wr.write("imu", b"", -1)
        with pytest.raises(ValueError, match="QoS"):
            wr.add_topic("q", "std_msgs/msg/String", "- history: sometimes\n")
    with pytest.raises(ValueError, match="already finished"):
        wr.write("imu", b"", 1)
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "f").write_text("x")
    with pytest.raises(ValueError, match="not an empty directory"):
        Rosbag2McapWriter(tmp_path / "full", bag_directory=True)


def test_batches_are_merged_by_log_time_across_channels(tmp_path):
    """Oracle: Python's stable sort of the concatenated batches by log time (batch order
    breaks ties), against the mcap package's reader in file order."""
    rng = np.random.default_rng(8)
    specs = [("imu", 700), ("att", 300), ("imu2", 50)]
    batches, expected = [], []
    pub_id = 0
    for topic, n in specs:
        log = rng.integers(0, 400, size=n).astype(np.int64) * 1000  # ties and disorder
        pub = np.arange(pub_id, pub_id + n, dtype=np.int64)  # message identity
        pub_id += n
        if topic == "att":
            batches.append(quaternion_stamped_batch(topic, log, [0, 0, 0, 1.0],
                                                    log_time_ns=log, publish_time_ns=pub))
        else:
            batches.append(imu_batch(topic, log, np.zeros((n, 3)), log_time_ns=log,
                                     publish_time_ns=pub, frame_id=topic))
        order = np.argsort(log, kind="stable")
        expected += [("/" + topic, int(log[k]), int(pub[k])) for k in order]
    expected.sort(key=lambda m: m[1])  # stable: batch order among equal times
    path = tmp_path / "m.mcap"
    with Rosbag2McapWriter(path, chunk_size=5000) as wr:
        wr.add_topic("imu", "sensor_msgs/msg/Imu")
        wr.add_topic("att", "geometry_msgs/msg/QuaternionStamped")
        wr.add_topic("imu2", "sensor_msgs/msg/Imu")
        wr.write_batches(batches)
    with open(path, "rb") as f:
        reader = make_reader(f, validate_crcs=True)
        got = [(ch.topic, m.log_time, m.publish_time)
               for _, ch, m in reader.iter_messages(log_time_order=False)]
        chunks = reader.get_summary().chunk_indexes
    assert got == expected
    assert len(chunks) > 10 and {c.compression for c in chunks} == {"zstd"}
    # each chunk's time range is what it holds, and sequences count per channel
    with open(path, "rb") as f:
        seqs = {}
        for _, ch, m in make_reader(f).iter_messages(log_time_order=False):
            seqs.setdefault(ch.topic, []).append(m.sequence)
    assert all(s == list(range(len(s))) for s in seqs.values())


def test_batches_with_the_same_log_times_alternate(tmp_path):
    """A replay's two outputs share log times: round robin in batch order, checked by the
    mcap package's reader (and the bytes by decoding every message)."""
    n = 3000
    log = 10**9 + np.arange(n, dtype=np.int64) * 1000
    q = random_unit_quaternions(np.random.default_rng(3), n)
    w = np.random.default_rng(4).normal(size=(n, 3))
    path = tmp_path / "rr.mcap"
    with Rosbag2McapWriter(path, chunk_size=20_000) as wr:
        wr.add_topic("attitude", "geometry_msgs/msg/QuaternionStamped")
        wr.add_topic("imu/data", "sensor_msgs/msg/Imu")
        wr.write_batches([quaternion_stamped_batch("attitude", log, q),
                          imu_batch("imu/data", log, w, None, q)])
    with open(path, "rb") as f:
        got = [(ch.topic, m.log_time)
               for _, ch, m in make_reader(f, validate_crcs=True).iter_messages(
                   log_time_order=False)]
    assert got == [(t, int(x)) for x in log for t in ("/attitude", "/imu/data")]
    att = read_quaternion_stamped_arrays(path, "attitude")
    imu = read_imu_arrays(path, "imu/data")
    np.testing.assert_array_equal(att.quaternion, q)
    np.testing.assert_array_equal(imu.orientation, q)
    np.testing.assert_array_equal(imu.angular_velocity, w)
