"""ROS 2 node ``gyro_sim``: publish a simulated scene as Imu, gimbal joint states and truth.

Publishes (relative names, so a namespace applies):

* ``imu/data_raw`` (sensor_msgs/Imu, REP-145): ``angular_velocity`` = measured ω_ib^b
  [rad/s], ``linear_acceleration`` = specific force [m/s²] when the scene has
  accelerometers; covariances = per-sample variances of the scene's noise model
  (``SceneSimulator.imu_variances()``) on the diagonal, all zeros when the model gives no
  estimate; element 0 = −1 for orientation (a raw gyro has none) and for
  linear_acceleration without accelerometers. ``header.stamp`` = sample time.
* ``gyro/joint_states`` (sensor_msgs/JointState): the named joints of the scene's gimballed
  instrument (gimbal angles and indications [rad], their rates [rad/s]), only when it has one.
* ``truth/attitude`` (geometry_msgs/QuaternionStamped): true q_nb, frame ``world_frame_id``.
* ``truth/odom`` (nav_msgs/Odometry): position in the local ENU plane of the start point
  [m], orientation q_nb; twist in ``frame_id``: body-frame velocity and ω_nb^b.
* ``imu/mag`` (sensor_msgs/MagneticField, tesla, frame ``frame_id``) when the scene has a
  ``magnetometer:`` section; covariance σ² on the diagonal (all zeros for a noise-free one:
  unknown, REP-145).
* ``/tf`` with ``publish_tf``: the true q_nb as ``world_frame_id`` -> ``<frame_id>_truth``.
* ``/clock`` (rosgraph_msgs/Clock) in ``time_mode: fast``.

Timing. Stamps are on the sample grid: ``start + t_k`` with ``t_k`` the scene's own int-ns
sample times, ``start`` = wall clock at start. ``realtime`` publishes each sample once the
wall clock has reached its stamp, from a timer (``publish_period_s``); the schedule is
computed from the absolute start, so late ticks catch up and nothing drifts. ``fast``
publishes block after block as fast as possible and ``/clock`` along. The scene is
simulated ``block_s`` ahead. With ``duration_s > 0`` the node stops after that much
simulated time and ``main()`` exits 0. ``record_path`` records every published topic
in-process to a rosbag2-compatible MCAP file.
"""

from __future__ import annotations

import dataclasses
import struct
import sys
import time

import numpy as np
import rclpy
from geometry_msgs.msg import QuaternionStamped
from nav_msgs.msg import Odometry
from rcl_interfaces.msg import SetParametersResult
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.qos import ReliabilityPolicy
from rclpy.serialization import serialize_message
from rclpy.task import Future
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu, JointState, MagneticField
from std_msgs.msg import Header

from gyro_attitude.core.scene import BLOCK_SAMPLES, SceneSimulator
from gyro_attitude.core.scene.magnetometer import magnetometer_covariance
from gyro_attitude.core.sim_topics import (
    DEFAULT_FRAME_ID,
    DEFAULT_WORLD_FRAME_ID,
    MAG_TOPIC,
    TOPICS,
    SimTopics,
    local_enu_position,  # noqa: F401  (re-exported: its home moved to core.sim_topics)
)
from gyro_attitude.core.trajectory import LiveTrajectory
from gyro_attitude.io.cdr_arrays import imu_batch
from gyro_attitude.io.recording import SafeRecording
from gyro_attitude.io.safe_output import check_output_path
from gyro_attitude.io.scene_file import load_scene
from gyro_attitude.ros import convert
from gyro_attitude.ros.node_main import run_node
from gyro_attitude.ros.params import ParameterError, ParamSpec, check_update, declare_all
from gyro_attitude.ros.qos import imu_qos
from gyro_attitude.ros.tf import TF_TOPIC, TF_TYPE, TfBroadcaster

NODE_NAME = "gyro_sim"
_GRID_MARGIN_NS = 50_000  # realtime: a sample is due this long before the timer tick
DEFAULT_SCENE = "coning"
_STAMP = struct.Struct("<iI")  # builtin_interfaces/Time serialized (sec, nanosec)



