"""``allan`` on the stamps a real driver writes (issue 38): a regular stream stamped on receipt
scatters by up to ±1/3 of the step about the clock it was sampled on, so one interval may be
off by 2/3 of a step; the samples are still evenly spaced.  Judged by each stamp's distance
from that clock, not by each interval.  Oracles: the closed-form Allan deviation of white
noise of known density, the same samples on even stamps, BROAD 05's evenly stamped file."""

from __future__ import annotations

import numpy as np
import pytest

from gyro_attitude.benchmarks.jitter import jittered_copy
from gyro_attitude.benchmarks.real import real_dir
from gyro_attitude.cli import main as cli_main
from gyro_attitude.io.mcap_writer import Rosbag2McapWriter
from gyro_attitude.offline.allan import analyse_mcap

IMU = "sensor_msgs/msg/Imu"
N, DT_NS, DENS = 120_000, 10_000_000, 1e-3  # 100 Hz, 20 min; white rate noise [rad/√s]
BROAD_05 = real_dir() / "broad_05_slow_rotation_with_breaks.mcap"


def _write(path, t, w):
    with Rosbag2McapWriter(path) as wr:
        wr.add_topic("imu/data_raw", IMU)
        wr.write_imu_array("imu/data_raw", t, w)
    return path


def _still(seed=5):
    rng = np.random.default_rng(seed)
    t = np.arange(N, dtype=np.int64) * DT_NS + 10**9
    return t, rng.normal(scale=DENS / np.sqrt(DT_NS * 1e-9), size=(N, 3))


def test_white_noise_on_stamps_jittered_by_a_third_of_the_step_reads_its_density(tmp_path):
    t, w = _still()
    keep = np.setdiff1d(np.arange(N), [30_000, 70_001, 70_002])  # and a few samples missing
    jitter = np.round(np.random.default_rng(9).uniform(-1 / 3, 1 / 3, N) * DT_NS)
    even = analyse_mcap(_write(tmp_path / "even.mcap", t[keep], w[keep]))
    jit = analyse_mcap(_write(tmp_path / "jit.mcap", (t + jitter.astype(np.int64))[keep],
                              w[keep]))
    assert jit.samples == even.samples == keep.size
    assert any(n.startswith("3 samples missing in 2 holes (first 300 s") for n in jit.notes)
    assert any("scatter up to 3" in n and "about their clock" in n for n in jit.notes)
    np.testing.assert_allclose(jit.tau_s, even.tau_s, rtol=1e-5)
    for axis in "xyz":
        # the same samples: the same deviation; and the closed form σ(τ) = N/√τ for white
        # noise (to its estimate's statistical error at the shortest cluster times)
        np.testing.assert_allclose(jit.gyro[axis].adev, even.gyro[axis].adev, rtol=1e-5)
        short = jit.tau_s <= 1.0
        np.testing.assert_allclose(jit.gyro[axis].adev[short],
                                   DENS / np.sqrt(jit.tau_s[short]), rtol=0.05)
        assert jit.gyro[axis].terms.random_walk == pytest.approx(DENS, rel=0.03)


def test_stamps_off_any_regular_clock_are_refused_in_one_line_saying_how_far(tmp_path,
                                                                             capsys):
    # intervals uniform in 0.5-1.5 steps: the stamps wander a random walk off any clock
    t, w = _still()
    steps = np.round(np.random.default_rng(2).uniform(0.5, 1.5, N - 1) * DT_NS)
    t = np.r_[t[0], t[0] + np.cumsum(steps).astype(np.int64)]
    assert cli_main(["allan", str(_write(tmp_path / "irr.mcap", t, w))]) == 1
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    assert "not a regular stream" in err and "from the clock they scatter about" in err
    assert "evenly spaced samples" in err


@pytest.mark.skipif(not BROAD_05.exists(), reason=f"real recordings not found in {BROAD_05}")
def test_broad_05_with_stamps_jittered_by_a_third_of_the_step_gives_the_even_files_terms(
        tmp_path):
    jittered_copy(BROAD_05, tmp_path / "j.mcap")
    even = analyse_mcap(BROAD_05, "/imu/data_raw")
    jit = analyse_mcap(tmp_path / "j.mcap", "/imu/data_raw")
    assert jit.analysed_s == pytest.approx(even.analysed_s, abs=0.01)  # the longest rest
    assert jit.samples == even.samples
    for sensor in ("gyro", "accel"):
        a, b = getattr(even, sensor), getattr(jit, sensor)
        for axis in "xyz":
            np.testing.assert_allclose(b[axis].adev, a[axis].adev, rtol=1e-3)
            assert b[axis].terms.random_walk == pytest.approx(a[axis].terms.random_walk,
                                                              rel=1e-3)
