"""TF: publish_tf of attitude_integrator and gyro_sim, received in another process; refused
in one line where tf2_msgs is not installed, everything else running."""

from __future__ import annotations

import os
import signal
import struct
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from geometry_msgs.msg import QuaternionStamped, TransformStamped
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Imu

from gyro_attitude.ros import convert

pytestmark = [pytest.mark.ros, pytest.mark.timeout(150)]

REPO = Path(__file__).resolve().parents[2]
SIM = "gyro_attitude.ros.gyro_sim_node"
INTEGRATOR = "gyro_attitude.ros.attitude_integrator_node"
RELIABLE = QoSProfile(depth=20000, reliability=ReliabilityPolicy.RELIABLE)
# Jazzy's tf2_msgs/msg/TFMessage (its share/tf2_msgs/msg/TFMessage.json in a ROS install)
JAZZY_TF_HASH = "RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087"

try:
    import tf2_msgs.msg as tf2_msgs
except ImportError:  # not built here (no compiler): in CI, where dev.sh builds it, a failure
    tf2_msgs = None
needs_tf2_msgs = pytest.mark.skipif(
    tf2_msgs is None and os.environ.get("CI") != "true",
    reason="tf2_msgs is not installed (dev.sh builds it: needs a C/C++ compiler and CMake)")


def _collect(node, msg_type, topic):
    box: list = []
    node.create_subscription(msg_type, topic, box.append, RELIABLE)
    return box


def _stamp(m) -> int:
    return convert.stamp_to_ns(m.header.stamp)


@needs_tf2_msgs
def test_integrator_and_sim_publish_tf_equal_to_their_attitude_topics(launch, ros_node):
    rate, duration = 200.0, 1.0
    n = int(rate * duration)
    tf = _collect(ros_node, tf2_msgs.TFMessage, "/tf")
    att = _collect(ros_node, QuaternionStamped, "attitude")
    truth = _collect(ros_node, QuaternionStamped, "truth/attitude")
    # the simulator starts once this probe and the integrator take imu/data_raw: its
    # participant then knows this probe's, and its truth and /tf writers match quickly
    raw = _collect(ros_node, Imu, "imu/data_raw")
    config = REPO / "config"
    integ = launch(INTEGRATOR, "--params-file", str(config / "attitude_integrator.yaml"),
                   "-p", "initial_attitude_source:=truth", "-p", "qos_reliability:=reliable",
                   "-p", "publish_tf:=true")
    assert ros_node.wait_for_publishers("attitude"), integ.output()
    assert ros_node.wait_for_publishers("/tf"), integ.output()
    # the type is Jazzy's: a system ROS's tf2 tools read it
    hashes = {str(i.topic_type_hash) for i in ros_node.get_publishers_info_by_topic("/tf")}
    assert hashes == {JAZZY_TF_HASH}, hashes
    # discovery is two-sided: the node's /tf writer must have matched this reader too
    ros_node.spin_until(lambda: False, 1.5)
    sim = launch(SIM, "--params-file", str(config / "gyro_sim.yaml"), "-p", "scene:=coning",
                 "-p", f"rate_hz:={rate}", "-p", f"duration_s:={duration}",
                 "-p", "wait_for_subscribers:=2", "-p", "qos_reliability:=reliable",
                 "-p", "publish_tf:=true")
    # (with initial_attitude_source truth, an Imu sample that comes before the first truth
    # sample gets no attitude: a loaded machine may skip one or two)
    assert ros_node.spin_until(lambda: len(att) >= n - 2 and len(truth) >= n
                               and len(tf) >= len(att) + len(truth), timeout=60), (
        f"{len(raw)} Imu, {len(truth)} truth, {len(att)} attitudes, TF messages of {n}: "
        f"{Counter(t.child_frame_id for m in tf for t in m.transforms)}\n"
        f"{integ.output()}\n{sim.output()}")
    assert sim.wait(timeout=15) == 0, sim.output()
    ros_node.spin_until(lambda: len(att) >= n and len(tf) >= 2 * n, timeout=2)
    assert integ.stop(signal.SIGTERM) == 0, integ.output()

    transforms = [t for m in tf for t in m.transforms]
    assert len(transforms) == len(tf)  # one transform per message
    by_child: dict[str, list] = {}
    for t in transforms:
        by_child.setdefault(t.child_frame_id, []).append(t)
    assert sorted(by_child) == ["imu_link", "imu_link_truth"]
    for child, topic, parent in (("imu_link", att, "inertial"),
                                 ("imu_link_truth", truth, "enu")):
        ts = by_child[child]
        assert len(ts) == len(topic) >= n - 2, (child, len(ts), len(topic))
        assert {t.header.frame_id for t in ts} == {parent}
        assert {m.header.frame_id for m in topic} == {parent}
        assert [_stamp(t) for t in ts] == [_stamp(m) for m in topic]
        rot = np.array([convert.quat_from_msg(t.transform.rotation) for t in ts])
        q = np.array([convert.quat_from_msg(m.quaternion) for m in topic])
        np.testing.assert_array_equal(rot, q)
        assert not np.any([convert.vector3_from_msg(t.transform.translation) for t in ts])


