"""The node benchmark runs end to end and reports consistent figures (no speed asserted)."""

import json

import pytest

pytestmark = [pytest.mark.ros, pytest.mark.timeout(120)]


def test_nodes_benchmark_quick_reports_loss_and_latency(ros_env, tmp_path, monkeypatch):
    from gyro_attitude.benchmarks import nodes

    for key in ("ROS_DOMAIN_ID", "ROS_AUTOMATIC_DISCOVERY_RANGE", "PYTHONPATH"):
        monkeypatch.setenv(key, ros_env[key])
    monkeypatch.setattr(nodes, "QUICK_RATES", (200.0,))
    monkeypatch.setattr(nodes, "PEER_RATE_HZ", 100.0)
    rows = nodes.run(quick=True, out_dir=tmp_path)
    row, peer, summary = rows
    assert peer["integrator_params"] == ["executor:=single_threaded", "drain_queue:=false"]
    assert peer["published"] == 500
    assert row["published"] == 1000  # 200 Hz for the quick 5 s
    assert row["integrated"] + row["lost"] == row["published"]
    assert 0 < row["latency_pairs"] <= row["published"]
    assert 0 < row["latency_p50_ms"] <= row["latency_p99_ms"] <= row["latency_max_ms"]
    assert summary["summary"] and summary["rates_tested"] == [200.0]
    assert summary["max_rate_no_loss_hz"] == (200.0 if row["lost"] == 0 else None)
    assert summary["max_rate_no_loss_p99_under_target_hz"] in (200.0, None)
    assert json.loads((tmp_path / "nodes.json").read_text()) == rows
