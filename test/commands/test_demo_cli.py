"""``gyro-attitude demo`` refuses bad input with one line and a nonzero exit, before any node
starts (argument checks need no ROS graph); a node that exits with an error is reported."""

from __future__ import annotations

import os

import pytest

from gyro_attitude import cli
from gyro_attitude.commands import demo
from gyro_attitude.core.attitude import causal_algorithms, offline_algorithms


def _no_nodes(monkeypatch):
    """Fail the test if the demo gets as far as starting a node process."""
    def refuse(*_a, **_k):
        raise AssertionError("a node process was started")
    monkeypatch.setattr(demo.subprocess, "Popen", refuse)


def _one_line(text: str) -> str:
    lines = [ln for ln in text.strip().splitlines() if ln.strip()]
    assert len(lines) == 1 and "Traceback" not in text, text
    return lines[0]


@pytest.mark.parametrize("flag, value", [
    ("--rate", "nan"), ("--rate", "-1"), ("--rate", "0"), ("--rate", "inf"),
    ("--rate", "1e9"),  # above gyro_sim's rate_hz limit
    ("--rate", "fast"),
    ("--duration", "nan"), ("--duration", "inf"), ("--duration", "-2"), ("--duration", "0"),
    ("--duration", "1e300"),  # above gyro_sim's duration_s limit
    ("--algorithm", "bogus"),
    ("--plot", "p.xyz"), ("--plot", "noext"),
])
def test_bad_argument_one_line_exit_2(flag, value, capsys, monkeypatch):
    _no_nodes(monkeypatch)
    with pytest.raises(SystemExit) as exc:
        cli.main(["demo", flag, value])
    assert exc.value.code == 2
    line = _one_line(capsys.readouterr().err.splitlines()[-1])
    assert flag in line, line


def test_rate_and_duration_limits_are_gyro_sims():
    from gyro_attitude.ros.gyro_sim_node import parameter_specs

    high = {s.name: s.high for s in parameter_specs()}
    parser = demo.argparse.ArgumentParser()
    demo.configure(parser)
    assert parser.parse_args(["--rate", str(high["rate_hz"])]).rate == high["rate_hz"]
    with pytest.raises(SystemExit):
        parser.parse_args(["--rate", repr(high["rate_hz"] * (1 + 1e-12))])
    assert parser.parse_args(["--duration", str(high["duration_s"])]).duration == \
        high["duration_s"]


def test_algorithm_choices_are_the_nodes_causal_ones(capsys):
    parser = demo.argparse.ArgumentParser()
    demo.configure(parser)
    for name in causal_algorithms():
        assert parser.parse_args(["--algorithm", name]).algorithm == name
    offline = next(iter(offline_algorithms()))  # e.g. magnus6_quintic: replay only
    with pytest.raises(SystemExit):
        parser.parse_args(["--algorithm", offline])


@pytest.mark.parametrize("duration", ["1e-6", "1e-300", "0.0005"])
def test_duration_below_two_samples_refused(duration, capsys, monkeypatch, tmp_path):
    _no_nodes(monkeypatch)
    status = cli.main(["demo", "--duration", duration, "--bag-dir", str(tmp_path / "b")])
    assert status == 2
    assert "samples" in _one_line(capsys.readouterr().err)
    assert not (tmp_path / "b").exists()


def test_bag_dir_that_is_a_file(capsys, monkeypatch, tmp_path):
    _no_nodes(monkeypatch)
    not_a_dir = tmp_path / "in.mcap"
    not_a_dir.write_bytes(b"precious")
    assert cli.main(["demo", "--duration", "1", "--bag-dir", str(not_a_dir)]) == 1
    assert "not a directory" in _one_line(capsys.readouterr().err)
    assert not_a_dir.read_bytes() == b"precious"


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only directories")
def test_read_only_bag_dir(capsys, monkeypatch, tmp_path):
    _no_nodes(monkeypatch)
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    try:
        assert cli.main(["demo", "--duration", "1", "--bag-dir", str(ro / "bags")]) == 1
        _one_line(capsys.readouterr().err)
    finally:
        ro.chmod(0o700)


def test_existing_plot_refused_without_force(capsys, monkeypatch, tmp_path):
    _no_nodes(monkeypatch)
    precious = tmp_path / "precious.png"
    precious.write_bytes(b"precious")
    status = cli.main(["demo", "--duration", "1", "--bag-dir", str(tmp_path / "b"),
                       "--plot", str(precious)])
    assert status == 1
    line = _one_line(capsys.readouterr().err)
    assert "exists" in line and "--force" in line
    assert precious.read_bytes() == b"precious"


def test_plot_directory_refused(capsys, monkeypatch, tmp_path):
    _no_nodes(monkeypatch)
    adir = tmp_path / "adir.png"
    adir.mkdir()
    status = cli.main(["demo", "--duration", "1", "--no-record", "--plot", str(adir),
                       "--force"])
    assert status == 1
    assert "is a directory" in _one_line(capsys.readouterr().err)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["adir.png"]
