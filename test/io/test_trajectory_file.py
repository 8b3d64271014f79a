"""Pose files and topics: TUM, CSV, MCAP (Odometry, PoseStamped, TFMessage) read exactly; bad ones refused."""

import math

import numpy as np
import pytest
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

from gyro_attitude.cli import main as cli_main
from gyro_attitude.io.trajectory_file import read_csv, read_pose_topic, read_poses, read_tum

TS = get_typestore(Stores.ROS2_JAZZY)
T0 = 1_700_000_000_123_456_789  # an epoch stamp with nanoseconds a float would lose


def _rows(n=50, rate=100.0):
    t = T0 + np.round(np.arange(n) * 1e9 / rate).astype(np.int64)
    ang = 0.3 * np.arange(n) / n
    p = np.stack((np.cos(ang), np.sin(ang), 0.1 * ang), axis=1)
    q = np.stack((np.zeros(n), np.zeros(n), np.sin(ang / 2), np.cos(ang / 2)), axis=1)
    return t, p, q


def _stamp_text(ns):
    return f"{ns // 10**9}.{ns % 10**9:09d}"


def write_tum(path, t, p, q, comment=True):
    lines = ["# timestamp tx ty tz qx qy qz qw", ""] if comment else []
    for k in range(len(t)):
        vals = " ".join(f"{x:.12g}" for x in (*p[k], *q[k]))
        lines.append(f"{_stamp_text(int(t[k]))} {vals}  # pose {k}" if k == 3 else
                     f"{_stamp_text(int(t[k]))} {vals}")
    path.write_text("\n".join(lines) + "\n")
    return path


def test_tum_is_read_with_exact_nanosecond_stamps_and_comments(tmp_path):
    t, p, q = _rows()
    poses = read_tum(write_tum(tmp_path / "a.tum", t, p, q))
    assert np.array_equal(poses.t_ns, t)
    np.testing.assert_allclose(poses.p, p, rtol=0, atol=1e-11)
    np.testing.assert_allclose(poses.q, q, rtol=0, atol=1e-11)
    assert poses.labels[0] == "line 3"  # after the comment and the blank line


@pytest.mark.parametrize("kind", ["tum", "csv"])
def test_a_file_longer_than_a_text_block_is_read_whole_and_a_late_bad_row_named(
        tmp_path, monkeypatch, kind):
    """Text rows are converted a block at a time (memory): blocks of 8 rows give the same
    poses as one, and a bad number in a later block is named by its own line."""
    import gyro_attitude.io.trajectory_file as tf

    monkeypatch.setattr(tf, "TEXT_BLOCK_ROWS", 8)
    t, p, q = _rows(n=37)
    text = write_tum(tmp_path / "a.tum", t, p, q).read_text()
    if kind == "csv":
        text = "timestamp,tx,ty,tz,qx,qy,qz,qw\n" + "\n".join(
            ",".join(line.split("#")[0].split()) for line in text.splitlines()
            if line.strip() and not line.startswith("#")) + "\n"
    path = tmp_path / f"a.{kind}"
    path.write_text(text)
    poses = read_poses(path)
    assert np.array_equal(poses.t_ns, t) and len(poses.labels) == 37
    np.testing.assert_allclose(poses.p, p, rtol=0, atol=1e-11)
    np.testing.assert_allclose(poses.q, q, rtol=0, atol=1e-11)
    lines = text.splitlines()
    lines[30] = lines[30].replace(lines[30].split(" " if kind == "tum" else ",")[2], "x2", 1)
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(ValueError, match=r"line 31: ty 'x2' is not a number"):
        read_poses(path)


def test_csv_columns_in_any_order_with_extra_columns(tmp_path):
    t, p, q = _rows()
    cols = ["qw", "note", "tz", "timestamp", "tx", "qx", "ty", "qz", "qy"]
    lines = ["# " + ",".join(cols)]
    for k in range(len(t)):
        v = {"timestamp": _stamp_text(int(t[k])), "tx": p[k, 0], "ty": p[k, 1], "tz": p[k, 2],
             "qx": q[k, 0], "qy": q[k, 1], "qz": q[k, 2], "qw": q[k, 3], "note": "walk"}
        lines.append(",".join(str(v[c]) for c in cols))
    (tmp_path / "a.csv").write_text("\n".join(lines) + "\n")
    poses = read_poses(tmp_path / "a.csv")
    assert np.array_equal(poses.t_ns, t)
    np.testing.assert_allclose(poses.p, p, atol=1e-12)
    np.testing.assert_allclose(poses.q, q, atol=1e-12)
    (tmp_path / "b.csv").write_text("time,x,y\n1,2,3\n")
    with pytest.raises(ValueError, match=r"b\.csv: line 1: the header must name .* missing timestamp"):
        read_csv(tmp_path / "b.csv")


