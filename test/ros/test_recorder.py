"""mcap_recorder as a process: SIGINT/SIGTERM lose nothing, kill -9 loses at most the last
flush period; the files are read by the mcap package and our reader."""

from __future__ import annotations

import signal
import time

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap.stream_reader import StreamReader

from gyro_attitude.io.imu_fast import read_imu_arrays
from gyro_attitude.io.mcap_reader import McapStreamReader

pytestmark = pytest.mark.ros

MODULE = "gyro_attitude.ros.mcap_recorder_node"
FLUSH_S = 0.5


def _publisher(node):
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import Imu

    pub = node.create_publisher(Imu, "imu/data_raw",
                                QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE))

    def publish(k: int) -> None:
        m = Imu()
        m.header.stamp.sec, m.header.stamp.nanosec = divmod(10**9 + k * 1_000_000, 10**9)
        m.header.frame_id = "imu_link"
        m.angular_velocity.x = float(k)
        pub.publish(m)

    return pub, publish


def _start(launch, out, *extra):
    return launch(MODULE, "-p", f"output:={out}", "-p", "topics:=[imu/data_raw]",
                  "-p", f"flush_period_s:={FLUSH_S}", *extra)


def _wait_subscribed(node, pub, proc, timeout=20.0):
    ok = node.spin_until(lambda: pub.get_subscription_count() > 0, timeout)
    assert ok, f"recorder never subscribed; its output:\n{proc.output()}"


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_signal_finishes_file_without_loss(launch, ros_node, tmp_path, sig):
    out = tmp_path / "rec.mcap"
    proc = _start(launch, out)
    pub, publish = _publisher(ros_node)
    _wait_subscribed(ros_node, pub, proc)
    n = 300
    for k in range(n):
        publish(k)
        ros_node.executor_.spin_once(timeout_sec=0.001)
    time.sleep(1.0)  # delivery
    assert proc.stop(sig=sig, timeout=15.0) == 0, proc.output()
    with open(out, "rb") as f:
        reader = make_reader(f, validate_crcs=True)
        summary = reader.get_summary()  # footer + summary present: the file was finished
        assert summary.statistics.message_count == n
        ch = next(iter(summary.channels.values()))
        assert ch.topic.endswith("/imu/data_raw")
        assert "reliability: reliable" in ch.metadata["offered_qos_profiles"]
        assert ch.metadata["topic_type_hash"].startswith("RIHS01_")
    imu = read_imu_arrays(out)
    np.testing.assert_array_equal(imu.angular_velocity[:, 0], np.arange(n))
    # log_time = receive time, publish_time = the publisher's source timestamp: earlier,
    # and by less than a second on loopback
    lag = imu.log_time_ns - imu.publish_time_ns
    assert (lag > 0).all() and (lag < 10**9).all()
    print(f"\n{sig.name}: published {n}, recorded {len(imu)}, lost {n - len(imu)}")


def test_kill_9_loses_at_most_the_last_flush_period(launch, ros_node, tmp_path):
    out = tmp_path / "rec.mcap"
    proc = _start(launch, out)
    pub, publish = _publisher(ros_node)
    _wait_subscribed(ros_node, pub, proc)
    rate_hz = 200.0
    k = 0
    start = time.monotonic()
    while time.monotonic() - start < 3.0:
        publish(k)
        k += 1
        ros_node.executor_.spin_once(timeout_sec=0.0)
        time.sleep(max(0.0, start + k / rate_hz - time.monotonic()))
    proc.proc.send_signal(signal.SIGKILL)
    proc.proc.wait(timeout=10)
    published = k
    # Killed before finishing: nothing under the requested name, the partial file beside it.
    assert not out.exists()
    (partial,) = tmp_path.glob(".rec.mcap.*.partial/rec.mcap")
    out = partial
    reader = McapStreamReader(out, on_damage="warn")
    got = [m.data for m in reader.iter_messages()]
    assert reader.damage is not None and not reader.complete  # no summary: killed
    imu = read_imu_arrays(out, on_damage="warn")
    recovered = len(imu)
    assert recovered == len(got) > 0
    # What was recovered is exactly the first messages, in order.
    np.testing.assert_array_equal(imu.angular_velocity[:, 0], np.arange(recovered))
    # The mcap package's record walker reads the same messages before hitting the end.
    seen = 0
    with open(out, "rb") as f, pytest.raises(Exception):  # noqa: B017 - mcap's EndOfFile
        for rec in StreamReader(f, skip_magic=False).records:
            seen += type(rec).__name__ == "Message"
    assert seen == recovered
    lost = published - recovered
    # At most one flush period of messages (plus delivery latency of a few ms) is lost.
    bound = rate_hz * (FLUSH_S + 0.25)
    print(f"\nkill -9: published {published}, recovered {recovered}, lost {lost} "
          f"(bound {bound:.0f} = {rate_hz:g} Hz x ({FLUSH_S} s flush + 0.25 s slack))")
    assert 0 <= lost <= bound