def parameter_specs() -> list[ParamSpec]:
    return [
        ParamSpec("scene", DEFAULT_SCENE, "scene name (config/scenes/<name>.yaml) or YAML path"),
        ParamSpec("rate_hz", 0.0, "Imu output rate [Hz] (0 = the scene's own rate_hz)",
                  low=0.0, high=100000.0),
        ParamSpec("frame_id", DEFAULT_FRAME_ID, "header.frame_id of the Imu (sensor frame)"),
        ParamSpec("world_frame_id", DEFAULT_WORLD_FRAME_ID,
                  "frame of truth/attitude and truth/odom (ENU)"),
        ParamSpec("seed", -1, "random seed of the noise model (-1: the scene's own seed)", low=-1,
                  high=2**31 - 1),
        ParamSpec("time_mode", "realtime",
                  "'realtime': on the wall clock; 'fast': as fast as possible, with /clock",
                  choices=("realtime", "fast")),
        ParamSpec("duration_s", 0.0, "simulated duration [s] (0 = forever)", low=0.0,
                  high=1.0e7),
        ParamSpec("record_path", "", "MCAP file to record all published topics to ('' = off)"),
        ParamSpec("block_s", 0.05, "simulate this far ahead per block [s]", low=1e-4, high=10.0),
        ParamSpec("publish_period_s", 0.001, "realtime publishing timer period [s]", low=1e-4,
                  high=1.0),
        ParamSpec("publish_truth", True, "publish truth/attitude and truth/odom"),
        ParamSpec("publish_tf", False,
                  "also publish the true attitude on /tf (tf2_msgs/TFMessage) as "
                  "world_frame_id -> truth_frame_id (needs tf2_msgs)"),
        ParamSpec("truth_frame_id", "", "publish_tf: the child frame ('' = <frame_id>_truth)"),
        ParamSpec("wait_for_subscribers", 0,
                  "wait until imu/data_raw has this many subscribers before starting",
                  low=0, high=1000),
        ParamSpec("wait_timeout_s", 10.0, "give up waiting for subscribers after [s]",
                  low=0.0, high=3600.0),
        ParamSpec("qos_reliability", "best_effort", "imu/data_raw publisher reliability",
                  choices=("best_effort", "reliable")),
        ParamSpec("qos_depth", 1000, "imu/data_raw publisher queue depth", low=1, high=100000),
        ParamSpec("motion_topic", "",
                  "nav_msgs/Odometry ground truth to move the sensors along ('' = the scene's "
                  "motion): the Imu follows it, stamped in its time base"),
        ParamSpec("motion_delay_s", 0.05,
                  "motion_topic: publish a sample once the odometry is this far past it [s]",
                  low=0.0, high=10.0),
        ParamSpec("motion_timeout_s", 1.0,
                  "motion_topic: no odometry for this long (wall clock) is reported; a gap "
                  "this long in its stamps restarts the Imu [s]", low=0.01, high=3600.0),
        ParamSpec("motion_window_s", 2.0, "motion_topic: poses kept for the spline fit [s]",
                  low=0.1, high=600.0),
    ]


