"""The README's commands work as written.

Every line of the README's fenced ``bash`` blocks is one command. The cheap ones (``gyro-attitude
scenes``, ``replay`` of the bundled bag, ``simulate``, ``allan``) run in a subprocess, in README
order, in one temporary directory that holds a link to ``bags/``: each must exit 0, write the
files it names and print what the README says it prints. The expensive ones are checked without
running: ``montecarlo``, ``bench`` and ``demo`` parse their arguments with the subcommand's own
parser; the node executables (``.venv/lib/gyro_attitude/<exe>``, ``ros2 run``) must be declared
executables whose ``-p name:=value`` are declared parameters with valid values and whose
``--params-file`` exists; ``ros2 launch`` may pass only the launch file's declared arguments;
``bash dev.sh`` only its two subcommands. A command of any other kind fails the test, so a new
README command comes with its check here.
"""

from __future__ import annotations

import argparse
import ast
import importlib
import json
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

REPO = Path(__file__).resolve().parents[1]
README = REPO / "README.md"
RUN = {"scenes", "replay", "simulate", "allan"}  # cheap: run
PARSE = {"montecarlo", "bench", "demo"}  # expensive: arguments parsed only
NODES = {"gyro_sim", "attitude_integrator", "mcap_recorder", "mcap_player"}
OUTPUT_FLAGS = ("--out", "--json", "--plot", "--scene-out", "--kalibr-out")
PLACEHOLDER = re.compile(r"^[A-Z][A-Z_]*\.\w+$")  # REC.mcap, OUT.mcap: the user's own files


def shell_lines(text: str) -> list[str]:
    """The commands of the ``bash``/``sh`` fenced blocks, comments dropped."""
    blocks = re.findall(r"^```(?:bash|sh|shell)[ \t]*\n(.*?)^```", text, re.M | re.S)
    return [line.strip() for block in blocks for line in block.splitlines()
            if line.strip() and not line.strip().startswith("#")]


def readme_commands() -> list[list[str]]:
    return [shlex.split(line, comments=True) for line in shell_lines(README.read_text())]


def kind(argv: list[str]) -> str:
    if argv[:2] == ["bash", "dev.sh"]:
        return "dev.sh"
    if argv[0] == "source":
        return "environment"
    if argv[0] == "gyro-attitude" and len(argv) > 1:
        if argv[1] in RUN and not any(PLACEHOLDER.match(a) for a in argv):
            return "run"
        return "parse"
    if argv[:2] == ["ros2", "launch"]:
        return "launch"
    if argv[:2] == ["ros2", "run"] or argv[0].startswith(".venv/lib/gyro_attitude/"):
        return "node"
    return "unknown"


COMMANDS = readme_commands()
RUNS = [a for a in COMMANDS if kind(a) == "run"]


def _gyro_attitude() -> list[str]:
    exe = Path(sys.prefix, "bin", "gyro-attitude")
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "gyro_attitude.cli"]


# ------------------------------------------------------------------------- the README's shape
def test_the_readme_has_the_commands_of_every_quick_start():
    subcommands = {a[1] for a in COMMANDS if a[0] == "gyro-attitude"}
    assert {"replay", "simulate", "scenes", "allan", "montecarlo", "bench"} <= subcommands
    assert {a[2] for a in COMMANDS if kind(a) == "dev.sh"} == {"demo", "test"}
    assert any(kind(a) == "launch" for a in COMMANDS)
    assert any(a[:2] == ["ros2", "run"] for a in COMMANDS)
    assert len(README.read_text().splitlines()) <= 300


def test_the_readme_links_resolve_and_it_tells_no_release_history():
    text = README.read_text()
    for target in re.findall(r"\]\(([^)\s#]+)(?:#[^)]*)?\)", text):
        if not target.startswith(("http://", "https://")):
            assert (REPO / target).exists(), target
    assert not re.search(r"(?im)^#+ .*(change|release|history)", text)
    assert "CHANGELOG.md" in text


def test_every_readme_command_is_of_a_kind_this_test_checks():
    unknown = [shlex.join(a) for a in COMMANDS if kind(a) == "unknown"]
    assert not unknown, f"README commands this test does not check: {unknown}"


def test_the_shell_block_parser_finds_lines_and_drops_comments():
    text = "x\n```bash\na b  # c\n# d\n\ne 'f g'\n```\n```\nnot shell\n```\n"
    assert shell_lines(text) == ["a b  # c", "e 'f g'"]
    assert [shlex.split(s, comments=True) for s in shell_lines(text)] == [["a", "b"],
                                                                          ["e", "f g"]]


