"""attitude_integrator on a simulated hand-held MEMS IMU (config/scenes/handheld_mems.yaml:
rest 6 s, motion 8 s, rest 6 s; gyro bias 0.3–0.6 °/s): levelling publishes no attitude
until the first rest ends, then starts near the truth; gyro_bias auto finds the scene's bias
and removes it. Truth: the simulator's closed-form truth/attitude topic and the scene file."""

from __future__ import annotations

import math
import signal

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import QuaternionStamped
from rclpy.qos import QoSProfile, ReliabilityPolicy
from scipy.spatial.transform import Rotation
from sensor_msgs.msg import Imu

from gyro_attitude.ros import convert

pytestmark = [pytest.mark.ros, pytest.mark.timeout(180)]

SIM = "gyro_attitude.ros.gyro_sim_node"
INTEGRATOR = "gyro_attitude.ros.attitude_integrator_node"
RELIABLE = QoSProfile(depth=20000, reliability=ReliabilityPolicy.RELIABLE)
SCENE_BIAS = np.array([0.0052, -0.0087, 0.0105])  # gyro.errors.bias_rad_s of the scene
LAT = math.radians(52.5)


def _collect(node, msg_type, topic, qos=RELIABLE):
    box: list = []
    node.create_subscription(msg_type, topic, box.append, qos)
    return box


def _values(status) -> dict[str, str]:
    return {kv.key: kv.value for kv in status.values}


def test_level_alignment_and_auto_bias_on_handheld_scene(launch, ros_node):
    att_level = _collect(ros_node, QuaternionStamped, "attitude")
    att_auto = _collect(ros_node, QuaternionStamped, "attitude_auto")
    truth = _collect(ros_node, QuaternionStamped, "truth/attitude")
    diag = _collect(ros_node, DiagnosticArray, "/diagnostics", 200)
    _collect(ros_node, Imu, "imu/data_raw")  # the sim waits for 3 subscribers
    common = ["-p", "frame:=enu", "-p", f"latitude_rad:={LAT!r}", "-p", "qos_reliability:=reliable",
              "-p", "diagnostics_period_s:=0.2"]
    level = launch(INTEGRATOR, *common, "-p", "initial_attitude_source:=level",
                   "-p", "initial_heading_deg:=70.0")  # yaw 20° from east = 70° from north
    auto = launch(INTEGRATOR, *common, "-p", "initial_attitude_source:=truth",
                  "-r", "__node:=integrator_auto", "-r", "attitude:=attitude_auto",
                  "-r", "imu/data:=imu/data_auto")
    assert ros_node.wait_for_publishers("attitude") and ros_node.wait_for_publishers(
        "attitude_auto"), level.output() + auto.output()
    # real time (20 s): fast mode outruns two per-sample integrators on a loaded machine
    sim = launch(SIM, "-p", "scene:=handheld_mems", "-p", "duration_s:=20.0",
                 "-p", "qos_reliability:=reliable", "-p", "wait_for_subscribers:=3",
                 "-p", "wait_timeout_s:=30.0")
    n = 4000  # 20 s at 200 Hz
    assert ros_node.spin_until(lambda: len(truth) >= n and len(att_auto) >= n
                               and len(att_level) > 2000, timeout=120), (
        f"{len(truth)} {len(att_auto)} {len(att_level)}\n" + sim.output() + level.output()
        + auto.output())
    ros_node.spin_until(lambda: False, timeout=1.0)  # last diagnostics
    assert sim.wait(timeout=10) == 0, sim.output()
    for p in (level, auto):
        assert p.stop(signal.SIGINT) == 0 and "Traceback" not in p.output(), p.output()

    t_truth = np.array([convert.stamp_to_ns(m.header.stamp) for m in truth])
    t0 = t_truth[0]  # the scene's start (realtime stamps follow the clock)
    q_truth = np.array([convert.quat_from_msg(m.quaternion) for m in truth])

    def error_deg(att):
        t = np.array([convert.stamp_to_ns(m.header.stamp) for m in att])
        q = np.array([convert.quat_from_msg(m.quaternion) for m in att])
        k = np.searchsorted(t_truth, t)
        assert np.array_equal(t_truth[k], t)
        return t, np.degrees((Rotation.from_quat(q) * Rotation.from_quat(q_truth[k]).inv())
                             .magnitude())

    # levelling: nothing published during the first rest (6 s), the first attitude within
    # one rest window (0.5 s) of the motion's start, near the truth from there on
    t_lvl, e_lvl = error_deg(att_level)
    assert t0 + 6_000_000_000 <= t_lvl[0] <= t0 + 6_500_000_000, (t_lvl[0] - t0) * 1e-9
    # 1σ levelling error with the default 0.05 m/s² accelerometer bias: 0.29°; allow 3σ
    assert e_lvl.max() < 0.9, e_lvl.max()
    name_level = [s for d in diag for s in d.status if s.name.startswith("attitude_integrator:")]
    phases = [_values(s).get("phase") for s in name_level]
    assert "aligning" in phases and phases[-1] == "running"
    aligning = next(s for s in name_level if _values(s).get("phase") == "aligning")
    assert "keep the IMU still" in _values(aligning)["alignment"]
    assert "roll" in _values(name_level[-1])["alignment"]

    # auto bias: the scene's bias found at the rests (± bias instability), Earth rate removed
    _, e_auto = error_deg(att_auto)
    assert e_auto[-1] < 0.2, e_auto[-1]  # raw gyro: |bias| · 20 s ≈ 17°
    last = _values([s for d in diag for s in d.status
                    if s.name.startswith("integrator_auto:")][-1])
    bias = np.array(json_list(last["gyro_bias_rad_s"]))
    np.testing.assert_allclose(bias, SCENE_BIAS, rtol=0, atol=5e-4)
    assert last["gyro_bias_rests_used"] == "2" and last["earth_rate"] == "removed from the bias"
    assert float(json_list(last["gyro_bias_std_error_rad_s"])[0]) < 1e-4


def json_list(text: str) -> list[float]:
    return [float(c) for c in text.strip("[]").split(",")]
