"""replay copies /tf and /tf_static of its input into its output unchanged (bytes, times,
schema, offered QoS, type hash), read back by the mcap library, an independent reader."""

from __future__ import annotations

import os
import struct
import sys

import numpy as np
from mcap.reader import make_reader

from gyro_attitude.io.cdr_arrays import TransformCdr
from gyro_attitude.io.mcap_writer import Rosbag2McapWriter
from gyro_attitude.io.qos import qos_profile, qos_profiles_yaml
from gyro_attitude.offline import replay
from gyro_attitude.offline.replay import replay_file

os.environ.setdefault("AMENT_PREFIX_PATH", sys.prefix)

TF_SCHEMA = b"geometry_msgs/TransformStamped[] transforms\n"  # as recorded (any text is kept)
TF_HASH = "RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087"
STATIC_QOS = qos_profiles_yaml([qos_profile(depth=1, durability="transient_local")])


def _tf(t_ns: int, child: str, k: int) -> bytes:
    stamp = struct.pack("<iI", *divmod(t_ns, 10**9))
    return TransformCdr("odom").encode(stamp, child, 0.0, 0.0, np.sin(k / 10), np.cos(k / 10))


def _input(path, n=500):
    t = 5 * 10**9 + np.arange(n, dtype=np.int64) * 2_000_000
    w = np.tile([0.0, 0.0, 0.1], (n, 1))
    with Rosbag2McapWriter(path, chunk_size=4096) as wr:
        wr.add_topic("imu/data_raw", "sensor_msgs/msg/Imu")
        wr.add_topic("/tf_static", "tf2_msgs/msg/TFMessage", STATIC_QOS,
                     recorded_schema=("ros2msg", TF_SCHEMA, TF_HASH))
        wr.add_topic("/tf", "tf2_msgs/msg/TFMessage",
                     recorded_schema=("ros2msg", TF_SCHEMA, TF_HASH))
        wr.write("/tf_static", _tf(t[0], "imu_link", 0), t[0] - 10**6)  # before any Imu
        wr.write_imu_array("imu/data_raw", t, w)
        # every 10th sample, published 1 us before it was logged, and one after the last Imu
        for k, tk in enumerate(list(t[::10]) + [t[-1] + 10**6]):
            wr.write("/tf", _tf(int(tk), "base_link", k), int(tk), int(tk) - 1000)
    return t


def _read(path, topics):
    with open(path, "rb") as f:
        reader = make_reader(f)
        return [(c.topic, s.name, s.encoding, s.data, dict(c.metadata), m.data, m.log_time,
                 m.publish_time)
                for s, c, m in reader.iter_messages(topics=topics, log_time_order=True)]


def test_tf_and_tf_static_are_copied_unchanged_between_the_output_blocks(tmp_path, monkeypatch):
    monkeypatch.setattr(replay, "OUTPUT_BLOCK_MESSAGES", 64)  # several blocks interleaved
    _input(tmp_path / "in.mcap")
    r = replay_file(tmp_path / "in.mcap", tmp_path / "out.mcap")
    assert r.attitude_messages == 500
    topics = ["/tf", "/tf_static"]
    want = _read(tmp_path / "in.mcap", topics)
    got = _read(tmp_path / "out.mcap", topics)
    assert len(want) == 1 + 51
    assert got == want
    # interleaved with the output's blocks (64 samples of 2 ms): in file order no message is
    # logged earlier than one block before a message written ahead of it, so a reader in
    # log-time order streams the output chunk by chunk instead of holding it all
    with open(tmp_path / "out.mcap", "rb") as f:
        logs = np.array([m.log_time for _, _, m in make_reader(f).iter_messages(
            log_time_order=False)], dtype=np.int64)
    assert logs.size == 2 * 500 + 52
    assert (np.maximum.accumulate(logs) - logs).max() <= 64 * 2_000_000


def test_a_recording_without_tf_gets_none(tmp_path):
    t = 5 * 10**9 + np.arange(100, dtype=np.int64) * 2_000_000
    with Rosbag2McapWriter(tmp_path / "in.mcap") as wr:
        wr.add_topic("imu/data_raw", "sensor_msgs/msg/Imu")
        wr.write_imu_array("imu/data_raw", t, np.zeros((100, 3)))
    replay_file(tmp_path / "in.mcap", tmp_path / "out.mcap")
    with open(tmp_path / "out.mcap", "rb") as f:
        summary = make_reader(f).get_summary()
    assert sorted(c.topic for c in summary.channels.values()) == ["/attitude", "/imu/data"]
