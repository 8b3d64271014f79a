"""sim -> record -> replay reproduces the live integrator: gyro_sim records its Imu
in-process (record_path, our writer), attitude_integrator integrates the same stream live,
mcap_recorder records the integrator's attitude; offline, the recorded Imu integrated from
the integrator's first sample equals the live attitude to 1e-12."""

from __future__ import annotations

import signal

import numpy as np
import pytest

from gyro_attitude.commands.replay import replay_file
from gyro_attitude.core.attitude import integrate_batch
from gyro_attitude.io.imu_fast import read_imu_arrays, read_quaternion_stamped_arrays

pytestmark = pytest.mark.ros

ALGORITHM = "rotvec_cubic"


def test_live_integrator_equals_offline_replay(launch, ros_node, namespace, tmp_path):
    sim_bag = tmp_path / "sim.mcap"
    live_bag = tmp_path / "live.mcap"
    integ = launch("gyro_attitude.ros.attitude_integrator_node", "-p",
                   f"algorithm:={ALGORITHM}", "-p", "frame:=inertial")
    rec = launch("gyro_attitude.ros.mcap_recorder_node", "-p", f"output:={live_bag}",
                 "-p", "topics:=[attitude]", "-p", "flush_period_s:=0.5")
    ok = ros_node.spin_until(
        lambda: ros_node.count_subscribers(f"{namespace}/imu/data_raw") >= 1
        and ros_node.count_subscribers(f"{namespace}/attitude") >= 1, 30.0)
    assert ok, integ.output() + rec.output()
    from geometry_msgs.msg import QuaternionStamped

    probe = []  # a second, independent listener: tells a silent integrator from the recorder
    ros_node.create_subscription(QuaternionStamped, "attitude", probe.append, 1000)
    assert ros_node.wait_for_publishers("attitude"), integ.output()
    sim = launch("gyro_attitude.ros.gyro_sim_node", "-p", "scene:=coning", "-p",
                 "rate_hz:=200.0", "-p", "duration_s:=2.0", "-p", f"record_path:={sim_bag}",
                 "-p", "wait_for_subscribers:=1")  # the integrator (discovery can be slow)
    assert sim.wait(timeout=60) == 0, sim.output()
    ros_node.spin_until(lambda: False, 1.0)  # let the last samples arrive
    assert rec.stop(sig=signal.SIGINT, timeout=15) == 0, rec.output()
    integ.stop()

    imu = read_imu_arrays(sim_bag)
    live = read_quaternion_stamped_arrays(live_bag, "attitude")
    assert len(imu) == 400 and len(live) > 300, (len(imu), len(live), len(probe),
                                                 integ.output(), rec.output())
    # The integrator starts at identity on the first sample it received.
    k0 = int(np.searchsorted(imu.stamp_ns, live.stamp_ns[0]))
    t = imu.stamp_ns[k0:]
    q = integrate_batch(t, imu.angular_velocity[k0:], algorithm=ALGORITHM)
    idx = np.searchsorted(t, live.stamp_ns)
    assert np.array_equal(t[idx], live.stamp_ns), "live attitude stamps not on the Imu grid"
    diff = np.abs(q[idx] - live.quaternion).max()
    print(f"\nlive vs offline: {len(live)} attitudes, max |dq| = {diff:.2e}")
    assert diff < 1e-12
    if k0 == 0:  # the integrator saw the whole stream: the replay command reproduces it too
        replay_file(sim_bag, tmp_path / "replayed.mcap", algorithm=ALGORITHM, estimator="causal")
        rep = read_quaternion_stamped_arrays(tmp_path / "replayed.mcap", "attitude")
        idx = np.searchsorted(rep.stamp_ns, live.stamp_ns)
        assert np.abs(rep.quaternion[idx] - live.quaternion).max() < 1e-12
