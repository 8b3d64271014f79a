"""Live and offline give the same attitudes: one hostile recording (NaN samples, an implausible
rate, duplicate stamps, a gap longer than max_gap_s, a backward time jump) played through
``mcap_player`` → ``attitude_integrator`` and integrated by ``gyro-attitude replay`` with the node's
algorithm: the same samples get an attitude, and the attitudes agree sample for sample."""

from __future__ import annotations

import numpy as np
import pytest

from gyro_attitude.io.mcap_writer import Rosbag2McapWriter
from gyro_attitude.offline.replay import replay_file

pytestmark = pytest.mark.ros

N = 600
RATE_HZ = 200
ALGORITHM = "rotvec_cubic"


def hostile_recording(path):
    """600 Imu samples at 200 Hz of log time; the header stamps carry the damage."""
    k = np.arange(N, dtype=np.int64)
    log = 10_000_000_000 + k * (10**9 // RATE_HZ)
    stamps = log.copy()
    stamps[150:] += 500_000_000  # a 0.5 s gap (> max_gap_s = 0.1 s)
    stamps[400:] -= 3_000_000_000  # a 3 s backward jump (> time_jump_threshold_s = 1 s)
    stamps[100] = stamps[99]  # duplicate stamp
    t = k / RATE_HZ
    w = np.stack([0.3 * np.sin(2 * np.pi * 1.3 * t), 0.2 * np.cos(2 * np.pi * 0.7 * t),
                  0.5 + 0.1 * t], axis=1)
    w[50] = [np.nan, 0.0, 0.0]
    w[51] = [0.0, np.inf, 0.0]
    w[300] = [1e200, 0.0, 0.0]
    with Rosbag2McapWriter(path, chunk_size=8000) as wr:
        wr.add_topic("imu/data_raw", "sensor_msgs/msg/Imu")
        wr.write_imu_array("imu/data_raw", stamps, w, frame_id="imu_link", log_time_ns=log)
    return stamps


def test_player_and_integrator_equal_replay(launch, ros_node, tmp_path):
    from geometry_msgs.msg import QuaternionStamped
    from rclpy.qos import QoSProfile, ReliabilityPolicy

    rec = tmp_path / "hostile.mcap"
    hostile_recording(rec)
    offline = replay_file(rec, tmp_path / "replayed.mcap", algorithm=ALGORITHM,
                          estimator="causal")
    q_off = offline.q
    assert len(q_off) == N - 4  # 2 non-finite, 1 implausible rate, 1 duplicate stamp skipped
    got: list[tuple[int, tuple[float, float, float, float]]] = []
    ros_node.create_subscription(
        QuaternionStamped, "attitude",
        lambda m: got.append((m.header.stamp.sec * 10**9 + m.header.stamp.nanosec,
                              (m.quaternion.x, m.quaternion.y, m.quaternion.z, m.quaternion.w))),
        QoSProfile(depth=5000, reliability=ReliabilityPolicy.RELIABLE))
    integ = launch("gyro_attitude.ros.attitude_integrator_node",
                   "-p", f"algorithm:={ALGORITHM}", "-p", "qos_reliability:=reliable")
    assert ros_node.wait_for_publishers("attitude"), integ.output()
    player = launch("gyro_attitude.ros.mcap_player_node", "-p", f"input:={rec}",
                    "-p", "namespace_topics:=true", "-p", "wait_for_subscribers:=1",
                    "-p", "publish_clock:=false")
    assert ros_node.spin_until(lambda: len(got) >= len(q_off), 60.0), (
        f"{len(got)} of {len(q_off)} attitudes\n{player.output()}\n{integ.output()}")
    assert player.wait(timeout=20) == 0, player.output()
    ros_node.spin_until(lambda: False, 0.5)  # nothing more may arrive
    assert len(got) == len(q_off)
    np.testing.assert_array_equal([g[0] for g in got], offline.t_ns)
    q_live = np.array([g[1] for g in got])
    assert np.isfinite(q_live).all()
    diff = float(np.max(np.abs(q_live - q_off)))
    print(f"\nlive vs replay: {len(q_live)} attitudes, max |Δq| = {diff:.3e}")
    assert diff <= 1e-12
