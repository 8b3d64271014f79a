"""``gyro-attitude allan`` on records that are not all at rest, and stamps that are not times.

Allan analysis describes a sensor at rest: motion in the record must not be reported as noise
terms, and no scene is ever written that ``simulate`` refuses."""

from __future__ import annotations

import json
import os
import sys

import numpy as np
import pytest

from gyro_attitude.benchmarks import real
from gyro_attitude.cli import main as cli_main
from gyro_attitude.io.mcap_writer import Rosbag2McapWriter
from gyro_attitude.io.scene_file import load_scene
from gyro_attitude.offline.allan import find_rests

os.environ.setdefault("AMENT_PREFIX_PATH", sys.prefix)
IMU = "sensor_msgs/msg/Imu"
RATE, N_ARW = 100.0, 2e-3  # Hz; white rate noise N [rad/√s]
G = np.array([0.0, 0.0, 9.81])


def _record(path, spans, seed=3, bias=(0.0, 0.0, 0.0), zero_stamps=0):
    """An IMU record at 100 Hz: white gyro noise N (plus ``bias``), the accelerometer at rest
    (+g on z and white noise); ``spans`` = [(seconds, moving)]: a moving span turns the IMU
    about x by ±40° at 0.5 Hz (rate up to 1.1 rad/s, gravity turning in the accelerometer)."""
    rng = np.random.default_rng(seed)
    gyro, acc = [], []
    for seconds, moving in spans:
        n = int(seconds * RATE)
        w = rng.normal(scale=N_ARW * np.sqrt(RATE), size=(n, 3)) + np.asarray(bias)
        f = G + rng.normal(scale=0.02, size=(n, 3))
        if moving:
            t = np.arange(n) / RATE
            angle = np.radians(40.0) * np.sin(2 * np.pi * 0.5 * t)
            w[:, 0] += np.radians(40.0) * 2 * np.pi * 0.5 * np.cos(2 * np.pi * 0.5 * t)
            f = np.c_[f[:, 0], 9.81 * np.sin(angle) + f[:, 1] * 0, 9.81 * np.cos(angle)] + \
                rng.normal(scale=0.02, size=(n, 3))
        gyro.append(w)
        acc.append(f)
    gyro, acc = np.concatenate(gyro), np.concatenate(acc)
    t = np.arange(gyro.shape[0], dtype=np.int64) * 10_000_000 + 10**9
    t[:zero_stamps] = 0
    with Rosbag2McapWriter(path) as wr:
        wr.add_topic("imu/data_raw", IMU)
        wr.write_imu_array("imu/data_raw", t, gyro, acc)
    return path


def test_rests_are_found_where_the_record_is_still_within_a_block():
    rng = np.random.default_rng(1)
    n = int(300 * RATE)
    g = rng.normal(scale=0.02, size=(n, 3)) + [0.03, -0.02, 0.01]  # a 1.7°/s bias: still
    a = G + rng.normal(scale=0.02, size=(n, 3))
    moving = slice(int(100 * RATE), int(130 * RATE))  # 100-130 s: a wobble
    g[moving, 1] += np.sin(np.arange(30 * RATE) / RATE * 3.0)
    a[moving, 0] += 0.5 * np.sin(np.arange(30 * RATE) / RATE * 3.0)
    turn = slice(int(200 * RATE), int(230 * RATE))  # 200-230 s: a steady turn about the
    g[turn, 2] += 0.2  # vertical (no spread, the accelerometer unchanged): only its mean shows
    segs = find_rests(g, 1 / RATE, a).segments
    assert len(segs) == 3
    (a0, a1), (b0, b1), (c0, c1) = segs
    block = 100  # samples: 1 s blocks, one trimmed beside the motion
    assert a0 == 0 and 100 * RATE - 2 * block <= a1 < 100 * RATE
    assert 130 * RATE <= b0 <= 130 * RATE + 2 * block
    assert 200 * RATE - 2 * block <= b1 < 200 * RATE
    assert 230 * RATE <= c0 <= 230 * RATE + 2 * block and c1 >= n - block - 1
    g[turn, 2] -= 0.2
    # a static record of the same noisy, biased gyro is one rest holding every sample
    assert find_rests(np.delete(g, moving, axis=0), 1 / RATE).still


