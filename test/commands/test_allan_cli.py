"""``gyro-attitude allan``: report, JSON, scene round trip, plot, bad input."""

from __future__ import annotations

import json
import os
import sys

import numpy as np
import pytest

from gyro_attitude.cli import main as cli_main
from gyro_attitude.io.mcap_writer import Rosbag2McapWriter
from gyro_attitude.io.scene_file import load_scene
from gyro_attitude.offline.simulate import simulate

os.environ.setdefault("AMENT_PREFIX_PATH", sys.prefix)
IMU = "sensor_msgs/msg/Imu"


@pytest.fixture(scope="module")
def white_bag(tmp_path_factory):
    """10 min of white rate noise N = 1e-3 rad/√s at 100 Hz (no accelerometer)."""
    path = tmp_path_factory.mktemp("allan") / "white.mcap"
    n, dt, dens = 60_000, 0.01, 1e-3
    rng = np.random.default_rng(5)
    w = rng.normal(scale=dens / np.sqrt(dt), size=(n, 3))
    t = np.arange(n, dtype=np.int64) * 10_000_000 + 10**9
    with Rosbag2McapWriter(path) as wr:
        wr.add_topic("imu/data_raw", IMU)
        wr.write_imu_array("imu/data_raw", t, w)
    return path, dens


def test_report_json_plot_and_scene(white_bag, tmp_path, capsys):
    path, dens = white_bag
    js, png, yml = tmp_path / "a.json", tmp_path / "a.png", tmp_path / "s.yaml"
    assert cli_main(["allan", str(path), "--json", str(js), "--plot", str(png),
                     "--scene-out", str(yml)]) == 0
    out = capsys.readouterr().out
    assert "N (ARW)" in out and "accelerometer" not in out
    d = json.loads(js.read_text())
    assert set(d["adev_rad_s"]) == {"x", "y", "z"} and len(d["tau_s"]) == len(d["adev_rad_s"]["x"])
    assert "accel_axes" not in d
    for axis in "xyz":
        terms = d["axes"][axis]
        # White noise only: N from 6e4 samples (±2 %); nothing else visible.
        assert terms["arw_rad_sqrt_s"] == pytest.approx(dens, rel=0.03)
        assert terms["rrw_rad_s_sqrt_s"] is None
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    spec = load_scene(str(yml))  # the scene loader accepts the written block
    assert spec.gyro_errors.noise_density == pytest.approx(np.full(3, dens), rel=0.03)
    assert spec.rate_hz == pytest.approx(100.0)


def test_scene_out_round_trip_through_simulate(tmp_path):
    # record (simulated) -> allan --scene-out -> simulate that scene -> same terms
    rec, yml, sim2 = tmp_path / "r.mcap", tmp_path / "s.yaml", tmp_path / "r2.mcap"
    simulate("lab_bench", 600.0, rec, publish_truth=False)
    assert cli_main(["allan", str(rec), "--scene-out", str(yml)]) == 0
    spec = load_scene(str(yml))
    assert spec.accelerometer and spec.gyro_errors.noise_density[0] > 0
    assert cli_main(["simulate", str(yml), "--duration", "10", "--out", str(sim2),
                     "--quiet"]) == 0


@pytest.mark.parametrize("content,match", [
    (b"", "cannot read|not an MCAP|empty|magic"),
    (b"hello, this is not an mcap file at all" * 10, "cannot read|not an MCAP|magic"),
])
def test_bad_files_one_line(tmp_path, capsys, content, match):
    p = tmp_path / "bad.mcap"
    p.write_bytes(content)
    assert cli_main(["allan", str(p)]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    assert __import__("re").search(match, err, flags=__import__("re").I), err


def test_no_imu_too_short_missing(tmp_path, capsys, white_bag):
    no_imu = tmp_path / "q.mcap"
    with Rosbag2McapWriter(no_imu) as wr:
        wr.add_topic("truth/attitude", "geometry_msgs/msg/QuaternionStamped")
        wr.write_quaternion_stamped_array("truth/attitude", np.arange(5) + 1, np.tile(
            [0.0, 0.0, 0.0, 1.0], (5, 1)))
    short = tmp_path / "s.mcap"
    with Rosbag2McapWriter(short) as wr:
        wr.add_topic("imu/data_raw", IMU)
        wr.write_imu_array("imu/data_raw", np.arange(10, dtype=np.int64) * 10**7 + 1,
                           np.zeros((10, 3)))
    nan = tmp_path / "n.mcap"
    w = np.zeros((100, 3))
    w[50, 1] = np.nan
    with Rosbag2McapWriter(nan) as wr:
        wr.add_topic("imu/data_raw", IMU)
        wr.write_imu_array("imu/data_raw", np.arange(100, dtype=np.int64) * 10**7 + 1, w)
    for path, match in ((no_imu, "no topic 'imu/data_raw'"), (short, "too few"),
                        (nan, "NaN"), (tmp_path / "missing.mcap", "no such file")):
        assert cli_main(["allan", str(path)]) == 1
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and match in err, err
    path, _ = white_bag
    assert cli_main(["allan", str(path), "--imu-topic", "other"]) == 1
    assert "no topic 'other'" in capsys.readouterr().err
    assert cli_main(["allan", str(path), "--json", str(path)]) == 1
    assert "is the input" in capsys.readouterr().err


def test_outputs_are_checked_before_any_work(white_bag, tmp_path, capsys):
    """Never the input (also through a symlink or a relative path), never an existing file
    without --force, never one output twice, never into a missing directory; nothing left
    behind."""
    path, _ = white_bag
    before = path.read_bytes()
    link = tmp_path / "link.json"
    link.symlink_to(path)
    rel = os.path.relpath(path)
    # (a --plot named like the input is refused by its suffix already: test_one_line_errors)
    for flag, out, match in (("--json", link, "is the input"), ("--json", rel, "is the input"),
                             ("--scene-out", path, "is the input"),
                             ("--json", tmp_path / "nodir" / "a.json", "does not exist"),
                             ("--json", tmp_path, "is a directory")):
        assert cli_main(["allan", str(path), flag, str(out), "--force"]) == 1
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and match in err, err
    assert path.read_bytes() == before
    existing = tmp_path / "a.json"
    existing.write_text("keep")
    assert cli_main(["allan", str(path), "--json", str(existing)]) == 1
    assert "exists" in capsys.readouterr().err and existing.read_text() == "keep"
    twice = tmp_path / "b.out"
    assert cli_main(["allan", str(path), "--json", str(twice), "--scene-out", str(twice)]) == 1
    assert "is the input" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.json", "link.json"]
    # with --force the existing one is replaced, atomically (no temporary left)
    assert cli_main(["allan", str(path), "--json", str(existing), "--force"]) == 0
    assert json.loads(existing.read_text())["samples"] == 60_000
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.json", "link.json"]


def test_bad_input_leaves_no_output(tmp_path, capsys):
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(b"\x89MCAP0\r\n" + bytes(64))  # magic, then garbage: truncated
    for p in (bad, tmp_path / "empty.mcap"):
        p.touch()
        assert cli_main(["allan", str(p), "--json", str(tmp_path / "o.json"),
                         "--plot", str(tmp_path / "o.png")]) == 1
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.mcap", "empty.mcap"]
