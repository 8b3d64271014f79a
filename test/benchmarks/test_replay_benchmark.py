"""Smoke test of the replay benchmark in quick mode: it runs and reports every figure.
(Speed is the benchmark's business, never asserted here.)"""

from __future__ import annotations

import json
import os
import sys

import numpy as np

from gyro_attitude.benchmarks import replay as bench

os.environ.setdefault("AMENT_PREFIX_PATH", sys.prefix)


def test_quick_run_reports_all_rows(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(bench, "QUICK_SECONDS", 5)
    monkeypatch.setattr(bench, "PEER_SUBSET", 500)
    monkeypatch.setenv("GYRO_BENCH_TMPDIR", str(tmp_path))
    rows = bench.run(True, tmp_path / "out")
    names = [r["name"] for r in rows]
    assert names == ["write_input", "peer/mcap_read", "peer/mcap_ros2_decode",
                     "replay/rotvec_cubic/cold", "replay/rotvec_cubic/warm",
                     "replay/magnus6_quintic/cold", "replay/magnus6_quintic/warm"]
    assert rows[1]["messages"] == 5000
    for r in rows[3:]:
        assert r["messages"] == r["fast_path_messages"] == 5000 and r["fallback_messages"] == 0
        assert r["truth_matched"] == 50 and r["ratio_vs_mcap_read"] > 0
        assert r["speedup_vs_decode"] > 0
    for r in (rows[3], rows[5]):  # the whole CLI process includes the command's own wall
        assert r["process_wall_seconds"] > r["wall_seconds"]
    # cold (CLI process) and warm (in process) compute the same thing
    assert rows[3]["max_error_rad"] == rows[4]["max_error_rad"]
    # closed-form coning at 1 kHz: the node's 4th-order default and replay's 6th-order one
    # track the truth closely, the 6th-order one closer
    assert rows[4]["max_error_rad"] < 1e-6
    assert rows[6]["max_error_rad"] < rows[4]["max_error_rad"]
    assert json.loads((tmp_path / "out" / "replay.json").read_text())[0]["name"] == "write_input"
    assert "replay/rotvec_cubic/cold" in capsys.readouterr().out
    assert not [p for p in tmp_path.iterdir() if p.name.startswith("gyro_replay_bench_")]


def test_closed_form_coning_matches_its_derivative():
    """ω_b of the benchmark's motion is the body rate of its q(t): 2 q⁻¹ ⊗ dq/dt."""
    t = np.linspace(0.0, 2.0, 2001)
    w, q = bench.coning_closed_form(t)
    h = 1e-6
    _, qp = bench.coning_closed_form(t + h)
    _, qm = bench.coning_closed_form(t - h)
    dq = (qp - qm) / (2 * h)
    # q⁻¹ ⊗ dq with scalar-last quaternions (unit q: inverse = conjugate)
    x, y, z, s = -q[:, 0], -q[:, 1], -q[:, 2], q[:, 3]
    a, b, c, d = dq[:, 0], dq[:, 1], dq[:, 2], dq[:, 3]
    vec = np.stack([s * a + d * x + (y * c - z * b), s * b + d * y + (z * a - x * c),
                    s * c + d * z + (x * b - y * a)], axis=1)
    np.testing.assert_allclose(2 * vec, w, atol=1e-6)
