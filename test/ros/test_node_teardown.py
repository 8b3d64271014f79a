"""node_main.run_node's teardown: a middleware teardown that never returns ends the process
anyway (one line, the node's exit status); finishing the node's output is never cut short."""

from __future__ import annotations

import subprocess
import sys
import time

import pytest

pytestmark = pytest.mark.ros

_SCRIPT = """
import os, signal, sys, time
from rclpy.node import Node
from gyro_attitude.ros import node_main
node_main.TEARDOWN_TIMEOUT_S = 1.0

class Node_(Node):
    def __init__(self):
        super().__init__("teardown_probe")

    def destroy_node(self):
        if {stuck!r}:
            time.sleep(600)  # a destruction that never returns
        return super().destroy_node()

def spin(node, executor):
    if {signalled!r}:
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(0.5)  # the handler records it; rclpy's shuts the context down

def finish(node):
    time.sleep({finish_s!r})  # longer than the teardown's timeout: must not be cut
    open({marker!r}, "w").write("finished")

sys.exit(node_main.run_node("teardown_probe", Node_, ["teardown_probe"],
                            spin=spin, finish=finish))
"""


def _run(ros_env, tmp_path, stuck: bool, finish_s: float, signalled: bool = False):
    marker = tmp_path / "finished"
    code = _SCRIPT.format(stuck=stuck, finish_s=finish_s, marker=str(marker),
                          signalled=signalled)
    t0 = time.monotonic()
    done = subprocess.run([sys.executable, "-c", code], env=ros_env, capture_output=True,
                          text=True, timeout=120)
    return done, time.monotonic() - t0, marker


def test_a_teardown_that_never_returns_ends_the_process_with_one_line(ros_env, tmp_path):
    done, elapsed, marker = _run(ros_env, tmp_path, stuck=True, finish_s=0.0)
    assert done.returncode == 0, done.stderr
    assert "did not tear the node down within 1 s" in done.stderr
    assert "Traceback" not in done.stderr
    assert marker.read_text() == "finished"
    assert elapsed < 60


def test_finishing_the_output_is_never_cut_by_the_teardown_timeout(ros_env, tmp_path):
    done, _, marker = _run(ros_env, tmp_path, stuck=False, finish_s=2.5)
    assert done.returncode == 0, done.stderr
    assert marker.read_text() == "finished"
    assert "did not tear" not in done.stderr


def test_a_signalled_node_exits_once_its_output_is_finished_without_the_teardown(
        ros_env, tmp_path):
    """The teardown that hangs after a signal can hold the GIL (no Python watchdog runs then):
    a signalled process must not enter it at all."""
    done, elapsed, marker = _run(ros_env, tmp_path, stuck=True, finish_s=1.5, signalled=True)
    assert done.returncode == 0, done.stderr
    assert marker.read_text() == "finished"
    assert "did not tear" not in done.stderr
    assert "Traceback" not in done.stderr
    assert elapsed < 30
