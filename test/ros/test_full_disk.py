"""A full disk under mcap_recorder and gyro_sim record_path: one line naming the file and the
free space, the recording so far finished and readable under its name, exit 1 (the
``small_disk`` fixture: a 256 kB tmpfs)."""

from __future__ import annotations

import time

import pytest
from mcap.reader import make_reader

pytestmark = pytest.mark.ros


def _check(proc, out, code: int) -> int:
    log = proc.output()
    assert code == 1, log
    assert "Traceback" not in log, log
    [line] = [ln for ln in log.splitlines() if "cannot write output" in ln]
    assert f"{out}: No space left on device (" in line and " free in " in line
    assert f"finished and readable at {out}" in line
    assert [p.name for p in out.parent.iterdir()] == [out.name]  # no hidden .partial left
    with open(out, "rb") as f:
        n = sum(1 for _ in make_reader(f).iter_messages())
    assert n > 0
    return n


def test_gyro_sim_record_path_on_a_full_disk(launch, small_disk):
    out = small_disk / "sim.mcap"
    proc = launch("gyro_attitude.ros.gyro_sim_node", "-p", "scene:=lab_bench",
                  "-p", "time_mode:=fast", "-p", "rate_hz:=1000.0", "-p", "duration_s:=600.0",
                  "-p", f"record_path:={out}")
    n = _check(proc, out, proc.wait(timeout=120))
    print(f"\nkept {n} messages on a 256 kB disk")


def test_mcap_recorder_on_a_full_disk(launch, ros_node, small_disk):
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from std_msgs.msg import String

    out = small_disk / "rec.mcap"
    proc = launch("gyro_attitude.ros.mcap_recorder_node", "-p", f"output:={out}",
                  "-p", "topics:=[big]", "-p", "compression:=''", "-p", "flush_period_s:=0.1")
    pub = ros_node.create_publisher(String, "big", QoSProfile(
        depth=100, reliability=ReliabilityPolicy.RELIABLE))
    assert ros_node.spin_until(lambda: pub.get_subscription_count() > 0, 30), proc.output()
    msg = String(data="x" * 4000)
    end = time.monotonic() + 60
    while proc.proc.poll() is None and time.monotonic() < end:
        pub.publish(msg)
        ros_node.executor_.spin_once(timeout_sec=0.002)
    n = _check(proc, out, proc.wait(timeout=30))
    print(f"\nkept {n} messages on a 256 kB disk")
