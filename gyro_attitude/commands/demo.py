"""``gyro-attitude demo``: gyro_sim + attitude_integrator on a scene, recorded and summarized.

Default scene: ``coning`` (classical coning, 1° half-angle at 10 Hz, Earth rotation off),
whose truth is the closed form of docs/equations.md: the attitude is periodic, so any error of the
integrated attitude against ``truth/attitude`` is algorithm error.

The two nodes run as separate processes started the way ``ros2 run`` does (ament index →
``<prefix>/lib/gyro_attitude/<exe>``; ``python -m gyro_attitude.ros.<exe>_node`` when the
package is not installed). DDS stays on loopback (``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``)
on a ROS_DOMAIN_ID of its own unless the user's environment sets them. gyro_sim records
its topics in-process to ``bags/demo_<scene>_<UTC time>.mcap``; this command listens to
``attitude``, ``truth/attitude`` and ``/diagnostics``, prints a summary (samples, rates,
attitude error against truth over time) and writes a PNG of the error versus time.
"""

from __future__ import annotations

import argparse
import math
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from datetime import UTC, datetime
from pathlib import Path

from gyro_attitude.commands import error_line
from gyro_attitude.core.attitude import causal_algorithms
from gyro_attitude.core.rotation import quat_angle_between
from gyro_attitude.io.ament_prefix import node_command, node_environment
from gyro_attitude.io.cdr_arrays import QuaternionStampedCdr
from gyro_attitude.io.safe_output import OutputPathError, SafeOutput, check_output_path
from gyro_attitude.io.scene_file import load_scene

PACKAGE = "gyro_attitude"
DEFAULT_SCENE = "coning"
PROG = "gyro-attitude demo"


MIN_SAMPLES = 2  # an attitude error needs at least one integrated interval
SETTLE_QUIET_S = 0.5  # after the sim: no new attitude for this long means the integrator is done
SETTLE_MAX_S = 15.0  # ... and never longer than this


def _gyro_sim_limit(name: str) -> float:
    """Upper bound of gyro_sim's parameter ``name`` (its parameter table is the one home of
    the limit). Loaded lazily: the node module imports rclpy, which ``--help`` need not pay."""
    from gyro_attitude.ros.gyro_sim_node import parameter_specs

    (spec,) = [s for s in parameter_specs() if s.name == name]
    return float(spec.high)


def _positive_up_to(param: str, unit: str):
    """argparse type: a finite float in (0, gyro_sim's limit of ``param``]."""
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
        high = _gyro_sim_limit(param)
        if not (math.isfinite(value) and 0.0 < value <= high):
            raise argparse.ArgumentTypeError(
                f"must be finite, > 0 and <= {high:g} {unit} (gyro_sim's {param} limit), "
                f"got {text}")
        return value
    return parse


def _png_path(text: str) -> Path:
    """argparse type: a path ending in .png (the plot is written as PNG only)."""
    if Path(text).suffix.lower() != ".png":
        raise argparse.ArgumentTypeError(f"must end in .png, got {text!r}")
    return Path(text)


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--scene", default=DEFAULT_SCENE,
                        help=f"scene name or YAML path (default {DEFAULT_SCENE}: closed-form truth)")
    parser.add_argument("--duration", type=_positive_up_to("duration_s", "s"), default=10.0,
                        help="simulated seconds (default 10)")
    parser.add_argument("--rate", type=_positive_up_to("rate_hz", "Hz"), default=None,
                        help="Imu rate in Hz (default: the scene's own rate)")
    parser.add_argument("--algorithm", default=None, choices=sorted(causal_algorithms()),
                        metavar="NAME",
                        help="attitude algorithm (default: the integrator's default): "
                             + ", ".join(sorted(causal_algorithms())))
    parser.add_argument("--bag-dir", default="bags", help="where the MCAP recording goes")
    parser.add_argument("--plot", default=None, type=_png_path,
                        help="PNG path of the error plot (default: next to the recording)")
    parser.add_argument("--force", action="store_true", help="overwrite an existing --plot")
    parser.add_argument("--reliable", action="store_true",
                        help="reliable QoS on imu/data_raw (default: best effort, sensor data)")
    parser.add_argument("--no-record", action="store_true", help="do not record MCAP")


