"""Fixtures for tests that start ROS 2 node processes.

* Each test process claims its own ROS_DOMAIN_ID (an flock on a file per id under the temp
  dir, so concurrent pytest runs on one machine never share a domain) and keeps DDS on
  loopback (ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST). Both are set in os.environ before
  any rclpy.init, and passed to the node processes.
* Every test gets a unique namespace as a second fence against cross-talk.
* ``launch`` starts ``python -m <module> --ros-args ...`` in a new process group with
  PYTHONPATH = this checkout; at teardown every process still running gets SIGINT, then
  SIGKILL of its whole group after a timeout, so no node outlives its test.
"""

from __future__ import annotations

import itertools
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
_ns_counter = itertools.count()


@pytest.fixture
def ros_env(ros_domain_id) -> dict[str, str]:
    env = dict(os.environ)
    extra = env.get("PYTHONPATH", "")
    env["PYTHONPATH"] = str(REPO) + (os.pathsep + extra if extra else "")
    env["ROS_DOMAIN_ID"] = str(ros_domain_id)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env.setdefault("AMENT_PREFIX_PATH", sys.prefix)
    env["PYTHONUNBUFFERED"] = "1"
    env["RCUTILS_LOGGING_BUFFERED_STREAM"] = "0"
    env["MPLBACKEND"] = "Agg"
    # a node that hangs can be made to show where (SIGABRT prints every thread's stack)
    env["PYTHONFAULTHANDLER"] = "1"
    return env


@pytest.fixture
def namespace() -> str:
    return f"/gyro_test_{os.getpid()}_{next(_ns_counter)}"


class NodeProcess:
    """A node started as its own process; stdout+stderr go to ``log``."""

    def __init__(self, module: str, args: list[str], env: dict[str, str], log: Path):
        self.module = module
        self.log = log
        self._log_f = open(log, "w")  # closed in stop()
        self.proc = subprocess.Popen(
            [sys.executable, "-m", module, *args],
            env=env,
            cwd=str(REPO),
            stdout=self._log_f,
            stderr=subprocess.STDOUT,
            start_new_session=True,  # own process group: cleanup can kill all of it
        )

    def output(self) -> str:
        if not self._log_f.closed:
            self._log_f.flush()
        return self.log.read_text(errors="replace")

    def wait(self, timeout: float) -> int:
        return self.proc.wait(timeout=timeout)

    def stop(self, sig=signal.SIGINT, timeout: float = 10.0) -> int:
        """Send ``sig``; after ``timeout`` SIGKILL the process group. Returns the exit code."""
        if self.proc.poll() is None:
            try:
                self.proc.send_signal(sig)
                self.proc.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait(timeout=5)
        if not self._log_f.closed:
            self._log_f.close()
        return self.proc.returncode


@pytest.fixture
def launch(ros_env, namespace, tmp_path):
    """``launch(module, *ros_args, namespace=True)`` -> NodeProcess (stopped at teardown)."""
    procs: list[NodeProcess] = []

    def start(module: str, *ros_args: str, use_namespace: bool = True) -> NodeProcess:
        args = ["--ros-args"]
        if use_namespace:
            args += ["-r", f"__ns:={namespace}"]
        args += list(ros_args)
        name = module.rsplit(".", 1)[-1]
        log = tmp_path / f"{name}_{len(procs)}.log"
        p = NodeProcess(module, args, ros_env, log)
        procs.append(p)
        return p

    yield start
    for p in procs:
        p.stop(timeout=5.0)


@pytest.fixture
def ros_node(ros_domain_id, namespace):
    """An rclpy node in the test process (own context), in the test's namespace."""
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor

    context = Context()
    rclpy.init(context=context, domain_id=ros_domain_id)
    node = rclpy.create_node("gyro_test_probe", namespace=namespace, context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)

    def spin_until(predicate, timeout: float) -> bool:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if predicate():
                return True
            executor.spin_once(timeout_sec=0.02)
        return bool(predicate())

    def wait_for_publishers(topic: str, count: int = 1, timeout: float = 30.0) -> bool:
        """Until ``count`` publishers of ``topic`` are discovered, then a short settle: a
        node started next must not publish before this probe's subscriptions have matched
        the publishers it listens to (on a loaded machine discovery takes seconds)."""
        found = spin_until(lambda: node.count_publishers(topic) >= count, timeout)
        spin_until(lambda: False, 0.3)
        return found

    node.spin_until = spin_until
    node.wait_for_publishers = wait_for_publishers
    node.executor_ = executor
    yield node
    executor.shutdown()
    node.destroy_node()
    rclpy.shutdown(context=context)
