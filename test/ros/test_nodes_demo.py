"""`gyro-attitude demo`: both nodes as processes, recording, summary and plot."""

import re
import subprocess
import sys

import pytest

pytestmark = [pytest.mark.ros, pytest.mark.timeout(120)]


def test_demo_runs_records_and_plots(ros_env, tmp_path):
    from mcap.reader import make_reader

    proc = subprocess.run(
        [sys.executable, "-m", "gyro_attitude.cli", "demo", "--duration", "1.5",
         "--bag-dir", str(tmp_path / "bags"), "--reliable"],
        env=ros_env, capture_output=True, text=True, timeout=100,
    )
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, out
    assert "scene 'coning'" in out and "Traceback" not in out
    bags = list((tmp_path / "bags").glob("demo_coning_*.mcap"))
    pngs = list((tmp_path / "bags").glob("demo_coning_*_error.png"))
    assert len(bags) == 1 and len(pngs) == 1, out
    assert pngs[0].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with open(bags[0], "rb") as f:  # independent reader
        n_imu = sum(1 for _s, ch, _m in make_reader(f).iter_messages()
                    if ch.topic.endswith("imu/data_raw"))
    assert n_imu == 1500  # the coning scene's 1 kHz for 1.5 s
    assert "received here: 1500 imu/data_raw, 1500 truth/attitude, 1500 attitude" in out, out
    # coning drift bound without coning correction, α²Ω(Ωh)²/12 per second (docs/equations.md)
    import math

    alpha, big_omega, h = math.radians(1.0), 2 * math.pi * 10.0, 1e-3
    bound = alpha**2 * big_omega * (big_omega * h) ** 2 / 12 * 1.5
    max_err = float(re.search(r"\[demo\] max ([0-9.e+-]+) rad", out).group(1))
    assert max_err < bound, (max_err, bound)


def test_node_error_reported_in_one_line(ros_env, tmp_path):
    """gyro_sim refuses rate_hz below 1 Hz (exit 2): the demo names it and prints no summary;
    with --no-record nothing is left in the bag directory (logs went to a temporary folder)."""
    proc = subprocess.run(
        [sys.executable, "-m", "gyro_attitude.cli", "demo", "--rate", "0.5", "--duration", "10",
         "--no-record", "--plot", str(tmp_path / "p.png"), "--bag-dir", str(tmp_path / "bags")],
        env=ros_env, capture_output=True, text=True, timeout=100, cwd=tmp_path)
    assert proc.returncode == 1, proc.stdout + proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr
    line = lines[0]
    assert "gyro_sim exited with status 2" in line and "rate_hz" in line, line
    assert "[demo] samples" not in proc.stdout and "attitude error" not in proc.stdout
    assert sorted(p.name for p in tmp_path.iterdir()) == []