# ------------------------------------------------------------------------- run: cheap commands
def _outputs(argv: list[str]) -> list[str]:
    return [argv[i + 1] for i, a in enumerate(argv[:-1])
            if a in OUTPUT_FLAGS and not argv[i + 1].startswith("-")]


def _check_output(argv: list[str], out: str, cwd: Path) -> None:
    """What the README says each command gives, beyond exit 0 and its files."""
    cmd = argv[1]
    if cmd == "scenes":
        names = {p.stem for p in (REPO / "config" / "scenes").glob("*.yaml")}
        listed = {line.split()[0] for line in out.splitlines() if line.strip()}
        assert names <= listed, names - listed
    elif cmd == "simulate":
        assert re.search(r"messages: /imu/data_raw \d+", out), out
        if "--duration" in argv:
            duration = float(argv[argv.index("--duration") + 1])
            n = int(re.search(r"messages: /imu/data_raw (\d+)", out).group(1))
            assert n >= duration * 10, (n, duration)  # every scene here runs at >= 10 Hz
    elif cmd == "replay" and "--json" in argv:
        summary = json.loads(out)
        assert summary["messages"] == summary["attitude_messages"] == 4000  # 20 s at 200 Hz
        estimator = argv[argv.index("--estimator") + 1] if "--estimator" in argv else "offline"
        assert summary["estimator"] == estimator
    elif cmd == "replay" and "broad_05" in " ".join(argv):
        # a real IMU with an accelerometer and no flags: the tilt is aided, and it says so
        assert "aiding auto: the AHRS filter, tilt from the accelerometer" in out, out
        final = re.search(r"tilt RMS ([0-9.e+-]+)°", out)
        assert final and float(final.group(1)) < 0.5, out
    elif cmd == "replay":
        assert "4000 attitudes" in out, out
        if "truth" in argv:  # started from the truth: the coning bag's error stays tiny
            final = re.search(r"final error ([0-9.e+-]+)°", out)
            assert final and float(final.group(1)) < 1e-3, out
    elif cmd == "allan":
        assert "N (ARW)" in out, out
        if "--json" in argv:
            data = json.loads((cwd / argv[argv.index("--json") + 1]).read_text())
            assert set(data["axes"]) == {"x", "y", "z"}


@pytest.fixture(scope="module")
def readme_runs(tmp_path_factory):
    """Every cheap README command run in order in one directory: [(argv, result)]."""
    cwd = tmp_path_factory.mktemp("readme")
    (cwd / "bags").symlink_to(REPO / "bags")
    # ../shared (the real recordings beside the repository, as in CI) seen from cwd too
    if not (cwd.parent / "shared").exists():
        (cwd.parent / "shared").symlink_to(REPO.parent / "shared")
    env = dict(os.environ, MPLBACKEND="Agg")
    results = []
    for argv in RUNS:
        result = subprocess.run(_gyro_attitude() + argv[1:], cwd=cwd, env=env, text=True,
                                capture_output=True, timeout=240)
        results.append((argv, result))
    return cwd, results


@pytest.mark.parametrize("index", range(len(RUNS)), ids=[" ".join(a[:3]) for a in RUNS])
def test_a_cheap_readme_command_runs_and_gives_what_the_readme_says(readme_runs, index):
    cwd, results = readme_runs
    argv, result = results[index]
    assert result.returncode == 0, (shlex.join(argv), result.stderr[-2000:])
    assert "Traceback" not in result.stderr
    for path in _outputs(argv):
        assert (cwd / path).is_file() and (cwd / path).stat().st_size > 0, path
    _check_output(argv, result.stdout, cwd)


# ------------------------------------------------------------------------- parse: expensive ones
def parse_subcommand(argv: list[str]) -> argparse.Namespace:
    """``gyro-attitude CMD ARGS`` through CMD's own parser, as the CLI builds it."""
    module = importlib.import_module(f"gyro_attitude.commands.{argv[1]}")
    parser = argparse.ArgumentParser(prog=f"gyro-attitude {argv[1]}")
    module.configure(parser)

    def refuse(message):
        raise AssertionError(f"{shlex.join(argv)}: {message}")

    parser.error = refuse
    return parser.parse_args(argv[2:])


@pytest.mark.parametrize("argv", [a for a in COMMANDS if kind(a) == "parse"],
                         ids=lambda a: " ".join(a[:3]))