def _integrator_params(spec, algorithm: str | None, reliable: bool) -> list[str]:
    args = ["-p", "initial_attitude_source:=truth", "-p", "diagnostics_period_s:=0.5"]
    if algorithm:
        args += ["-p", f"algorithm:={algorithm}"]
    if reliable:
        args += ["-p", "qos_reliability:=reliable"]
    earth = spec.earth
    if earth.rotation or (earth.transport_rate and spec.motion.moves):
        # the scene's gyro sees Earth (and transport) rate: integrate q_nb in ENU from the
        # start position; the velocity for the transport rate follows truth/odom (the
        # initial velocity covers the samples before the first odometry message).
        import numpy as np

        v0 = [float(v) for v in np.asarray(spec.motion.velocity(np.zeros(1)))[0]]
        args += ["-p", "frame:=enu", "-p", f"latitude_rad:={earth.latitude_rad!r}",
                 "-p", f"velocity_enu:=[{v0[0]!r}, {v0[1]!r}, {v0[2]!r}]",
                 "-p", f"longitude_rad:={earth.longitude_rad!r}",
                 "-p", f"height_m:={float(earth.height_m)!r}",
                 "-p", "world_frame_id:=enu"]
        if earth.transport_rate and spec.motion.moves:
            args += ["-p", "odometry_topic:=truth/odom"]
    else:
        # no Earth rate: n is inertial and q_ib = q_nb
        args += ["-p", "world_frame_id:=enu"]
    return args


def _stop(proc: subprocess.Popen, timeout: float = 10.0) -> int:
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(timeout=5)
    return proc.returncode


def _prepare_outputs(args, spec, stamp: str):
    """Check and create the output locations before any work: (bag, plot) or a reason."""
    bag_dir = Path(args.bag_dir)
    try:
        if bag_dir.exists() and not bag_dir.is_dir():
            return f"--bag-dir {bag_dir}: not a directory"
        if not args.no_record or args.plot is None:
            bag_dir.mkdir(parents=True, exist_ok=True)
            if not os.access(bag_dir, os.W_OK | os.X_OK):
                return f"--bag-dir {bag_dir}: not writable"
        plot = args.plot or bag_dir / f"demo_{spec.name}_{stamp}_error.png"
        if not plot.is_dir():  # a directory is refused by the check below, not created
            plot.parent.mkdir(parents=True, exist_ok=True)
        check_output_path(plot, force=args.force, what="--plot")
    except OutputPathError as exc:
        return str(exc)
    except OSError as exc:  # e.g. a read-only or foreign directory on the way
        return f"{exc.filename}: {exc.strerror or exc}"
    bag = None if args.no_record else bag_dir / f"demo_{spec.name}_{stamp}.mcap"
    return bag, plot


def _last_line(log: Path) -> str:
    """The last non-empty line a node wrote (its one-line error on a bad parameter)."""
    try:
        lines = [ln for ln in log.read_text(errors="replace").splitlines() if ln.strip()]
    except OSError:
        return ""
    return lines[-1].strip() if lines else ""


