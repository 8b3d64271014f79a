"""Replay's figures against the truth as a user's own bags give it (issue 38 items 2 and 8):
truth that covers only part of the Imu (or more), truth on another clock, and the error
reported as tilt and heading apart, the heading less the start's offset when the start was not
the truth's.  Expected values from closed forms: a turn about the vertical at a constant rate."""

from __future__ import annotations

import json
import math
import os
import sys

import numpy as np
import pytest

from gyro_attitude.cli import main as cli_main
from gyro_attitude.io.mcap_writer import Rosbag2McapWriter
from gyro_attitude.offline import replay as replay_mod
from gyro_attitude.offline.replay import replay_file

os.environ.setdefault("AMENT_PREFIX_PATH", sys.prefix)
IMU = "sensor_msgs/msg/Imu"
QS = "geometry_msgs/msg/QuaternionStamped"
RATE = 0.2  # rad/s about z


def rz(angle):
    a = np.asarray(angle, dtype=np.float64)
    return np.stack([np.zeros_like(a), np.zeros_like(a), np.sin(a / 2), np.cos(a / 2)], axis=-1)


def record(path, t_imu, t_truth, truth_offset=None, rest_s=0.0):
    """An ideal gyro at rest for ``rest_s``, then turning about z at RATE; the truth the same
    turn (at its own stamps) after ``truth_offset`` (a quaternion applied on the left)."""
    moving = (t_imu - t_imu[0]) * 1e-9 >= rest_s
    w = np.zeros((t_imu.size, 3))
    w[moving, 2] = RATE
    w += np.random.default_rng(0).normal(scale=1e-3, size=w.shape) if rest_s else 0.0
    a = np.tile([0.0, 0.0, 9.80665], (t_imu.size, 1))
    q = rz(RATE * np.maximum((t_truth - t_imu[0]) * 1e-9 - rest_s, 0.0))
    if truth_offset is not None:
        from gyro_attitude.core.rotation import quat_multiply
        q = quat_multiply(np.broadcast_to(truth_offset, q.shape), q)
    with Rosbag2McapWriter(path) as wr:
        wr.add_topic("imu/data_raw", IMU)
        wr.write_imu_array("imu/data_raw", t_imu, w, a)
        wr.add_topic("truth/attitude", QS)
        wr.write_quaternion_stamped_array("truth/attitude", t_truth, q, frame_id="enu")


def stamps(t0_s, seconds, hz):
    return (int(t0_s * 1e9) + np.arange(int(seconds * hz)) * int(1e9 / hz)).astype(np.int64)


def run(argv, capsys):
    code = cli_main(argv)
    out, err = capsys.readouterr()
    assert "Traceback" not in out + err
    return code, out, err


def test_truth_running_past_the_imu_is_compared_where_they_overlap_and_says_how_much(
        tmp_path, capsys, monkeypatch):
    # the Imu stops at 10 s, the truth runs to 20 s; small truth blocks put whole blocks of
    # truth after the output (the case that gave an IndexError)
    monkeypatch.setattr(replay_mod, "TRUTH_BLOCK", 64)
    t_imu, t_truth = stamps(100, 10, 200), stamps(100, 20, 100)
    record(tmp_path / "in.mcap", t_imu, t_truth)
    code, out, err = run(["replay", str(tmp_path / "in.mcap"), "--out",
                          str(tmp_path / "o.mcap"), "--json"], capsys)
    assert code == 0
    s = json.loads(out)
    inside = int(np.count_nonzero(t_truth <= t_imu[-1]))
    assert s["truth_matched"] == inside
    ov = s["truth_overlap"]
    assert ov["overlap_s"] == pytest.approx((t_imu[-1] - t_imu[0]) * 1e-9)
    assert ov["truth_span_s"] == pytest.approx([t_truth[0] * 1e-9, t_truth[-1] * 1e-9])
    assert s["final_error_rad"] < 1e-6  # an ideal gyro from the truth's start
    code, out, err = run(["replay", str(tmp_path / "in.mcap"), "--out",
                          str(tmp_path / "o.mcap"), "--force"], capsys)
    assert code == 0 and "compared over the 9.995 s where truth and output overlap" in out
    assert "50 % of the truth's" in out


def test_truth_before_the_imu_starts_is_compared_where_they_overlap(tmp_path, monkeypatch):
    monkeypatch.setattr(replay_mod, "TRUTH_BLOCK", 64)
    t_imu, t_truth = stamps(110, 10, 200), stamps(100, 15, 100)
    record(tmp_path / "in.mcap", t_imu, t_truth)
    r = replay_file(tmp_path / "in.mcap", tmp_path / "o.mcap")
    assert r.truth_matched == int(np.count_nonzero(t_truth >= t_imu[0]))
    assert r.truth_overlap["overlap_s"] == pytest.approx(5.0, abs=0.01)


@pytest.mark.parametrize("flags", [[], ["--initial-attitude", "level"],
                                   ["--aiding", "gravity"], ["--estimator", "causal"]])
