"""ROS 2 node ``attitude_integrator``: integrate ``imu/data_raw`` rates into attitude.

Subscribes ``imu/data_raw`` (sensor_msgs/Imu, ω_ib^b in rad/s) and, when
``initial_attitude_source`` is ``truth``, ``truth/attitude`` (geometry_msgs/QuaternionStamped,
q_nb) once to take the starting attitude, and with ``frame: enu`` and a non-empty
``odometry_topic`` a nav_msgs/Odometry topic whose velocity sets the transport rate (below).
Publishes

* ``imu/data``: the input Imu with ``orientation`` filled (q_ib for ``frame: inertial``,
  q_nb for ``frame: enu``) and an orientation covariance that grows with the gyro noise
  (angle-random-walk growth: per axis, variance += gyro variance · dt² per sample, with
  the gyro variance taken from the input's ``angular_velocity_covariance`` diagonal; all
  zeros = unknown when the input carries no covariance);
* ``attitude``: geometry_msgs/QuaternionStamped, same quaternion, header frame =
  ``world_frame_id``;
* ``/diagnostics``: diagnostic_msgs/DiagnosticArray about every ``diagnostics_period_s``:
  input rate, dt jitter, accepted samples and rejected samples by reason.

Every input sample passes :class:`gyro_attitude.core.imu_validation.ImuStreamValidator`
first: non-finite values, zero/duplicate/out-of-order stamps and a changed frame_id are
rejected (counted, warned at most once per second per reason); a gap longer than
``max_gap_s`` is not integrated across (attitude held, time base restarted); a backward
time jump beyond ``time_jump_threshold_s`` resets the attitude to the initial one. The
attitude therefore never becomes NaN.

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

import sys
import time
from collections import deque

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import QuaternionStamped
from nav_msgs.msg import Odometry
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Imu
from std_msgs.msg import Header

from gyro_attitude.core import imu_validation as iv
from gyro_attitude.core.rotation import quat_normalize
from gyro_attitude.ros import convert
from gyro_attitude.ros.node_main import run_node
from gyro_attitude.ros.params import ParameterError, ParamSpec, check_update, declare_all
from gyro_attitude.ros.qos import imu_qos

NODE_NAME = "attitude_integrator"


def _algorithms():
    """The attitude algorithm registry (imported lazily so this module imports without it)."""
    from gyro_attitude.core.integrate import ALGORITHMS, DEFAULT_ALGORITHM

    return ALGORITHMS, DEFAULT_ALGORITHM


def parameter_specs() -> list[ParamSpec]:
    algorithms, default_algorithm = _algorithms()
    return [
        ParamSpec("algorithm", default_algorithm,
                  "attitude update algorithm (gyro-attitude bench lists them)",
                  choices=tuple(algorithms), runtime=True),
        ParamSpec("frame", "inertial",
                  "'inertial': integrate q_ib; 'enu': q_nb with Earth and transport rate removed",
                  choices=("inertial", "enu")),
        ParamSpec("latitude_rad", 0.0, "geodetic latitude for frame=enu [rad]",
                  low=-1.5707963267948966, high=1.5707963267948966),
        ParamSpec("longitude_rad", 0.0, "longitude for frame=enu [rad]",
                  low=-3.141592653589793, high=3.141592653589793),
        ParamSpec("height_m", 0.0, "height above the WGS-84 ellipsoid for frame=enu [m]",
                  low=-1.0e4, high=1.0e6),
        ParamSpec("velocity_enu", (0.0, 0.0, 0.0),
                  "carrier velocity (east, north, up) for frame=enu [m/s]", length=3),
        ParamSpec("odometry_topic", "",
                  "nav_msgs/Odometry topic giving the carrier velocity for the transport "
                  "rate (frame=enu; twist in child_frame_id, rotated to ENU with the pose "
                  "orientation); '' = off, velocity_enu is used"),
        ParamSpec("initial_attitude_source", "parameter",
                  "'parameter': initial_attitude; 'truth': first truth/attitude message "
                  "whose stamp equals an Imu stamp", choices=("parameter", "truth")),
        ParamSpec("initial_attitude", (0.0, 0.0, 0.0, 1.0),
                  "initial attitude quaternion (x, y, z, w), normalized on use", length=4),
        ParamSpec("initial_attitude_variance", 0.0,
                  "initial per-axis attitude variance [rad^2]", low=0.0, high=10.0),
        ParamSpec("world_frame_id", "",
                  "header.frame_id of the attitude output ('' = 'enu' or 'inertial' per frame)"),
        ParamSpec("qos_reliability", "best_effort",
                  "imu/data_raw subscription reliability", choices=("best_effort", "reliable")),
        ParamSpec("qos_depth", 1000, "imu/data_raw subscription queue depth", low=1,
                  high=100000),
        ParamSpec("time_jump_threshold_s", 1.0,
                  "a backward stamp jump longer than this resets the attitude [s]",
                  low=1e-6, high=1e6, runtime=True),
        ParamSpec("max_gap_s", 0.1, "a forward stamp step longer than this is a gap [s]",
                  low=1e-6, high=1e6, runtime=True),
        ParamSpec("drain_queue", True,
                  "take all queued Imu messages per executor wakeup (less overhead at high "
                  "rates); false: one message per wakeup (plain rclpy)"),
        ParamSpec("diagnostics_period_s", 1.0, "period of /diagnostics [s]", low=0.01,
                  high=3600.0),
    ]


class AttitudeIntegratorNode(Node):
    """Thin ROS wrapper around ``StreamingIntegrator`` + ``ImuStreamValidator``."""

    def __init__(self, **kwargs):
        super().__init__(NODE_NAME, **kwargs)
        specs = parameter_specs()
        self._specs = {s.name: s for s in specs}
        p = declare_all(self, specs)  # raises ParameterError naming a bad parameter
        self._p = p
        q0 = np.asarray(p["initial_attitude"], dtype=float)
        if not np.linalg.norm(q0) > 1e-9:
            raise ParameterError("parameter 'initial_attitude' must be a nonzero quaternion")
        self._q_init = quat_normalize(q0)
        self._nav = None
        if p["frame"] == "enu":
            from gyro_attitude.core.integrate import NavFrame

            self._nav = NavFrame(
                latitude_rad=p["latitude_rad"],
                longitude_rad=p["longitude_rad"],
                height_m=p["height_m"],
                velocity_enu=np.asarray(p["velocity_enu"], dtype=float),
            )
        self._world_frame = p["world_frame_id"] or p["frame"]
        self._algorithm = p["algorithm"]
        try:
            self._integrator = self._make_integrator(self._q_init)
        except ValueError as exc:  # e.g. an Euler-angle algorithm with frame=enu
            raise ParameterError(f"parameter 'algorithm' = {self._algorithm!r}: {exc}") from exc
        # attitude to start from at the next START verdict instead of the initial one
        # (after an integrator error the attitude is kept)
        self._resume_q: np.ndarray | None = None
        self._validator = iv.ImuStreamValidator(self._check_config(p))
        self._intervals = iv.IntervalStatistics(window=2000)
        self._awaiting_truth = p["initial_attitude_source"] == "truth"
        self._truth_by_stamp: dict[int, np.ndarray] = {}
        self._truth_order: deque[int] = deque()
        self._pending: deque[Imu] = deque(maxlen=5000)
        self.skipped_before_init = 0
        self.integrator_errors = 0
        self._angle_var = np.full(3, p["initial_attitude_variance"])
        self._gyro_var_known = False
        self._last_warn: dict[str, float] = {}
        self._last_period_rejected = 0
        self._last_period_accepted = 0
        self._published = 0
        self.odometry_updates = 0
        self._sub_odom = None
        # (stamp ns, NavFrame) of received Odometry not yet applied, in stamp order
        self._odom_queue: deque = deque(maxlen=self._ODOM_QUEUE)

        self._pub_imu = self.create_publisher(Imu, "imu/data", 100)
        self._pub_att = self.create_publisher(QuaternionStamped, "attitude", 100)
        self._pub_diag = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self._sub_imu = self.create_subscription(
            Imu, "imu/data_raw", self._on_imu_wakeup,
            imu_qos(p["qos_reliability"], p["qos_depth"]),
        )
        if self._awaiting_truth:
            self.create_subscription(QuaternionStamped, "truth/attitude", self._on_truth, 1000)
        if p["odometry_topic"]:
            if self._nav is None:
                self.get_logger().warning(
                    f"odometry_topic '{p['odometry_topic']}' is ignored with frame=inertial")
            else:
                self._sub_odom = self.create_subscription(
                    Odometry, p["odometry_topic"], self._on_odometry,
                    QoSProfile(depth=self._ODOM_QUEUE, reliability=ReliabilityPolicy.RELIABLE))
        self.create_timer(p["diagnostics_period_s"], self._publish_diagnostics)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.get_logger().info(
            f"integrating imu/data_raw with '{self._algorithm}' in frame '{p['frame']}' "
            f"(initial attitude from {p['initial_attitude_source']}, "
            f"QoS {p['qos_reliability']}/{p['qos_depth']})"
        )

    # ------------------------------------------------------------------ set-up helpers
    @staticmethod
    def _check_config(p) -> iv.ImuCheckConfig:
        return iv.ImuCheckConfig(
            max_gap_ns=int(round(p["max_gap_s"] * 1e9)),
            time_jump_ns=int(round(p["time_jump_threshold_s"] * 1e9)),
        )

    def _make_integrator(self, q0, t0_ns: int | None = None):
        from gyro_attitude.core.integrate import StreamingIntegrator

        return StreamingIntegrator(algorithm=self._algorithm, q0=q0, nav=self._nav, t0_ns=t0_ns)

    def _on_set_parameters(self, params) -> SetParametersResult:
        reason = check_update(self._specs, params)
        if reason is not None:
            return SetParametersResult(successful=False, reason=reason)
        new = dict(self._p)
        new.update({q.name: q.value for q in params if q.name in self._specs})
        if new["algorithm"] != self._algorithm:
            # keep the attitude and the time base: the next sample continues from here
            q_now = self._integrator.quaternion
            old = self._algorithm
            self._algorithm = new["algorithm"]
            try:
                integrator = self._make_integrator(q_now, self._integrator.last_t_ns)
            except ValueError as exc:
                self._algorithm = old
                return SetParametersResult(
                    successful=False, reason=f"parameter 'algorithm' = {new['algorithm']!r}: {exc}"
                )
            self._integrator = integrator
            self.get_logger().info(f"algorithm switched to '{self._algorithm}'")
        self._validator.config = self._check_config(new)
        self._p = new
        return SetParametersResult(successful=True)

    def _warn(self, key: str, text: str) -> None:
        # throttled per reason (a flood of one bad kind must not hide another)
        now = time.monotonic()
        if now - self._last_warn.get(key, -1e9) >= 1.0:
            self._last_warn[key] = now
            self.get_logger().warning(text)

    # ------------------------------------------------------------------ callbacks
    def _on_truth(self, msg: QuaternionStamped) -> None:
        if not self._awaiting_truth:
            return
        t_ns = convert.stamp_to_ns(msg.header.stamp)
        q = convert.quat_from_msg(msg.quaternion)
        if not np.all(np.isfinite(q)) or np.linalg.norm(q) < 1e-9:
            self._warn("truth", "ignoring a non-finite or zero truth/attitude quaternion")
            return
        self._truth_by_stamp[t_ns] = q / np.linalg.norm(q)
        self._truth_order.append(t_ns)
        while len(self._truth_order) > 5000:
            self._truth_by_stamp.pop(self._truth_order.popleft(), None)
        # an Imu sample with this stamp may already be waiting
        pending = list(self._pending)
        for j, m in enumerate(pending):
            if convert.stamp_to_ns(m.header.stamp) in self._truth_by_stamp:
                self.skipped_before_init += j
                self._pending.clear()
                for later in pending[j:]:
                    self._on_imu(later)
                return

    _ODOM_QUEUE = 1000  # Odometry messages waiting for the Imu time line

    def _on_odometry(self, msg: Odometry) -> None:
        from gyro_attitude.core.integrate import NavFrame

        try:
            v_enu = convert.odometry_velocity_parent(msg)
        except ValueError as exc:
            self._warn("odometry", f"ignoring an Odometry message: {exc}")
            return
        nav = NavFrame(latitude_rad=self._nav.latitude_rad,
                       longitude_rad=self._nav.longitude_rad,
                       height_m=self._nav.height_m, velocity_enu=v_enu)
        t_ns = convert.stamp_to_ns(msg.header.stamp)
        q = self._odom_queue
        if q and t_ns < q[-1][0]:  # out of order: keep the queue sorted by stamp
            items = sorted([*q, (t_ns, nav)], key=lambda item: item[0])
            q.clear()
            q.extend(items)
        else:
            q.append((t_ns, nav))

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
        """Make the newest queued Odometry stamped at or before ``t_ns`` the nav frame."""
        q = self._odom_queue
        if not q or q[-1][0] < t_ns:
            self._take_odometry()  # a newer message may be waiting
        nav = None
        while q and q[0][0] <= t_ns:
            nav = q.popleft()[1]
        if nav is None:
            return
        try:
            self._integrator.update_nav(nav)  # ω_in^n evaluated here, once per message
        except ValueError as exc:
            self._warn("odometry", f"ignoring an Odometry message: {exc}")
            return
        self._nav = nav  # also for an integrator rebuilt on an algorithm switch
        self.odometry_updates += 1

    # at most this many extra messages per wakeup, so timers (diagnostics) still run
    _DRAIN_MAX = 200

    def _on_imu_wakeup(self, msg: Imu) -> None:
        self._on_imu(msg)
        if not self._p["drain_queue"]:
            return
        # rclpy's executor rebuilds its wait set for every callback, which costs more than
        # integrating one sample; taking the messages already queued here (as the executor
        # itself does, via the subscription handle) keeps up at several kHz.
        sub = self._sub_imu
        for _ in range(self._DRAIN_MAX):
            try:
                with sub.handle:
                    taken = sub.handle.take_message(Imu, False)
            except Exception:  # handle destroyed at shutdown: the executor handles the rest
                return
            if taken is None:
                return
            self._on_imu(taken[0])

    def _on_imu(self, msg: Imu) -> None:
        t_ns, frame_id, omega, _ = convert.imu_arrays(msg)
        if self._awaiting_truth:
            q_truth = self._truth_by_stamp.get(t_ns)
            if q_truth is None:
                self._pending.append(msg)
                return
            self._awaiting_truth = False
            self._q_init = q_truth
            self._truth_by_stamp.clear()
            self._truth_order.clear()
            self._validator.reset()
            self.get_logger().info("initial attitude taken from truth/attitude")
        verdict = self._validator.check(t_ns, omega, frame_id)
        if verdict.rejected:
            self._warn(verdict.reason, f"rejected Imu sample ({verdict.reason}): {verdict.detail}")
            return
        if self._sub_odom is not None:
            if verdict.action == iv.RESET_TIME_JUMP:
                self._odom_queue.clear()  # stamps of the old time line
            else:
                self._apply_odometry(t_ns)
        last_t = self._integrator.last_t_ns
        try:
            if verdict.action == iv.ACCEPT:
                q = self._integrator.update(t_ns, omega)
                dt_s = (t_ns - last_t) * 1e-9 if last_t is not None else 0.0
                self._intervals.add(t_ns - last_t if last_t is not None else 0)
                self._grow_covariance(msg, dt_s)
            else:
                if verdict.action == iv.RESET_TIME_JUMP:
                    self._warn("time_jump", f"{verdict.detail}: attitude reset")
                    q0 = self._q_init
                    self._angle_var = np.full(3, self._p["initial_attitude_variance"])
                    self._intervals.clear()
                elif verdict.action == iv.RESTART_AFTER_GAP:
                    self._warn("gap", f"{verdict.detail}: not integrated across, attitude held")
                    q0 = self._integrator.quaternion
                else:  # START
                    q0 = self._q_init if self._resume_q is None else self._resume_q
                    self._resume_q = None
                self._integrator.reset(q0, None)
                q = self._integrator.update(t_ns, omega)
        except ValueError as exc:  # defensive: the validator should have caught it
            self.integrator_errors += 1
            self._warn("integrator", f"integrator refused a sample ({exc}); restarting")
            self._resume_q = self._integrator.quaternion
            self._validator.reset()
            return
        self._publish(msg, t_ns, q)

    def _grow_covariance(self, msg: Imu, dt_s: float) -> None:
        var = convert.variances_from_covariance(msg.angular_velocity_covariance)
        if var is None:
            return
        self._gyro_var_known = True
        # angle random walk: each sample adds an independent angle error of variance
        # σ_ω² dt² per axis, so the variance grows linearly in time (σ_ω² dt · T).
        self._angle_var += var * (dt_s * dt_s)

    def _publish(self, msg: Imu, t_ns: int, q: np.ndarray) -> None:
        x, y, z, w = q.tolist()
        o = msg.orientation
        o.x, o.y, o.z, o.w = x, y, z, w
        if self._gyro_var_known:
            msg.orientation_covariance = convert.covariance_from_variances(self._angle_var)
        else:
            msg.orientation_covariance = list(convert.UNKNOWN_COVARIANCE)
        self._pub_imu.publish(msg)
        att = QuaternionStamped()
        att.header = Header(stamp=msg.header.stamp, frame_id=self._world_frame)
        a = att.quaternion
        a.x, a.y, a.z, a.w = x, y, z, w
        self._pub_att.publish(att)
        self._published += 1

    # ------------------------------------------------------------------ diagnostics
    def diagnostics_values(self) -> dict[str, str]:
        s = self._intervals.summary()
        v = self._validator
        values = {
            "algorithm": self._algorithm,
            "input_rate_hz": f"{s['rate_hz']:.3f}",
            "dt_mean_s": f"{s['mean_dt_s']:.9f}",
            "dt_jitter_s": f"{s['jitter_s']:.9f}",
            "dt_max_s": f"{s['max_dt_s']:.9f}",
            "accepted": str(v.accepted),
            "published": str(self._published),
            "rejected_total": str(v.rejected_total),
            "time_jump_resets": str(v.time_jump_resets),
            "skipped_before_initial_attitude": str(self.skipped_before_init),
            "integrator_errors": str(self.integrator_errors),
            "odometry_updates": str(self.odometry_updates),
        }
        for reason in iv.REJECT_REASONS:
            values[f"rejected_{reason}" if reason != iv.GAP else "gaps"] = str(v.counts[reason])
        return values

    def _publish_diagnostics(self) -> None:
        v = self._validator
        values = self.diagnostics_values()
        new_rejected = v.rejected_total - self._last_period_rejected
        new_accepted = v.accepted - self._last_period_accepted
        self._last_period_rejected = v.rejected_total
        self._last_period_accepted = v.accepted
        status = DiagnosticStatus()
        status.name = f"{self.get_name()}: imu input"
        status.hardware_id = v.frame_id or ""
        if new_rejected > 0:
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


def main(args=None) -> int:
    """Spin the node until SIGINT/SIGTERM; exit 0, or 2 on an invalid parameter."""
    return run_node(NODE_NAME, AttitudeIntegratorNode, args)



if __name__ == "__main__":
    sys.exit(main())
