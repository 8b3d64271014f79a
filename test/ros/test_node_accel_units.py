"""attitude_integrator, live: an accelerometer not in m/s² (here in g) is named in one line after
the node's first 2 s of samples and not pushed from then on (counted in /diagnostics), as replay
refuses it for the whole recording (issue 38 follow-up; core/attitude/accel_units.py)."""

from __future__ import annotations

import numpy as np
import pytest

pytestmark = pytest.mark.ros

G = 9.80665


@pytest.mark.parametrize("scale, ok", [(1 / G, False), (0.96, True)])
def test_node_names_an_accelerometer_in_g_once_and_stops_using_it(launch, ros_node, scale, ok):
    from diagnostic_msgs.msg import DiagnosticArray
    from geometry_msgs.msg import QuaternionStamped
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import Imu

    from gyro_attitude.ros import convert

    reliable = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
    got, diag = [], []
    ros_node.create_subscription(QuaternionStamped, "attitude", got.append, reliable)
    ros_node.create_subscription(DiagnosticArray, "/diagnostics", diag.append, 50)
    integ = launch("gyro_attitude.ros.attitude_integrator_node", "-p",
                   "qos_reliability:=reliable", "-p", "diagnostics_period_s:=0.2")
    pub = ros_node.create_publisher(Imu, "imu/data_raw", reliable)
    assert ros_node.wait_for_publishers("attitude"), integ.output()
    assert ros_node.spin_until(lambda: pub.get_subscription_count() >= 1, 20.0), integ.output()
    rng = np.random.default_rng(5)
    n, rate = 400, 100.0  # 4 s at 100 Hz: judged at 2 s, 200 samples pushed without it after
    for k in range(n):
        f = (np.array([0.3, -0.2, G]) + rng.normal(scale=0.05, size=3)) * scale
        msg = convert.imu_msg(10**10 + int(k * 1e9 / rate), "imu_link",
                              rng.normal(scale=0.002, size=3), f, gyro_variances=[1e-6] * 3,
                              accel_variances=[1e-3] * 3)
        pub.publish(msg)
        if k % 50 == 49:
            ros_node.spin_until(lambda: False, 0.05)

    def values():
        for d in reversed(diag):
            for s in d.status:
                return {kv.key: kv.value for kv in s.values}
        return {}

    assert ros_node.spin_until(lambda: len(got) >= n and values().get("accepted") == str(n),
                               30.0), f"{len(got)} attitudes\n{integ.output()}"
    v = values()
    lines = [ln for ln in integ.output().splitlines() if "not in m/s²" in ln]
    if ok:
        assert v["accel_units"] == "m/s²" and v["accels_not_used"] == "0" and not lines, v
    else:
        assert v["accel_units"] == "not m/s²: not used", v
        assert 150 <= int(v["accels_not_used"]) <= n - 200, v  # the samples after 2 s
        assert len(lines) == 1 and "in g?" in lines[0] and "not used from now on" in lines[0]
