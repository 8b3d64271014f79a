"""attitude_integrator with ``odometry_topic``: the transport rate follows a turning carrier.

One process test: gyro_sim plays aircraft_turn (120 m/s, 3°/s coordinated turn at 50°N) for
3 s in real time with its gyro errors removed, so what remains is the integrator's nav-frame
model. Two integrators in frame=enu start from truth with the initial velocity: one follows
``truth/odom``, one keeps the constant velocity. Truth: the sim's truth/attitude and
truth/odom as it recorded them (the scene's closed-form motion; the velocity is checked
against it) and, for the stale-velocity error, the closed-form transport rate of the
velocity change (docs/conventions.md formula written out below).
"""

from __future__ import annotations

import math
import signal

import numpy as np
import pytest
import yaml
from geometry_msgs.msg import QuaternionStamped
from mcap.reader import make_reader
from nav_msgs.msg import Odometry
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from scipy.spatial.transform import Rotation
from sensor_msgs.msg import Imu

from gyro_attitude.io.scene_file import find_scene_file, load_scene
from gyro_attitude.ros import convert

pytestmark = [pytest.mark.ros, pytest.mark.timeout(60)]

SIM = "gyro_attitude.ros.gyro_sim_node"
INTEGRATOR = "gyro_attitude.ros.attitude_integrator_node"
RELIABLE = QoSProfile(depth=20000, reliability=ReliabilityPolicy.RELIABLE)
T1_NS = 500_000_000  # the drift is measured from here: the sim waits for its Imu readers
# only, so its truth/odom may reach the integrator a little after the first Imu samples
A, F = 6378137.0, 1.0 / 298.257223563  # WGS-84


def _angle(q1, q2) -> np.ndarray:
    return (Rotation.from_quat(q1).inv() * Rotation.from_quat(q2)).magnitude()


