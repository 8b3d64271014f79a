"""Replay takes the truth as motion-capture systems publish it (issue 38 item 9):
``geometry_msgs/PoseStamped`` (a VRPN client's ``/mocap/pose``), ``nav_msgs/Odometry`` and the
transforms of a ``tf2_msgs/TFMessage``, read by the trajectory input's reader; the figures are
those of the same truth as a ``QuaternionStamped``.  And a missing Imu topic names the Imu
topics the file has (item 10)."""

from __future__ import annotations

import json
import os
import sys

import numpy as np
import pytest
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

from gyro_attitude.cli import main as cli_main

os.environ.setdefault("AMENT_PREFIX_PATH", sys.prefix)
TS = get_typestore(Stores.ROS2_JAZZY)
TYPES = {"quat": "geometry_msgs/msg/QuaternionStamped", "pose": "geometry_msgs/msg/PoseStamped",
         "odom": "nav_msgs/msg/Odometry", "tf": "tf2_msgs/msg/TFMessage"}


def m(type_name, **kw):
    return TS.types[type_name](**kw)


def header(ns, frame="world"):
    return m("std_msgs/msg/Header", frame_id=frame,
             stamp=m("builtin_interfaces/msg/Time", sec=ns // 10**9, nanosec=ns % 10**9))


def vec(cls, v):
    return m(cls, x=float(v[0]), y=float(v[1]), z=float(v[2]))


def quat(q):
    return m("geometry_msgs/msg/Quaternion", x=q[0], y=q[1], z=q[2], w=q[3])


def truth_message(kind, ns, q):
    h = header(ns)
    pose = m("geometry_msgs/msg/Pose", position=vec("geometry_msgs/msg/Point", [1, 2, 3]),
             orientation=quat(q))
    if kind == "quat":
        return m(TYPES[kind], header=h, quaternion=quat(q))
    if kind == "pose":
        return m(TYPES[kind], header=h, pose=pose)
    if kind == "odom":
        cov = np.zeros(36)
        zero = vec("geometry_msgs/msg/Vector3", [0, 0, 0])
        return m(TYPES[kind], header=h, child_frame_id="imu_body",
                 pose=m("geometry_msgs/msg/PoseWithCovariance", pose=pose, covariance=cov),
                 twist=m("geometry_msgs/msg/TwistWithCovariance", covariance=cov,
                         twist=m("geometry_msgs/msg/Twist", linear=zero, angular=zero)))

    def tf(child, qq):
        return m("geometry_msgs/msg/TransformStamped", header=h, child_frame_id=child,
                 transform=m("geometry_msgs/msg/Transform",
                             translation=vec("geometry_msgs/msg/Vector3", [1, 2, 3]),
                             rotation=quat(qq)))
    return m(TYPES[kind], transforms=[tf("wand", [0.0, 0.0, 0.0, 1.0]), tf("imu_body", q)])


def write_bag(path, kind, truth_topic="/mocap/pose", imu_topic="/imu/data_raw"):
    """An IMU turning about z at 0.3 rad/s at 200 Hz, and its truth at 100 Hz (with a 7°
    tilt the gyro does not see, so the error is not zero) as ``kind``."""
    n = 1000
    t = (5 * 10**9 + np.arange(n) * 5_000_000).astype(np.int64)
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        imu = w.add_connection(imu_topic, "sensor_msgs/msg/Imu", typestore=TS)
        truth = w.add_connection(truth_topic, TYPES[kind], typestore=TS)
        for k in range(n):
            ns = int(t[k])
            msg = m("sensor_msgs/msg/Imu", header=header(ns, "imu"),
                    orientation=quat([0.0, 0.0, 0.0, 1.0]),
                    orientation_covariance=np.r_[-1.0, np.zeros(8)],
                    angular_velocity=vec("geometry_msgs/msg/Vector3", [0, 0, 0.3]),
                    angular_velocity_covariance=np.zeros(9),
                    linear_acceleration=vec("geometry_msgs/msg/Vector3", [0, 0, 9.8]),
                    linear_acceleration_covariance=np.zeros(9))
            w.write(imu, ns, TS.serialize_cdr(msg, "sensor_msgs/msg/Imu"))
            if k % 2 == 0:
                yaw = 0.3 * (ns - t[0]) * 1e-9
                q = np.array([np.sin(0.06), 0.0, 0.0, np.cos(0.06)])  # 6.9° about x
                qz = np.array([0.0, 0.0, np.sin(yaw / 2), np.cos(yaw / 2)])
                # q_true = R_x ⊗ R_z(yaw)
                x1, y1, z1, w1 = q
                x2, y2, z2, w2 = qz
                qt = [w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2, w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
                      w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2, w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2]
                w.write(truth, ns, TS.serialize_cdr(truth_message(kind, ns, qt), TYPES[kind]))
    return path


def replay_json(capsys, bag, out, *extra):
    code = cli_main(["replay", str(bag), "--out", str(out), "--truth-topic", "/mocap/pose",
                     "--imu-topic", "/imu/data_raw", "--json", *extra])
    o, e = capsys.readouterr()
    assert "Traceback" not in o + e
    return code, (json.loads(o) if code == 0 else e)


@pytest.mark.parametrize("kind", ["pose", "odom", "tf"])
def test_truth_from_a_motion_capture_pose_topic_gives_the_figures_of_the_same_quaternions(
        tmp_path, capsys, kind):
    ref = write_bag(tmp_path / "quat", "quat")
    code, want = replay_json(capsys, ref, tmp_path / "q.mcap")
    assert code == 0 and want["truth_matched"] == 500
    assert np.degrees(want["final_error_rad"]) == pytest.approx(6.9, abs=0.1)
    bag = write_bag(tmp_path / kind, kind)
    extra = ["--truth-child-frame", "imu_body"] if kind == "tf" else []
    code, got = replay_json(capsys, bag, tmp_path / "o.mcap", *extra)
    assert code == 0
    for key in ("truth_matched", "final_error_rad", "max_error_rad", "rms_error_rad",
                "final_tilt_error_rad"):
        assert got[key] == want[key], key


def test_a_tf_truth_topic_without_its_child_frame_is_one_line(tmp_path, capsys):
    bag = write_bag(tmp_path / "tf", "tf")
    code, err = replay_json(capsys, bag, tmp_path / "o.mcap")
    assert code == 1 and len(err.strip().splitlines()) == 1
    assert "TFMessage" in err and "--truth-child-frame" in err


def test_a_missing_imu_topic_names_the_imu_topics_the_file_has(tmp_path, capsys):
    bag = write_bag(tmp_path / "b", "quat", imu_topic="/robot/imu")
    code = cli_main(["replay", str(bag), "--out", str(tmp_path / "o.mcap")])
    _, err = capsys.readouterr()
    assert code == 1 and len(err.strip().splitlines()) == 1
    assert "no Imu topic 'imu/data_raw'" in err and "/robot/imu" in err