def test_publish_tf_refused_in_one_line_without_tf2_msgs_and_the_rest_runs(
        launch, ros_node, ros_env, tmp_path):
    # tf2_msgs hidden from the node processes: a package of that name that fails to import
    hide = tmp_path / "hide" / "tf2_msgs"
    hide.mkdir(parents=True)
    (hide / "__init__.py").write_text("raise ImportError('tf2_msgs hidden by the test')\n")
    ros_env["PYTHONPATH"] = f"{hide.parent}{os.pathsep}{ros_env['PYTHONPATH']}"
    refused = [launch(INTEGRATOR, "-p", "publish_tf:=true"),
               launch(SIM, "-p", "publish_tf:=true")]
    att = _collect(ros_node, QuaternionStamped, "attitude")
    integ = launch(INTEGRATOR, "-p", "qos_reliability:=reliable")
    for proc in refused:
        assert proc.wait(timeout=60) == 2, proc.output()
        out = proc.output()
        lines = [ln for ln in out.splitlines() if "tf2_msgs" in ln]
        assert len(lines) == 1 and "publish_tf" in lines[0] and "dev.sh" in lines[0], out
        assert "Traceback" not in out, out
    assert ros_node.wait_for_publishers("attitude"), integ.output()
    sim = launch(SIM, "-p", "scene:=coning", "-p", "rate_hz:=100.0", "-p", "duration_s:=0.5",
                 "-p", "wait_for_subscribers:=1", "-p", "qos_reliability:=reliable")
    assert ros_node.spin_until(lambda: len(att) >= 50, timeout=60), (
        f"{len(att)}\n{integ.output()}\n{sim.output()}")
    assert sim.wait(timeout=15) == 0, sim.output()
    assert integ.stop(signal.SIGTERM) == 0, integ.output()


@needs_tf2_msgs
def test_player_republishes_tf_and_tf_static_as_tf2_listeners_take_them(
        launch, ros_node, tmp_path):
    from rclpy.serialization import serialize_message

    from gyro_attitude.io.mcap_writer import Rosbag2McapWriter
    from gyro_attitude.ros.tf import tf_static_qos

    def tf_msg(t_ns, parent, child, z):
        m = TransformStamped()
        m.header.stamp = convert.ns_to_stamp(t_ns)
        m.header.frame_id, m.child_frame_id = parent, child
        m.transform.translation.z = z
        m.transform.rotation.w = 1.0
        return tf2_msgs.TFMessage(transforms=[m])

    static = tf_msg(10**9, "base_link", "imu_link", 0.25)
    # /tf 2 s after /tf_static: a reader of this probe matching the player's writers late
    # (discovery is two-sided, slow on a loaded machine) still gets every volatile message;
    # the transient-local static one it gets whenever it matches
    t0 = 3 * 10**9
    dynamic = [tf_msg(t0 + k * 10**7, "odom", "base_link", 0.01 * k) for k in range(20)]
    path = tmp_path / "tf.mcap"
    with Rosbag2McapWriter(path) as wr:
        # no offered QoS recorded (as mcap_ros2 / Foxglove tools write it): the rosbag2
        # default is volatile, which a tf2 static listener (transient local) never matches
        wr.add_topic("/tf_static", "tf2_msgs/msg/TFMessage")
        wr.add_topic("/tf", "tf2_msgs/msg/TFMessage")
        wr.write("/tf_static", serialize_message(static), 10**9 - 1)
        for k, m in enumerate(dynamic):
            wr.write("/tf", serialize_message(m), t0 + k * 10**7)
    got_static: list = []
    ros_node.create_subscription(tf2_msgs.TFMessage, "/tf_static", got_static.append,
                                 tf_static_qos(10))
    got = _collect(ros_node, tf2_msgs.TFMessage, "/tf")
    proc = launch("gyro_attitude.ros.mcap_player_node", "-p", f"input:={path}",
                  "-p", "wait_for_subscribers:=1", "-p", "publish_clock:=false")
    assert ros_node.spin_until(lambda: len(got) >= 20 and got_static, 30.0), proc.output()
    assert proc.wait(timeout=15) == 0, proc.output()
    assert got_static == [static]
    assert got == dynamic


