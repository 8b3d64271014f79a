"""A bad argument to allan, bench, demo or montecarlo is one line ``gyro-attitude CMD: error: ...``
and exit 2: no usage block before it (the form cli.py's argparse subcommands use)."""

from __future__ import annotations

import pytest

from gyro_attitude import cli


@pytest.mark.parametrize("argv, names", [
    (["allan"], "IN.mcap"),
    (["allan", "x.mcap", "--bogus"], "--bogus"),
    (["bench", "--suite", "bogus"], "bogus"),
    (["bench", "--frobnicate"], "--frobnicate"),
    (["demo", "--rate", "nan"], "--rate"),
    (["demo", "--algorithm", "bogus"], "--algorithm"),
    (["montecarlo", "lab_bench", "--runs", "0"], "--runs"),
    (["montecarlo", "lab_bench", "--runs", "2", "--worker-timeout", "nan"], "--worker-timeout"),
])
def test_a_bad_argument_is_one_line_with_the_command_prefix(argv, names, capsys):
    with pytest.raises(SystemExit) as stop:
        cli.main(argv)
    assert stop.value.code == 2
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and "usage:" not in err, err
    assert lines[0].startswith(f"gyro-attitude {argv[0]}: error: ") and names in lines[0], err


@pytest.mark.parametrize("argv, names", [
    (["allan", "x.mcap", "--json", "-"], "standard output"),
    (["allan", "x.mcap", "--scene-out", "-"], "standard output"),
    (["allan", "x.mcap", "--plot", "a.xyz"], ".png"),
    (["allan", "x.mcap", "--plot", "noext"], ".png"),
    # (montecarlo's --plot format is refused before the work too, exit 1:
    # test_command_errors.test_a_plot_of_an_unknown_format_is_refused_before_the_work)
    (["montecarlo", "lab_bench", "--runs", "2", "--json", "-"], "standard output"),
    (["bench", "--json", "-"], "standard output"),
])
def test_an_output_named_dash_or_a_figure_of_an_unknown_format_is_refused_before_any_work(
        argv, names, capsys, tmp_path, monkeypatch):
    """Never a file named '-' where standard output was meant, never PNG bytes in a .jpg, never
    a figure refused after the other outputs were written."""
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as stop:
        cli.main(argv)
    assert stop.value.code == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"gyro-attitude {argv[0]}: error: ") and names in err, err
    assert "\n" not in err and list(tmp_path.iterdir()) == []


def test_bench_refusals_carry_the_command_prefix(tmp_path, capsys):
    not_a_dir = tmp_path / "file.txt"
    not_a_dir.write_text("x")
    assert cli.main(["bench", "--out-dir", str(not_a_dir)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("gyro-attitude bench: error: --out-dir") and "\n" not in err, err


def test_demo_refusals_carry_the_command_prefix(capsys):
    assert cli.main(["demo", "--scene", "no_such_scene_anywhere"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("gyro-attitude demo: error: --scene") and "\n" not in err, err
