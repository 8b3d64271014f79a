"""gyro_sim and attitude_integrator as separate processes, checked from a probe node.

Few tests, each doing a lot: the node processes are the slow part of the suite.
Truth used here: the classical-coning closed form (via the sim's truth topic, whose
values come from the closed form in C1's scene), constant-rate rotations and
angle-random-walk variance growth written out below, and an independent MCAP reader.
"""

from __future__ import annotations

import math
import signal
from pathlib import Path

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import QuaternionStamped
from nav_msgs.msg import Odometry
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from scipy.spatial.transform import Rotation
from sensor_msgs.msg import Imu, JointState

from gyro_attitude.core import attitude as integrate
from gyro_attitude.ros import convert

pytestmark = [pytest.mark.ros, pytest.mark.timeout(120)]

REPO = Path(__file__).resolve().parents[2]
SIM = "gyro_attitude.ros.gyro_sim_node"
INTEGRATOR = "gyro_attitude.ros.attitude_integrator_node"
RELIABLE = QoSProfile(depth=20000, reliability=ReliabilityPolicy.RELIABLE)


def _collect(node, msg_type, topic, qos=RELIABLE):
    box: list = []
    node.create_subscription(msg_type, topic, box.append, qos)
    return box


def _angle(q1, q2) -> np.ndarray:
    """Independent attitude error via scipy: magnitude of R1⁻¹ R2."""
    return (Rotation.from_quat(q1).inv() * Rotation.from_quat(q2)).magnitude()


def _assert_clean_exit(proc, code):
    out = proc.output()
    assert code == 0, f"{proc.module} exited {code}:\n{out}"
    assert "Traceback" not in out, out