def test_odometry_velocity_removes_the_transport_rate_error(launch, ros_node, tmp_path):
    scene = yaml.safe_load(find_scene_file("aircraft_turn").read_text())
    scene["gyro"].pop("errors", None)  # ideal gyro: only the nav-frame model is measured
    scene_path = tmp_path / "aircraft_turn_ideal.yaml"
    scene_path.write_text(yaml.safe_dump(scene))
    spec = load_scene(str(scene_path))
    lat, h = spec.earth.latitude_rad, float(spec.earth.height_m)
    v0 = [float(v) for v in np.asarray(spec.motion.velocity(np.zeros(1)))[0]]
    rate, duration = float(spec.rate_hz), 3.0
    n = int(rate * duration)

    boxes = {name: [] for name in ("with", "without")}
    # an Imu reader here too: the sim then waits for this participant as well (3 readers).
    # The truth comes from the sim's own recording: a probe that falls behind a fast sim
    # loses what the sim had not delivered when it exits.
    ros_node.create_subscription(Imu, "imu/data_raw", lambda _m: None,
                                 QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT))
    ros_node.create_subscription(QuaternionStamped, "attitude", boxes["with"].append, RELIABLE)
    ros_node.create_subscription(QuaternionStamped, "attitude_plain", boxes["without"].append,
                                 RELIABLE)
    common = ["-p", "frame:=enu", "-p", f"latitude_rad:={lat!r}", "-p", f"height_m:={h!r}",
              "-p", f"velocity_enu:=[{v0[0]!r}, {v0[1]!r}, {v0[2]!r}]",
              "-p", "initial_attitude_source:=truth", "-p", "qos_reliability:=reliable",
              # the gyro alone: a coordinated turn's specific force is no vertical
              "-p", "aiding:=none"]
    with_odom = launch(INTEGRATOR, *common, "-p", "odometry_topic:=truth/odom")
    plain = launch(INTEGRATOR, *common, "-r", "__node:=integrator_plain",
                   "-r", "attitude:=attitude_plain", "-r", "imu/data:=imu/data_plain")
    # start the sim only once the graph is connected (it waits for the Imu readers only)
    assert ros_node.spin_until(
        lambda: ros_node.count_subscribers("truth/attitude") >= 2
        and ros_node.count_subscribers("truth/odom") >= 1
        and ros_node.count_publishers("attitude") >= 1
        and ros_node.count_publishers("attitude_plain") >= 1, timeout=20), (
        with_odom.output(), plain.output())
    bag = tmp_path / "turn.mcap"
    # realtime: a fast-mode sim outruns the integrators and exits with samples undelivered
    sim = launch(SIM, "-p", f"scene:={scene_path}",
                 "-p", f"record_path:={bag}",
                 "-p", f"duration_s:={duration}", "-p", "qos_reliability:=reliable",
                 "-p", "wait_for_subscribers:=3", "-p", "wait_timeout_s:=20.0")
    assert ros_node.spin_until(lambda: sim.proc.poll() is not None, timeout=30), sim.output()
    assert sim.wait(timeout=1) == 0, sim.output()

    def by_stamp(msgs):
        return {convert.stamp_to_ns(m.header.stamp): convert.quat_from_msg(m.quaternion)
                for m in msgs}

    recorded = {"truth/attitude": [], "truth/odom": []}
    with open(bag, "rb") as f:
        for _schema, channel, message in make_reader(f).iter_messages():
            topic = "/".join(channel.topic.rsplit("/", 2)[-2:])
            if topic in recorded:
                msg_type = QuaternionStamped if topic == "truth/attitude" else Odometry
                recorded[topic].append(deserialize_message(message.data, msg_type))
    truth = by_stamp(recorded["truth/attitude"])
    assert len(truth) == n
    t_end = max(truth)
    # The integrators see every sample (reliable, queue 1000); this probe may miss some of
    # their outputs when it falls behind their publishers' queue of 100, never the last.
    assert ros_node.spin_until(
        lambda: all(t_end in by_stamp(boxes[k][-5:]) for k in boxes), timeout=20), (
        {k: len(v) for k, v in boxes.items()}, with_odom.output(), plain.output())
    for proc in (with_odom, plain):
        assert proc.stop(signal.SIGINT) == 0 and "Traceback" not in proc.output(), proc.output()
    q_w, q_wo = by_stamp(boxes["with"]), by_stamp(boxes["without"])
    assert len(q_w) > n // 4 and len(q_wo) > n // 4, (len(q_w), len(q_wo))
    stamps = sorted(truth)
    t1 = min(t for t in stamps if t >= stamps[0] + T1_NS and t in q_w and t in q_wo)
    k1 = stamps.index(t1)

    def error_rotation(q_node, t):  # n-frame error E with q_node = E q_truth
        return Rotation.from_quat(q_node[t]) * Rotation.from_quat(truth[t]).inv()

    def drift(q_node):  # error accumulated over [t1, t_end]: free of start-up transients
        return (error_rotation(q_node, t_end) * error_rotation(q_node, t1).inv()).magnitude()

    err_with, err_without = _angle(truth[t_end], q_w[t_end]), _angle(truth[t_end], q_wo[t_end])

    # truth/odom as the integrator reads it: body twist rotated to ENU = the scene's
    # closed-form velocity (120 m/s turning at 3°/s)
    t_rel = (np.array(stamps) - stamps[0]) * 1e-9
    odom = {convert.stamp_to_ns(m.header.stamp): m for m in recorded["truth/odom"]}
    v_enu = np.array([convert.odometry_velocity_parent(odom[t]) for t in stamps])
    np.testing.assert_allclose(v_enu, spec.motion.velocity(t_rel), atol=1e-9)

    # the stale-velocity error in closed form: ∫ Δω_en^n dt (trapezoid) with
    # Δω_en^n = [−Δv_N/(R_M+h), Δv_E/(R_N+h), Δv_E tan L/(R_N+h)]
    e2 = F * (2 - F)
    d = 1 - e2 * math.sin(lat) ** 2
    r_n, r_m = A / math.sqrt(d), A * (1 - e2) / d**1.5
    dv = v_enu - np.array(v0)
    dw = np.column_stack((-dv[:, 1] / (r_m + h), dv[:, 0] / (r_n + h),
                          dv[:, 0] * math.tan(lat) / (r_n + h)))
    zeta = np.vstack((np.zeros(3), np.cumsum(0.5 * (dw[1:] + dw[:-1]) / rate, axis=0)))
    expected = np.linalg.norm(zeta[-1])
    expected_drift = np.linalg.norm(zeta[-1] - zeta[k1])
    print(f"final error: with odometry {err_with:.3e} rad, without {err_without:.3e} rad "
          f"(closed-form stale error {expected:.3e}); drift over [{T1_NS * 1e-9:g} s, end]: "
          f"with {drift(q_w):.3e}, without {drift(q_wo):.3e} (closed form {expected_drift:.3e})")
    assert err_without == pytest.approx(expected, rel=0.02)
    assert drift(q_wo) == pytest.approx(expected_drift, rel=0.02)
    assert drift(q_w) < 0.02 * expected_drift