def run(args: argparse.Namespace) -> int:
    try:
        spec = load_scene(args.scene)
    except (ValueError, OSError) as exc:
        error_line("demo", f"--scene {args.scene!r}: {exc}")
        return 2
    rate = args.rate if args.rate is not None else float(spec.rate_hz)
    n_samples = int(round(args.duration * rate))
    if n_samples < MIN_SAMPLES:
        # gyro_sim reads 0 samples as "run forever"
        error_line("demo", f"--duration {args.duration:g} s at {rate:g} Hz gives {n_samples} "
                   f"samples; need at least {MIN_SAMPLES}")
        return 2
    stamp = datetime.now(UTC).strftime("%Y%m%dT%H%M%SZ")
    prepared = _prepare_outputs(args, spec, stamp)
    if isinstance(prepared, str):
        error_line("demo", prepared)
        return 1
    bag, plot = prepared
    env = node_environment()
    # this process joins the same graph: set before rclpy.init
    for key in ("ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_DOMAIN_ID", "AMENT_PREFIX_PATH"):
        os.environ[key] = env[key]

    print(f"[demo] scene '{spec.name}': {spec.description}")
    print(f"[demo] {args.duration:g} s at {rate:g} Hz; ROS_DOMAIN_ID={env['ROS_DOMAIN_ID']}, "
          f"discovery {env['ROS_AUTOMATIC_DISCOVERY_RANGE']}")
    print(f"[demo] nodes: {' '.join(node_command('gyro_sim'))}, "
          f"{' '.join(node_command('attitude_integrator'))}")

    import rclpy
    import rclpy.executors
    from diagnostic_msgs.msg import DiagnosticArray
    from geometry_msgs.msg import QuaternionStamped
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import Imu

    # ROS modules load rclpy: imported only when the demo runs (not for --help)
    from gyro_attitude.ros.qos import imu_qos

    # node output, for a post-mortem: beside the recording, or a temporary folder (removed
    # after a clean run) when not recording
    if bag is not None:
        log_dir = bag.parent / f"demo_{spec.name}_{stamp}_logs"
        log_dir.mkdir(exist_ok=True)
    else:
        log_dir = Path(tempfile.mkdtemp(prefix=f"gyro_attitude_demo_{spec.name}_"))
    integ_log_path = log_dir / f"attitude_integrator_{stamp}.log"
    sim_log_path = log_dir / f"gyro_sim_{stamp}.log"
    sim_code: int | None = None
    procs: list[subprocess.Popen] = []
    context = None
    try:
        rclpy.init(domain_id=int(env["ROS_DOMAIN_ID"]))
        context = True
        node = rclpy.create_node("gyro_attitude_demo")
        # One executor for the whole run (rclpy.spin_once(node) adds and removes the node on
        # every call), and serialized subscriptions whose callbacks only keep the bytes: at
        # 1 kHz on three topics a deserializing Python monitor falls behind on a loaded
        # machine, and a reliable keep-last publisher then overwrites what it has not acked.
        # The bytes are decoded after the run.
        executor = rclpy.executors.SingleThreadedExecutor()
        executor.add_node(node)
        qos = QoSProfile(depth=20000, reliability=ReliabilityPolicy.RELIABLE)
        truth_raw: list[bytes] = []
        attitude_raw: list[bytes] = []
        diagnostics: list[dict[str, str]] = []

        def on_diag(m):
            for s in m.status:
                if s.name.endswith("attitude_integrator: imu input"):
                    diagnostics.append({kv.key: kv.value for kv in s.values})

        raw_count = [0]

        def on_raw(_m):
            raw_count[0] += 1

        # the sim starts once both the integrator and this monitor listen to imu/data_raw;
        # the monitor takes the run's reliability, so a reliable run is counted losslessly
        node.create_subscription(
            Imu, "imu/data_raw", on_raw,
            imu_qos("reliable" if args.reliable else "best_effort", 20000), raw=True)
        node.create_subscription(QuaternionStamped, "truth/attitude", truth_raw.append, qos,
                                 raw=True)
        att_sub = node.create_subscription(QuaternionStamped, "attitude", attitude_raw.append,
                                           qos, raw=True)
        node.create_subscription(DiagnosticArray, "/diagnostics", on_diag, 50)

        integ_log = open(integ_log_path, "w")
        sim_log = open(sim_log_path, "w")
        integ = subprocess.Popen(
            node_command("attitude_integrator") + ["--ros-args"]
            + _integrator_params(spec, args.algorithm, args.reliable),
            env=env, stdout=integ_log, stderr=subprocess.STDOUT, start_new_session=True)
        procs.append(integ)
        # The sim waits for its subscribers, but nothing waits for the integrator's attitude
        # publisher to match this monitor: on a loaded machine discovery can take longer than a
        # short run, and every attitude would be lost. Start the sim once it has matched.
        match_deadline = time.monotonic() + 30.0
        while (att_sub.get_publisher_count() < 1 and integ.poll() is None
               and time.monotonic() < match_deadline):
            executor.spin_once(timeout_sec=0.05)
        if integ.poll() is not None:  # e.g. a parameter it refused: no point starting the sim
            integ_log.close()
            return _node_failed("attitude_integrator", integ.returncode, integ_log_path)
        sim_args = ["-p", f"scene:={args.scene}", "-p", f"rate_hz:={rate!r}",
                    "-p", f"duration_s:={args.duration!r}", "-p", "wait_for_subscribers:=2",
                    "-p", "wait_timeout_s:=30.0"]
        if bag is not None:
            sim_args += ["-p", f"record_path:={bag.resolve()}"]
        if args.reliable:
            sim_args += ["-p", "qos_reliability:=reliable"]
        t_wall = time.monotonic()
        sim = subprocess.Popen(node_command("gyro_sim") + ["--ros-args"] + sim_args, env=env,
                               stdout=sim_log, stderr=subprocess.STDOUT, start_new_session=True)
        procs.append(sim)
        deadline = time.monotonic() + args.duration * 3 + 60
        while sim.poll() is None and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
            if integ.poll() is not None:
                break
        # the last attitudes and one more diagnostics message: at least 1 s, and on a loaded
        # machine until the integrator has caught up with what the sim published (no new
        # attitude for SETTLE_QUIET_S), at most SETTLE_MAX_S
        t_sim_done = last_change = time.monotonic()
        seen = len(attitude_raw)
        while True:
            executor.spin_once(timeout_sec=0.05)
            now = time.monotonic()
            if len(attitude_raw) != seen:
                seen, last_change = len(attitude_raw), now
            if now - t_sim_done >= SETTLE_MAX_S or (
                    now - t_sim_done >= 1.0 and now - last_change >= SETTLE_QUIET_S):
                break
        wall = time.monotonic() - t_wall
        if sim.poll() is None:
            try:
                sim_code = sim.wait(timeout=5)
            except subprocess.TimeoutExpired:
                _stop(sim)
                print(f"{PROG}: error: gyro_sim did not finish {args.duration:g} s within "
                      f"{time.monotonic() - t_wall:.0f} s; logs in {log_dir}", file=sys.stderr)
                return 1
        sim_code = sim.returncode
        integ_code = _stop(integ)
        integ_log.close()
        sim_log.close()
        executor.shutdown()
        node.destroy_node()
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted", file=sys.stderr)
        return 130
    finally:
        for p in procs:
            _stop(p)
        if context is not None:
            rclpy.try_shutdown()

    if sim_code != 0:
        return _node_failed("gyro_sim", sim_code, sim_log_path)
    if integ_code != 0:
        return _node_failed("attitude_integrator", integ_code, integ_log_path)
    if bag is None:
        shutil.rmtree(log_dir, ignore_errors=True)
    truth = _quaternions_by_stamp(truth_raw)
    attitude = _quaternions_by_stamp(attitude_raw)
    return _summarize(spec, rate, args, truth, attitude, diagnostics, bag, plot, wall,
                      sim_code, integ_code, raw_count[0])