def test_truth_on_another_clock_is_one_line_naming_both_spans(tmp_path, capsys, flags):
    # the Imu on the device's boot clock (from 5 s), the truth in epoch time
    t_imu, t_truth = stamps(5, 10, 200), stamps(1.7e9, 10, 100)
    record(tmp_path / "in.mcap", t_imu, t_truth, rest_s=3.0)
    code, out, err = run(["replay", str(tmp_path / "in.mcap"), "--out",
                          str(tmp_path / "o.mcap"), *flags], capsys)
    assert code == 0
    lines = [ln for ln in err.splitlines() if "does not overlap" in ln]
    assert len(lines) == 1
    assert "[5.000, 14.995] s" in lines[0] and "[1700000000.000, 1700000009.990] s" in lines[0]


def test_truth_start_on_another_clock_is_refused_in_one_line_naming_both_spans(tmp_path,
                                                                              capsys):
    t_imu, t_truth = stamps(5, 10, 200), stamps(1.7e9, 10, 100)
    record(tmp_path / "in.mcap", t_imu, t_truth)
    code, out, err = run(["replay", str(tmp_path / "in.mcap"), "--out",
                          str(tmp_path / "o.mcap"), "--initial-attitude", "truth"], capsys)
    assert code == 1 and len(err.strip().splitlines()) == 1
    assert "[1700000000.000, 1700000009.990] s" in err and "[5.000, 14.995] s" in err
    assert not (tmp_path / "o.mcap").exists()


def test_error_is_reported_as_tilt_and_heading_and_the_heading_less_the_start_offset(tmp_path):
    # the truth faces 40° further round than the identity start: the raw error is 40°
    # throughout, all of it heading; less the start's offset the heading error is 0
    t = stamps(100, 10, 200)
    record(tmp_path / "in.mcap", t, t, truth_offset=rz(math.radians(40.0)))
    r = replay_file(tmp_path / "in.mcap", tmp_path / "o.mcap")
    assert math.degrees(r.final_error_rad) == pytest.approx(40.0, abs=1e-6)
    assert r.final_tilt_error_rad < 1e-9 and r.max_tilt_error_rad < 1e-9
    assert math.degrees(r.final_heading_error_rad) == pytest.approx(-40.0, abs=1e-6)
    assert abs(r.final_heading_error_from_start_rad) < 1e-8
    # from the truth the offset is the truth's own: nothing to remove, nothing said
    r = replay_file(tmp_path / "in.mcap", tmp_path / "o.mcap", force=True,
                    initial_attitude="truth")
    assert r.final_error_rad < 1e-8 and r.final_heading_error_from_start_rad is None


def test_an_upside_down_mounting_replayed_from_identity_names_the_wrong_start(tmp_path,
                                                                             capsys):
    # an NED-mounted IMU (body z down): the identity start is 180° off in tilt, not a drift
    t = stamps(100, 10, 200)
    record(tmp_path / "in.mcap", t, t, truth_offset=np.array([1.0, 0.0, 0.0, 0.0]))
    code, out, err = run(["replay", str(tmp_path / "in.mcap"), "--out",
                          str(tmp_path / "o.mcap")], capsys)
    assert code == 0
    assert "tilt 180°" in out and "a wrong start: --initial-attitude level or truth" in out


def test_a_repeated_truth_stamp_or_a_lost_marker_is_left_out_of_the_start_and_the_figures(
        tmp_path):
    # a tracker repeats a stamp and loses the markers once (NaN): the truth start took the
    # whole truth for broken ("truth stamps must be strictly increasing")
    t = stamps(100, 10, 200)
    w = np.tile([0.0, 0.0, RATE], (t.size, 1))
    q = rz(RATE * (t - t[0]) * 1e-9)
    tt = t.copy()
    tt[50] = tt[49]
    q[80] = np.nan
    with Rosbag2McapWriter(tmp_path / "in.mcap") as wr:
        wr.add_topic("imu/data_raw", IMU)
        wr.write_imu_array("imu/data_raw", t, w)
        wr.add_topic("truth/attitude", QS)
        wr.write_quaternion_stamped_array("truth/attitude", tt, q, frame_id="enu")
    r = replay_file(tmp_path / "in.mcap", tmp_path / "o.mcap", initial_attitude="truth")
    assert r.truth_matched == t.size - 2 and r.final_error_rad < 1e-8
    assert any("2 of 2000 samples left out" in n for n in r.estimator_notes)


def test_a_truth_topic_not_in_the_input_is_named(tmp_path, capsys):
    t = stamps(100, 5, 200)
    record(tmp_path / "in.mcap", t, t)
    code, out, err = run(["replay", str(tmp_path / "in.mcap"), "--out", str(tmp_path / "o.mcap"),
                          "--truth-topic", "/mocap/typo"], capsys)
    assert code == 0 and "no truth topic '/mocap/typo' with messages in the input" in out