def test_all_topics_into_a_bag_directory_read_by_rosbags(launch, ros_node, tmp_path,
                                                           namespace):
    from rosbags.highlevel import AnyReader
    from std_msgs.msg import String

    bag = tmp_path / "bag"
    proc = launch(MODULE, "-p", f"output:={bag}", "-p", "all_topics:=true",
                  "-p", "bag_directory:=true")
    pub, publish = _publisher(ros_node)
    chatter = ros_node.create_publisher(String, "chatter", 100)
    ok = ros_node.spin_until(lambda: pub.get_subscription_count() > 0
                             and chatter.get_subscription_count() > 0, 20.0)
    assert ok, proc.output()
    for k in range(50):
        publish(k)
        chatter.publish(String(data=f"msg {k}"))
        ros_node.executor_.spin_once(timeout_sec=0.002)
    time.sleep(1.0)
    assert proc.stop(timeout=15.0) == 0, proc.output()
    with AnyReader([bag]) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
        texts = [reader.deserialize(raw, c.msgtype).data for c, _, raw in
                 reader.messages([c for c in reader.connections if c.topic.endswith("chatter")])]
    assert counts[f"{namespace}/imu/data_raw"] == 50 and counts[f"{namespace}/chatter"] == 50
    assert texts == [f"msg {k}" for k in range(50)]


def test_existing_output_refused_unless_forced(launch, tmp_path):
    out = tmp_path / "rec.mcap"
    out.write_bytes(b"precious")
    refused = _start(launch, out)
    assert refused.wait(timeout=30) == 2, refused.output()
    assert "parameter 'output'" in refused.output() and "exists" in refused.output()
    assert "Traceback" not in refused.output()
    assert out.read_bytes() == b"precious"
    forced = _start(launch, out, "-p", "force:=true")
    deadline = time.monotonic() + 30
    while "recording" not in forced.output() and time.monotonic() < deadline:
        time.sleep(0.1)
    # while recording, the requested name still holds the old file
    assert out.read_bytes() == b"precious", forced.output()
    assert forced.stop(sig=signal.SIGTERM, timeout=15.0) == 0, forced.output()
    with open(out, "rb") as f:
        assert make_reader(f).get_summary() is not None
    assert sorted(p.name for p in tmp_path.iterdir() if not p.name.endswith(".log")) == [
        "rec.mcap"]


@pytest.mark.parametrize("args, name", [
    (["-p", "queue_depth:=1.5"], "queue_depth"),
    (["-p", "flush_period_s:=abc"], "flush_period_s"),
    (["-p", "flush_period_s:=2.0"], "flush_period_s"),
    (["-p", "topics:=5"], "topics"),
    (["-p", "compression:=gzip"], "compression"),
    (["-p", "topics:=['bad topic']"], "topics"),
    (["-p", "topics:=['imu/data_raw', '1starts_with_digit']"], "topics"),
    (["-p", "topics:=['/a//b']"], "topics"),
])
def test_bad_parameters_one_line_exit_2(launch, tmp_path, args, name):
    proc = launch(MODULE, "-p", f"output:={tmp_path / 'x.mcap'}", *args)
    assert proc.wait(timeout=30) == 2, proc.output()
    out = proc.output()
    assert f"'{name}'" in out and "Traceback" not in out, out
    assert not (tmp_path / "x.mcap").exists()
    assert [p.name for p in tmp_path.iterdir() if not p.name.endswith(".log")] == []


def test_forced_output_replaces_an_existing_bag_directory(launch, ros_node, tmp_path):
    """force:=true replaces an existing bag directory (refused without force); a directory
    holding anything else than a bag is never replaced."""
    bag = tmp_path / "bag"
    bag.mkdir()
    (bag / "metadata.yaml").write_text("old")
    (bag / "bag_0.mcap").write_bytes(b"old")
    refused = _start(launch, bag, "-p", "bag_directory:=true")
    assert refused.wait(timeout=30) == 2, refused.output()
    assert "parameter 'output'" in refused.output() and "Traceback" not in refused.output()
    other = tmp_path / "notabag"
    other.mkdir()
    (other / "notes.txt").write_text("keep")
    not_bag = _start(launch, other, "-p", "bag_directory:=true", "-p", "force:=true")
    assert not_bag.wait(timeout=30) == 2, not_bag.output()
    assert (other / "notes.txt").read_text() == "keep"

    forced = _start(launch, bag, "-p", "bag_directory:=true", "-p", "force:=true")
    pub, publish = _publisher(ros_node)
    _wait_subscribed(ros_node, pub, forced)
    for k in range(20):
        publish(k)
        ros_node.executor_.spin_once(timeout_sec=0.002)
    time.sleep(1.0)
    assert forced.stop(sig=signal.SIGTERM, timeout=15.0) == 0, forced.output()
    (mcap_file,) = bag.glob("*.mcap")
    assert (bag / "metadata.yaml").read_text() != "old"
    with open(mcap_file, "rb") as f:
        assert sum(1 for _ in make_reader(f).iter_messages()) == 20
