"""``gyro-attitude montecarlo``: outputs, the same numbers as simulate + replay, bad input, Ctrl-C."""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from gyro_attitude.cli import main as cli_main
from gyro_attitude.offline import montecarlo as mc

os.environ.setdefault("AMENT_PREFIX_PATH", sys.prefix)
REPO = Path(__file__).resolve().parents[2]


def _children(pid: int) -> list[int]:
    """Process ids whose parent is ``pid`` (Linux /proc)."""
    out = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            out.append(int(stat.parent.name))
    return out


def _lines(text: str) -> list[str]:
    return [ln for ln in text.splitlines() if ln.strip()]


def test_table_json_and_plot(tmp_path, capsys):
    out, png = tmp_path / "mc.json", tmp_path / "mc.png"
    assert cli_main(["montecarlo", "lab_bench", "--runs", "5", "--duration", "2", "--rate", "50",
                     "--workers", "1", "--grade", "lab_bench", "--grade", "*3",
                     "--json", str(out), "--plot", str(png), "--grid-points", "11"]) == 0
    table = capsys.readouterr().out
    assert "lab_bench*3" in table and "NEES final" in table and "per run" in table
    doc = json.loads(out.read_text())
    assert doc["complete"] is True and doc["interrupted"] is False
    assert doc["grades"] == ["lab_bench", "lab_bench*3"]
    assert len(doc["runs"]) == 10 and doc["runs_finished"] == 10
    r = doc["runs"][0]
    assert r["index"] == 0 and r["seed"] == mc.run_seeds(1, 5)[0]  # lab_bench's seed: 1
    assert len(r["final_error_rad"]) == 3 and len(r["rms_error_rad"]) == 3
    assert math.isclose(r["final_error_angle_rad"], math.hypot(*r["final_error_rad"]))
    st = doc["statistics"][1]
    assert st["label"] == "lab_bench*3" and len(st["time_s"]) == 11
    assert st["time_s"][0] == 0.0 and st["time_s"][-1] == pytest.approx(99 / 50)
    for key in ("error_angle_rad", "heading_error_rad", "tilt_error_rad"):
        assert set(st[key]) == {"p50", "p68", "p95", "p99"}
        p = [st[key][k][-1] for k in ("p50", "p68", "p95", "p99")]
        assert p == sorted(p)
    nees = st["nees"]
    assert nees["dof"] == 3 and nees["final"]["runs"] == 5
    assert nees["final"]["lower"] < 3 < nees["final"]["upper"]
    assert png.stat().st_size > 10_000


