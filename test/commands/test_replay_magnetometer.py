"""replay --aiding magnetometer on a simulated recording with imu/mag: the field is read and matched
to the Imu stamps, the heading follows true north with the declination, counts in the summary;
a missing field topic is one line and exit 1."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from gyro_attitude.cli import main as cli_main
from gyro_attitude.io.imu_fast import read_quaternion_stamped_arrays
from gyro_attitude.io.scene_file import load_scene
from gyro_attitude.offline.simulate import simulate


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    path = tmp_path_factory.mktemp("mag") / "magnet.mcap"
    simulate("magnet_disturbance", 60.0, path)
    return path


def test_replay_takes_the_heading_from_the_field(recording, tmp_path, capsys):
    m = load_scene("magnet_disturbance").magnetometer
    out = tmp_path / "out.mcap"
    hard = ",".join(f"{c:.9g}" for c in m.hard_iron)
    rc = cli_main(["replay", str(recording), "--out", str(out), "--aiding", "magnetometer",
                   "--initial-attitude", "level", "--magnetic-declination-deg",
                   f"{math.degrees(m.declination):.6f}", "--mag-hard-iron-t", hard, "--json"])
    assert rc == 0
    summary = json.loads(capsys.readouterr().out)
    mag = summary["magnetometer"]
    assert mag["messages"] == 12000 and mag["mag_missing"] == 0
    assert 1900 <= mag["mag_disturbed"] <= 2100  # the 10 s magnet at 200 Hz
    assert mag["reference_norm_t"] == pytest.approx(m.intensity, rel=0.01)
    assert mag["clock_offset_s"] is None  # a steady turn cannot tell a delay of the field
    # heading from the field, no truth given: the final error is that of the filter
    assert math.degrees(summary["final_error_rad"]) < 1.0
    att = read_quaternion_stamped_arrays(out, "attitude")
    assert np.isfinite(att.quaternion).all()


@pytest.mark.parametrize("estimator", ["offline", "causal"])
def test_replay_aiding_magnetometer_runs_the_offline_estimator_by_default(recording, tmp_path,
                                                                          capsys, estimator):
    m = load_scene("magnet_disturbance").magnetometer
    hard = ",".join(f"{c:.9g}" for c in m.hard_iron)
    flags = [] if estimator == "offline" else ["--estimator", "causal"]
    rc = cli_main(["replay", str(recording), "--out", str(tmp_path / "o.mcap"), "--aiding",
                   "magnetometer", "--initial-attitude", "level", "--magnetic-declination-deg",
                   f"{math.degrees(m.declination):.6f}", "--mag-hard-iron-t", hard, "--json",
                   *flags])
    assert rc == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["estimator"] == estimator
    assert 1900 <= summary["magnetometer"]["mag_disturbed"] <= 2100  # the 10 s magnet
    assert math.degrees(summary["final_error_rad"]) < 1.0
    if estimator == "offline":
        assert any("heading from the magnetometer" in n for n in summary["estimator_notes"])


def test_replay_without_the_field_topic_says_so_in_one_line(recording, tmp_path, capsys):
    rc = cli_main(["replay", str(recording), "--out", str(tmp_path / "o.mcap"), "--aiding",
                   "magnetometer", "--mag-topic", "compass"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 1 and len(err) == 1
    assert "MagneticField topic 'compass'" in err[0] and "--mag-topic" in err[0]
    assert not (tmp_path / "o.mcap").exists()


def test_a_field_late_against_the_gyro_is_warned_about(recording, tmp_path, capsys, monkeypatch):
    import gyro_attitude.offline.replay as replay_module

    seen = []

    def late(t_ns, omega, rows):
        seen.append(rows.shape)
        return 0.2

    monkeypatch.setattr(replay_module, "field_clock_offset", late)
    rc = cli_main(["replay", str(recording), "--out", str(tmp_path / "o.mcap"), "--aiding",
                   "magnetometer", "--initial-attitude", "level"])
    assert rc == 0 and seen == [(12000, 3)]  # the field rows at the Imu stamps
    err = capsys.readouterr().err
    assert "warning: the magnetic field's stamps look 200 ms late against the gyro's" in err


def test_a_levelled_start_aided_by_the_field_reports_the_field_heading_not_the_given_one(
        recording, tmp_path, capsys):
    # offline --initial-attitude level --aiding magnetometer levels with the given heading
    # (0°), then the field turns the attitude: the summary's heading is the field's, near the
    # truth's at the start (issue 38 item 10; it printed "heading 0.00° (given)")
    m = load_scene("magnet_disturbance").magnetometer
    hard = ",".join(f"{c:.9g}" for c in m.hard_iron)
    args = ["replay", str(recording), "--out", str(tmp_path / "o.mcap"), "--aiding",
            "magnetometer", "--initial-attitude", "level", "--magnetic-declination-deg",
            f"{math.degrees(m.declination):.6f}", "--mag-hard-iron-t", hard]
    assert cli_main([*args, "--json"]) == 0
    a = json.loads(capsys.readouterr().out)["alignment"]
    truth = read_quaternion_stamped_arrays(recording, "truth/attitude").quaternion[0]
    x, y, z, w = truth
    yaw = math.atan2(2 * (x * y + z * w), 1 - 2 * (y * y + z * z))
    want = math.degrees(math.pi / 2 - yaw) % 360.0
    assert a["heading_source"] == "magnetometer"
    assert abs((a["heading_deg"] - want + 180.0) % 360.0 - 180.0) < 1.0
    assert cli_main([*args, "--force"]) == 0
    out = capsys.readouterr().out
    assert "(magnetometer)" in out and "(given)" not in out
