"""A folder of separate .mcap recordings (not a rosbag2 directory: no metadata.yaml) given where
one bag is expected: one line naming the files and the remedy that works, never a guess."""

from __future__ import annotations

import shlex

import numpy as np

from gyro_attitude.cli import main as cli_main
from gyro_attitude.io.mcap_writer import Rosbag2McapWriter


def _folder(tmp_path):
    d = tmp_path / "runs"
    d.mkdir()
    rng = np.random.default_rng(1)
    for name in ("monday", "tuesday"):
        t = np.arange(2000, dtype=np.int64) * 10_000_000 + 10**9
        with Rosbag2McapWriter(d / f"{name}.mcap") as w:
            w.add_topic("imu/data_raw", "sensor_msgs/msg/Imu")
            w.write_imu_array("imu/data_raw", t, rng.normal(scale=0.01, size=(t.size, 3)),
                              np.tile([0.0, 0.0, 9.81], (t.size, 1)))
    return d


def _one_line(capsys):
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    return err


def test_replay_of_a_folder_of_recordings_names_the_files_and_the_fleet_command_that_works(
        tmp_path, capsys):
    d = _folder(tmp_path)
    assert cli_main(["replay", str(d), "--out", str(tmp_path / "x.mcap")]) == 1
    err = _one_line(capsys)
    assert "monday.mcap, tuesday.mcap" in err and "no metadata.yaml" in err
    assert f"ros2 bag reindex {d}" in err
    # the command it names replays each recording
    command = err.split("replay each with gyro-attitude ")[1].strip()
    args = [a.replace("OUT_DIR", str(tmp_path / "out")) for a in shlex.split(command)]
    assert args[:2] == ["replay", f"{d}/*.mcap"] and "--out-dir" in args
    assert cli_main(args) == 0
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["monday.mcap",
                                                                     "tuesday.mcap"]
    assert not (tmp_path / "x.mcap").exists()


def test_fleet_replay_of_a_folder_of_recordings_is_refused_before_any_work(tmp_path, capsys):
    d = _folder(tmp_path)
    assert cli_main(["replay", str(d), "--out-dir", str(tmp_path / "out")]) == 1
    err = _one_line(capsys)
    assert f"'{d}/*.mcap' --out-dir" in err
    assert not (tmp_path / "out").exists()


def test_allan_of_a_folder_of_recordings_says_give_one_or_write_the_metadata(tmp_path, capsys):
    d = _folder(tmp_path)
    assert cli_main(["allan", str(d)]) == 1
    err = _one_line(capsys)
    assert "give one of them" in err and f"ros2 bag reindex {d} -s mcap" in err
