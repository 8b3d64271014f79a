"""``gyro-attitude simulate``: scene -> MCAP offline; contents against the scene, bad input."""

from __future__ import annotations

import os
import sys

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

from gyro_attitude.cli import main as cli_main
from gyro_attitude.core.scene import SceneSimulator
from gyro_attitude.io.scene_file import load_scene

os.environ.setdefault("AMENT_PREFIX_PATH", sys.prefix)


def test_simulate_writes_the_scene(tmp_path, capsys):
    out = tmp_path / "coning.mcap"
    assert cli_main(["simulate", "coning", "--duration", "0.5", "--rate", "400",
                     "--out", str(out), "--quiet"]) == 0
    assert "200 samples" in capsys.readouterr().out
    # Independent readers: `mcap` (CRCs checked) + mcap-ros2-support decoding.
    msgs: dict[str, list] = {}
    with open(out, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        assert {c.compression for c in summary.chunk_indexes} == {"zstd"}
        for schema, channel, message, decoded in reader.iter_decoded_messages(
                log_time_order=True):
            msgs.setdefault(channel.topic, []).append((schema.name, message, decoded))
    assert sorted(msgs) == ["/imu/data_raw", "/truth/attitude", "/truth/odom"]
    # Expected values straight from the core simulator at the same rate and seed.
    spec = load_scene("coning")
    b = SceneSimulator(spec, 400.0).next_block(200)
    imu = msgs["/imu/data_raw"]
    assert len(imu) == 200 and imu[0][0] == "sensor_msgs/msg/Imu"
    w = np.array([[m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z]
                  for _, _, m in imu])
    assert np.array_equal(w, b.omega_ib_b)
    t = np.array([m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for _, _, m in imu])
    assert np.array_equal(t, b.t_ns)
    assert [raw.log_time for _, raw, _ in imu] == t.tolist()
    assert imu[0][2].header.frame_id == "imu_link"
    assert imu[0][2].linear_acceleration_covariance[0] == -1.0  # no accelerometer
    q = np.array([[m.quaternion.x, m.quaternion.y, m.quaternion.z, m.quaternion.w]
                  for _, _, m in msgs["/truth/attitude"]])
    assert np.array_equal(q, b.truth_q_nb)
    odom = msgs["/truth/odom"]
    assert odom[0][2].header.frame_id == "enu" and odom[0][2].child_frame_id == "imu_link"
    wnb = np.array([[m.twist.twist.angular.x, m.twist.twist.angular.y, m.twist.twist.angular.z]
                    for _, _, m in odom])
    assert np.array_equal(wnb, b.truth_omega_nb_b)


def test_no_truth_and_seed(tmp_path):
    a, b, c = (tmp_path / f"{k}.mcap" for k in "abc")
    for path, seed in ((a, 3), (b, 3), (c, 4)):
        assert cli_main(["simulate", "lab_bench", "--duration", "1", "--seed", str(seed),
                         "--no-truth", "--out", str(path), "--quiet"]) == 0
    from gyro_attitude.io.imu_fast import read_imu_arrays

    ra, rb, rc = (read_imu_arrays(p) for p in (a, b, c))
    assert len(ra) == 200
    assert np.array_equal(ra.angular_velocity, rb.angular_velocity)
    assert not np.array_equal(ra.angular_velocity, rc.angular_velocity)
    with open(a, "rb") as f:
        topics = {ch.topic for ch in make_reader(f).get_summary().channels.values()}
    assert topics == {"/imu/data_raw"}


@pytest.mark.parametrize("args,match", [
    (["nosuchscene", "--duration", "1"], "unknown scene"),
    (["coning", "--duration", "nan"], "duration must be a finite"),
    (["coning", "--duration", "inf"], "duration must be a finite"),
    (["coning", "--duration", "-1"], "duration must be a finite"),
    (["coning", "--duration", "1e300"], "limit"),
    (["coning", "--duration", "0"], "duration must be a finite"),
    (["coning", "--duration", "1", "--rate", "1e12"], "rate must be"),
    (["coning", "--duration", "1", "--rate", "-5"], "rate must be"),
    (["coning", "--duration", "1e-9"], "gives no sample"),
    (["coning", "--duration", "1", "--rate", "0"], "rate must be"),
    (["coning", "--duration", "1", "--rate", "nan"], "rate must be"),
    (["coning", "--duration", "1", "--seed", "-2"], "seed must be"),
])
def test_bad_input_one_line(tmp_path, capsys, args, match):
    out = tmp_path / "o.mcap"
    assert cli_main(["simulate", *args, "--out", str(out), "--quiet"]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and match in err and "Traceback" not in err
    assert not out.exists() and not list(tmp_path.iterdir())  # no partial or temp file


def test_existing_output_needs_force(tmp_path, capsys):
    out = tmp_path / "o.mcap"
    out.write_bytes(b"keep me")
    assert cli_main(["simulate", "coning", "--duration", "0.1", "--out", str(out),
                     "--quiet"]) == 1
    assert "exists" in capsys.readouterr().err and out.read_bytes() == b"keep me"
    assert cli_main(["simulate", "coning", "--duration", "0.1", "--out", str(out), "--quiet",
                     "--force"]) == 0
    assert out.read_bytes()[:8] == b"\x89MCAP0\r\n"
    assert cli_main(["simulate", "coning", "--duration", "0.1", "--out", str(tmp_path),
                     "--quiet", "--force"]) == 1
    assert "directory" in capsys.readouterr().err


INSTRUMENT_SCENES = ["gyrocompass_ship", "vertical_gyro_turn", "free_gyro_drift"]


@pytest.mark.parametrize("scene", ["lab_bench", "ship", *INSTRUMENT_SCENES])
def test_log_time_order_decoding_and_joints(tmp_path, monkeypatch, scene):
    """Several blocks (block size made small): the whole file in log-time order in file
    order, every message decodes with mcap-ros2-support, joints named and valued as the
    core simulator gives them."""
    from gyro_attitude.offline import simulate as simulate_module

    block, n_blocks = 700, 3
    monkeypatch.setattr(simulate_module, "BLOCK_SAMPLES", block)
    spec = load_scene(scene)
    n = block * n_blocks - 55  # the last block short
    out = tmp_path / "o.mcap"
    r = simulate_module.simulate(scene, n / spec.rate_hz, out)
    assert r.samples == n
    logs, decoded = [], {}
    with open(out, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for schema, channel, message, msg in reader.iter_decoded_messages(
                log_time_order=False):  # file order
            logs.append(message.log_time)
            decoded.setdefault(channel.topic, []).append((schema.name, msg))
    assert len(logs) == n * len(decoded)
    assert np.all(np.diff(np.array(logs, dtype=np.int64)) >= 0)
    # expected: the core simulator in the same blocks (instrument solvers restart per block)
    sim = SceneSimulator(spec, spec.rate_hz)
    blocks = [sim.next_block(min(block, n - k)) for k in range(0, n, block)]
    t = np.concatenate([b.t_ns for b in blocks])
    for topic, msgs in decoded.items():
        stamps = [m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for _, m in msgs]
        assert stamps == t.tolist(), topic
    if scene in INSTRUMENT_SCENES:
        js = decoded["/gyro/joint_states"]
        assert js[0][0] == "sensor_msgs/msg/JointState"
        names = blocks[0].gimbal.names
        assert len(names) >= 2
        assert all(list(m.name) == list(names) and list(m.effort) == [] for _, m in js)
        assert all(m.header.frame_id == "imu_link" for _, m in js)
        pos = np.array([m.position for _, m in js])
        vel = np.array([m.velocity for _, m in js])
        assert np.array_equal(pos, np.concatenate([b.gimbal.positions for b in blocks]))
        assert np.array_equal(vel, np.concatenate([b.gimbal.velocities for b in blocks]))
    else:
        assert "/gyro/joint_states" not in decoded
    odom = decoded["/truth/odom"]
    assert all(m.header.frame_id == "enu" and m.child_frame_id == "imu_link" for _, m in odom)
    q = np.array([[m.pose.pose.orientation.x, m.pose.pose.orientation.y,
                   m.pose.pose.orientation.z, m.pose.pose.orientation.w] for _, m in odom])
    assert np.array_equal(q, np.concatenate([b.truth_q_nb for b in blocks]))
    assert all(not any(m.pose.covariance) for _, m in odom)


def _one_line_failure(capsys, argv, match):
    assert cli_main(argv) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and match in err and "Traceback" not in err, err
    return err


def test_output_never_overwrites_the_scene_file(tmp_path, capsys):
    from gyro_attitude.io.scene_file import find_scene_file

    scene = tmp_path / "my.yaml"
    scene.write_text(find_scene_file("coning").read_text())
    link = tmp_path / "link.mcap"
    link.symlink_to(scene)
    before = scene.read_bytes()
    for out in (scene, link, tmp_path / "." / "my.yaml"):
        _one_line_failure(capsys, ["simulate", str(scene), "--duration", "0.1", "--out",
                                   str(out), "--quiet", "--force"], "is the input")
    assert scene.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link.mcap", "my.yaml"]


def test_unwritable_output_and_not_a_scene(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    _one_line_failure(capsys, ["simulate", "coning", "--duration", "0.1", "--out",
                               str(blocker / "o.mcap"), "--quiet"], "does not exist")
    _one_line_failure(capsys, ["simulate", "coning", "--duration", "0.1", "--out",
                               str(tmp_path / "no" / "o.mcap"), "--quiet"], "does not exist")
    if os.geteuid() != 0:  # root writes anywhere
        ro = tmp_path / "ro"
        ro.mkdir()
        ro.chmod(0o555)
        try:
            _one_line_failure(capsys, ["simulate", "coning", "--duration", "0.1", "--out",
                                       str(ro / "o.mcap"), "--quiet"], "not writable")
            assert not list(ro.iterdir())
        finally:
            ro.chmod(0o755)
    for name, content in (("list.yaml", "- 1\n- 2\n"), ("bag.mcap", None),
                          ("empty.yaml", ""), ("junk.yaml", "{{{: ::\n\x00")):
        p = tmp_path / name
        if content is None:
            p.write_bytes(b"\x89MCAP0\r\n" + bytes(100))
        else:
            p.write_text(content)
        out = tmp_path / "o.mcap"
        _one_line_failure(capsys, ["simulate", str(p), "--duration", "0.1", "--out", str(out),
                                   "--quiet"], name)
        assert not out.exists()
    assert sorted(x.name for x in tmp_path.iterdir()) == [
        "bag.mcap", "empty.yaml", "file", "junk.yaml", "list.yaml"] + (
        ["ro"] if os.geteuid() != 0 else [])
