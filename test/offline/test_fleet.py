"""Fleet replay (``replay IN... --out-dir DIR``): each file as a single replay, failures per file."""

from __future__ import annotations

import os
import sys

import pytest
from mcap.reader import make_reader

from gyro_attitude.cli import main as cli_main

os.environ.setdefault("AMENT_PREFIX_PATH", sys.prefix)


def _messages(path):
    """Every message (topic, log time, bytes) of an MCAP file (its metadata records hold the
    writing time, so the files themselves differ)."""
    with open(path, "rb") as f:
        return [(c.topic, m.log_time, m.data) for _, c, m in make_reader(f).iter_messages()]


def _bags(tmp_path):
    src = tmp_path / "in"
    src.mkdir()
    for name, scene in (("a", "coning"), ("b", "lab_bench")):
        assert cli_main(["simulate", scene, "--duration", "1", "--rate", "200",
                         "--out", str(src / f"{name}.mcap"), "--quiet"]) == 0
    (src / "c.mcap").write_bytes(b"not an mcap file\n")
    return src


def test_fleet_equals_single_replays_and_reports_the_bad_file(tmp_path, capsys):
    src = _bags(tmp_path)
    capsys.readouterr()
    out = tmp_path / "out"
    # the glob quoted (not expanded by a shell), two workers
    assert cli_main(["replay", str(src / "*.mcap"), "--out-dir", str(out), "--workers", "2",
                     "--gyro-bias", "none"]) == 1
    text = capsys.readouterr().out
    lines = text.splitlines()
    assert sum(ln.startswith("ok ") for ln in lines) == 2
    assert [ln for ln in lines if ln.startswith("FAILED")] == [
        f"FAILED {src / 'c.mcap'}: {src / 'c.mcap'}: not an MCAP file (bad magic)"]
    assert lines[-1].startswith("total: 2 of 3 file(s) replayed") and "1 failed" in lines[-1]
    assert sorted(p.name for p in out.iterdir()) == ["a.mcap", "b.mcap"]
    for name in ("a", "b"):
        single = tmp_path / f"single_{name}.mcap"
        assert cli_main(["replay", str(src / f"{name}.mcap"), "--out", str(single),
                         "--gyro-bias", "none"]) == 0
        assert _messages(out / f"{name}.mcap") == _messages(single)


def test_fleet_refuses_colliding_outputs_and_empty_globs(tmp_path, capsys):
    src = _bags(tmp_path)
    other = tmp_path / "other"
    other.mkdir()
    (other / "a.mcap").write_bytes((src / "a.mcap").read_bytes())
    capsys.readouterr()
    assert cli_main(["replay", str(src / "a.mcap"), str(other / "a.mcap"), "--out-dir",
                     str(tmp_path / "o")]) == 1
    assert "would both be written to" in capsys.readouterr().err
    assert cli_main(["replay", str(tmp_path / "none*.mcap"), "--out-dir",
                     str(tmp_path / "o")]) == 1
    assert "matches no file" in capsys.readouterr().err
    # an existing output is not overwritten without --force; nothing is replayed
    assert cli_main(["replay", str(src / "a.mcap"), str(src / "b.mcap"), "--out-dir",
                     str(src)]) == 1
    assert "input" in capsys.readouterr().err
    assert cli_main(["replay", str(src / "a.mcap"), str(src / "b.mcap")]) == 2
    assert "--out-dir" in capsys.readouterr().err


def test_ctrl_c_keeps_only_complete_outputs(tmp_path):
    """SIGINT while the workers write: exit 130, one line; what is in DIR is complete (every
    message there), nothing half-written, no temporary left."""
    import signal
    import subprocess
    import time
    from pathlib import Path

    src = tmp_path / "in"
    src.mkdir()
    for k in range(4):
        assert cli_main(["simulate", "coning", "--duration", "100", "--rate", "1000", "--seed",
                         str(k), "--out", str(src / f"c{k}.mcap"), "--quiet"]) == 0
    out = tmp_path / "out"
    repo = Path(__file__).resolve().parents[2]
    env = dict(os.environ, PYTHONPATH=str(repo) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    proc = subprocess.Popen(
        [sys.executable, "-m", "gyro_attitude.cli", "replay", *sorted(map(str, src.iterdir())),
         "--out-dir", str(out), "--workers", "2"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    deadline = time.monotonic() + 60
    while not (out.exists() and any(out.iterdir())) and proc.poll() is None \
            and time.monotonic() < deadline:
        time.sleep(0.01)  # a temporary output exists: a worker is writing
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    if proc.returncode == 0:
        pytest.skip("the fleet finished before the signal arrived")
    assert proc.returncode == 130, err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("interrupted:"), err
    names = sorted(p.name for p in out.iterdir())
    assert all(n.endswith(".mcap") and not n.startswith(".") for n in names), names
    for n in names:  # complete: every Imu message replayed
        msgs = _messages(out / n)
        assert sum(topic == "/imu/data" for topic, _, _ in msgs) == 100_000 - 1  # stamp 0 skipped
