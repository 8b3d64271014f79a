"""Packaging: `ros2 run gyro_attitude <exe>` finds and starts every declared executable.

There is no ros2cli wheel, so the test reproduces what `ros2 run` does: look the package up
in the ament index (``share/ament_index/resource_index/packages/gyro_attitude`` under a prefix of
``AMENT_PREFIX_PATH``), take ``PREFIX/lib/gyro_attitude/<exe>``, check it is an executable file
and start it. Both install routes are covered: the README's venv (pip) install and a
``colcon build`` of the source tree.
"""

from __future__ import annotations

import importlib.metadata
import os
import shutil
import signal
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PACKAGE = "gyro_attitude"
# The ROS executables and the console command the package declares (setup.py EXECUTABLES).
DECLARED = {"gyro-attitude", "gyro_sim", "attitude_integrator", "mcap_recorder", "mcap_player"}


def _ros_env(domain_id: int, extra_prefix: Path | None = None,
             pythonpath: Path | None = None) -> dict[str, str]:
    env = dict(os.environ)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env["ROS_DOMAIN_ID"] = str(domain_id)
    if extra_prefix is not None:
        env["AMENT_PREFIX_PATH"] = os.pathsep.join(
            [str(extra_prefix)] + [p for p in env.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
        )
    if pythonpath is not None:
        env["PYTHONPATH"] = os.pathsep.join([str(pythonpath), env.get("PYTHONPATH", "")])
    env.pop("PYTHONSAFEPATH", None)
    return env


def _ros2_run_lookup(exe: str, env: dict[str, str]) -> Path:
    """What `ros2 run PKG EXE` does: ament index → PREFIX/lib/PKG/EXE (an executable file)."""
    prefixes = [p for p in env.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    for prefix in prefixes:
        marker = Path(prefix, "share", "ament_index", "resource_index", "packages", PACKAGE)
        if marker.is_file():
            path = Path(prefix, "lib", PACKAGE, exe)
            assert path.is_file(), f"{PACKAGE} is indexed under {prefix} but {path} is missing"
            assert os.access(path, os.X_OK), f"{path} is not executable"
            return path
    raise AssertionError(f"package {PACKAGE} not found in the ament index of {prefixes}")


def _starts(path: Path, env: dict[str, str], cwd: Path) -> None:
    """The executable starts its own code: `--help` for the CLI; nodes run until SIGINT.

    A node that needs an argument (the player without a bag) may instead exit with its own
    error message; what must never appear is an import failure or a traceback.
    """
    if path.name == "gyro-attitude":
        out = subprocess.run([str(path), "--help"], env=env, cwd=cwd, capture_output=True,
                             text=True, timeout=60)
        assert out.returncode == 0, out.stderr
        for sub in ("demo", "replay", "bench", "scenes"):
            assert sub in out.stdout
        return
    proc = subprocess.Popen([str(path)], env=env, cwd=cwd, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, start_new_session=True)
    try:
        try:
            output, _ = proc.communicate(timeout=4.0)
            exited_by_itself = True
        except subprocess.TimeoutExpired:
            exited_by_itself = False
            os.killpg(proc.pid, signal.SIGINT)
            output, _ = proc.communicate(timeout=20.0)
        assert "Traceback" not in output, output
        assert "ModuleNotFoundError" not in output, output
        if not exited_by_itself:
            assert proc.returncode == 0, f"{path.name} did not shut down cleanly on SIGINT:\n{output}"
        else:
            assert output.strip(), f"{path.name} exited at once without saying why"
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(timeout=10)


def _declared_console_scripts() -> set[str]:
    dist = importlib.metadata.distribution(PACKAGE)
    return {ep.name for ep in dist.entry_points if ep.group == "console_scripts"}


def test_package_xml_is_format3_with_runtime_dependencies():
    root = ET.parse(REPO / "package.xml").getroot()
    assert root.tag == "package" and root.get("format") == "3"
    assert root.findtext("name") == PACKAGE
    deps = {e.text for e in root if e.tag in ("depend", "exec_depend")}
    for needed in ("rclpy", "sensor_msgs", "geometry_msgs", "std_msgs", "diagnostic_msgs",
                   "nav_msgs", "python3-numpy"):
        assert needed in deps, f"package.xml lacks {needed}"
    assert any("mcap" in d for d in deps)
    assert root.find("export/build_type").text == "ament_python"


def test_package_xml_test_and_launch_dependencies():
    root = ET.parse(REPO / "package.xml").getroot()
    tests = {e.text for e in root if e.tag == "test_depend"}
    # what CI runs: pytest with pytest-timeout (rosdep keys); the lint that runs is ruff,
    # not ament_flake8
    assert {"python3-pytest", "python3-pytest-timeout"} <= tests, tests
    assert "ament_flake8" not in tests
    execs = {e.text for e in root if e.tag in ("depend", "exec_depend")}
    assert {"launch", "launch_ros"} <= execs  # launch/demo.launch.py


def test_venv_install_ships_the_launch_file():
    share = Path(sys.prefix, "share", PACKAGE, "launch")
    assert (share / "demo.launch.py").read_text() == (
        REPO / "launch" / "demo.launch.py").read_text()


@pytest.mark.ros
def test_console_commands_work_without_any_ros_variable(tmp_path):
    """No AMENT_PREFIX_PATH (a plain shell, venv not sourced): the commands find the ament
    index of their own install prefix."""
    env = {"PATH": "/usr/bin:/bin", "HOME": str(tmp_path), "ROS_AUTOMATIC_DISCOVERY_RANGE":
           "LOCALHOST", "MPLBACKEND": "Agg"}
    exe = Path(sys.prefix, "bin", "gyro-attitude")
    out = subprocess.run([str(exe), "scenes"], env=env, cwd=tmp_path, capture_output=True,
                         text=True, timeout=60)
    assert out.returncode == 0 and "coning" in out.stdout, out.stderr
    # replay writes a recording-derived MCAP: message definitions come from the ament index
    bag = next((REPO / "bags").glob("*.mcap"))
    out = subprocess.run([str(exe), "replay", str(bag), "--out", str(tmp_path / "r.mcap")],
                         env=env, cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert "AMENT_PREFIX_PATH" not in out.stderr and "Traceback" not in out.stderr, out.stderr
    assert out.returncode == 0, out.stderr
    # a node started the way `ros2 run` starts it, then stopped with SIGINT
    node = Path(sys.prefix, "lib", PACKAGE, "gyro_sim")
    proc = subprocess.Popen([str(node), "--ros-args", "-p", "duration_s:=0.5",
                             "-p", "time_mode:=fast"], env=env, cwd=tmp_path,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    output, _ = proc.communicate(timeout=60)
    assert proc.returncode == 0 and "published 500 samples" in output, output


def test_installed_distribution_declares_every_executable():
    assert _declared_console_scripts() == DECLARED


@pytest.mark.ros
@pytest.mark.parametrize("exe", sorted(DECLARED))
def test_ros2_run_finds_and_starts_venv_install(exe, tmp_path, ros_domain_id):
    env = _ros_env(ros_domain_id)
    path = _ros2_run_lookup(exe, env)
    _starts(path, env, tmp_path)


@pytest.mark.ros
def test_colcon_build_installs_where_ros2_run_looks(tmp_path, ros_domain_id):
    colcon = shutil.which("colcon", path=os.pathsep.join([str(Path(sys.executable).parent),
                                                          os.environ.get("PATH", "")]))
    if colcon is None:
        pytest.fail("colcon is not installed (requirements-test.txt installs colcon-common-extensions)")
    src = tmp_path / "src" / PACKAGE
    # Build a copy so that colcon's egg-info and build files stay out of the work tree.
    shutil.copytree(REPO, src, ignore=shutil.ignore_patterns(
        ".venv", ".git", "build", "install", "log", "*.egg-info", "__pycache__", "bench_out"))
    out = subprocess.run(
        [colcon, "--log-base", str(tmp_path / "log"), "build", "--base-paths", str(tmp_path / "src"),
         "--build-base", str(tmp_path / "build"), "--install-base", str(tmp_path / "install")],
        cwd=tmp_path, capture_output=True, text=True, timeout=300,
        env={**os.environ, "PATH": os.pathsep.join([str(Path(sys.executable).parent),
                                                     os.environ.get("PATH", "")])},
    )
    assert out.returncode == 0, out.stdout + out.stderr
    prefix = tmp_path / "install" / PACKAGE
    # Sourcing install/setup.bash would put this on PYTHONPATH; with no system ROS it does not
    # extend AMENT_PREFIX_PATH (without a system ROS), so prepend the prefix as a user would.
    site = prefix / "lib" / f"python{sys.version_info.major}.{sys.version_info.minor}" / "site-packages"
    env = _ros_env(ros_domain_id, extra_prefix=prefix, pythonpath=site)
    for exe in sorted(DECLARED):
        path = _ros2_run_lookup(exe, env)
        assert path.is_relative_to(prefix), f"{exe} resolved outside the colcon install: {path}"
    assert (prefix / "share" / PACKAGE / "package.xml").is_file()
    assert (prefix / "share" / PACKAGE / "launch" / "demo.launch.py").is_file()
    assert list((prefix / "share" / PACKAGE / "config" / "scenes").glob("*.yaml")) or not list(
        (REPO / "config" / "scenes").glob("*.yaml"))
    out = subprocess.run([str(prefix / "lib" / PACKAGE / "gyro-attitude"), "--help"], env=env,
                         capture_output=True, text=True, timeout=60, cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    # The colcon-installed code is the one that runs, not the venv's copy.
    probe = subprocess.run([sys.executable, "-c", "import gyro_attitude; print(gyro_attitude.__file__)"],
                           env=env, capture_output=True, text=True, timeout=60, cwd=tmp_path)
    assert Path(probe.stdout.strip()).is_relative_to(prefix), probe.stdout + probe.stderr