def _msg(type_name, **kw):
    return TS.types[type_name](**kw)


def _header(ns, frame="world"):
    stamp = _msg("builtin_interfaces/msg/Time", sec=ns // 10**9, nanosec=ns % 10**9)
    return _msg("std_msgs/msg/Header", stamp=stamp, frame_id=frame)


def _pose(p, q):
    return _msg("geometry_msgs/msg/Pose",
                position=_msg("geometry_msgs/msg/Point", x=p[0], y=p[1], z=p[2]),
                orientation=_msg("geometry_msgs/msg/Quaternion", x=q[0], y=q[1], z=q[2], w=q[3]))


def write_bag(path, kind, t, p, q, topic="/pose"):
    """A rosbag2 MCAP bag (written by rosbags, an independent writer) of one pose topic."""
    type_name = {"odom": "nav_msgs/msg/Odometry", "pose": "geometry_msgs/msg/PoseStamped",
                 "tf": "tf2_msgs/msg/TFMessage"}[kind]
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        conn = w.add_connection(topic, type_name, typestore=TS)
        for k in range(len(t)):
            ns = int(t[k])
            h = _header(ns)
            if kind == "odom":
                cov = np.zeros(36)
                zero = _msg("geometry_msgs/msg/Vector3", x=0.0, y=0.0, z=0.0)
                m = _msg(type_name, header=h, child_frame_id="body",
                         pose=_msg("geometry_msgs/msg/PoseWithCovariance", pose=_pose(p[k], q[k]),
                                   covariance=cov),
                         twist=_msg("geometry_msgs/msg/TwistWithCovariance",
                                    twist=_msg("geometry_msgs/msg/Twist", linear=zero, angular=zero),
                                    covariance=cov))
            elif kind == "pose":
                m = _msg(type_name, header=h, pose=_pose(p[k], q[k]))
            else:
                def tf(child, pk, qk, h=h):
                    return _msg("geometry_msgs/msg/TransformStamped", header=h, child_frame_id=child,
                                transform=_msg("geometry_msgs/msg/Transform",
                                               translation=_msg("geometry_msgs/msg/Vector3",
                                                                x=pk[0], y=pk[1], z=pk[2]),
                                               rotation=_msg("geometry_msgs/msg/Quaternion", x=qk[0],
                                                             y=qk[1], z=qk[2], w=qk[3])))
                # another frame in the same message, and messages without the body
                others = [tf("camera", p[k] + 1.0, [0.0, 0.0, 0.0, 1.0])]
                m = _msg(type_name, transforms=others + [tf("body", p[k], q[k])])
                w.write(conn, ns, TS.serialize_cdr(_msg(type_name, transforms=others), type_name))
            w.write(conn, ns, TS.serialize_cdr(m, type_name))
    return path


@pytest.mark.parametrize("kind", ["odom", "pose", "tf"])
def test_mcap_pose_topics_are_read(tmp_path, kind):
    t, p, q = _rows()
    bag = write_bag(tmp_path / "bag", kind, t, p, q)
    poses = read_pose_topic(bag, "/pose", child_frame_id="body" if kind == "tf" else None)
    assert np.array_equal(poses.t_ns, t)
    np.testing.assert_array_equal(poses.p, p)
    np.testing.assert_array_equal(poses.q, q)
    assert poses.labels[0].startswith("/pose message ")


def _simulate(tmp_path, traj, *extra):
    out = tmp_path / "o.mcap"
    rc = cli_main(["simulate", "lab_bench", "--trajectory", str(traj), "--out", str(out),
                   "--quiet", *extra])
    return rc, out


def test_simulate_along_a_tum_file_covers_its_span_in_its_time_base(tmp_path, capsys):
    from gyro_attitude.io.imu_fast import read_imu_arrays

    t, p, q = _rows(n=201)  # 2 s at 100 Hz
    rc, out = _simulate(tmp_path, write_tum(tmp_path / "a.tum", t, p, q), "--rate", "400")
    assert rc == 0, capsys.readouterr().err
    imu = read_imu_arrays(out, "imu/data_raw")
    assert imu.stamp_ns[0] == T0 and imu.stamp_ns.size == 801
    assert imu.stamp_ns[-1] == T0 + 2 * 10**9


BAD = [
    ("unsorted", lambda lines: [lines[0], lines[2], lines[1], *lines[3:]],
     r"line 3: timestamp 1700000000\.133456789 s goes back from the previous one "
     r"\(1700000000\.143456789 s\)"),
    ("duplicated", lambda lines: [lines[0], lines[0], *lines[1:]],
     r"line 2: timestamp 1700000000\.123456789 s repeats"),
    ("nan stamp", lambda lines: ["nan" + lines[1][lines[1].index(" "):], *lines[1:]],
     r"line 1: timestamp 'nan' is not finite"),
    ("non-unit q", lambda lines: [*lines[:4], lines[4].rsplit(" ", 1)[0] + " 2.0", *lines[5:]],
     r"line 5: quaternion .* not a unit"),
    ("nan q", lambda lines: [*lines[:4], lines[4].rsplit(" ", 1)[0] + " nan", *lines[5:]],
     r"line 5: quaternion .* not a unit"),
    ("one pose", lambda lines: lines[:1], r"1 pose; a trajectory needs at least 2"),
    ("text", lambda lines: [*lines[:2], "1.0 2.0 three", *lines[3:]], r"line 3: 3 values, expected 8"),
    ("stamp past int32 seconds", lambda lines: [lines[0], "10000000000.5" + lines[1][
        lines[1].index(" "):], *lines[2:]],
     r"line 2: timestamp 10000000000\.5 s is outside \[0, 2147483647\] s"),
    ("stamp of a huge exponent", lambda lines: ["1e999999999" + lines[0][lines[0].index(" "):],
                                                *lines[1:]], r"line 1: timestamp 1e999999999 s is outside"),
    ("1e300 in q", lambda lines: [*lines[:4], lines[4].rsplit(" ", 4)[0] + " 1e300 0 0 1",
                                  *lines[5:]], r"line 5: quaternion .* \(\|q\| = inf"),
]


@pytest.mark.filterwarnings("error")  # a numpy overflow warning is a second line on stderr
@pytest.mark.parametrize("name, edit, message", BAD, ids=[b[0] for b in BAD])
def test_bad_pose_file_is_one_line_and_exit_1(tmp_path, capsys, name, edit, message):
    t, p, q = _rows()
    good = write_tum(tmp_path / "good.tum", t, p, q, comment=False).read_text().splitlines()
    (tmp_path / "bad.tum").write_text("\n".join(edit(good)) + "\n")
    rc, out = _simulate(tmp_path, tmp_path / "bad.tum")
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 1 and len(err) == 1 and "Traceback" not in err[0], err
    assert __import__("re").search(message, err[0]), err[0]
    assert not out.exists()


@pytest.mark.parametrize("kind", ["tum", "csv"])
def test_a_byte_order_mark_is_not_part_of_the_first_line(tmp_path, kind):
    t, p, q = _rows()
    text = write_tum(tmp_path / "a.tum", t, p, q, comment=False).read_text()
    if kind == "csv":
        text = "timestamp,tx,ty,tz,qx,qy,qz,qw\r\n" + text.replace(" ", ",").replace("\n", "\r\n")
    path = tmp_path / f"bom.{kind}"
    path.write_bytes(b"\xef\xbb\xbf" + text.encode())  # as Windows editors and Excel save
    poses = read_poses(path)
    assert np.array_equal(poses.t_ns, t)
    np.testing.assert_allclose(poses.q, q, rtol=0, atol=1e-11)


def test_gap_of_minutes_is_refused_naming_the_line(tmp_path, capsys):
    t, p, q = _rows()
    t = t.copy()
    t[20:] += 180 * 10**9
    rc, out = _simulate(tmp_path, write_tum(tmp_path / "gap.tum", t, p, q))
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 1 and len(err) == 1
    assert "line 23: gap of 180.01 s" in err[0] and "max_gap_s" in err[0]


def test_topic_of_the_wrong_type_is_one_line(tmp_path, capsys):
    from gyro_attitude.io.mcap_writer import Rosbag2McapWriter

    t, p, q = _rows()
    bag = tmp_path / "imu.mcap"
    with Rosbag2McapWriter(bag) as wr:
        wr.add_topic("pose", "sensor_msgs/msg/Imu")
        wr.write_imu_array("pose", t, p)
    rc, out = _simulate(tmp_path, bag, "--trajectory-topic", "/pose")
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 1 and len(err) == 1
    assert "topic /pose has type sensor_msgs/msg/Imu; a trajectory is read from" in err[0]
    rc, _ = _simulate(tmp_path, write_bag(tmp_path / "bag2", "odom", t, p, q),
                      "--trajectory-topic", "/elsewhere")
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 1 and len(err) == 1 and "no messages on topic '/elsewhere' (topics: /pose)" in err[0]


def test_tf_without_the_child_frame_is_one_line(tmp_path, capsys):
    t, p, q = _rows()
    bag = write_bag(tmp_path / "bag", "tf", t, p, q)
    rc, _ = _simulate(tmp_path, bag, "--trajectory-topic", "/pose")
    assert rc == 1 and "say which transform" in capsys.readouterr().err
    rc, _ = _simulate(tmp_path, bag, "--trajectory-topic", "/pose", "--child-frame-id", "wheel")
    assert rc == 1 and "no transform with child_frame_id 'wheel'" in capsys.readouterr().err


def test_binary_or_missing_file_is_one_line(tmp_path, capsys):
    (tmp_path / "b.tum").write_bytes(b"\x00\xff\xfe garbage")
    rc, _ = _simulate(tmp_path, tmp_path / "b.tum")
    assert rc == 1 and "not a text file" in capsys.readouterr().err
    rc, _ = _simulate(tmp_path, tmp_path / "missing.tum")
    assert rc == 1 and "trajectory file not found" in capsys.readouterr().err
    assert math.isfinite(1.0)


@pytest.mark.parametrize("kind", ["fifo", "device"])
@pytest.mark.timeout(20)
def test_a_pipe_or_device_as_the_pose_file_is_one_line_not_a_hang(tmp_path, capsys, kind):
    import os

    path = tmp_path / "poses.tum"
    if kind == "fifo":
        os.mkfifo(path)  # open() would wait for a writer for ever
    else:
        path = "/dev/zero"  # an endless line of NULs
    rc, out = _simulate(tmp_path, path)
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 1 and len(err) == 1 and "not a regular file" in err[0], err
    assert not out.exists()


def test_output_never_overwrites_the_pose_file_and_flags_are_checked(tmp_path, capsys):
    t, p, q = _rows()
    tum = write_tum(tmp_path / "a.tum", t, p, q)
    before = tum.read_bytes()
    assert cli_main(["simulate", "lab_bench", "--trajectory", str(tum), "--out", str(tum),
                     "--force", "--quiet"]) == 1
    assert tum.read_bytes() == before and "gyro-attitude simulate: error" in capsys.readouterr().err
    rc, _ = _simulate(tmp_path, tum, "--position-sigma", "nan")
    assert rc == 1 and "--position-sigma must lie in [0, 1]" in capsys.readouterr().err
    rc, _ = _simulate(tmp_path, tum, "--duration", "100")
    err = capsys.readouterr().err
    assert rc == 1 and "longer than the 0.49 s the trajectory covers" in err
    assert cli_main(["simulate", "lab_bench", "--out", str(tmp_path / "x.mcap")]) == 1
    assert "--duration is required" in capsys.readouterr().err


def test_scene_with_a_trajectory_reads_its_file_relative_to_itself(tmp_path):
    import yaml

    from gyro_attitude.io.scene_file import load_scene

    t, p, q = _rows()
    (tmp_path / "poses").mkdir()
    write_tum(tmp_path / "poses" / "walk.tum", t, p, q)
    scene = {"description": "walk", "seed": 1, "earth": {"latitude_deg": 45.0},
             "motion": {"type": "trajectory", "file": "poses/walk.tum",
                        "position_sigma_m": 0.0}}
    (tmp_path / "walk.yaml").write_text(yaml.safe_dump(scene))
    spec = load_scene(str(tmp_path / "walk.yaml"))
    assert spec.start_time_ns == T0 and spec.duration_s == pytest.approx(0.49)
    scene["motion"]["file"] = "nowhere.tum"
    (tmp_path / "bad.yaml").write_text(yaml.safe_dump(scene))
    with pytest.raises(ValueError, match="trajectory file not found"):
        load_scene(str(tmp_path / "bad.yaml"))
    scene["motion"] = {"type": "trajectory", "file": "poses/walk.tum", "position_sigma_m": 5.0}
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(scene))
    with pytest.raises(ValueError, match=r"motion\.position_sigma_m: must be <= 1"):
        load_scene(str(tmp_path / "s.yaml"))
