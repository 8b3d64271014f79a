"""mcap_player as a process: original timing scaled by the rate factor, content, /clock,
looping, and a recording without summary (kill -9 leftovers)."""

from __future__ import annotations

import struct
import time

import numpy as np
import pytest

from gyro_attitude.io.mcap_records import MAGIC
from gyro_attitude.io.mcap_writer import Rosbag2McapWriter

pytestmark = pytest.mark.ros

MODULE = "gyro_attitude.ros.mcap_player_node"


def _recording(path, n=200, rate_hz=100, finish=True):
    t = 10**9 + (np.arange(n, dtype=np.int64) * 10**9) // rate_hz
    w = np.zeros((n, 3))
    w[:, 0] = np.arange(n)
    wr = Rosbag2McapWriter(path, chunk_size=4000)
    wr.add_topic("imu/data_raw", "sensor_msgs/msg/Imu")
    wr.write_imu_array("imu/data_raw", t, w)
    if finish:
        wr.finish()
    else:
        wr.flush()
        wr.abandon()
    return t


def _subscribe(node):
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import Imu

    got, clock = [], []
    node.create_subscription(
        Imu, "imu/data_raw",
        lambda m: got.append((time.monotonic(), m.angular_velocity.x,
                              m.header.stamp.sec * 10**9 + m.header.stamp.nanosec)),
        QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE))
    node.create_subscription(Clock, "/clock",
                             lambda m: clock.append(m.clock.sec * 10**9 + m.clock.nanosec), 100)
    return got, clock


@pytest.mark.parametrize("finished", [True, False])
def test_plays_with_timing_rate_and_clock(launch, ros_node, tmp_path, finished):
    t = _recording(tmp_path / "in.mcap", finish=finished)
    got, clock = _subscribe(ros_node)
    proc = launch(MODULE, "-p", f"input:={tmp_path / 'in.mcap'}", "-p", "rate:=2.0",
                  "-p", "namespace_topics:=true", "-p", "wait_for_subscribers:=1")
    assert ros_node.spin_until(lambda: len(got) >= len(t), 30.0), proc.output()
    assert proc.wait(timeout=15) == 0, proc.output()
    np.testing.assert_array_equal([g[1] for g in got], np.arange(len(t)))
    np.testing.assert_array_equal([g[2] for g in got], t)
    # 1.99 s of recording at rate 2: ~1.0 s of wall time between first and last message.
    span = got[-1][0] - got[0][0]
    print(f"\nplayback span {span:.3f} s for {(t[-1] - t[0]) * 1e-9:.3f} s at rate 2")
    assert 0.85 < span < 1.6
    assert clock and all(t[0] <= c <= t[-1] + 10**8 for c in clock)
    assert all(b >= a for a, b in zip(clock, clock[1:], strict=False))


def test_loop_repeats_until_stopped(launch, ros_node, tmp_path):
    t = _recording(tmp_path / "in.mcap", n=20, rate_hz=100)
    got, _ = _subscribe(ros_node)
    proc = launch(MODULE, "-p", f"input:={tmp_path / 'in.mcap'}", "-p", "loop:=true",
                  "-p", "namespace_topics:=true", "-p", "wait_for_subscribers:=1",
                  "-p", "publish_clock:=false")
    assert ros_node.spin_until(lambda: len(got) >= 3 * len(t), 30.0), proc.output()
    assert proc.stop(timeout=10) == 0
    vals = [g[1] for g in got[:3 * len(t)]]
    assert vals == list(range(len(t))) * 3


def test_bad_input_parameter(launch, tmp_path):
    proc = launch(MODULE, "-p", f"input:={tmp_path / 'missing.mcap'}")
    assert proc.wait(timeout=20) == 2
    assert "parameter 'input'" in proc.output()