@needs_tf2_msgs
def test_transform_cdr_is_what_rclpy_reads_as_the_tf_message():
    from rclpy.serialization import deserialize_message

    from gyro_attitude.io.cdr_arrays import TransformCdr

    for parent in ("", "a", "odom", "inertial", "w" * 13):
        enc = TransformCdr(parent)
        for child in ("", "b", "imu_link", "imu_link_truth", "é" * 5, "x" * 16):
            t_ns = 1_700_000_000 * 10**9 + 123_456_789
            raw = enc.encode(struct.pack("<iI", *divmod(t_ns, 10**9)), child,
                             0.1, -0.2, 0.3, 0.9)
            m = TransformStamped()
            m.header.stamp = convert.ns_to_stamp(t_ns)
            m.header.frame_id, m.child_frame_id = parent, child
            r = m.transform.rotation
            r.x, r.y, r.z, r.w = 0.1, -0.2, 0.3, 0.9
            assert deserialize_message(raw, tf2_msgs.TFMessage) == \
                tf2_msgs.TFMessage(transforms=[m]), (parent, child)


@needs_tf2_msgs
def test_gyro_sim_records_its_tf_with_the_other_topics(launch, namespace, tmp_path):
    from mcap_ros2.reader import read_ros2_messages

    out = tmp_path / "sim.mcap"
    sim = launch(SIM, "-p", "time_mode:=fast", "-p", "duration_s:=0.2", "-p", "rate_hz:=100.0",
                 "-p", "publish_tf:=true", "-p", f"record_path:={out}")
    assert sim.wait(timeout=60) == 0, sim.output()
    # read back by mcap_ros2 (an independent decoder), against the recorded truth/attitude
    tf = list(read_ros2_messages(str(out), topics=["/tf"]))
    truth = list(read_ros2_messages(str(out), topics=[f"{namespace}/truth/attitude"]))
    assert len(tf) == len(truth) == 20
    assert {m.channel.metadata["topic_type_hash"] for m in tf} == {JAZZY_TF_HASH}
    for a, b in zip(tf, truth, strict=True):
        (t,) = a.ros_msg.transforms
        assert (t.header.frame_id, t.child_frame_id) == ("enu", "imu_link_truth")
        assert (t.header.stamp.sec, t.header.stamp.nanosec) == (
            b.ros_msg.header.stamp.sec, b.ros_msg.header.stamp.nanosec)
        r, q = t.transform.rotation, b.ros_msg.quaternion
        assert (r.x, r.y, r.z, r.w) == (q.x, q.y, q.z, q.w)


@needs_tf2_msgs
def test_a_transform_from_a_frame_to_itself_is_refused_at_start(launch):
    procs = [launch(INTEGRATOR, "-p", "publish_tf:=true", "-p", "tf_child_frame_id:=inertial"),
             launch(SIM, "-p", "publish_tf:=true", "-p", "world_frame_id:=w",
                    "-p", "truth_frame_id:=w")]
    for proc in procs:
        assert proc.wait(timeout=60) == 2, proc.output()
        out = proc.output()
        assert "'publish_tf'" in out and "is the parent frame" in out, out
        assert "Traceback" not in out, out
