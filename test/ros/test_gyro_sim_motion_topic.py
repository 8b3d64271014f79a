"""gyro_sim with ``motion_topic``: the Imu follows a live nav_msgs/Odometry ground truth with a
bounded delay, stamped in its time base; slow and stopped odometry are reported."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
import yaml
from nav_msgs.msg import Odometry
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Imu

from gyro_attitude.core.figure_eight import FigureEight
from gyro_attitude.ros import convert

pytestmark = [pytest.mark.ros, pytest.mark.timeout(90)]

SIM = "gyro_attitude.ros.gyro_sim_node"
T0_NS = 1_000 * 10**9
ODOM_HZ, IMU_HZ, DELAY = 100.0, 200.0, 0.05


def test_imu_follows_live_odometry_with_a_bounded_delay(launch, ros_node, tmp_path):
    scene = {"description": "live", "seed": 1, "rate_hz": IMU_HZ,
             "earth": {"latitude_deg": 45.0, "rotation": False},
             "motion": {"type": "stationary"}, "accelerometer": {"gravity": False}}
    path = tmp_path / "live.yaml"
    path.write_text(yaml.safe_dump(scene))
    received = []  # (imu stamp ns, latest odometry stamp published when it arrived, gyro)
    last_sent = [0]

    def on_imu(m: Imu):
        received.append((convert.stamp_to_ns(m.header.stamp), last_sent[0],
                         (m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z)))

    ros_node.create_subscription(Imu, "imu/data_raw", on_imu,
                                 QoSProfile(depth=5000, reliability=ReliabilityPolicy.BEST_EFFORT))
    pub = ros_node.create_publisher(Odometry, "odom_in", 100)
    sim = launch(SIM, "-p", f"scene:={path}", "-p", "motion_topic:=odom_in",
                 "-p", f"motion_delay_s:={DELAY}", "-p", "motion_timeout_s:=0.5")
    assert ros_node.spin_until(lambda: pub.get_subscription_count() >= 1, timeout=30), sim.output()
    ros_node.spin_until(lambda: ros_node.count_publishers("imu/data_raw") >= 1, timeout=30)
    ros_node.spin_until(lambda: False, 0.5)
    f8 = FigureEight()
    k = [0]
    start = time.monotonic()

    def publish_due() -> bool:
        while k[0] / ODOM_HZ <= time.monotonic() - start and k[0] < 300:  # 3 s of poses
            t = k[0] / ODOM_HZ
            p, q = f8.poses(np.array([t]))
            msg = Odometry()
            t_ns = T0_NS + int(round(t * 1e9))
            msg.header.stamp = convert.ns_to_stamp(t_ns)
            msg.header.frame_id = "enu"
            msg.pose.pose.position.x, msg.pose.pose.position.y, msg.pose.pose.position.z = p[0]
            o = msg.pose.pose.orientation
            o.x, o.y, o.z, o.w = q[0]
            pub.publish(msg)
            last_sent[0] = t_ns
            k[0] += 1
        return k[0] >= 300

    assert ros_node.spin_until(publish_due, timeout=30)
    ros_node.spin_until(lambda: False, 1.5)  # the odometry stops: the node must say so
    log = sim.output()
    assert len(received) > 300, log
    stamps = np.array([r[0] for r in received])
    assert stamps[0] == T0_NS and np.all(np.diff(stamps) == 5_000_000)  # its time base, 200 Hz
    # bounded delay: a sample went out only once the odometry had passed it by DELAY
    assert all(s <= sent - DELAY * 1e9 + 1 for s, sent, _ in received)
    assert stamps[-1] >= T0_NS + int((2.99 - DELAY) * 1e9) - 10_000_000
    t = (stamps - T0_NS) / 1e9
    gyro = np.array([r[2] for r in received])
    mid = (t > 0.3) & (t < t[-1] - 0.3)
    rms = math.sqrt(np.mean(np.sum((gyro - f8.body_rate(t))[mid] ** 2, axis=1)))
    assert rms < 5e-3, rms  # 100 Hz poses fitted in 2 s windows
    assert "slower than the Imu rate 200 Hz" in log
    assert "no odometry on odom_in" in log
