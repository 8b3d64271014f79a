"""ROS 2 node ``attitude_integrator``: integrate ``imu/data_raw`` rates into attitude.

Subscribes ``imu/data_raw`` (sensor_msgs/Imu, ω_ib^b in rad/s) and, when
``initial_attitude_source`` is ``truth``, ``truth/attitude`` (geometry_msgs/QuaternionStamped,
q_nb) to take the starting attitude (slerped to the first Imu stamp it covers; Imu samples
before the first truth are skipped and counted), and with ``frame: enu`` and a non-empty
``odometry_topic`` a nav_msgs/Odometry topic whose velocity sets the transport rate (below).
Publishes

* ``imu/data``: the input Imu with ``orientation`` filled (q_ib for ``frame: inertial``,
  q_nb for ``frame: enu``) and an orientation covariance that grows with the gyro noise
  (angle-random-walk growth: per axis, variance += gyro variance · dt² per sample, with
  the gyro variance taken from the input's ``angular_velocity_covariance`` diagonal; all
  zeros = unknown when the input carries no covariance);
* ``attitude``: geometry_msgs/QuaternionStamped, same quaternion, header frame =
  ``world_frame_id``;
* ``/tf`` with ``publish_tf``: the same rotation as ``world_frame_id`` -> the Imu's frame
  (ros/tf.py, docs/tf.md);
* ``/diagnostics``: diagnostic_msgs/DiagnosticArray about every ``diagnostics_period_s``:
  input rate, dt jitter, accepted samples and rejected samples by reason, the phase
  (``aligning`` | ``running`` | ``failed``), the gyro bias estimate, its standard error, the
  rests used, whether the Earth rate was removed from it or absorbed, and the alignment result.

Real IMUs (all in the shared policy, below): ``gyro_bias`` ``auto`` (default) estimates the
bias at every rest of at least ``min_rest_s`` and holds it in motion (``none``,
``parameter`` + ``gyro_bias_rad_s`` otherwise); with ``frame: enu`` the Earth rate is taken
out of it, with ``frame: inertial`` it is absorbed (the diagnostics say which).
``initial_attitude_source: level`` levels from the specific force over the first rest, with
``initial_heading_deg`` or ``heading_source: gyrocompass``; while aligning, no attitude is
published, only diagnostics; the attitude then starts with the alignment's covariance.
``aiding: auto`` (the default) runs the AHRS filter on the accelerometer whenever the Imu
carries one (tilt; heading gyro-only, it drifts without ``aiding: magnetometer``) and starts
the tilt from the first accelerometer sample; gyro-only without one; the log says which, once.
The orientation covariance grows with the gyro noise
(input covariance or ``gyro_noise_density``) and the bias uncertainty, and shrinks with
alignment, rests and aiding (core/attitude/covariance.py). ``linear_acceleration_covariance[0]
= -1`` means no accelerometer.

Every input sample goes through :class:`gyro_attitude.core.attitude.stream.AttitudeStream`,
the policy ``gyro-attitude replay`` applies too: non-finite rates, rates beyond
``max_rate_rad_s``, zero/duplicate/out-of-order stamps and a changed frame_id are rejected
(counted, warned at most once per second per reason); a gap longer than ``max_gap_s`` is not
integrated across (attitude held, time base restarted); a backward time jump beyond
``time_jump_threshold_s`` resets the attitude to the initial one; an invalid
``angular_velocity_covariance`` counts as unknown; a non-finite update restores the last good
attitude (``integrator_errors``). Every published quaternion is finite and unit.

Moving carrier (``frame: enu``). The nav-frame rate ``ω_in^n = ω_ie^n + ω_en^n`` starts
from the parameters ``latitude_rad``, ``height_m`` and ``velocity_enu``. With
``odometry_topic`` set, every Odometry message replaces the velocity by its linear
velocity expressed in ENU: ``twist.twist.linear`` is taken in ``child_frame_id``
(nav_msgs / REP-105) and rotated into ``header.frame_id`` with ``pose.pose.orientation``
(gyro_sim's ``truth/odom``: frame ``enu``, child = the Imu frame, orientation q_nb, twist =
body velocity); with an empty or equal ``child_frame_id`` it is used as is. The header
frame must be ENU-aligned (its origin does not matter). Messages are applied in stamp
order on the Imu time line: before integrating an Imu sample, the newest queued message
whose stamp is not after the sample's stamp becomes the nav frame (``ω_in^n`` evaluated
once per applied message) and holds from that sample on, until a newer one. So the
velocity is time-aligned however the two topics interleave (an Odometry stamp equal to an
Imu stamp is the rate at that sample, as a NavFrame time series); a message arriving after
its Imu sample takes effect at the next one. Both topics must share one clock; a backward
time jump drops the queue. Latitude and height stay the
parameters: the Odometry position is in a local frame with no geodetic origin, and over a
flight of minutes the change of ω_in^n with latitude (~ω_ie·ΔL) is orders below the
transport rate itself.
"""