# --------------------------------------------------------------------------- pipeline
def test_sim_to_integrator_coning_against_truth(launch, ros_node):
    """Every topic, type, frame and covariance convention; integrated attitude vs truth."""
    rate, duration = 500.0, 2.0
    n_expected = int(rate * duration)
    boxes = {
        "raw": _collect(ros_node, Imu, "imu/data_raw"),
        "truth": _collect(ros_node, QuaternionStamped, "truth/attitude"),
        "odom": _collect(ros_node, Odometry, "truth/odom"),
        "imu": _collect(ros_node, Imu, "imu/data"),
        "att": _collect(ros_node, QuaternionStamped, "attitude"),
        "joint": _collect(ros_node, JointState, "gyro/joint_states"),
        "diag": _collect(ros_node, DiagnosticArray, "/diagnostics", 100),
    }
    config = REPO / "config"
    integ = launch(INTEGRATOR, "--params-file", str(config / "attitude_integrator.yaml"),
                   "-p", "initial_attitude_source:=truth",
                   "-p", "qos_reliability:=reliable", "-p", "diagnostics_period_s:=0.5")
    assert ros_node.wait_for_publishers("attitude"), integ.output()
    sim = launch(SIM, "--params-file", str(config / "gyro_sim.yaml"),
                 "-p", "scene:=coning", "-p", f"rate_hz:={rate}",
                 "-p", f"duration_s:={duration}", "-p", "wait_for_subscribers:=2",
                 "-p", "qos_reliability:=reliable")
    assert ros_node.spin_until(lambda: len(boxes["att"]) >= n_expected, timeout=40), (
        f"{len(boxes['att'])} attitudes of {n_expected}\n{integ.output()}\n{sim.output()}"
    )
    assert ros_node.spin_until(
        lambda: any(s.values and dict((kv.key, kv.value) for kv in s.values).get("accepted")
                    == str(n_expected) for d in boxes["diag"] for s in d.status),
        timeout=5,
    )
    _assert_clean_exit(sim, sim.wait(timeout=15))
    _assert_clean_exit(integ, integ.stop(signal.SIGTERM))

    raw, truth, att = boxes["raw"], boxes["truth"], boxes["att"]
    assert len(raw) == len(truth) == len(boxes["odom"]) == n_expected
    assert boxes["joint"] == []  # the coning scene has no gimballed gyro

    # imu/data_raw: frame, stamps on the grid, REP-145 covariance conventions
    t = np.array([convert.stamp_to_ns(m.header.stamp) for m in raw])
    assert np.all(np.diff(t) == 2_000_000)  # 500 Hz: exactly 2 ms, no drift
    for m in raw:
        assert m.header.frame_id == "imu_link"
        assert m.orientation_covariance[0] == -1.0  # raw gyro: no orientation estimate
        assert m.linear_acceleration_covariance[0] == -1.0  # coning has no accelerometer
        assert not any(m.angular_velocity_covariance)  # ideal gyro: no random error model
    # the coning rate in closed form (docs/equations.md): |ω| = Ω·sqrt(sin²α + 4 sin⁴(α/2))
    alpha, big_omega = math.radians(1.0), 2 * math.pi * 10.0
    w = np.array([convert.vector3_from_msg(m.angular_velocity) for m in raw])
    expected_norm = big_omega * math.sqrt(math.sin(alpha) ** 2 + 4 * math.sin(alpha / 2) ** 4)
    np.testing.assert_allclose(np.linalg.norm(w, axis=1), expected_norm, rtol=1e-9)

    # truth topics: frames, stamps equal the Imu stamps
    assert all(m.header.frame_id == "enu" for m in truth)
    assert [convert.stamp_to_ns(m.header.stamp) for m in truth] == t.tolist()
    odom = boxes["odom"][-1]
    assert odom.header.frame_id == "enu" and odom.child_frame_id == "imu_link"
    np.testing.assert_allclose(convert.vector3_from_msg(odom.twist.twist.angular),
                               w[-1], atol=1e-12)  # ideal gyro, no Earth rate: ω_nb = ω_ib
    q_truth = np.array([convert.quat_from_msg(m.quaternion) for m in truth])
    # coning truth is the closed form: the spin axis x stays on a cone of half-angle α
    x_axis = Rotation.from_quat(q_truth).apply([1.0, 0.0, 0.0])
    np.testing.assert_allclose(np.degrees(np.arccos(x_axis[:, 0])), 1.0, atol=1e-9)

    # integrated attitude: same stamps as the input, initialised from truth at sample 0
    assert [convert.stamp_to_ns(m.header.stamp) for m in att] == t.tolist()
    assert all(m.header.frame_id == "inertial" for m in att)
    q_node = np.array([convert.quat_from_msg(m.quaternion) for m in att])
    assert np.all(np.isfinite(q_node))
    err = _angle(q_truth, q_node)
    # bound: drift of an update with no coning correction, α²Ω(Ωh)²/12 per second
    # (docs/equations.md, N=1); every shipped rate algorithm is at least second order and beats it.
    h = 1.0 / rate
    bound = alpha**2 * big_omega * (big_omega * h) ** 2 / 12 * duration
    assert err.max() < bound, (err.max(), bound)
    # and the node integrates exactly the samples it received (nothing lost/reordered):
    q_batch = integrate.integrate_batch(t, w, q_truth[0], algorithm=integrate.DEFAULT_ALGORITHM)
    assert _angle(q_batch, q_node).max() < 1e-9

    # imu/data = input Imu + orientation; unknown gyro covariance -> orientation cov unknown
    imu = boxes["imu"]
    assert len(imu) == n_expected and imu[-1].header.frame_id == "imu_link"
    np.testing.assert_array_equal(convert.quat_from_msg(imu[-1].orientation), q_node[-1])
    assert not any(imu[-1].orientation_covariance)

    status = [s for d in boxes["diag"] for s in d.status][-1]
    values = {kv.key: kv.value for kv in status.values}
    assert status.name.endswith("attitude_integrator: imu input")
    assert values["rejected_total"] == "0" and values["gaps"] == "0"
    assert values["rate_fit_fallbacks"] == "0"  # resolved coning: the rate fit is trusted
    assert float(values["input_rate_hz"]) == pytest.approx(rate, rel=1e-6)
    assert float(values["dt_jitter_s"]) == pytest.approx(0.0, abs=1e-12)


