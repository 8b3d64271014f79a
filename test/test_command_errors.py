"""Every command fails in one line of one form (issue 38 item 10): ``gyro-attitude <command>:
error: <message>`` on stderr, argument errors without the usage block; ``--out -`` refused
(outputs are files renamed into place, not streams); a plot takes its format from its suffix
and an unknown suffix is refused before the work."""

from __future__ import annotations

import os
import re
import sys

import numpy as np
import pytest

from gyro_attitude.cli import main as cli_main
from gyro_attitude.io.mcap_writer import Rosbag2McapWriter

os.environ.setdefault("AMENT_PREFIX_PATH", sys.prefix)


def one_error_line(capsys, argv, code):
    try:
        rc = cli_main(argv)
    except SystemExit as exc:  # argparse's exit, in process
        rc = exc.code
    out, err = capsys.readouterr()
    assert rc == code, (rc, err)
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith(f"gyro-attitude {argv[0]}: error: "), lines[0]
    assert "usage:" not in err and "Traceback" not in err
    return lines[0]


@pytest.mark.parametrize("argv", [
    ["replay"], ["replay", "x.mcap", "--bogus"], ["simulate", "lab_bench"],
    ["allan"], ["scenes", "--bogus"], ["montecarlo", "lab_bench"],
    ["bench", "--suite", "no_such_suite"], ["demo", "--bogus"], ["demo", "--plot", "x.jpg"],
])
def test_argument_errors_of_every_command_are_one_line_of_one_form(capsys, argv):
    one_error_line(capsys, argv, 2)


@pytest.mark.parametrize("argv, code", [
    (["replay", "/no/such.mcap", "--out", "{tmp}/o.mcap"], 1),
    (["replay", "a.mcap", "b.mcap"], 2),
    (["simulate", "no_such_scene", "--out", "{tmp}/o.mcap"], 1),
    (["allan", "/no/such.mcap"], 1),
    (["scenes", "no_such_scene"], 1),
    (["montecarlo", "no_such_scene", "--runs", "2"], 1),
    (["bench", "--json", "-"], 2),
    (["demo", "--scene", "no_such_scene"], 2),
    (["simulate", "lab_bench", "--duration", "1e300", "--out", "{tmp}/o.mcap"], 1),
])
def test_runtime_errors_of_every_command_are_one_line_of_one_form(capsys, tmp_path, argv, code):
    line = one_error_line(capsys, [a.replace("{tmp}", str(tmp_path)) for a in argv], code)
    assert not re.search(r"\d{30}", line)  # a count of 1e302 samples is not printed in full


def _bag(path):
    t = (10**9 + np.arange(400) * 5_000_000).astype(np.int64)
    with Rosbag2McapWriter(path) as wr:
        wr.add_topic("imu/data_raw", "sensor_msgs/msg/Imu")
        wr.write_imu_array("imu/data_raw", t, np.tile([0.0, 0.0, 0.1], (t.size, 1)))


@pytest.mark.parametrize("argv", [["replay", "{bag}", "--out", "-"],
                                  ["simulate", "lab_bench", "--duration", "1", "--out", "-"],
                                  ["replay", "{bag}", "--out", "{tmp}/o.mcap", "--plot", "-"]])
def test_an_output_named_dash_is_refused_in_one_line_and_no_file_is_written(capsys, tmp_path,
                                                                            argv, monkeypatch):
    _bag(tmp_path / "in.mcap")
    monkeypatch.chdir(tmp_path)
    line = one_error_line(capsys, [a.replace("{bag}", str(tmp_path / "in.mcap"))
                                   .replace("{tmp}", str(tmp_path)) for a in argv], 1)
    assert "'-' (standard output) is not supported" in line
    assert not (tmp_path / "-").exists() and not (tmp_path / "o.mcap").exists()


@pytest.mark.parametrize("suffix, magic", [(".jpg", b"\xff\xd8\xff"), (".png", b"\x89PNG"),
                                           (".pdf", b"%PDF"), (".svg", b"<?xml")])
def test_a_plot_is_written_in_the_format_its_suffix_names(capsys, tmp_path, suffix, magic):
    _bag(tmp_path / "in.mcap")
    plot = tmp_path / f"o{suffix}"
    rc = cli_main(["replay", str(tmp_path / "in.mcap"), "--out", str(tmp_path / "o.mcap"),
                   "--plot", str(plot)])
    assert rc == 0
    assert plot.read_bytes().startswith(magic)


@pytest.mark.parametrize("argv", [
    ["replay", "{bag}", "--out", "{tmp}/o.mcap", "--plot", "{tmp}/o.gif"],
    ["allan", "{bag}", "--plot", "{tmp}/o.tiff"],
    ["montecarlo", "lab_bench", "--runs", "2", "--plot", "{tmp}/o"],
])
def test_a_plot_of_an_unknown_format_is_refused_before_the_work(capsys, tmp_path, argv):
    _bag(tmp_path / "in.mcap")
    line = one_error_line(capsys, [a.replace("{bag}", str(tmp_path / "in.mcap"))
                                   .replace("{tmp}", str(tmp_path)) for a in argv], 1)
    assert "unknown image format" in line and ".png, .pdf, .svg, .jpg, .jpeg" in line
    assert not (tmp_path / "o.mcap").exists()
