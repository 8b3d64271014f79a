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
