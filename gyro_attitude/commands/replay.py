"""``gyro-attitude replay IN.mcap --out OUT.mcap``: integrate every Imu message offline.

No ROS graph: the Imu topic is read array-wide (:mod:`gyro_attitude.io.imu_fast`),
integrated in one call of :func:`gyro_attitude.core.attitude.integrate_batch`, and
written array-wide to OUT as ``attitude`` (geometry_msgs/QuaternionStamped, frame
``inertial`` or ``enu``) and ``imu/data`` (the input Imu with the orientation filled in),
stamped and logged with the input's stamps and log times.  When IN has
``truth/attitude`` the attitude error (angle of q_est⁻¹ ⊗ q_truth) is reported at the
truth stamps that coincide with Imu stamps.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from gyro_attitude.io.cdr_arrays import IMU_TYPE, QUATERNION_STAMPED_TYPE

DEFAULT_IMU_TOPIC = "imu/data_raw"
TRUTH_TOPIC = "truth/attitude"
_PROGRESS_MIN_BYTES = 50 * 1024 * 1024  # show a progress bar from this file size on


def _floats(text: str, n: int, what: str) -> tuple[float, ...]:
    try:
        vals = tuple(float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{what} must be {n} comma-separated numbers, "
                                         f"got {text!r}") from None
    if len(vals) != n or not all(np.isfinite(vals)):
        raise argparse.ArgumentTypeError(f"{what} must be {n} finite comma-separated numbers, "
                                         f"got {text!r}")
    return vals


def _initial_attitude(text: str):
    if text.strip().lower() == "truth":
        return "truth"
    return _floats(text, 4, "--initial-attitude")


def configure(parser: argparse.ArgumentParser) -> None:
    from gyro_attitude.core.attitude import ALGORITHMS, DEFAULT_ALGORITHM

    parser.add_argument("input", metavar="IN.mcap", help="recording (file or bag directory)")
    parser.add_argument("--out", required=True, metavar="OUT.mcap", help="output MCAP file")
    parser.add_argument("--imu-topic", default=DEFAULT_IMU_TOPIC,
                        help=f"sensor_msgs/Imu topic to integrate (default {DEFAULT_IMU_TOPIC})")
    parser.add_argument("--algorithm", default=DEFAULT_ALGORITHM, choices=sorted(ALGORITHMS),
                        help=f"attitude update algorithm (default {DEFAULT_ALGORITHM})")
    parser.add_argument("--frame", choices=("inertial", "enu"), default="inertial",
                        help="inertial: q_ib; enu: q_nb with Earth and transport rate removed")
    parser.add_argument("--latitude-deg", type=float, default=None, help="(enu) latitude")
    parser.add_argument("--longitude-deg", type=float, default=0.0, help="(enu) longitude")
    parser.add_argument("--height-m", type=float, default=0.0, help="(enu) height, WGS-84")
    parser.add_argument("--velocity-enu", type=lambda s: _floats(s, 3, "--velocity-enu"),
                        default=(0.0, 0.0, 0.0), metavar="E,N,U", help="(enu) velocity m/s")
    parser.add_argument("--initial-attitude", type=_initial_attitude,
                        default=(0.0, 0.0, 0.0, 1.0), metavar="X,Y,Z,W|truth",
                        help="attitude at the first Imu stamp (default identity); 'truth' "
                        "takes it from the truth topic at that stamp")
    parser.add_argument("--truth-topic", default=TRUTH_TOPIC,
                        help=f"QuaternionStamped truth to compare with (default {TRUTH_TOPIC})")
    parser.add_argument("--compression", choices=("", "zstd", "lz4"), default="",
                        help="chunk compression of OUT (default none)")
    parser.add_argument("--json", action="store_true", help="print the summary as JSON")
    parser.add_argument("--plot", metavar="PNG", default=None, help="write an error plot")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def replay_file(input_path, output_path, *, imu_topic: str = DEFAULT_IMU_TOPIC,
                algorithm: str | None = None, frame: str = "inertial", nav=None,
                initial_attitude=(0.0, 0.0, 0.0, 1.0), truth_topic: str = TRUTH_TOPIC,
                compression: str = "", chunk_size: int = 4 * 1024 * 1024,
                progress: bool = False, on_damage: str = "warn") -> dict:
    """Integrate every Imu message of ``input_path`` and write ``output_path``.

    ``nav`` is a :class:`gyro_attitude.core.attitude.NavFrame` when ``frame == "enu"``.
    Returns the summary dict (also what ``--json`` prints); the attitudes and error series
    are under the private keys ``_t_ns``, ``_q``, ``_err_t_ns``, ``_err_rad``.
    """
    from gyro_attitude.core.attitude import DEFAULT_ALGORITHM, integrate_batch
    from gyro_attitude.core.rotation import quat_angle_between
    from gyro_attitude.io.imu_fast import read_topic_arrays
    from gyro_attitude.io.mcap_writer import Rosbag2McapWriter

    if frame not in ("inertial", "enu"):
        raise ValueError(f"frame must be 'inertial' or 'enu', got {frame!r}")
    if (frame == "enu") != (nav is not None):
        raise ValueError("frame 'enu' needs a NavFrame (latitude); 'inertial' takes none")
    algorithm = algorithm or DEFAULT_ALGORITHM
    t_start = time.perf_counter()
    bar = None
    cb = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=100, unit="%", desc="read", file=sys.stderr, leave=False)

        def cb(done, total):
            bar.n = int(100 * done / max(total, 1))
            bar.refresh()

    arrays = read_topic_arrays(input_path, {imu_topic: IMU_TYPE,
                                            truth_topic: QUATERNION_STAMPED_TYPE},
                               on_damage=on_damage, progress=cb, required=False,
                               fields={imu_topic: ("angular_velocity", "linear_acceleration",
                                                   "angular_velocity_covariance",
                                                   "linear_acceleration_covariance")})
    if bar is not None:
        bar.close()
    if imu_topic not in arrays:
        raise ValueError(f"{input_path}: no Imu topic {imu_topic!r} (use --imu-topic)")
    imu = arrays[imu_topic]
    if len(imu) == 0:
        raise ValueError(f"{input_path}: topic {imu.topic} has no messages")
    t_read = time.perf_counter()

    t = imu.stamp_ns
    order = None
    if np.any(np.diff(t) <= 0):  # file order is not stamp order: sort, refuse duplicates
        order = np.argsort(t, kind="stable")
        t = t[order]
        dup = np.flatnonzero(np.diff(t) == 0)
        if dup.size:
            raise ValueError(f"{imu.topic}: {dup.size} duplicate header stamps (first at "
                             f"{int(t[dup[0]])} ns); cannot integrate")

    def ordered(a):
        return a if order is None else a[order]

    omega = ordered(imu.angular_velocity)
    truth = arrays.get(truth_topic)
    if isinstance(initial_attitude, str):
        if initial_attitude != "truth":
            raise ValueError(f"initial_attitude must be 4 numbers or 'truth', got "
                             f"{initial_attitude!r}")
        at0 = (np.flatnonzero(truth.stamp_ns == t[0]) if truth is not None
               else np.zeros(0, dtype=np.int64))
        if at0.size == 0:
            raise ValueError(f"initial attitude 'truth': no {truth_topic} message stamped at "
                             f"the first Imu stamp {int(t[0])} ns")
        initial_attitude = truth.quaternion[at0[0]]
    q = integrate_batch(t, omega, q0=initial_attitude, algorithm=algorithm, nav=nav)
    t_int = time.perf_counter()

    with Rosbag2McapWriter(output_path, compression=compression, chunk_size=chunk_size) as w:
        w.add_topic("attitude", QUATERNION_STAMPED_TYPE)
        w.add_topic("imu/data", IMU_TYPE)
        log = ordered(imu.log_time_ns)
        pub = ordered(imu.publish_time_ns)
        w.write_quaternion_stamped_array("attitude", t, q, frame_id=frame,
                                         log_time_ns=log, publish_time_ns=pub)
        w.write_imu_array("imu/data", t, omega, ordered(imu.linear_acceleration), q,
                          frame_id=imu.frame_id,
                          orientation_covariance=np.zeros(9),
                          angular_velocity_covariance=ordered(imu.angular_velocity_covariance),
                          linear_acceleration_covariance=ordered(
                              imu.linear_acceleration_covariance),
                          log_time_ns=log, publish_time_ns=pub)
    t_end = time.perf_counter()

    summary = {
        "input": str(input_path),
        "output": str(output_path),
        "imu_topic": imu.topic,
        "algorithm": algorithm,
        "frame": frame,
        "messages": int(len(imu)),
        "fast_path_messages": int(imu.fast_messages),
        "fallback_messages": int(imu.fallback_messages),
        "frame_ids": sorted(imu.frame_ids),
        "sorted_by_stamp": order is not None,
        "duration_s": float((t[-1] - t[0]) * 1e-9),
        "wall_seconds": t_end - t_start,
        "read_seconds": t_read - t_start,
        "integrate_seconds": t_int - t_read,
        "write_seconds": t_end - t_int,
        "messages_per_second": len(imu) / max(t_end - t_start, 1e-12),
        "input_damage": imu.damage,
        "truth_topic": None,
        "truth_matched": 0,
        "final_error_rad": None,
        "max_error_rad": None,
        "rms_error_rad": None,
        "_t_ns": t,
        "_q": q,
    }
    if truth is not None and len(truth):
        idx = np.searchsorted(t, truth.stamp_ns)
        idx_c = np.minimum(idx, t.size - 1)
        hit = t[idx_c] == truth.stamp_ns
        if hit.any():
            err = quat_angle_between(q[idx_c[hit]], truth.quaternion[hit])
            tt = truth.stamp_ns[hit]
            k = np.argsort(tt, kind="stable")
            err, tt = err[k], tt[k]
            summary.update({
                "truth_topic": truth.topic,
                "truth_matched": int(hit.sum()),
                "final_error_rad": float(err[-1]),
                "max_error_rad": float(err.max()),
                "rms_error_rad": float(np.sqrt(np.mean(err**2))),
                "_err_t_ns": tt,
                "_err_rad": err,
            })
    return summary


def public_summary(summary: dict) -> dict:
    return {k: v for k, v in summary.items() if not k.startswith("_")}


def write_error_plot(summary: dict, png) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 4), constrained_layout=True)
    if summary.get("_err_rad") is not None:
        t = (summary["_err_t_ns"] - summary["_t_ns"][0]) * 1e-9
        ax.semilogy(t, np.maximum(np.degrees(summary["_err_rad"]), 1e-16), lw=1)
        ax.set_ylabel("attitude error vs truth [deg]")
    else:
        t = (summary["_t_ns"] - summary["_t_ns"][0]) * 1e-9
        from gyro_attitude.core.rotation import quat_angle_between

        ang = quat_angle_between(summary["_q"], summary["_q"][0])
        ax.plot(t, np.degrees(ang), lw=1)
        ax.set_ylabel("rotation from the initial attitude [deg] (no truth in file)")
    ax.set_xlabel("time since first Imu stamp [s]")
    ax.set_title(f"replay {Path(summary['input']).name}: {summary['algorithm']}, "
                 f"{summary['frame']}, {summary['messages']} msgs")
    ax.grid(True, which="both", alpha=0.3)
    fig.savefig(png, dpi=110)
    plt.close(fig)


def run(args) -> int:
    from gyro_attitude.core.attitude import NavFrame

    nav = None
    if args.frame == "enu":
        if args.latitude_deg is None:
            print("error: --frame enu needs --latitude-deg", file=sys.stderr)
            return 2
        nav = NavFrame(latitude_rad=np.radians(args.latitude_deg),
                       longitude_rad=np.radians(args.longitude_deg), height_m=args.height_m,
                       velocity_enu=np.asarray(args.velocity_enu))
    in_path = Path(args.input)
    size = in_path.stat().st_size if in_path.is_file() else 0
    try:
        summary = replay_file(
            args.input, args.out, imu_topic=args.imu_topic, algorithm=args.algorithm,
            frame=args.frame, nav=nav, initial_attitude=args.initial_attitude,
            truth_topic=args.truth_topic, compression=args.compression,
            progress=not args.no_progress and not args.json and size >= _PROGRESS_MIN_BYTES
            and sys.stderr.isatty(),
        )
    except (ValueError, OSError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    if args.plot:
        write_error_plot(summary, args.plot)
    out = public_summary(summary)
    if out["input_damage"]:
        print(f"warning: input damaged, replayed what precedes the damage: "
              f"{out['input_damage']}", file=sys.stderr)
    if args.json:
        print(json.dumps(out, indent=2))
    else:
        print(f"replayed {out['messages']} Imu messages from {out['imu_topic']} "
              f"({out['duration_s']:.3f} s of data) with {out['algorithm']} in the "
              f"{out['frame']} frame")
        print(f"  wall {out['wall_seconds']:.3f} s ({out['messages_per_second']:.0f} msg/s): "
              f"read {out['read_seconds']:.3f} s, integrate {out['integrate_seconds']:.3f} s, "
              f"write {out['write_seconds']:.3f} s")
        if out["truth_matched"]:
            print(f"  vs {out['truth_topic']} ({out['truth_matched']} stamps): final error "
                  f"{np.degrees(out['final_error_rad']):.3e} deg, max "
                  f"{np.degrees(out['max_error_rad']):.3e} deg")
        else:
            print("  no truth topic in the input: no error figures")
        print(f"  wrote {out['output']} (attitude, imu/data)"
              + (f", plot {args.plot}" if args.plot else ""))
    return 0