def _quaternions_by_stamp(messages: list[bytes]) -> dict[int, tuple]:
    """Serialized QuaternionStamped messages as {header.stamp ns: (x, y, z, w)}."""
    out = {}
    for raw in messages:
        fields = QuaternionStampedCdr.parse(bytes(raw))
        if fields is not None:
            out[fields[0]] = fields[1]
    return out


def _node_failed(name: str, code: int, log: Path) -> int:
    """One line for a node that exited with an error; the demo's exit status (1)."""
    said = _last_line(log)
    print(f"{PROG}: error: {name} exited with status {code}" + (f": {said}" if said else "")
          + f" (log: {log})", file=sys.stderr)
    return 1


def _summarize(spec, rate, args, truth, attitude, diagnostics, bag, plot, wall, sim_code,
               integ_code, raw_received) -> int:
    import numpy as np


    n_expected = int(round(args.duration * rate))
    stamps = sorted(set(truth) & set(attitude))
    print(f"[demo] samples: {n_expected} simulated; received here: {raw_received} imu/data_raw, "
          f"{len(truth)} truth/attitude, {len(attitude)} attitude ({wall:.1f} s wall)")
    if diagnostics:
        d = diagnostics[-1]
        rejected = {k: v for k, v in d.items() if k.startswith("rejected_") and v != "0"}
        print(f"[demo] integrator: algorithm {d.get('algorithm')}, input {d.get('input_rate_hz')}"
              f" Hz, dt jitter {float(d.get('dt_jitter_s', 'nan')) * 1e6:.3f} us, accepted "
              f"{d.get('accepted')}, rejected {d.get('rejected_total')}"
              f"{' ' + str(rejected) if rejected else ''}, "
              f"gaps {d.get('gaps')}")
    if bag is not None and bag.exists():
        print(f"[demo] recording: {bag} ({bag.stat().st_size / 1e6:.1f} MB)")
    if not stamps:
        print(f"{PROG}: error: no attitude matched a truth stamp: nothing to compare",
              file=sys.stderr)
        return 1
    t_ns = np.array(stamps, dtype=np.int64)
    q_t = np.array([truth[s] for s in stamps])
    q_a = np.array([attitude[s] for s in stamps])
    err = quat_angle_between(q_t, q_a)
    t = (t_ns - t_ns[0]) * 1e-9
    print("[demo] attitude error against truth/attitude (rad):")
    marks = sorted({min(len(t) - 1, int(np.searchsorted(t, x))) for x in
                    np.linspace(0.0, t[-1], 6)})
    for i in marks:
        print(f"         t = {t[i]:7.3f} s   error = {err[i]:.3e}")
    print(f"[demo] max {err.max():.3e} rad, RMS {math.sqrt(float(np.mean(err**2))):.3e} rad, "
          f"final {err[-1]:.3e} rad")
    if spec.motion_type == "coning":
        print("[demo] coning truth is periodic: the error is the integration algorithm's drift")

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 4))
    ax.plot(t, np.maximum(err, 1e-18), lw=0.8)
    ax.set_yscale("log")
    ax.set_xlabel("time since first sample [s]")
    ax.set_ylabel("attitude error [rad]")
    algo = diagnostics[-1].get("algorithm") if diagnostics else "default"
    ax.set_title(f"{spec.name}: attitude_integrator ({algo}) vs truth, {rate:g} Hz")
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    try:
        # written beside the plot and renamed into place when complete
        with SafeOutput(plot, force=args.force) as tmp:
            fig.savefig(tmp, dpi=110, format="png")
    except (OutputPathError, OSError) as exc:
        error_line("demo", f"--plot {plot}: {exc}")
        return 1
    finally:
        plt.close(fig)
    print(f"[demo] plot: {plot}")
    return 0 if sim_code == 0 and integ_code == 0 else 1
