"""attitude_integrator with its defaults (``aiding: auto``, ``initial_attitude_source: auto``): on an
Imu that carries an accelerometer it runs the AHRS filter and starts from the accelerometer's tilt
(a sensor tilted 30° publishes its tilt from the first attitude on); on one that does not
(REP-145: linear_acceleration_covariance[0] = -1) it integrates the gyro alone; it says which,
once."""

from __future__ import annotations

import numpy as np
import pytest

pytestmark = pytest.mark.ros

G = 9.80665


@pytest.mark.parametrize("with_accel", [True, False], ids=["accelerometer", "gyro only"])
def test_the_node_aids_the_tilt_exactly_when_the_imu_carries_an_accelerometer(
        launch, ros_node, with_accel):
    from geometry_msgs.msg import QuaternionStamped
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from scipy.spatial.transform import Rotation
    from sensor_msgs.msg import Imu

    from gyro_attitude.ros import convert

    reliable = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
    got = []
    ros_node.create_subscription(QuaternionStamped, "attitude", got.append, reliable)
    integ = launch("gyro_attitude.ros.attitude_integrator_node", "-p",
                   "qos_reliability:=reliable")
    pub = ros_node.create_publisher(Imu, "imu/data_raw", reliable)
    assert ros_node.wait_for_publishers("attitude"), integ.output()
    assert ros_node.spin_until(lambda: pub.get_subscription_count() >= 1, 20.0), integ.output()
    tilt = Rotation.from_euler("x", 30, degrees=True)  # held still
    rng = np.random.default_rng(7)
    n = 100
    for k in range(n):
        f = tilt.inv().apply([0.0, 0.0, G]) + rng.normal(scale=0.03, size=3)
        msg = convert.imu_msg(10**10 + k * 10_000_000, "imu_link",
                              rng.normal(scale=0.002, size=3), f if with_accel else None)
        pub.publish(msg)
        if k % 25 == 24:
            ros_node.spin_until(lambda: False, 0.05)
    assert ros_node.spin_until(lambda: len(got) >= n - 1, 30.0), \
        f"{len(got)} attitudes\n{integ.output()}"
    q = np.array([[m.quaternion.x, m.quaternion.y, m.quaternion.z, m.quaternion.w]
                  for m in got])
    up = Rotation.from_quat(q).inv().apply([0.0, 0.0, 1.0])
    tilt_deg = np.degrees(np.arccos(np.clip(up[:, 2], -1.0, 1.0)))  # from the vertical
    out = integ.output()
    if with_accel:
        assert np.all(np.abs(tilt_deg - 30.0) < 1.0), tilt_deg[:5]
        assert out.count("aiding auto: the AHRS filter, tilt from the accelerometer") == 1, out
        assert "roll and pitch from the first accelerometer sample" in out, out
    else:
        assert np.all(tilt_deg < 1.0), tilt_deg[:5]  # the identity, integrated: no tilt seen
        assert out.count("aiding auto: gyro-only, the Imu carries no linear acceleration") == 1, \
            out
