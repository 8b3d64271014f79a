"""gyro_sim publishes an instrument scene's named joints on gyro/joint_states, equal to the offline
SceneSimulator's, with the truth alongside (so the indication error can be plotted)."""

from __future__ import annotations

import numpy as np
import pytest
from geometry_msgs.msg import QuaternionStamped
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState

from gyro_attitude.core.scene import SceneSimulator
from gyro_attitude.io.scene_file import load_scene

pytestmark = [pytest.mark.ros, pytest.mark.timeout(120)]

SIM = "gyro_attitude.ros.gyro_sim_node"
RELIABLE = QoSProfile(depth=20000, reliability=ReliabilityPolicy.RELIABLE)


def test_gyro_sim_publishes_directional_gyro_joints(launch, ros_node):
    joints: list = []
    truth: list = []
    ros_node.create_subscription(JointState, "gyro/joint_states", joints.append, RELIABLE)
    ros_node.create_subscription(QuaternionStamped, "truth/attitude", truth.append, RELIABLE)
    n = 100  # 2 s at the scene's 50 Hz
    sim = launch(SIM, "-p", "scene:=directional_gyro_bank", "-p", "time_mode:=fast",
                 "-p", "duration_s:=2.0", "-p", "qos_reliability:=reliable",
                 "-p", "wait_for_subscribers:=1", "-p", "wait_timeout_s:=20.0")
    assert ros_node.spin_until(lambda: sim.proc.poll() is not None and len(joints) >= n
                               and len(truth) >= n, timeout=60), sim.output()
    assert sim.wait(timeout=5) == 0, sim.output()
    offline = SceneSimulator(load_scene("directional_gyro_bank"), 50.0).next_block(n)
    assert [list(m.name) for m in joints[:1]] == [list(offline.gimbal.names)]
    pos = np.array([m.position for m in joints[:n]])
    vel = np.array([m.velocity for m in joints[:n]])
    # the node simulates in its own block sizes: equal to within the solver tolerance
    # (block-splitting test in test/core/scene/test_instrument_scenes.py)
    np.testing.assert_allclose(pos, offline.gimbal.positions, rtol=0, atol=1e-8)
    np.testing.assert_allclose(vel, offline.gimbal.velocities, rtol=0, atol=1e-8)