# --------------------------------------------------------------------------- bad input
def test_integrator_rejects_bad_input_and_refuses_bad_parameters(launch, ros_node):
    from rcl_interfaces.srv import SetParameters
    from rclpy.parameter import Parameter

    q_init = Rotation.from_euler("xyz", [0.1, -0.2, 0.3]).as_quat()
    integ = launch(INTEGRATOR, "-p", "qos_reliability:=reliable", "-p", "max_gap_s:=0.05",
                   "-p", "time_jump_threshold_s:=0.5", "-p", "diagnostics_period_s:=0.2",
                   "-p", "initial_attitude:=[" + ",".join(repr(float(v)) for v in q_init) + "]",
                   "-p", "initial_attitude_variance:=1.0e-4")
    att = _collect(ros_node, QuaternionStamped, "attitude")
    imu_out = _collect(ros_node, Imu, "imu/data")
    diag = _collect(ros_node, DiagnosticArray, "/diagnostics", 100)
    pub = ros_node.create_publisher(Imu, "imu/data_raw", RELIABLE)
    assert ros_node.wait_for_publishers("attitude"), integ.output()
    assert ros_node.spin_until(lambda: pub.get_subscription_count() >= 1, timeout=20), (
        integ.output()
    )

    t0, dt_ns = 1000 * 10**9, 10_000_000
    dt = dt_ns * 1e-9
    omega, var = [0.0, 0.0, 0.5], 1e-6

    def send(t_ns, w=omega, frame="imu_link"):
        msg = convert.imu_msg(1, frame, [0.0, 0.0, 0.0], gyro_variances=[var] * 3)
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(int(t_ns), 10**9)
        v = msg.angular_velocity
        v.x, v.y, v.z = (float(x) for x in w)
        pub.publish(msg)

    for k in range(10):
        send(t0 + k * dt_ns)
    send(t0 + 10 * dt_ns, [0.0, math.nan, 0.0])  # non-finite
    send(0)  # zero stamp
    send(t0 + 9 * dt_ns)  # duplicate
    send(t0 + 8 * dt_ns + dt_ns // 2)  # out of order (within the jump threshold)
    send(t0 + 10 * dt_ns, frame="other_link")  # frame changed
    for k in range(10, 20):
        send(t0 + k * dt_ns)
    for k in range(29, 35):  # k=29 follows a 100 ms gap (> 50 ms): not integrated across
        send(t0 + k * dt_ns)
    t1 = t0 - 2 * 10**9  # backward jump of 2.34 s > 0.5 s: reset
    for k in range(4):
        send(t1 + k * dt_ns)
    n_accepted = 10 + 10 + 6 + 4

    # both outputs: imu/data (the covariances read below) may arrive after the attitudes
    assert ros_node.spin_until(lambda: len(att) >= n_accepted and len(imu_out) >= n_accepted,
                               timeout=20), integ.output()

    def last_values():
        for d in reversed(diag):
            for s in d.status:
                return {kv.key: kv.value for kv in s.values}, s.level
        return {}, None

    assert ros_node.spin_until(lambda: last_values()[0].get("accepted") == str(n_accepted),
                               timeout=5)
    values, _ = last_values()
    expected = {"rejected_non_finite": "1", "rejected_zero_stamp": "1",
                "rejected_duplicate_stamp": "1", "rejected_out_of_order": "1",
                "rejected_frame_changed": "1", "gaps": "1", "time_jump_resets": "1",
                "rejected_total": "5", "published": str(n_accepted)}
    assert {k: values[k] for k in expected} == expected
    assert any(s.level == s.WARN for d in diag for s in d.status)
    assert len(att) == n_accepted
    q = np.array([convert.quat_from_msg(m.quaternion) for m in att])
    assert np.all(np.isfinite(q))

    # closed form for a constant body rate: q(t) = q_init ⊗ exp(ω t) (rotation about body z)
    def truth(n_intervals, q_start=q_init):
        return (Rotation.from_quat(q_start) * Rotation.from_rotvec(
            np.array(omega) * dt * n_intervals)).as_quat()

    stamps = [convert.stamp_to_ns(m.header.stamp) for m in att]
    i19 = stamps.index(t0 + 19 * dt_ns)
    assert _angle(q[i19], truth(19)) < 1e-12
    i29 = stamps.index(t0 + 29 * dt_ns)
    assert _angle(q[i29], truth(19)) < 1e-12  # held across the gap
    assert _angle(q[i29 + 5], truth(24)) < 1e-12
    assert _angle(q[-4], q_init) < 1e-12  # reset to the initial attitude
    assert _angle(q[-1], truth(3)) < 1e-12

    # orientation covariance: initial + ARW growth σ²·dt² per integrated interval
    # The growth (1e-6 · 0.01² = 1e-10 per interval) is far below numpy's default atol of
    # 1e-8: compare the growth itself, relative only (atol=0), against the closed form.
    # Each step adds 1e-10 to ~1e-4 in float64 (rounding ~1e-20 per step): rtol 1e-8.
    cov = np.array([m.orientation_covariance for m in imu_out])
    initial = 1e-4
    for index, intervals in ((i19, 19), (i29 + 5, 24), (-1, 3)):
        c = cov[index].reshape(3, 3)
        np.testing.assert_allclose(np.diag(c) - initial, [intervals * var * dt**2] * 3,
                                   rtol=1e-8, atol=0)
        np.testing.assert_array_equal(c - np.diag(np.diag(c)), 0.0)

    # runtime parameter changes: refused with a reason naming the parameter, or applied
    client = ros_node.create_client(SetParameters, "attitude_integrator/set_parameters")
    assert client.wait_for_service(timeout_sec=10)

    def set_param(name, value):
        req = SetParameters.Request(parameters=[Parameter(name, value=value).to_parameter_msg()])
        future = client.call_async(req)
        assert ros_node.spin_until(future.done, timeout=10)
        return future.result().results[0]

    for name, value in (("algorithm", "no_such_algorithm"), ("algorithm", "quat_rk4"),
                        ("max_gap_s", -1.0), ("frame", "enu"),
                        ("time_jump_threshold_s", math.inf)):
        result = set_param(name, value)
        assert not result.successful and name in result.reason, (name, result.reason)
    assert set_param("algorithm", "exp_map").successful
    # the switch keeps attitude and time base: constant rate stays exact (exp_map to 1e-9)
    for k in range(4, 8):
        send(t1 + k * dt_ns)
    assert ros_node.spin_until(lambda: len(att) >= n_accepted + 4, timeout=10)
    assert _angle(convert.quat_from_msg(att[-1].quaternion), truth(7)) < 1e-9

    _assert_clean_exit(integ, integ.stop(signal.SIGINT))


# --------------------------------------------------------------------------- start-up
def test_invalid_parameters_refused_at_start(launch):
    cases = [
        (INTEGRATOR, ["-p", "algorithm:=no_such_algorithm"], "algorithm"),
        (INTEGRATOR, ["-p", "max_gap_s:=-1.0"], "max_gap_s"),
        (INTEGRATOR, ["-p", "frame:=ecef"], "frame"),
        (INTEGRATOR, ["-p", "initial_attitude:=[0.0, 0.0, 1.0]"], "initial_attitude"),
        # one topic as two inputs of different types (the resolved names compared)
        (INTEGRATOR, ["-p", "initial_attitude_source:=truth", "-p", "aiding:=magnetometer",
                      "-p", "mag_topic:=truth/attitude"], "mag_topic"),
        (INTEGRATOR, ["-p", "frame:=enu", "-p", "latitude_rad:=0.8", "-p",
                      "odometry_topic:=imu/data_raw"], "odometry_topic"),
        (INTEGRATOR, ["-p", "aiding:=magnetometer", "-p", "mag_topic:=a b"], "mag_topic"),
        # an input on the node's own output: it would read back what it publishes
        (INTEGRATOR, ["-p", "aiding:=magnetometer", "-p", "mag_topic:=imu/data"], "mag_topic"),
        (INTEGRATOR, ["-r", "imu/data_raw:=attitude"], "attitude"),
        (INTEGRATOR, ["-r", "attitude:=imu/data"], "attitude"),  # two outputs on one topic
        (SIM, ["-p", "rate_hz:=-5.0"], "rate_hz"),
        (SIM, ["-p", "time_mode:=slow"], "time_mode"),
        (SIM, ["-p", "scene:=no_such_scene_xyz"], "scene"),
    ]
    procs = [(launch(module, *args), name) for module, args, name in cases]
    # alongside: a valid sim running forever stops cleanly on SIGINT (exit 0, no traceback)
    running = launch(SIM, "-p", "scene:=coning")
    for proc, name in procs:
        code = proc.wait(timeout=30)
        out = proc.output()
        assert code == 2, f"{proc.module} {name}: exit {code}\n{out}"
        assert f"'{name}'" in out and "Traceback" not in out, out
    assert running.proc.poll() is None, running.output()
    _assert_clean_exit(running, running.stop(signal.SIGINT))
    assert "scene 'coning'" in running.output()


# --------------------------------------------------------------------------- fast + record
def test_fast_mode_gimbal_scene_recording_clock_and_enu_at_rest(launch, ros_node, tmp_path):
    from mcap.reader import make_reader

    bag = tmp_path / "free_gyro.mcap"
    clock = _collect(ros_node, Clock, "/clock", 100)
    joints = _collect(ros_node, JointState, "gyro/joint_states")
    att = _collect(ros_node, QuaternionStamped, "attitude")
    truth = _collect(ros_node, QuaternionStamped, "truth/attitude")
    _collect(ros_node, Imu, "imu/data_raw")  # with the integrator: the sim waits for 2
    lat = math.radians(45.0)  # the scene's latitude
    integ = launch(INTEGRATOR, "-p", "frame:=enu", "-p", f"latitude_rad:={lat!r}",
                   "-p", "initial_attitude_source:=truth", "-p", "qos_reliability:=reliable")
    assert ros_node.wait_for_publishers("attitude"), integ.output()
    sim = launch(SIM, "-p", "scene:=free_gyro_drift", "-p", "time_mode:=fast",
                 "-p", "duration_s:=4.0", "-p", f"record_path:={bag}",
                 "-p", "qos_reliability:=reliable",
                 "-p", "wait_for_subscribers:=2", "-p", "wait_timeout_s:=20.0")
    assert ros_node.spin_until(lambda: sim.proc.poll() is not None and len(clock) > 0
                               and len(att) >= 200, timeout=60), sim.output() + integ.output()
    _assert_clean_exit(sim, sim.wait(timeout=5))
    _assert_clean_exit(integ, integ.stop(signal.SIGINT))
    # A body at rest in ENU: the gyro sees only Earth rate, which frame=enu removes, so the
    # attitude stays put (docs/conventions.md). Without the removal it would turn by ω_ie·4 s ≈ 2.9e-4.
    q_truth = np.array([convert.quat_from_msg(m.quaternion) for m in truth])
    q_att = np.array([convert.quat_from_msg(m.quaternion) for m in att])
    assert _angle(q_truth, np.broadcast_to(q_truth[0], q_truth.shape)).max() == 0.0
    assert _angle(q_att, np.broadcast_to(q_truth[0], q_att.shape)).max() < 1e-12
    assert all(m.header.frame_id == "enu" for m in att)
    n = 200  # the scene's own 50 Hz for 4 s
    assert "published 200 samples" in sim.output()

    counts: dict[str, int] = {}
    schemas = {}
    with open(bag, "rb") as f:  # the independent `mcap` reader
        for schema, channel, _message in make_reader(f).iter_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            schemas[channel.topic] = schema.name
    topics = {t.rsplit("/", 2)[-2] + "/" + t.rsplit("/", 1)[-1]: c for t, c in counts.items()}
    assert topics == {"imu/data_raw": n, "gyro/joint_states": n, "truth/attitude": n,
                      "truth/odom": n}, counts
    assert sorted(set(schemas.values())) == ["geometry_msgs/msg/QuaternionStamped",
                                             "nav_msgs/msg/Odometry", "sensor_msgs/msg/Imu",
                                             "sensor_msgs/msg/JointState"]
    assert joints, "no gyro/joint_states received"
    assert list(joints[0].name) == ["outer_gimbal", "inner_gimbal"]
    assert all(np.all(np.isfinite(m.position)) and len(m.velocity) == 2 for m in joints)
    # /clock carries the sample stamps in fast mode (monotonic, on the 20 ms grid)
    c = np.array([convert.stamp_to_ns(m.clock) for m in clock])
    assert np.all(np.diff(c) > 0) and np.all(np.diff(c) % 20_000_000 == 0)


def test_gyro_sim_refuses_to_overwrite_a_recording(launch, tmp_path):
    """record_path naming an existing file: one line, exit 2, the file untouched."""
    bag = tmp_path / "old.mcap"
    bag.write_bytes(b"precious")
    proc = launch("gyro_attitude.ros.gyro_sim_node", "-p", "scene:=coning", "-p",
                  "time_mode:=fast", "-p", "duration_s:=0.5", "-p", f"record_path:={bag}")
    assert proc.wait(timeout=30) == 2, proc.output()
    out = proc.output()
    assert "record_path" in out and "exists" in out and "Traceback" not in out
    assert bag.read_bytes() == b"precious"