@pytest.mark.parametrize("args, code, text", [
    (["-p", "rate:=abc"], 2, "parameter 'rate'"),
    (["-p", "rate:=0.0"], 2, "parameter 'rate'"),
    (["-p", "loop:=3"], 2, "parameter 'loop'"),
    (["--params-file", "/nonexistent.yaml"], 2, "--params-file /nonexistent.yaml"),
])
def test_bad_parameters_one_line(launch, tmp_path, args, code, text):
    _recording(tmp_path / "in.mcap", n=5)
    proc = launch(MODULE, "-p", f"input:={tmp_path / 'in.mcap'}", *args)
    assert proc.wait(timeout=30) == code, proc.output()
    assert text in proc.output() and "Traceback" not in proc.output(), proc.output()


@pytest.mark.parametrize("content, text", [
    (b"", "empty file"),
    (b"hello, this is not a recording\n" * 4, "not an MCAP file"),
    (MAGIC, "no messages"),
    (MAGIC * 2, "cut by the end of the file"),  # read as a damaged file: also exit 1
])
def test_unusable_input_one_line_exit_1(launch, tmp_path, content, text):
    path = tmp_path / "in.mcap"
    path.write_bytes(content)
    proc = launch(MODULE, "-p", f"input:={path}", "-p", "rate:=100.0")
    assert proc.wait(timeout=30) == 1, proc.output()
    out = proc.output()
    assert text in out and "unusable input" in out and "Traceback" not in out, out


@pytest.mark.parametrize("error", [ValueError("damaged at byte 1234"), OSError(5, "I/O error"),
                                   struct.error("unpack requires a buffer of 8 bytes")])
def test_reading_errors_become_input_errors(error):
    """Whatever reading the recording raises ends the node as unusable input (exit 1)."""
    from gyro_attitude.ros.mcap_player_node import _play_passes
    from gyro_attitude.ros.node_main import InputError

    class Node:
        path, rate, loop = "in.mcap", 1.0, False

        def get_logger(self):
            return type("L", (), {"info": staticmethod(lambda *_: None)})()

        def play_once(self):
            raise error

    import rclpy

    rclpy.init()
    try:
        with pytest.raises(InputError) as caught:
            _play_passes(Node())  # the passes, without the service thread a real node has
        assert str(caught.value) == f"in.mcap: {error}"
    finally:
        rclpy.shutdown()


def test_damaged_chunk_plays_the_rest_and_exits_1(launch, ros_node, tmp_path):
    """A chunk whose CRC fails is skipped: every other message is played, the damage is named
    in one line, and the exit status says the input was damaged (1), never 0."""
    from mcap.reader import make_reader

    path = tmp_path / "in.mcap"
    t = _recording(path, n=200)
    with open(path, "rb") as f:
        chunks = sorted(make_reader(f).get_summary().chunk_indexes,
                        key=lambda c: c.chunk_start_offset)
    assert len(chunks) >= 3
    bad = chunks[1]
    data = bytearray(path.read_bytes())
    mid = bad.chunk_start_offset + bad.chunk_length // 2
    data[mid] ^= 0xFF
    path.write_bytes(bytes(data))
    got, _ = _subscribe(ros_node)
    proc = launch(MODULE, "-p", f"input:={path}", "-p", "namespace_topics:=true",
                  "-p", "wait_for_subscribers:=1", "-p", "publish_clock:=false", "-p", "rate:=4.0")
    assert proc.wait(timeout=30) == 1, proc.output()
    ros_node.spin_until(lambda: False, 0.5)
    out = proc.output()
    assert "damaged at byte" in out and "Traceback" not in out
    played = {g[2] for g in got}
    assert 0 < len(played) < len(t) and played <= set(t.tolist())


def test_topics_not_recorded_one_line_exit_1(launch, tmp_path):
    _recording(tmp_path / "in.mcap", n=5)
    proc = launch(MODULE, "-p", f"input:={tmp_path / 'in.mcap'}", "-p", "topics:=['nope']",
                  "-p", "rate:=100.0")
    assert proc.wait(timeout=30) == 1, proc.output()
    out = proc.output()
    (line,) = [ln for ln in out.splitlines() if "unusable input" in ln]
    assert "nope" in line and "imu/data_raw" in line and "Traceback" not in out, out


