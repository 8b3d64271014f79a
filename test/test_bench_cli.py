"""Smoke test of ``gyro-attitude bench`` with tiny sizes: CLI, JSON rows, plot, content."""

from __future__ import annotations

import json

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
