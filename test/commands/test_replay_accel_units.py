"""Replay with an accelerometer that is not in m/s² (issue 38 item 3): named in one line and
not used for rests, levelling or aiding; levelling, which needs it, refused in one line."""

from __future__ import annotations

import json
import os
import sys

import numpy as np
import pytest

from gyro_attitude.cli import main as cli_main
from gyro_attitude.io.imu_fast import read_quaternion_stamped_arrays
from gyro_attitude.io.mcap_writer import Rosbag2McapWriter

os.environ.setdefault("AMENT_PREFIX_PATH", sys.prefix)
G = 9.80665


def record(path, scale=1.0, with_accel=True):
    """3 s still, 6 s turning about z at 0.3 rad/s, 3 s still, at 200 Hz; the specific force
    of a sensor tilted 10° times ``scale`` (1/G: in g)."""
    rng = np.random.default_rng(1)
    n = 2400
    t = (10**9 + np.arange(n) * 5_000_000).astype(np.int64)
    w = rng.normal(scale=0.002, size=(n, 3)) + [0.003, -0.002, 0.001]
    w[600:1800, 2] += 0.3
    f = np.tile(G * np.array([0.0, np.sin(0.17), np.cos(0.17)]), (n, 1))
    f += rng.normal(scale=0.03, size=(n, 3))
    with Rosbag2McapWriter(path) as wr:
        wr.add_topic("imu/data_raw", "sensor_msgs/msg/Imu")
        wr.write_imu_array("imu/data_raw", t, w, f * scale if with_accel else None)


def replay(capsys, *argv):
    code = cli_main(["replay", *map(str, argv)])
    out, err = capsys.readouterr()
    assert "Traceback" not in out + err
    return code, out, err


@pytest.mark.parametrize("scale, words", [(1 / G, "in g?"), (1000 / G, "in mg or cm/s²?"),
                                          (100.0, "in mg or cm/s²?"),
                                          (0.0, "all zero: no accelerometer?")])
def test_an_accelerometer_not_in_m_s2_is_named_in_one_line_and_not_used_for_aiding(
        tmp_path, capsys, scale, words):
    record(tmp_path / "in.mcap", scale)
    record(tmp_path / "gyro_only.mcap", with_accel=False)
    for estimator in ("offline", "causal"):
        code, out, err = replay(capsys, tmp_path / "in.mcap", "--out", tmp_path / "o.mcap",
                                "--aiding", "gravity", "--estimator", estimator, "--force")
        assert code == 0
        lines = [ln for ln in err.splitlines() if "not in m/s²" in ln]
        assert len(lines) == 1 and words in lines[0] and "not used" in lines[0]
        assert "tilt from gravity" not in out
        # the attitude is the gyro-only one of the same recording without an accelerometer
        code, _, _ = replay(capsys, tmp_path / "gyro_only.mcap", "--out", tmp_path / "g.mcap",
                            "--aiding", "gravity", "--estimator", estimator, "--force")
        assert code == 0
        np.testing.assert_array_equal(
            read_quaternion_stamped_arrays(tmp_path / "o.mcap", "attitude").quaternion,
            read_quaternion_stamped_arrays(tmp_path / "g.mcap", "attitude").quaternion)


def test_levelling_with_an_accelerometer_in_g_is_refused_in_one_line(tmp_path, capsys):
    record(tmp_path / "in.mcap", 1 / G)
    code, out, err = replay(capsys, tmp_path / "in.mcap", "--out", tmp_path / "o.mcap",
                            "--initial-attitude", "level")
    assert code == 1 and len(err.strip().splitlines()) == 1
    assert "not in m/s²" in err and "in g?" in err and "level" in err
    assert not (tmp_path / "o.mcap").exists()


def test_an_accelerometer_reading_4_percent_low_is_used(tmp_path, capsys):
    record(tmp_path / "in.mcap", 0.96)
    code, out, err = replay(capsys, tmp_path / "in.mcap", "--out", tmp_path / "o.mcap",
                            "--aiding", "gravity", "--json")
    assert code == 0 and "not in m/s²" not in err
    s = json.loads(out)
    assert s["accel_problem"] is None and any("tilt from gravity" in n
                                              for n in s["estimator_notes"])


def test_an_accelerometer_too_far_off_g_for_the_rest_test_is_said_with_the_remedy(tmp_path,
                                                                                  capsys):
    # 12 % low: m/s² (used), but 1.18 m/s² from g is beyond rest_accel_norm_tol (1.0): no
    # window passes the rest test, which the user must hear of
    record(tmp_path / "in.mcap", 0.88)
    code, out, err = replay(capsys, tmp_path / "in.mcap", "--out", tmp_path / "o.mcap")
    assert code == 0
    lines = [ln for ln in err.splitlines() if "beyond rest_accel_norm_tol" in ln]
    assert len(lines) == 1 and "--rest-accel-norm-tol" in lines[0]
    assert "no rest found" in out
    code, out, err = replay(capsys, tmp_path / "in.mcap", "--out", tmp_path / "o.mcap",
                            "--force", "--rest-accel-norm-tol", "1.5")
    assert code == 0 and "beyond rest_accel_norm_tol" not in err and "no rest found" not in out


def test_the_aiding_line_says_the_accelerometer_was_left_out_for_its_units(tmp_path, capsys):
    """Not that the Imu carries none (REP-145): it carries one, in g."""
    record(tmp_path / "in.mcap", 1 / G)
    for estimator in ("offline", "causal"):
        code, out, err = replay(capsys, tmp_path / "in.mcap", "--out", tmp_path / "o.mcap",
                                "--estimator", estimator, "--force")
        assert code == 0
        said = [ln for ln in (out + err).splitlines() if "aiding auto" in ln]
        assert said and all("gyro-only, its accelerometer is not in m/s²" in ln
                            for ln in said), said
        assert "carries no linear acceleration" not in out + err
