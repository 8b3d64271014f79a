"""Smoke test of ``gyro-attitude bench`` with tiny sizes: CLI, JSON rows, plot, content."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys

import pytest

from gyro_attitude import cli
from gyro_attitude.benchmarks import attitude
from gyro_attitude.commands import bench

REQUIRED = {"algorithm", "interface", "case", "rate_hz", "alpha_rad", "omega_rad_s",
            "duration_s", "ns_per_sample", "final_error_rad", "max_error_rad", "drift_rad_s"}

TINY = dict(rates=(100.0,), duration=0.3, stream_cap=40, euler_cap=31, peer_cap=31,
            npq_duration=0.1, npq_timeout=10.0, grid=((0.1, 1.0),), spins=(300.0,),
            earth_hours=0.02, earth_algs=("rotvec_cubic",), theory_pers=(12,),
            throughput_n=3000, stream_n=300)


def test_bench_cli_quick_tiny(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(attitude.SIZES, "quick", TINY)
    monkeypatch.setitem(bench.SUITES, "not_there_yet", "gyro_attitude.benchmarks.no_such_suite")
    out_json = tmp_path / "rows.json"
    status = cli.main(["bench", "--suite", "attitude", "--suite", "not_there_yet", "--quick",
                       "--json", str(out_json), "--out-dir", str(tmp_path / "plots")])
    assert status == 0
    printed = capsys.readouterr().out
    assert "suite not_there_yet: missing" in printed
    assert "Coning drift with exact increments vs theory" in printed
    assert (tmp_path / "plots" / "attitude_pareto.png").stat().st_size > 1000

    doc = json.loads(out_json.read_text())
    assert doc["meta"]["suites"] == {"attitude": "ok", "not_there_yet": "missing"}
    rows = doc["rows"]
    assert rows and all(REQUIRED <= row.keys() for row in rows)
    assert {r["interface"] for r in rows} >= {"batch", "streaming", "peer"}
    measured = [r for r in rows if r["case"] == "coning" and r["status"] == "ok"]
    assert {r["algorithm"] for r in measured} >= {"rotvec_cubic", "coning4[exact]",
                                                  "scipy_rotation_loop", "ahrs_angular_rate"}
    assert all(r["ns_per_sample"] > 0 and r["final_error_rad"] >= 0 for r in measured)

    # Content, not just shape: coning passes body z through the vertical (z-x-z flagged),
    # the nav-frame rest case stays put, and the drift stands beside its theory.
    flagged = [r for r in rows if r["algorithm"] == "euler_zxz_rk4" and r["case"] == "coning"]
    assert flagged and all(r["status"] == "flagged_singular" for r in flagged)
    (earth,) = [r for r in rows if r["case"] == "earth_rate_24h"]
    assert earth["max_error_rad"] < 1e-8 and earth["norm_error"] < 1e-12
    theory = [r for r in rows if r["case"] == "coning_theory"]
    assert len(theory) == 5
    for r in theory:
        assert r["above_float_floor"]
        assert 0.8 < r["drift_ratio"] < 1.25, r


def test_bench_rejects_unknown_suite(capsys):
    with pytest.raises(SystemExit):
        cli.main(["bench", "--suite", "bogus"])
    assert "invalid choice" in capsys.readouterr().err


# Run under the CLI's interrupt handler (what `gyro-attitude bench` installs), on the input
# where numpy-quaternion's ODE loop stops advancing (10 Hz coning at 100 Hz): the peer must
# report the hang, and the process must then exit, without a traceback from the worker.
_HUNG_PEER_SCRIPT = """
import math
import numpy as np
from gyro_attitude import cli
from gyro_attitude.benchmarks import attitude
motion = attitude.Coning(0.1, 2 * math.pi * 10.0)
t = np.arange(51) * 0.01
with cli._Interrupt():
    result = attitude._numpy_quaternion_peer(t, motion.rate(t), motion.truth(t)[0], 1.0)
cli._Interrupt.ignore_from_now_on()
print("result:", result if isinstance(result, str) else "ok")
"""


def test_numpy_quaternion_peer_worker_ends_under_cli_interrupt_handler():
    pytest.importorskip("quaternion")
    proc = subprocess.Popen([sys.executable, "-c", _HUNG_PEER_SCRIPT], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        out, err = proc.communicate(timeout=30)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)  # the process and its leftover worker
        proc.communicate()
        pytest.fail("the process never exited: a forked peer worker outlived it")
    assert proc.returncode == 0, err
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err
    assert "result:" in out


def test_bench_refuses_existing_json_without_force(tmp_path, capsys):
    out_json = tmp_path / "rows.json"
    out_json.write_text("precious")
    status = cli.main(["bench", "--suite", "attitude", "--json", str(out_json),
                       "--out-dir", str(tmp_path / "plots")])
    assert status == 2
    err = capsys.readouterr().err
    assert "exists" in err and "--force" in err and len(err.strip().splitlines()) == 1
    assert out_json.read_text() == "precious"
    assert not (tmp_path / "plots").exists()  # refused before any work


def test_bench_refuses_json_directory_before_the_run(tmp_path, capsys, monkeypatch):
    ran = []
    monkeypatch.setattr(bench, "_load_suite", lambda name: ran.append(name))
    status = cli.main(["bench", "--json", str(tmp_path), "--out-dir", str(tmp_path / "p")])
    assert status == 2 and not ran
    err = capsys.readouterr().err
    assert "is a directory" in err and len(err.strip().splitlines()) == 1


def test_bench_out_dir_that_is_a_file(tmp_path, capsys, monkeypatch):
    ran = []
    monkeypatch.setattr(bench, "_load_suite", lambda name: ran.append(name))
    not_a_dir = tmp_path / "file.txt"
    not_a_dir.write_text("x")
    status = cli.main(["bench", "--out-dir", str(not_a_dir)])
    assert status == 2 and not ran
    err = capsys.readouterr().err
    assert "--out-dir" in err and "not a directory" in err
    assert len(err.strip().splitlines()) == 1 and not_a_dir.read_text() == "x"


def test_bench_force_overwrites_json(tmp_path, monkeypatch):
    monkeypatch.setitem(bench.SUITES, "tiny", "gyro_attitude.benchmarks.no_such_suite")
    out_json = tmp_path / "rows.json"
    out_json.write_text("old")
    status = cli.main(["bench", "--suite", "tiny", "--force", "--json", str(out_json),
                       "--out-dir", str(tmp_path / "plots")])
    assert status == 0
    assert json.loads(out_json.read_text())["meta"]["suites"] == {"tiny": "missing"}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["plots", "rows.json"]  # no leftover