@pytest.mark.parametrize("estimator", ["causal", "offline"])
def test_a_run_is_what_simulate_then_replay_give(tmp_path, capsys, estimator):
    """Run 0 through the command equals ``simulate --seed <its seed>`` then ``replay`` of
    that recording in the ENU frame of the scene (same library code, MCAP on the way), with
    the same estimator (montecarlo's default, replay's ``--estimator causal``)."""
    out = tmp_path / "mc.json"
    assert cli_main(["montecarlo", "lab_bench", "--runs", "1", "--duration", "3",
                     "--rate", "100", "--workers", "1", "--estimator", estimator,
                     "--json", str(out)]) == 0
    run = json.loads(out.read_text())["runs"][0]
    bag, rep = tmp_path / "r.mcap", tmp_path / "rep.mcap"
    assert cli_main(["simulate", "lab_bench", "--duration", "3", "--rate", "100", "--seed",
                     str(run["seed"]), "--out", str(bag), "--quiet"]) == 0
    capsys.readouterr()
    assert cli_main(["replay", str(bag), "--out", str(rep), "--initial-attitude", "truth",
                     "--frame", "enu", "--latitude-deg", "45", "--longitude-deg", "7",
                     "--height-m", "250", "--estimator", estimator, "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["attitude_messages"] == run["attitudes"]
    assert math.isclose(summary["final_error_rad"], run["final_error_angle_rad"], rel_tol=1e-9)


@pytest.mark.parametrize("args, flag", [
    (["--runs", "0"], "--runs"), (["--runs", "-3"], "--runs"), (["--runs", "2.5"], "--runs"),
    (["--runs", "2", "--duration", "-1"], "--duration"),
    (["--runs", "2", "--duration", "nan"], "--duration"),
    (["--runs", "2", "--duration", "inf"], "--duration"),
    (["--runs", "2", "--rate", "0"], "--rate"),
    (["--runs", "2", "--workers", "0"], "--workers"),
])
def test_bad_arguments_are_one_line_exit_2(capsys, args, flag):
    with pytest.raises(SystemExit) as exc:
        cli_main(["montecarlo", "lab_bench", *args])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert len(_lines(err)) == 1 and flag in err and "Traceback" not in err


@pytest.mark.parametrize("args, text", [
    (["--duration", "0.001"], "at least 2 are needed"),
    (["--grade", "nonexistent_scene"], "unknown scene"),
    (["--json", "{scene}"], "input"),
])
def test_unusable_input_is_one_line_exit_1(tmp_path, capsys, args, text):
    scene = tmp_path / "s.yaml"
    scene.write_text((REPO / "config" / "scenes" / "lab_bench.yaml").read_text())
    args = [a.replace("{scene}", str(scene)) for a in args]
    assert cli_main(["montecarlo", str(scene), "--runs", "2", *args]) == 1
    err = capsys.readouterr().err
    assert len(_lines(err)) == 1 and text in err, err
    assert scene.read_text() == (REPO / "config" / "scenes" / "lab_bench.yaml").read_text()


def test_unreachable_scheduler_is_one_line_within_the_timeout(tmp_path, capsys):
    t0 = time.monotonic()
    # port 9 (discard) on loopback: nothing listens, the connection is refused at once and
    # Dask retries until the timeout
    assert cli_main(["montecarlo", "lab_bench", "--runs", "2", "--duration", "1",
                     "--scheduler", "tcp://127.0.0.1:9", "--connect-timeout", "2",
                     "--json", str(tmp_path / "o.json")]) == 1
    elapsed = time.monotonic() - t0
    err = capsys.readouterr().err
    assert len(_lines(err)) == 1 and "no Dask scheduler answered" in err and "2 s" in err, err
    assert elapsed < 15
    assert not (tmp_path / "o.json").exists()


@pytest.mark.parametrize("address", ["foo", "", "tcp://127.0.0.1:notaport"])
def test_malformed_scheduler_address_is_one_line(capsys, address):
    assert cli_main(["montecarlo", "lab_bench", "--runs", "1", "--duration", "1",
                     "--scheduler", address]) == 1
    err = capsys.readouterr().err
    assert len(_lines(err)) == 1 and "is not a scheduler address" in err, err


def test_failing_run_17_is_reported_and_the_others_written(tmp_path, capsys, monkeypatch):
    real = mc.run_one

    def run_one(spec, setup, index, seed, label):
        if index == 17:
            raise ValueError("planted failure")
        return real(spec, setup, index, seed, label)

    monkeypatch.setattr(mc, "run_one", run_one)
    out = tmp_path / "o.json"
    assert cli_main(["montecarlo", "lab_bench", "--runs", "20", "--duration", "0.5",
                     "--rate", "50", "--workers", "1", "--json", str(out)]) == 1
    err = capsys.readouterr().err
    assert "run 17 (lab_bench, seed" in err and "planted failure" in err
    doc = json.loads(out.read_text())
    assert doc["runs_finished"] == 19 and doc["runs_failed"] == 1
    assert [r["index"] for r in doc["runs"] if "error" in r] == [17]
    assert doc["statistics"][0]["runs_finished"] == 19


def test_ctrl_c_exits_130_with_the_finished_runs_marked_partial(tmp_path):
    out = tmp_path / "o.json"
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    proc = subprocess.Popen(
        [sys.executable, "-m", "gyro_attitude.cli", "montecarlo", "lab_bench", "--runs", "4000",
         "--duration", "60", "--rate", "100", "--gyro-bias", "none", "--workers", "2",
         "--json", str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    deadline = time.monotonic() + 60
    while not _children(proc.pid) and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)  # until the pool's processes exist: the runs have begun
    time.sleep(2.0)
    if proc.poll() is not None:
        pytest.fail(f"montecarlo ended before the signal: {proc.communicate()}")
    proc.send_signal(signal.SIGINT)
    proc.send_signal(signal.SIGINT)  # a second Ctrl-C during the clean-up changes nothing
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert "Traceback" not in err and len(_lines(err)) == 1 and "interrupted after" in err, err
    doc = json.loads(out.read_text())
    assert doc["complete"] is False and doc["interrupted"] is True
    assert doc["runs_finished"] == len(doc["runs"]) < 400
    assert [p.name for p in tmp_path.iterdir()] == ["o.json"]