def test_a_static_record_of_a_noisy_biased_gyro_with_a_random_walk_is_still():
    """Relative thresholds: a 5 °/s bias, 0.3 rad/s of white noise per sample (30× the rest
    detector's bound) and a rate random walk of 2e-5 rad/s/√s (≈ 250 °/h/√h, worse than any
    MEMS datasheet) over an hour are rest."""
    rng = np.random.default_rng(2)
    n = 3600 * 100
    walk = np.cumsum(rng.normal(scale=2e-5 * np.sqrt(0.01), size=(n, 3)), axis=0)
    g = rng.normal(scale=0.3, size=(n, 3)) + np.radians(5.0) + walk
    assert find_rests(g, 0.01).still


def test_allan_on_a_moving_record_analyses_the_longest_rest_and_lists_the_rests(tmp_path,
                                                                               capsys):
    rec = _record(tmp_path / "m.mcap", [(40, False), (30, True), (120, False), (20, True),
                                        (15, False)])
    js, yml = tmp_path / "a.json", tmp_path / "s.yaml"
    assert cli_main(["allan", str(rec), "--json", str(js), "--scene-out", str(yml)]) == 0
    cap = capsys.readouterr()
    assert "moves" in cap.err and "longest rest" in cap.out
    d = json.loads(js.read_text())
    assert d["moving"] is True and len(d["rests_s"]) == 3
    start, end = d["analysed_s"]
    assert 70.0 <= start <= 72.0 and 188.0 <= end <= 190.0  # the 120-s rest, trimmed ≤ 2 s
    for axis in "xyz":  # the noise of the rest: N within 5 % (about 1.2e4 samples)
        assert d["axes"][axis]["arw_rad_sqrt_s"] == pytest.approx(N_ARW, rel=0.05)
        assert d["axes"][axis]["rrw_rad_s_sqrt_s"] is None
        assert d["axes"][axis]["bias_instability_rad_s"] is None
    spec = load_scene(str(yml))  # what simulate loads
    assert spec.gyro_errors.noise_density == pytest.approx(np.full(3, N_ARW), rel=0.05)


def test_allan_on_a_record_that_moves_throughout_names_the_rests_and_writes_nothing(
        tmp_path, capsys):
    rec = _record(tmp_path / "m.mcap", [(8, False), (60, True), (6, False), (60, True)])
    out = tmp_path / "s.yaml"
    assert cli_main(["allan", str(rec), "--scene-out", str(out)]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "moves" in err and "no rest lasts 10 s" in err, err
    assert "0–" in err  # where the (short) rests are
    assert not out.exists()


DIR = real.real_dir()
BROAD_05 = DIR / "broad_05_slow_rotation_with_breaks.mcap"


@pytest.mark.skipif(not BROAD_05.exists(), reason=f"real recordings not found in {DIR}")
def test_allan_never_writes_a_scene_simulate_refuses_on_broad_05(tmp_path, capsys):
    """The issue's case: rotation with pauses.  By default the longest rest (the initial
    ~30 s) is analysed: its terms make a scene simulate loads, with the ARW of a consumer
    MEMS (0.1–1 °/√h); analysing every sample gives terms no scene accepts: nothing written."""
    scene, kalibr = tmp_path / "s.yaml", tmp_path / "imu.yaml"
    assert cli_main(["allan", str(BROAD_05), "--imu-topic", "/imu/data_raw",
                     "--scene-out", str(scene), "--kalibr-out", str(kalibr)]) == 0
    assert "moves" in capsys.readouterr().err
    arw = load_scene(str(scene)).gyro_errors.noise_density
    assert np.all((arw > np.radians(0.1) / 60) & (arw < np.radians(1.0) / 60))
    whole = tmp_path / "w.yaml"
    assert cli_main(["allan", str(BROAD_05), "--imu-topic", "/imu/data_raw", "--whole-record",
                     "--scene-out", str(whole)]) == 1
    err = capsys.readouterr().err
    assert "no scene simulate accepts" in err and "rate_random_walk" in err
    assert not whole.exists()


def test_allan_names_zero_stamps(tmp_path, capsys):
    rec = _record(tmp_path / "z.mcap", [(30, False)], zero_stamps=5)
    assert cli_main(["allan", str(rec)]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "5 of the 3000 is zero" in err, err
    assert "header.stamp not set" in err


def test_allan_bad_argument_is_one_line(capsys):
    with pytest.raises(SystemExit) as stop:
        cli_main(["allan"])
    assert stop.value.code == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("gyro-attitude allan: error:") and len(err.splitlines()) == 1, err