def test_interrupted_pass_reports_what_it_published(launch, ros_node, tmp_path):
    """Stopped mid-pass, the player reports the messages it did publish (not 0)."""
    import re
    import signal

    _recording(tmp_path / "in.mcap", n=500, rate_hz=100)  # 5 s of recording
    got, _ = _subscribe(ros_node)
    proc = launch(MODULE, "-p", f"input:={tmp_path / 'in.mcap'}", "-p", "namespace_topics:=true",
                  "-p", "wait_for_subscribers:=1", "-p", "publish_clock:=false")
    assert ros_node.spin_until(lambda: len(got) >= 20, 30.0), proc.output()
    assert proc.stop(sig=signal.SIGINT, timeout=15.0) == 0, proc.output()
    ros_node.spin_until(lambda: False, 0.3)
    published = int(re.search(r"published (\d+) messages", proc.output()).group(1))
    assert len(got) <= published < 500, (len(got), published)


def test_bag_without_offered_qos_is_played_reliable_as_rosbag2_does(launch, ros_node, tmp_path):
    """mcap_ros2 / Foxglove tools write no ``offered_qos_profiles``: rosbag2 then plays with
    its default profile (reliable, volatile), which a reliable subscriber (the node's
    truth/attitude) matches."""
    from geometry_msgs.msg import QuaternionStamped
    from mcap_ros2.writer import Writer
    from rclpy.qos import QoSProfile, ReliabilityPolicy

    path = tmp_path / "foxglove.mcap"
    with open(path, "wb") as f:
        w = Writer(f)
        schema = w.register_msgdef("geometry_msgs/msg/QuaternionStamped",
                                   "std_msgs/Header header\ngeometry_msgs/Quaternion quaternion\n"
                                   "================================================================"
                                   "================\nMSG: std_msgs/Header\n"
                                   "builtin_interfaces/Time stamp\nstring frame_id\n"
                                   "================================================================"
                                   "================\nMSG: geometry_msgs/Quaternion\n"
                                   "float64 x\nfloat64 y\nfloat64 z\nfloat64 w\n")
        for k in range(50):
            t = 10**9 + k * 10**7
            w.write_message("/truth/attitude", schema, {
                "header": {"stamp": {"sec": t // 10**9, "nanosec": t % 10**9}, "frame_id": "map"},
                "quaternion": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}, log_time=t,
                publish_time=t)
        w.finish()
    got = []
    ros_node.create_subscription(QuaternionStamped, "truth/attitude", got.append,
                                 QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE))
    proc = launch(MODULE, "-p", f"input:={path}", "-p", "namespace_topics:=true",
                  "-p", "wait_for_subscribers:=1", "-p", "publish_clock:=false")
    assert ros_node.spin_until(lambda: len(got) >= 50, 30.0), proc.output()
    assert proc.wait(timeout=15) == 0, proc.output()
    assert "incompatible" not in proc.output().lower()


def test_parameter_services_answer_while_playing(launch, ros_node, tmp_path):
    from rcl_interfaces.srv import GetParameters, SetParameters
    from rclpy.parameter import Parameter

    _recording(tmp_path / "in.mcap", n=3000, rate_hz=100)  # 30 s
    got, _ = _subscribe(ros_node)
    proc = launch(MODULE, "-p", f"input:={tmp_path / 'in.mcap'}", "-p", "namespace_topics:=true",
                  "-p", "wait_for_subscribers:=1", "-p", "publish_clock:=false")
    assert ros_node.spin_until(lambda: len(got) >= 20, 30.0), proc.output()
    setter = ros_node.create_client(SetParameters, "mcap_player/set_parameters")
    getter = ros_node.create_client(GetParameters, "mcap_player/get_parameters")
    assert setter.wait_for_service(timeout_sec=10) and getter.wait_for_service(timeout_sec=10)

    def call(client, req):
        future = client.call_async(req)
        assert ros_node.spin_until(future.done, timeout=5), "no answer while playing"
        return future.result()

    answered = 0
    for name, value, ok in (("rate", 0.0, False), ("rate", 1e9, False),
                            ("clock_rate_hz", -1.0, False), ("loop", "yes", False),
                            ("rate", 1.5, False)):
        [r] = call(setter, SetParameters.Request(
            parameters=[Parameter(name, value=value).to_parameter_msg()])).results
        assert r.successful == ok, (name, value, r.reason)
        assert ok or name in r.reason or "parameter type" in r.reason  # rclpy's own type check
        answered += 1
    assert "cannot change at runtime" in r.reason  # a valid value: refused, saying why
    [v] = call(getter, GetParameters.Request(names=["rate"])).values
    assert v.double_value == 1.0
    n_mid = len(got)
    assert n_mid < 3000 and proc.proc.poll() is None  # still playing throughout
    print(f"\n{answered + 1} of {answered + 1} parameter calls answered while playing")
    assert proc.stop(timeout=10) == 0, proc.output()


def _truncated_message_recording(path, n=100, bad=40):
    """n Imu messages at 100 Hz, message ``bad`` cut by one byte (its record stays whole)."""
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import Imu

    t = 10**9 + np.arange(n, dtype=np.int64) * 10**7
    with Rosbag2McapWriter(path, chunk_size=4000) as wr:
        wr.add_topic("imu/data_raw", "sensor_msgs/msg/Imu")
        for k in range(n):
            m = Imu()
            m.header.stamp.sec, m.header.stamp.nanosec = divmod(int(t[k]), 10**9)
            m.header.frame_id = "imu_link"
            m.angular_velocity.x = float(k)
            data = serialize_message(m)
            wr.write("imu/data_raw", data[:-1] if k == bad else data, int(t[k]))
    return t


def test_a_message_that_does_not_decode_is_skipped_and_named_as_replay_does(
        launch, ros_node, tmp_path):
    from gyro_attitude.offline.replay import replay_file

    path = tmp_path / "in.mcap"
    t = _truncated_message_recording(path)
    r = replay_file(path, tmp_path / "out.mcap")  # the rule replay already follows
    assert r.attitude_messages == len(t) - 1 and "does not deserialize" in r.input_damage
    got, _ = _subscribe(ros_node)
    proc = launch(MODULE, "-p", f"input:={path}", "-p", "namespace_topics:=true",
                  "-p", "wait_for_subscribers:=1", "-p", "publish_clock:=false", "-p", "rate:=4.0")
    assert proc.wait(timeout=30) == 1, proc.output()
    ros_node.spin_until(lambda: len(got) >= len(t) - 1, 5.0)
    out = proc.output()
    assert "Traceback" not in out
    assert f"message at log time {t[40]} does not deserialize as sensor_msgs/msg/Imu" in out
    assert sorted(g[1] for g in got) == [k for k in range(len(t)) if k != 40]
    assert "published 99 messages" in out


def test_split_bag_is_played_file_after_file(launch, ros_node, tmp_path):
    """A rosbag2 split bag (metadata.yaml listing two .mcap files) plays as one recording."""
    from gyro_attitude.io.strict_yaml import dump_yaml

    bag = tmp_path / "split"
    bag.mkdir()
    t0 = _recording(bag / "split_0.mcap", n=60)
    t1 = t0 + 60 * 10**7
    wr = Rosbag2McapWriter(bag / "split_1.mcap", chunk_size=4000)
    wr.add_topic("imu/data_raw", "sensor_msgs/msg/Imu")
    w = np.zeros((60, 3))
    w[:, 0] = np.arange(60, 120)
    wr.write_imu_array("imu/data_raw", t1, w)
    wr.finish()
    (bag / "metadata.yaml").write_text(dump_yaml({"rosbag2_bagfile_information": {
        "version": 9, "storage_identifier": "mcap",
        "relative_file_paths": ["split_0.mcap", "split_1.mcap"]}}), encoding="utf-8")
    got, _ = _subscribe(ros_node)
    proc = launch(MODULE, "-p", f"input:={bag}", "-p", "namespace_topics:=true", "-p", "rate:=4.0",
                  "-p", "wait_for_subscribers:=1", "-p", "publish_clock:=false")
    assert ros_node.spin_until(lambda: len(got) >= 120, 30.0), proc.output()
    assert proc.wait(timeout=15) == 0, proc.output()
    assert [g[1] for g in got] == list(range(120))
    assert [g[2] for g in got] == np.r_[t0, t1].tolist()