def test_an_expensive_readme_command_parses(argv):
    assert argv[1] in RUN | PARSE, argv
    args = parse_subcommand(argv)
    if argv[1] == "montecarlo":
        assert (REPO / "config" / "scenes" / f"{args.scene}.yaml").is_file(), args.scene


def test_the_argument_check_refuses_what_the_command_refuses():
    with pytest.raises(AssertionError, match="--runs"):
        parse_subcommand(["gyro-attitude", "montecarlo", "ship", "--runs", "many"])
    with pytest.raises(AssertionError, match="invalid choice"):
        parse_subcommand(["gyro-attitude", "bench", "--suite", "nonesuch"])


# ------------------------------------------------------------------------- nodes and launch
def _declared_executables() -> set[str]:
    tree = ast.parse((REPO / "setup.py").read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.Assign) and getattr(node.targets[0], "id", "") == "EXECUTABLES":
            return set(ast.literal_eval(node.value))
    raise AssertionError("setup.py has no EXECUTABLES table")


def check_node_command(argv: list[str]) -> None:
    from gyro_attitude.ros.params import check_value

    exe = argv[3] if argv[0] == "ros2" else Path(argv[0]).name
    assert exe in NODES and exe in _declared_executables(), exe
    if argv[0] == "ros2":
        assert argv[1:3] == ["run", "gyro_attitude"], argv
        rest = argv[4:]
    else:
        rest = argv[1:]
    assert rest[0] == "--ros-args", argv
    module = importlib.import_module(f"gyro_attitude.ros.{exe}_node")
    specs = {s.name: s for s in module.parameter_specs()}
    i = 1
    while i < len(rest):
        flag, value = rest[i], rest[i + 1]
        if flag == "--params-file":
            params = yaml.safe_load((REPO / value).read_text())
            assert set(params[exe]["ros__parameters"]) <= set(specs), value
        else:
            assert flag == "-p", argv
            name, _, text = value.partition(":=")
            assert name in specs, f"{exe} has no parameter {name!r}"
            problem = check_value(specs[name], yaml.safe_load(text))
            assert problem is None, (name, problem)
        i += 2


@pytest.mark.ros
@pytest.mark.parametrize("argv", [a for a in COMMANDS if kind(a) == "node"],
                         ids=lambda a: " ".join(a[:4]))
def test_a_readme_node_command_names_a_node_and_its_parameters(argv):
    check_node_command(argv)


@pytest.mark.ros
def test_the_node_check_refuses_an_unknown_parameter_and_a_bad_value():
    with pytest.raises(AssertionError, match="no parameter"):
        check_node_command(["ros2", "run", "gyro_attitude", "gyro_sim", "--ros-args", "-p",
                            "nonesuch:=1"])
    with pytest.raises(AssertionError, match="aiding"):
        check_node_command(["ros2", "run", "gyro_attitude", "attitude_integrator",
                            "--ros-args", "-p", "aiding:=sometimes"])


def test_the_venv_holds_the_node_executables_the_readme_starts():
    lib = Path(sys.prefix, "lib", "gyro_attitude")
    if not lib.is_dir():
        pytest.skip(f"{lib}: not a pip install of the package (colcon or source tree)")
    for argv in COMMANDS:
        if argv[0].startswith(".venv/lib/gyro_attitude/"):
            assert os.access(lib / Path(argv[0]).name, os.X_OK), argv[0]


def _launch_arguments() -> set[str]:
    tree = ast.parse((REPO / "launch" / "demo.launch.py").read_text())
    return {n.args[0].value for n in ast.walk(tree) if isinstance(n, ast.Call)
            and getattr(n.func, "id", getattr(n.func, "attr", None)) == "DeclareLaunchArgument"}


@pytest.mark.parametrize("argv", [a for a in COMMANDS if kind(a) == "launch"],
                         ids=lambda a: " ".join(a[:4]))
def test_a_readme_launch_command_passes_only_declared_arguments(argv):
    assert argv[2:4] == ["gyro_attitude", "demo.launch.py"], argv
    given = {a.partition(":=")[0] for a in argv[4:]}
    assert all(":=" in a for a in argv[4:]), argv
    assert given <= _launch_arguments(), given - _launch_arguments()


def test_dev_sh_has_the_readme_subcommands():
    text = (REPO / "dev.sh").read_text()
    for argv in COMMANDS:
        if kind(argv) == "dev.sh":
            assert re.search(rf"^\s+{argv[2]}\)", text, re.M), argv