from __future__ import annotations

import math
import sys
import threading
import time
from dataclasses import replace

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import QuaternionStamped
from nav_msgs.msg import Odometry
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import Imu, MagneticField

from gyro_attitude.core.attitude import DEFAULT_ALGORITHM
from gyro_attitude.core.attitude import validation as iv
from gyro_attitude.core.attitude.accel_units import AccelScaleWatch
from gyro_attitude.core.attitude.input_topics import (
    input_on_output,
    input_on_output_message,
    shared_output_message,
    shared_topic,
    shared_topic_message,
)
from gyro_attitude.core.attitude.modes import Aiding, InitialAttitudeSource, SettingError
from gyro_attitude.core.attitude.nav_frame import VelocitySchedule
from gyro_attitude.core.attitude.sample_alignment import LatestSamples
from gyro_attitude.core.attitude.settings import RETIRED_SETTINGS, SETTINGS, StreamConfig
from gyro_attitude.core.attitude.stream import (
    ALIGNING,
    FAILED,
    INTEGRATOR_ERROR,
    INVALID_ACCEL,
    INVALID_COVARIANCE,
    INVALID_MAG,
    MAG_DISTURBED,
    MAG_MISSING,
    RATE_FIT_FALLBACK,
    RUNNING,
    SATURATED,
    STEP_ALGORITHMS,
    AttitudeStream,
    compile_kernels,
)
from gyro_attitude.core.attitude.truth import TruthStart
from gyro_attitude.core.attitude.world_frame import frame_id_of, from_enu_one
from gyro_attitude.io.cdr_arrays import ImuCdr, QuaternionStampedCdr
from gyro_attitude.ros import convert
from gyro_attitude.ros.input_thread import InputThread, spin_with_inputs
from gyro_attitude.ros.node_main import EXECUTORS, INPUT_THREAD, run_node
from gyro_attitude.ros.params import (
    ParameterError,
    ParamSpec,
    check_update,
    declare_all,
    spec_from_setting,
)
from gyro_attitude.ros.qos import imu_qos
from gyro_attitude.ros.tf import TfBroadcaster

NODE_NAME = "attitude_integrator"
OUTPUT_DEPTH = 1000  # keep-last history of imu/data and attitude
OUTPUT_TOPICS = ("imu/data", "attitude", "/diagnostics")


def parameter_specs(settings=SETTINGS) -> list[ParamSpec]:
    """The node's parameters: the estimator settings (one table, core/attitude/settings.py)
    and the node's own wiring (algorithm, topics, QoS, diagnostics)."""
    return [
        ParamSpec("algorithm", DEFAULT_ALGORITHM,
                  "attitude update algorithm (gyro-attitude bench lists them)",
                  choices=tuple(STEP_ALGORITHMS), runtime=True),
        *(spec_from_setting(s) for s in settings),
        ParamSpec("odometry_topic", "",
                  "nav_msgs/Odometry topic giving the carrier velocity for the transport "
                  "rate (frame=enu; twist in child_frame_id, rotated to ENU with the pose "
                  "orientation); '' = off, velocity_enu is used"),
        ParamSpec("mag_topic", "imu/mag",
                  "sensor_msgs/MagneticField topic (tesla) for aiding magnetometer, matched to "
                  "the Imu stamps (the latest sample at or before each, at most mag_max_age_s "
                  "old)"),
        ParamSpec("world_frame_id", "",
                  "header.frame_id of the attitude output ('' = the world_frame's name, or "
                  "'inertial' with frame inertial)"),
        ParamSpec("publish_tf", False,
                  "also publish the attitude on /tf (tf2_msgs/TFMessage) as world_frame_id -> "
                  "tf_child_frame_id, stamped as the attitude (needs tf2_msgs)"),
        ParamSpec("tf_child_frame_id", "",
                  "publish_tf: the child frame ('' = the Imu's header.frame_id)"),
        ParamSpec("qos_reliability", "best_effort",
                  "imu/data_raw subscription reliability", choices=("best_effort", "reliable")),
        ParamSpec("qos_depth", 1000, "imu/data_raw subscription queue depth", low=1,
                  high=100000),
        ParamSpec("executor", INPUT_THREAD,
                  "how inputs are taken: input_thread (a thread of the node waits on the input "
                  "subscriptions alone and takes every queued message; rclpy's single-threaded "
                  "executor serves the timers and parameter services) | single_threaded "
                  "(rclpy's default executor for everything; drain_queue applies) | events "
                  "(rclpy.experimental.EventsExecutor: EXPERIMENTAL, with the pinned Jazzy "
                  "rclpy its spin() holds the GIL while waiting, so timers and other threads "
                  "starve; falls back to single_threaded where it is missing)",
                  choices=EXECUTORS),
        ParamSpec("drain_queue", True,
                  "executor single_threaded: take all queued Imu messages per wakeup (less "
                  "overhead at high rates); false: one message per wakeup (plain rclpy). The "
                  "input thread always takes every queued message; the events executor "
                  "delivers every message itself and never drains"),
        ParamSpec("diagnostics_period_s", 1.0, "period of /diagnostics [s]", low=0.01,
                  high=3600.0),
    ]