class GyroSimNode(Node):
    """Thin ROS wrapper around the core ``SceneSimulator``."""

    def __init__(self, **kwargs):
        super().__init__(NODE_NAME, **kwargs)
        specs = parameter_specs()
        self._specs = {s.name: s for s in specs}
        p = declare_all(self, specs)
        self._p = p

        seed = None if p["seed"] < 0 else p["seed"]
        try:
            spec = load_scene(p["scene"], seed=seed)  # the parameter stands in for seed:
        except Exception as exc:  # unknown name, unreadable file, YAML syntax, bad key
            raise ParameterError(f"parameter 'scene' = {p['scene']!r}: {exc}") from exc
        if p["rate_hz"] == 0.0:
            p["rate_hz"] = float(spec.rate_hz)
        elif p["rate_hz"] < 1.0:
            raise ParameterError(f"parameter 'rate_hz' must be 0 (scene rate) or >= 1 Hz, "
                                 f"got {p['rate_hz']}")
        self._spec, self._seed = spec, seed
        try:
            # with motion_topic this one only gives the covariances; the live simulator is
            # made when the first odometry arrives (its stamp is the start)
            self._sim = SceneSimulator(spec, p["rate_hz"], seed=seed)
        except ValueError as exc:
            raise ParameterError(f"parameter 'scene'/'rate_hz': {exc}") from exc
        self._live: LiveTrajectory | None = None
        self._live_mode = bool(p["motion_topic"])
        gyro_var, accel_var = self._sim.imu_variances()
        # covariances on the Imu diagonal; None: all zeros, "unknown" (REP-145)
        self._gyro_cov = (None if gyro_var is None
                          else convert.covariance_from_variances(np.asarray(gyro_var, float)))
        self._accel_cov = (None if accel_var is None
                           else convert.covariance_from_variances(np.asarray(accel_var, float)))
        self._frame_id = p["frame_id"]
        self._world = p["world_frame_id"]
        self._fast = p["time_mode"] == "fast"
        # at most BLOCK_SAMPLES per block: the memory of a block (Python lists of every message
        # field) stays bounded whatever block_s x rate_hz a scene and the parameters ask for
        self._block_n = min(BLOCK_SAMPLES, max(1, int(round(p["block_s"] * p["rate_hz"]))))
        self._n_total = int(round(p["duration_s"] * p["rate_hz"])) if p["duration_s"] > 0 else 0

        self._pub_imu = self.create_publisher(
            Imu, "imu/data_raw", imu_qos(p["qos_reliability"], p["qos_depth"])
        )
        self._pub_joint = self.create_publisher(JointState, "gyro/joint_states", 100)
        self._pub_truth = self.create_publisher(QuaternionStamped, "truth/attitude", 1000)
        self._pub_odom = self.create_publisher(Odometry, "truth/odom", 100)
        self._pub_clock = self.create_publisher(Clock, "/clock", 10) if self._fast else None
        self._pub_mag = self._mag_cov = None
        if spec.magnetometer is not None:
            self._mag_cov = magnetometer_covariance(spec.magnetometer).tolist()
            self._pub_mag = self.create_publisher(
                MagneticField, MAG_TOPIC, imu_qos(p["qos_reliability"], p["qos_depth"]))
        self._topics_published = {t: ty for t, ty in TOPICS.items()
                                  if t != MAG_TOPIC or self._pub_mag is not None}
        self._tf = None
        if p["publish_tf"]:
            self._tf_child = p["truth_frame_id"] or f"{self._frame_id}_truth"
            self._tf = TfBroadcaster(self, self._world, self._tf_child)
            self._topics_published[TF_TOPIC] = TF_TYPE
        self._odom_wall: float | None = None  # monotonic time of the last odometry
        self._created_at = time.monotonic()
        self._odom_intervals: list[int] = []
        self._warned: set[str] = set()
        self.rejected_odometry = 0
        if self._live_mode:
            if spec.free_gyro_params is not None or spec.instrument is not None:
                raise ParameterError("parameter 'motion_topic': not with a scene's free gyro or "
                                     "instrument (their solvers need the motion ahead)")
            self.create_subscription(Odometry, p["motion_topic"], self._on_odometry,
                                     imu_qos("best_effort", 1000))

        self._recording: SafeRecording | None = None
        self._serialize = None
        if p["record_path"]:
            self._open_recorder(p["record_path"])

        self.published = 0  # samples published
        self.finished = False
        self.done = Future()  # completed when the duration is over
        self._start_ns: int | None = None
        self._topics = SimTopics()  # message fields, shared with offline `simulate`
        self._block: list | None = None  # rows of the current block, ready to publish
        self._imu_raw: list[bytes] | None = None  # their Imu messages, serialized
        self._block_fields = None
        self._block_pos = 0
        self._generated = 0
        self._wait_deadline = time.monotonic() + p["wait_timeout_s"]
        self._matched_at: float | None = None
        period = 1e-4 if self._fast else p["publish_period_s"]
        self._timer = self.create_timer(period, self._tick)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.get_logger().info(
            f"scene '{p['scene']}' at {p['rate_hz']:g} Hz, "
            + (f"motion from {p['motion_topic']} (delay {p['motion_delay_s']:g} s)"
               if self._live_mode else f"{p['time_mode']} time")
            + f", duration {p['duration_s']:g} s"
            + (f", recording to {p['record_path']}" if p["record_path"] else "")
        )

    # ------------------------------------------------------------------ recording
    def _open_recorder(self, path: str) -> None:
        # an existing file is never replaced, and the recording appears under its name only
        # when finished (a killed simulator leaves it in a hidden .NAME.*.partial folder)
        try:
            check_output_path(path, what="record_path")
            self._recording = SafeRecording(path)
            for topic, type_name in self._topics_published.items():
                self._recording.add_topic(self._resolve(topic), type_name)
        except (OSError, ValueError) as exc:
            if self._recording is not None:
                self._recording.discard()
                self._recording = None
            raise ParameterError(f"parameter 'record_path': {exc}") from exc
        self._serialize = serialize_message

    def _resolve(self, topic: str) -> str:
        return self.resolve_topic_name(topic)

    def _record(self, topic: str, msg, t_ns: int) -> None:
        # log_time = when the sample is published (receive time of an in-process recorder)
        data = msg if isinstance(msg, bytes) else self._serialize(msg)
        self._recording.write(self._resolve_cache[topic], data, t_ns, t_ns)

    def close(self) -> None:
        """Finish the recording (idempotent); a full disk raises OutputWriteError (one line,
        the recording so far kept readable under its name)."""
        if self._recording is not None:
            self._recording.close()

    # ------------------------------------------------------------------ parameters
    def _on_set_parameters(self, params) -> SetParametersResult:
        reason = check_update(self._specs, params)
        if reason is not None:
            return SetParametersResult(successful=False, reason=reason)
        return SetParametersResult(successful=True)

    # ------------------------------------------------------------------ simulation
    def _next_block(self) -> None:
        n = self._block_n
        if self._n_total:
            n = min(n, self._n_total - self._generated)
        before = sum(self._sim.saturated.values())
        f = self._topics.fields(self._sim.next_block(n))
        self._generated += n
        if before == 0 and sum(self._sim.saturated.values()) > 0:
            self.get_logger().warning(
                "output range reached: samples clipped at full scale "
                f"({', '.join(f'{k} {v}' for k, v in self._sim.saturated.items())} so far)")
        # plain Python lists: building messages from numpy scalars is several times slower
        cols = [f.t_rel_ns.tolist(), f.angular_velocity.tolist(),
                None if f.specific_force is None else f.specific_force.tolist(),
                f.q_nb.tolist(), f.position_enu.tolist(), f.velocity_body.tolist(),
                f.omega_nb_b.tolist(),
                None if f.gimbal_angles is None else f.gimbal_angles.tolist(),
                None if f.gimbal_rates is None else f.gimbal_rates.tolist(),
                None if f.magnetic_field is None else f.magnetic_field.tolist()]
        self._block = [tuple(None if c is None else c[k] for c in cols) for k in range(n)]
        self._gimbal_names = None if f.gimbal_names is None else list(f.gimbal_names)
        self._block_pos = 0
        self._block_fields = f
        self._imu_raw = None
        if self._start_ns is not None:
            self._serialize_imu_block()

    def _serialize_imu_block(self) -> None:
        """The block's Imu messages serialized at once (io/cdr_arrays.py: the same bytes
        rclpy writes for ``convert.imu_msg`` of each row), published as they are: building
        and serializing one Python message per sample cost more than the rest of the sample
        at kHz rates."""
        f = self._block_fields
        self._imu_raw = [bytes(row) for row in imu_batch(
            "imu/data_raw", self._start_ns + f.t_rel_ns.astype(np.int64), f.angular_velocity,
            f.specific_force, frame_id=self._frame_id,
            angular_velocity_covariance=self._gyro_cov,
            linear_acceleration_covariance=(None if f.specific_force is None
                                            else self._accel_cov)).payloads()]

    def _publish_row(self, row, imu_raw: bytes) -> None:
        t_rel, omega, sf, q, pos, v_b, w_nb, g_ang, g_rate, mag = row
        t_ns = self._start_ns + t_rel
        self._pub_imu.publish(imu_raw)
        msgs = [("imu/data_raw", imu_raw)]
        if g_ang is not None:
            js = convert.joint_state_msg(t_ns, self._gimbal_names, g_ang, g_rate)
            js.header.frame_id = self._frame_id
            self._pub_joint.publish(js)
            msgs.append(("gyro/joint_states", js))
        if mag is not None:
            mm = convert.magnetic_field_msg(t_ns, self._frame_id, mag, self._mag_cov)
            self._pub_mag.publish(mm)
            msgs.append((MAG_TOPIC, mm))
        if self._p["publish_truth"]:
            att = QuaternionStamped()
            att.header = Header(stamp=convert.ns_to_stamp(t_ns), frame_id=self._world)
            a = att.quaternion
            a.x, a.y, a.z, a.w = q
            self._pub_truth.publish(att)
            odom = convert.odometry_msg(t_ns, self._world, self._frame_id, pos, q, v_b, w_nb)
            self._pub_odom.publish(odom)
            msgs += [("truth/attitude", att), ("truth/odom", odom)]
        if self._tf is not None:
            raw = self._tf.encode(_STAMP.pack(*divmod(t_ns, 1_000_000_000)), self._tf_child, *q)
            self._tf.publish(raw)
            msgs.append((TF_TOPIC, raw))
        if self._pub_clock is not None:
            self._pub_clock.publish(Clock(clock=convert.ns_to_stamp(t_ns)))
        if self._recording is not None and not self._recording.closed:
            for topic, m in msgs:
                self._record(topic, m, t_ns)
        self.published += 1

    def _ready(self) -> bool:
        want = self._p["wait_for_subscribers"]
        if want <= 0:
            return True
        if self._pub_imu.get_subscription_count() >= want:
            # Discovery is two-sided: this writer has matched the readers, but a reader may
            # not have matched this writer yet and would drop best-effort samples. Settle.
            if self._matched_at is None:
                self._matched_at = time.monotonic()
            return time.monotonic() - self._matched_at >= 0.25
        if time.monotonic() > self._wait_deadline:
            self.get_logger().warning(
                f"only {self._pub_imu.get_subscription_count()} of {want} subscribers after "
                f"{self._p['wait_timeout_s']} s; starting anyway"
            )
            return True
        return False

    # ------------------------------------------------------------------ motion_topic
    def _warn_once(self, key: str, text: str) -> None:
        if key not in self._warned:
            self._warned.add(key)
            self.get_logger().warning(text)

    def _start_live(self, t_ns: int) -> None:
        """A new live trajectory and simulator starting at the odometry stamp ``t_ns``."""
        p, ea = self._p, self._spec.earth
        self._live = LiveTrajectory((ea.latitude_rad, ea.longitude_rad, ea.height_m), t_ns,
                                    p["motion_window_s"])
        spec = dataclasses.replace(self._spec, motion=self._live, motion_type="trajectory",
                                   start_time_ns=t_ns)
        self._sim = SceneSimulator(spec, p["rate_hz"], seed=self._seed)
        self._topics = SimTopics()
        self._start_ns = t_ns
        self._generated = 0
        self._block, self._block_pos = [], 0
        self._imu_raw = []
        self._resolve_cache = {t: self._resolve(t) for t in {**TOPICS, **self._topics_published}}

    def _on_odometry(self, msg: Odometry) -> None:
        t_ns = convert.stamp_to_ns(msg.header.stamp)
        pose = msg.pose.pose
        pos = (pose.position.x, pose.position.y, pose.position.z)
        q = (pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w)
        now = time.monotonic()
        if self._odom_wall is not None and now - self._odom_wall > self._p["motion_timeout_s"]:
            self.get_logger().info(f"odometry on {self._p['motion_topic']} resumed")
            self._warned.discard("stopped")
        self._odom_wall = now
        if self._live is not None and self._live.last_stamp_ns is not None:
            gap = t_ns - self._live.last_stamp_ns
            if gap > self._p["motion_timeout_s"] * 1e9:
                self.get_logger().warning(
                    f"odometry gap of {gap / 1e9:.3g} s in its stamps: the Imu restarts at "
                    f"{t_ns / 1e9:.9f} s (nothing is published across the gap)")
                self._live = None
            elif gap > 0:
                self._odom_intervals.append(gap)
        if self._live is None:
            if t_ns <= 0:
                self.rejected_odometry += 1
                self._warn_once("stamp0", "odometry with a zero stamp ignored")
                return
            self._start_live(t_ns)
        reason = self._live.add(t_ns, pos, q)
        if reason is not None:
            self.rejected_odometry += 1
            self._warn_once(f"bad:{reason.split(' ')[0]}", f"odometry rejected: {reason} "
                            f"(stamp {t_ns}; counted, later ones not logged)")
            return
        if len(self._odom_intervals) == 20:
            rate = 1e9 / float(np.median(self._odom_intervals))
            if rate < self._p["rate_hz"]:
                self._warn_once("slow", f"odometry at {rate:.4g} Hz is slower than the Imu "
                                f"rate {self._p['rate_hz']:g} Hz: the samples between poses "
                                "come from the spline fit (its bandwidth is the odometry's)")

    def _live_tick(self) -> None:
        last = self._odom_wall if self._odom_wall is not None else self._created_at
        waited = time.monotonic() - last
        if waited > self._p["motion_timeout_s"]:
            self._warn_once("stopped", f"no odometry on {self._p['motion_topic']} for "
                            f"{waited:.3g} s: the Imu waits for it")
        if self._live is None or self._live.pose_count < 4:
            return
        ready_s = self._live.covers()[1] - self._p["motion_delay_s"]
        rate = self._p["rate_hz"]
        n_ready = int(np.floor(ready_s * rate + 1e-9)) + 1 - self._generated
        if self._n_total:
            n_ready = min(n_ready, self._n_total - self._generated)
        if n_ready <= 0:
            if self._n_total and self._generated >= self._n_total:
                self._finish()
            return
        first = self._live.covers()[0]
        if self._generated / rate < first:  # the window moved past the next sample
            self.get_logger().error("motion_window_s is too short for the delay; raise it")
            self._finish()
            return
        while n_ready > 0:
            n = min(n_ready, BLOCK_SAMPLES)
            self._block_n = n
            self._next_block()
            for row, raw in zip(self._block, self._imu_raw, strict=True):
                self._publish_row(row, raw)
            n_ready -= n

    def _tick(self) -> None:
        if self.finished:
            return
        if self._live_mode:
            self._live_tick()
            return
        if self._start_ns is None:
            if not self._ready():
                return
            self._resolve_cache = {t: self._resolve(t) for t in self._topics_published}
            self._next_block()
            now = time.time_ns()
            until = self._timer.time_until_next_call()
            if self._fast or until is None:
                self._start_ns = now
            else:
                # Anchor the sample grid on this timer's own schedule: its nominal tick time
                # (next call − period) minus a small margin. Every later tick then finds the
                # samples up to its own time due and publishes them at once (margin +
                # scheduling jitter after their stamps), instead of up to a period late when
                # the grid's phase falls just after the ticks'.
                self._start_ns = now + until - self._timer.timer_period_ns - _GRID_MARGIN_NS
            self._serialize_imu_block()  # the first block: its stamps are known only now
        if self._fast:
            due = None  # everything in the current block
        else:
            due = time.time_ns() - self._start_ns
        while True:
            if self._block_pos >= len(self._block):
                if self._n_total and self._generated >= self._n_total:
                    self._finish()
                    return
                self._next_block()
                if self._fast:
                    return  # one block per tick: lets parameter services run in between
            row = self._block[self._block_pos]
            if due is not None and row[0] > due:
                return
            self._publish_row(row, self._imu_raw[self._block_pos])
            self._block_pos += 1

    def wait_for_reliable_acks(self, timeout_s: float) -> bool:
        """Block until every reliable subscriber acknowledged what was published (or
        ``timeout_s`` passed): the samples still in a reliable writer's history are lost when
        the process exits, and a slow subscriber on a loaded machine lags by more than the
        linger above. True when all were acknowledged."""
        deadline = time.monotonic() + timeout_s
        acked = True
        for pub in (self._pub_imu, self._pub_truth, self._pub_mag):
            if pub is None or pub.qos_profile.reliability != ReliabilityPolicy.RELIABLE:
                continue
            left = max(0.0, deadline - time.monotonic())
            try:
                acked &= pub.wait_for_all_acked(Duration(nanoseconds=int(left * 1e9)))
            except Exception:  # context shut down by a signal meanwhile: nothing to wait for
                return False
        return acked

    def _finish(self) -> None:
        self.finished = True
        self._timer.cancel()
        self.done.set_result(self.published)
        self.close()
        sat = "".join(f"; {k} saturated in {v} samples" for k, v in self._sim.saturated.items())
        self.get_logger().info(f"published {self.published} samples{sat}; done")


ACK_WAIT_S = 5.0  # how long a finished sim waits for its reliable subscribers to acknowledge


def _spin_until_done(node: GyroSimNode, executor) -> None:
    executor.spin_until_future_complete(node.done)
    if node.finished:
        # let DDS deliver the last samples before the participant goes away
        end = time.monotonic() + 0.3
        while rclpy.ok() and time.monotonic() < end:
            executor.spin_once(timeout_sec=0.05)
        node.wait_for_reliable_acks(ACK_WAIT_S)


def main(args=None) -> int:
    """Spin until the duration is over (exit 0), SIGINT/SIGTERM (exit 0), or exit 2 on an
    invalid parameter, 1 when the disk under ``record_path`` fills (the recording so far
    kept, readable, under its name)."""
    return run_node(NODE_NAME, GyroSimNode, args, spin=_spin_until_done,
                    finish=GyroSimNode.close)



if __name__ == "__main__":
    sys.exit(main())