class AttitudeIntegratorNode(Node):
    """Thin ROS wrapper around :class:`AttitudeStream` (the policy replay shares)."""

    def __init__(self, **kwargs):
        super().__init__(NODE_NAME, **kwargs)
        specs = parameter_specs()
        self._specs = {s.name: s for s in specs}
        p = declare_all(self, specs)  # raises ParameterError naming a bad parameter
        self._p = p
        self.executor_kind = p["executor"]  # read by node_main.run_node
        # taking messages from the subscription's handle behind the events executor's back
        # would leave its per-message events without a message: drain only without it
        self._drain = p["drain_queue"] and p["executor"] == "single_threaded"
        # the stream and the counters: taken by the input thread per batch of messages, by
        # the executor's callbacks (diagnostics, parameter changes) per call
        self._lock = threading.RLock()
        self.inputs = (InputThread(self.context, self._lock, name=f"{NODE_NAME} inputs")
                       if p["executor"] == INPUT_THREAD else None)
        config = self._make_stream(p)
        self._world = config.world_frame
        self._world_frame = p["world_frame_id"] or frame_id_of(config.frame, config.world_frame)
        self._truth_start = None
        if config.initial_attitude_source is InitialAttitudeSource.TRUTH:
            max_rate = config.max_rate_rad_s
            self._truth_start = TruthStart(
                lambda t, w: iv.sample_problem(t, w, max_rate) is None, kept=self._TRUTH_KEPT)
        self._phase_seen = self._stream.phase
        self._skipped_before_truth = 0
        self._last_warn: dict[str, float] = {}
        self._last_period_rejected = 0
        self._last_period_accepted = 0
        self._published = 0
        self.odometry_updates = 0
        self._sub_odom = None
        self._velocities = VelocitySchedule(kept=self._ODOM_QUEUE)

        self._undecodable = 0
        # is linear_acceleration in m/s²?  Judged once on the first accepted samples (as replay
        # judges the recording); a field in g, mg, cm/s² or all zero is pushed no more
        self._accel_watch = AccelScaleWatch()
        self._accel_dropped = 0  # samples whose accelerometer was not pushed for that
        self._att_cdr = QuaternionStampedCdr(self._world_frame)
        self._check_distinct_topics(p, config)  # before any publisher or subscription exists
        self._tf = (TfBroadcaster(self, self._world_frame, p["tf_child_frame_id"] or None)
                    if p["publish_tf"] else None)
        # the per-sample kernels compiled, or loaded from numba's cache, before any sample
        # arrives (the first start after an installation compiles, for seconds)
        started = time.monotonic()
        compile_kernels(config, p["algorithm"])
        if time.monotonic() - started > 5.0:
            self.get_logger().info(f"compiled the per-sample kernels in "
                                   f"{time.monotonic() - started:.0f} s (cached from now on)")
        # keep-last 1000 (1 s at 1 kHz): a reliable subscriber that lags by more than the
        # history loses what was overwritten before it acknowledged
        imu_out, attitude_out, diagnostics_out = OUTPUT_TOPICS
        self._pub_imu = self.create_publisher(Imu, imu_out, OUTPUT_DEPTH)
        self._pub_att = self.create_publisher(QuaternionStamped, attitude_out, OUTPUT_DEPTH)
        self._pub_diag = self.create_publisher(DiagnosticArray, diagnostics_out, 10)
        self._create_subscriptions(p, config)
        self.create_timer(p["diagnostics_period_s"], self._publish_diagnostics)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        if self.inputs is not None:
            # started here, not by the spin: the node takes its inputs however it is spun
            # (rclpy.spin, any executor, a container); destroy_node stops it
            self.inputs.start()
        self._say_start(p, config)

    def _make_stream(self, p) -> StreamConfig:
        """The estimator of the parameters ``p`` (ParameterError naming a bad one): its
        settings, nav frame and stream."""
        try:
            config = self._stream_config(p)
            self._nav = config.nav_frame()
            if self._nav is not None:
                try:
                    self._nav.rate_enu()  # height and velocity within what a carrier can have
                except ValueError as exc:
                    raise SettingError("velocity_enu", f"height_m/velocity_enu: {exc}") from None
            self._stream = AttitudeStream(p["algorithm"], nav=self._nav, config=config)
        except SettingError as exc:  # the message names the setting
            raise ParameterError(f"parameter '{exc.setting}': {exc}") from exc
        except ValueError as exc:  # e.g. an Euler-angle algorithm with frame=enu
            raise ParameterError(f"parameter 'algorithm' = {p['algorithm']!r}: {exc}") from exc
        return config

    def _create_subscriptions(self, p, config) -> None:
        """The inputs: truth (start from it), odometry, magnetometer, then the Imu."""
        # every input takes the one QoS rule: best effort (the default) matches any publisher,
        # reliable ones and the best-effort republishing of a bag without offered profiles
        qos = imu_qos(p["qos_reliability"], p["qos_depth"])
        if self._truth_start is not None:
            self._subscribe(QuaternionStamped, "truth/attitude", self._on_truth, qos)
        if p["odometry_topic"]:
            if self._nav is None:
                self.get_logger().warning(
                    f"odometry_topic '{p['odometry_topic']}' is ignored with frame=inertial")
            else:
                self._sub_odom = self._subscribe(
                    Odometry, p["odometry_topic"], self._on_odometry,
                    imu_qos(p["qos_reliability"], self._ODOM_QUEUE))
        self._mag = None
        if config.aiding is Aiding.MAGNETOMETER:
            self._mag = LatestSamples(int(round(config.mag_max_age_s * 1e9)))
            self._sub_mag = self._subscribe(MagneticField, p["mag_topic"], self._on_mag, qos)
        # serialized (raw): read in place and republished with the orientation filled in
        # (ImuCdr), instead of a Python message built and serialized per sample. Subscribed
        # last: the input thread takes the other inputs' queued messages before the Imu's.
        self._sub_imu = self._subscribe(
            Imu, "imu/data_raw", self._on_imu_raw if self.inputs else self._on_imu_wakeup,
            qos, raw=True)

    def _say_start(self, p, config) -> None:
        """The start-up lines: what runs, and any retired name the user gave."""
        self.get_logger().info(
            f"integrating imu/data_raw with '{p['algorithm']}' in frame '{config.frame}' "
            f"(aiding {config.aiding}, initial attitude from {config.initial_attitude_source}, "
            f"QoS {p['qos_reliability']}/{p['qos_depth']})"
        )
        for note in config.notes():
            self.get_logger().warning(note)
        # the values given (-p, --params-file) that no declaration took: rclpy keeps them in
        # _parameter_overrides and has no public reader (undeclared ones are dropped silently)
        for name in sorted(set(self._parameter_overrides) & set(RETIRED_SETTINGS)):
            self.get_logger().warning(f"parameter {name} is ignored: {RETIRED_SETTINGS[name]}")

    def destroy_node(self):
        if self.inputs is not None:
            self.inputs.stop()  # joined before the subscriptions it waits on are destroyed
        return super().destroy_node()

    # ------------------------------------------------------------------ set-up helpers
    def _subscribe(self, msg_type, topic: str, callback, qos, raw: bool = False):
        """An input subscription: taken by the input thread when there is one, else by the
        executor."""
        if self.inputs is None:
            return self.create_subscription(msg_type, topic, callback, qos, raw=raw)
        sub = self.create_subscription(msg_type, topic, callback, qos, raw=raw,
                                       callback_group=self.inputs.group)
        self.inputs.add(sub, callback)
        return sub

    def _check_distinct_topics(self, p, config) -> None:
        """One input per topic, none on an output of this node
        (:mod:`~gyro_attitude.core.attitude.input_topics`), the names resolved (namespace and
        remappings applied)."""
        inputs = [("imu/data_raw", "imu/data_raw")]
        if self._truth_start is not None:
            inputs.append(("truth/attitude", "truth/attitude"))
        if p["odometry_topic"] and self._nav is not None:
            inputs.append(("parameter 'odometry_topic'", p["odometry_topic"]))
        if config.aiding is Aiding.MAGNETOMETER:
            inputs.append(("parameter 'mag_topic'", p["mag_topic"]))
        resolved = [(role, self._resolved(role, t)) for role, t in inputs]
        outputs = [(t, self._resolved(f"output {t}", t)) for t in OUTPUT_TOPICS]
        shared = shared_topic(outputs)
        if shared is not None:  # two outputs remapped onto one topic
            raise ParameterError(shared_output_message(*shared))
        looped = input_on_output(resolved, outputs)
        if looped is not None:
            raise ParameterError(input_on_output_message(*looped))
        shared = shared_topic(resolved)
        if shared is not None:
            raise ParameterError(shared_topic_message(*shared))

    def _resolved(self, role: str, topic: str) -> str:
        try:
            return self.resolve_topic_name(topic)
        except Exception as exc:  # rclpy's RCLError: the name cannot be a topic
            raise ParameterError(f"{role}: {topic!r} is not a valid topic name "
                                 f"({str(exc).split(',')[0]})") from exc

    @staticmethod
    def _stream_config(p) -> StreamConfig:
        return StreamConfig(**{s.name: p[s.name] for s in SETTINGS})

    def _on_set_parameters(self, params) -> SetParametersResult:
        with self._lock:
            return self._set_parameters(params)

    def _set_parameters(self, params) -> SetParametersResult:
        reason = check_update(self._specs, params)
        if reason is not None:
            return SetParametersResult(successful=False, reason=reason)
        new = dict(self._p)
        new.update({q.name: q.value for q in params if q.name in self._specs})
        if new["algorithm"] != self._stream.algorithm:
            # keep the attitude and the time base: the next sample continues from here
            try:
                self._stream.set_algorithm(new["algorithm"])
            except ValueError as exc:
                return SetParametersResult(
                    successful=False, reason=f"parameter 'algorithm' = {new['algorithm']!r}: {exc}"
                )
            self.get_logger().info(f"algorithm switched to '{new['algorithm']}'")
        try:
            self._stream.set_config(self._stream_config(new))
        except ValueError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        self._p = new
        return SetParametersResult(successful=True)

    def _warn(self, key: str, text: str) -> None:
        # throttled per reason (a flood of one bad kind must not hide another)
        now = time.monotonic()
        if now - self._last_warn.get(key, -1e9) >= 1.0:
            self._last_warn[key] = now
            self.get_logger().warning(text)

    # ------------------------------------------------------------------ callbacks
    _TRUTH_KEPT = 5000  # truth samples and Imu messages kept while waiting for the truth

    def _on_truth(self, msg: QuaternionStamped) -> None:
        if self._truth_start is None:
            return
        refused = self._truth_start.add_truth(convert.stamp_to_ns(msg.header.stamp),
                                              convert.quat_from_msg(msg.quaternion))
        if refused is not None:
            self._warn("truth", f"ignoring {refused} on truth/attitude")
            return
        self._start_from_truth()

    @property
    def skipped_before_init(self) -> int:
        """Imu samples skipped while waiting for the truth (core.attitude.truth.TruthStart)."""
        return 0 if self._truth_start is None else self._truth_start.skipped

    def _start_from_truth(self) -> None:
        """Start at the first waiting Imu sample the estimator accepts and the truth covers,
        with the truth slerped to its stamp (core.attitude.truth.TruthStart)."""
        got = self._truth_start.start()
        if got is None:
            return
        q0, waiting = got
        skipped = self._truth_start.skipped
        self._truth_start = None
        self._skipped_before_truth = skipped
        self._stream.restart(q0)
        self.get_logger().info(
            "initial attitude from truth/attitude interpolated at the Imu stamp "
            f"{waiting[0].t_ns} ns ({skipped} Imu sample(s) "
            "skipped before it)")
        for m in waiting:
            self._on_imu(m)

    _ODOM_QUEUE = 1000  # Odometry messages waiting for the Imu time line

    def _on_odometry(self, msg: Odometry) -> None:
        try:
            v_enu = convert.odometry_velocity_parent(msg)
            self._velocities.add(convert.stamp_to_ns(msg.header.stamp), v_enu)
        except ValueError as exc:
            self._warn("odometry", f"ignoring an Odometry message: {exc}")

    def _take_odometry(self) -> None:
        # The executor hands over one Odometry per wakeup while the Imu drain takes many:
        # take what is already queued in the subscription, so the velocity keeps up.
        sub = self._sub_odom
        for _ in range(self._ODOM_QUEUE):
            try:
                with sub.handle:
                    taken = sub.handle.take_message(Odometry, False)
            except Exception:  # handle destroyed at shutdown
                return
            if taken is None:
                return
            self._on_odometry(taken[0])

    def _apply_odometry(self, t_ns: int) -> None:
        """Make the newest Odometry stamped at or before ``t_ns`` the nav frame
        (core.attitude.nav_frame.VelocitySchedule)."""
        sched = self._velocities
        if not len(sched) or sched.last_t_ns < t_ns:
            self._take_odometry()  # a newer message may be waiting in the subscription
        v_enu = sched.newest_due(t_ns)
        if v_enu is None:
            return
        nav = replace(self._nav, velocity_enu=v_enu)
        try:
            self._stream.update_nav(nav)  # ω_in^n evaluated here, once per message
        except ValueError as exc:
            self._warn("odometry", f"ignoring an Odometry message: {exc}")
            return
        self._nav = nav  # also for an integrator rebuilt on an algorithm switch
        self.odometry_updates += 1

    # at most this many extra messages per wakeup, so timers (diagnostics) still run
    _DRAIN_MAX = 200

    def _on_mag(self, msg: MagneticField) -> None:
        f = msg.magnetic_field
        self._mag.add(convert.stamp_to_ns(msg.header.stamp), (f.x, f.y, f.z))

    def _on_imu_wakeup(self, raw: bytes) -> None:
        self._on_imu_raw(raw)
        if not self._drain:
            return
        # rclpy's executor rebuilds its wait set for every callback, which costs more than
        # integrating one sample; taking the messages already queued here (as the executor
        # itself does, via the subscription handle) keeps up at several kHz.
        sub = self._sub_imu
        for _ in range(self._DRAIN_MAX):
            try:
                with sub.handle:
                    taken = sub.handle.take_message(Imu, True)
            except Exception:  # handle destroyed at shutdown: the executor handles the rest
                return
            if taken is None:
                return
            self._on_imu_raw(taken[0])

    def _on_imu_raw(self, raw: bytes) -> None:
        sample = ImuCdr.parse(raw)
        if sample is None:
            # not the plain little-endian layout: rclpy reads it, and its serialization of
            # the message (the plain layout) is what the old typed path published
            try:
                sample = ImuCdr.parse(serialize_message(deserialize_message(raw, Imu)))
            except Exception as exc:  # bytes that are no Imu at all
                sample = None
                problem = f"{type(exc).__name__}: {exc}"
            else:
                problem = "unreadable layout"
            if sample is None:
                self._undecodable += 1
                self._warn("undecodable", f"skipped an Imu message that does not deserialize "
                           f"({len(raw)} bytes; {problem})")
                return
        self._on_imu(sample)

    def _on_imu(self, msg: ImuCdr) -> None:
        t_ns, frame_id = msg.t_ns, msg.frame_id
        omega, accel = msg.angular_velocity, msg.linear_acceleration
        if self._truth_start is not None:
            self._truth_start.add_sample(t_ns, omega, msg)
            self._start_from_truth()
            return
        if iv.no_estimate(msg.linear_acceleration_covariance):  # REP-145: no accelerometer
            accel = None
        elif not self._accel_watch.use_accel:
            accel = None
            self._accel_dropped += 1
        if self._sub_odom is not None:
            self._apply_odometry(t_ns)
        st = self._stream
        mag = None if self._mag is None else self._mag.at(t_ns)
        verdict, q = st.push(t_ns, omega, frame_id, msg.angular_velocity_covariance, accel, mag)
        if st.phase != self._phase_seen:
            self._phase_seen = st.phase
            self._log_phase()
        if accel is not None and q is not None:
            self._watch_accel(t_ns, accel, omega)
        if q is None:
            if verdict.rejected:
                self._warn(verdict.reason,
                           f"rejected Imu sample ({verdict.reason}): {verdict.detail}")
            return
        if not self._aiding_said:
            self._say_aiding()
        if verdict.action == iv.RESET_TIME_JUMP:
            self._warn("time_jump", f"{verdict.detail}: attitude reset")
            self._velocities.clear()  # stamps of the old time line
        elif verdict.action == iv.RESTART_AFTER_GAP:
            self._warn("gap", f"{verdict.detail}: not integrated across, attitude held")
        elif verdict.reason == iv.MISSING_SAMPLES:
            self._warn(iv.MISSING_SAMPLES, f"{verdict.detail}: integrated across")
        self._publish(msg, q)

    _aiding_said = False  # which aiding runs is said once, at the first attitude

    def _say_aiding(self) -> None:
        """Which aiding runs and why, and how the attitude started: once, at the first
        attitude (the first Imu message shows whether it carries an accelerometer)."""
        self._aiding_said = True
        st = self._stream
        for note in (st.aiding_note, st.start_note):
            if note:
                self.get_logger().info(note)

    def _watch_accel(self, t_ns: int, accel, omega) -> None:
        scale = self._accel_watch.add(t_ns, accel, omega)
        if scale is not None and not scale.ok:
            self.get_logger().error(f"{scale.problem}: the accelerometer is not used from now on "
                                    "(no rests from it, no levelling, no aiding)")

    def _log_phase(self) -> None:
        st = self._stream
        if st.phase == RUNNING and st.alignment is not None:
            self.get_logger().info(f"aligned: {alignment_summary(st.alignment)}")
        elif st.phase == FAILED:
            self.get_logger().error(f"alignment failed: {st.alignment_error}")

    def _publish(self, msg: ImuCdr, q: np.ndarray) -> None:
        x, y, z, w = from_enu_one(q.tolist(), self._world)
        # only to topics somebody subscribes to: a write without a matched reader costs the
        # middleware as much as one with (history, serialization), and is never seen (the
        # outputs are volatile: nobody joining later receives earlier samples)
        sent = False
        if self._pub_imu.get_subscription_count():
            variance = self._stream.variance
            cov = (convert.UNKNOWN_COVARIANCE if variance is None
                   else convert.covariance_from_variances(variance))
            self._pub_imu.publish(msg.with_orientation(x, y, z, w, cov))
            sent = True
        if self._pub_att.get_subscription_count():
            self._pub_att.publish(self._att_cdr.encode(msg.stamp_cdr, x, y, z, w))
            sent = True
        if self._tf is not None:
            child = self._p["tf_child_frame_id"] or msg.frame_id
            if child and child != self._world_frame:
                sent |= self._tf.send(msg.stamp_cdr, child, x, y, z, w)
            else:  # tf2 refuses an empty frame and a transform from a frame to itself
                self._warn("tf", f"no TF sent: child frame {child!r} is empty or the parent "
                           "frame (set tf_child_frame_id)")
        self._published += sent  # the samples whose attitude went out on a topic

    # ------------------------------------------------------------------ diagnostics
    def diagnostics_values(self) -> dict[str, str]:
        st = self._stream
        s = st.intervals.summary()
        counts = st.counts
        values = {
            "algorithm": st.algorithm,
            "input_rate_hz": f"{s['rate_hz']:.3f}",
            "dt_mean_s": f"{s['mean_dt_s']:.9f}",
            "dt_jitter_s": f"{s['jitter_s']:.9f}",
            "dt_max_s": f"{s['max_dt_s']:.9f}",
            "accepted": str(st.accepted),
            "published": str(self._published),
            "undecodable_messages": str(self._undecodable),
            "rejected_total": str(st.rejected_total),
            "time_jump_resets": str(st.time_jump_resets),
            "skipped_before_initial_attitude": str(self._skipped_before_truth
                                                   if self._truth_start is None
                                                   else self.skipped_before_init),
            "integrator_errors": str(counts[INTEGRATOR_ERROR]),
            "missing_samples": str(counts[iv.MISSING_SAMPLES]),
            "saturated": str(counts[SATURATED]),
            "rate_fit_fallbacks": str(counts[RATE_FIT_FALLBACK]),
            "invalid_covariances": str(counts[INVALID_COVARIANCE]),
            "odometry_updates": str(self.odometry_updates),
            "invalid_accels": str(counts[INVALID_ACCEL]),
            "accel_units": ("watching" if self._accel_watch.verdict is None else "m/s²"
                            if self._accel_watch.verdict.ok else "not m/s²: not used"),
            "accels_not_used": str(self._accel_dropped),
            "phase": st.phase,
        }
        if self._mag is not None:
            aid = st.aiding
            values["mag_missing"] = str(counts[MAG_MISSING])
            values["invalid_mags"] = str(counts[INVALID_MAG])
            values["mag_disturbed"] = str(counts[MAG_DISTURBED])
            values["mag_reference"] = ("learning" if aid.mag_ref_norm is None else
                                       f"|B| {aid.mag_ref_norm * 1e6:.2f} uT, dip "
                                       f"{math.degrees(aid.mag_ref_dip or 0.0):.2f} deg")
            values["mag_hard_iron_t"] = _vec(aid.hard_iron)
        rep = st.bias_report
        values["gyro_bias_mode"] = rep.mode
        values["gyro_bias_rad_s"] = _vec(rep.bias)
        values["gyro_bias_std_error_rad_s"] = _vec(rep.standard_error)
        values["gyro_bias_rests_used"] = str(rep.rests_used)
        values["earth_rate"] = ("removed from the bias" if rep.earth_rate_removed else
                                "absorbed into the bias" if rep.rests_used else "n/a")
        values["gyro_bias_note"] = rep.note
        if st.alignment is not None:
            values["alignment"] = alignment_summary(st.alignment)
        elif st.phase == ALIGNING:
            values["alignment"] = st.alignment_error or (
                f"aligning: keep the IMU still for {st.config.min_rest_s:g} s, then move")
        elif st.phase == FAILED:
            values["alignment"] = f"failed: {st.alignment_error}"
        for reason in iv.REJECT_REASONS:
            values[f"rejected_{reason}" if reason != iv.GAP else "gaps"] = str(counts[reason])
        return values

    def _publish_diagnostics(self) -> None:
        with self._lock:
            self._publish_diagnostics_locked()

    def _publish_diagnostics_locked(self) -> None:
        v = self._stream
        values = self.diagnostics_values()
        new_rejected = v.rejected_total - self._last_period_rejected
        new_accepted = v.accepted - self._last_period_accepted
        self._last_period_rejected = v.rejected_total
        self._last_period_accepted = v.accepted
        status = DiagnosticStatus()
        status.name = f"{self.get_name()}: imu input"
        status.hardware_id = v.frame_id or ""
        if v.phase == FAILED:
            status.level = DiagnosticStatus.ERROR
            status.message = f"alignment failed: {v.alignment_error}"
        elif v.phase == ALIGNING and new_accepted > 0:
            status.level = DiagnosticStatus.OK
            status.message = values["alignment"]
        elif new_rejected > 0:
            status.level = DiagnosticStatus.WARN
            status.message = f"{new_rejected} sample(s) rejected in the last period"
        elif new_accepted == 0:
            status.level = DiagnosticStatus.WARN
            status.message = "no Imu input" if v.accepted == 0 else "Imu input stalled"
        else:
            status.level = DiagnosticStatus.OK
            status.message = f"integrating at {values['input_rate_hz']} Hz"
        status.values = [KeyValue(key=k, value=val) for k, val in values.items()]
        arr = DiagnosticArray()
        arr.header.stamp = self.get_clock().now().to_msg()
        arr.status = [status]
        self._pub_diag.publish(arr)


def _vec(x) -> str:
    return "[" + ", ".join(f"{float(c):.6g}" for c in x) + "]"


def alignment_summary(res) -> str:
    """One line on an alignment result (degrees)."""
    heading = f"{math.degrees(res.heading):.2f}° ({res.heading_source}"
    if res.heading_source in ("gyrocompass", "magnetometer"):
        heading += f", ±{math.degrees(res.heading_error_expected):.2g}°"
    return (f"roll {math.degrees(res.roll):.2f}°, pitch {math.degrees(res.pitch):.2f}° "
            f"(±{math.degrees(res.level_error_expected):.2g}°), heading {heading}) over "
            f"{res.samples} rest samples")


def main(args=None) -> int:
    """Spin the node until SIGINT/SIGTERM; exit 0, or 2 on an invalid parameter."""
    return run_node(NODE_NAME, AttitudeIntegratorNode, args, spin=spin_with_inputs)



if __name__ == "__main__":
    sys.exit(main())
