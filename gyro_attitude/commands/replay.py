"""``gyro-attitude replay IN.mcap --out OUT.mcap``: arguments and printing of the offline
replay (the pipeline is :func:`gyro_attitude.offline.replay.replay_file`).

Exit status: 0 done, 1 unusable input or output, 2 bad arguments, 130 interrupted; every
failure is one line on stderr, and no partial output is left under the requested names.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from gyro_attitude.core.attitude import ALGORITHMS, DEFAULT_OFFLINE_ALGORITHM, NavFrame
from gyro_attitude.core.attitude import validation as iv
from gyro_attitude.core.attitude.stream import StreamConfig
from gyro_attitude.io.mcap_writer import COMPRESSIONS, DEFAULT_COMPRESSION
from gyro_attitude.io.safe_output import check_output_path
from gyro_attitude.offline.replay import (
    DEFAULT_IMU_TOPIC,
    TRUTH_TOPIC,
    replay_file,
    write_error_plot,
)

__all__ = ["configure", "run", "replay_file"]

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


def _finite(text: str) -> float:
    return _floats(text, 1, "value")[0]


def _initial_attitude(text: str):
    if text.strip().lower() in ("truth", "level"):
        return text.strip().lower()
    return _floats(text, 4, "--initial-attitude")


def _gyro_bias(text: str):
    if text.strip().lower() in ("auto", "none"):
        return text.strip().lower()
    return _floats(text, 3, "--gyro-bias")


def _one_line_error(parser: argparse.ArgumentParser):
    def error(message: str):
        parser.exit(2, f"{parser.prog}: error: {message}\n")
    return error


def configure(parser: argparse.ArgumentParser) -> None:
    parser.error = _one_line_error(parser)  # one line, not usage + error
    parser.add_argument("input", metavar="IN.mcap", help="recording (file or bag directory)")
    parser.add_argument("--out", required=True, metavar="OUT.mcap",
                        help="output MCAP file (never the input; written to a temporary "
                        "file and renamed when complete)")
    parser.add_argument("--force", action="store_true",
                        help="overwrite an existing OUT (and --plot file)")
    parser.add_argument("--imu-topic", default=DEFAULT_IMU_TOPIC,
                        help=f"sensor_msgs/Imu topic to integrate (default {DEFAULT_IMU_TOPIC})")
    parser.add_argument("--algorithm", default=None,
                        choices=sorted(ALGORITHMS),
                        help=f"attitude update algorithm (default {DEFAULT_OFFLINE_ALGORITHM}, "
                        "which uses samples after each interval; the node's causal default "
                        "rotvec_cubic when a per-sample filter acts on the recording: "
                        "levelling, aiding, or auto gyro bias with a rest)")
    # The attitude-stream policy of the attitude_integrator node, same names and defaults.
    parser.add_argument("--max-gap-s", type=_positive_up_to(1e6), default=0.1,
                        help="a forward stamp step longer than this is a gap: not integrated "
                        "across, attitude held (default 0.1)")
    parser.add_argument("--time-jump-threshold-s", type=_positive_up_to(1e6), default=1.0,
                        help="a backward stamp jump longer than this resets the attitude "
                        "(default 1.0); shorter backward steps are skipped as out of order")
    parser.add_argument("--max-rate-rad-s", type=_positive_up_to(iv.MAX_RATE_LIMIT_RAD_S),
                        default=iv.DEFAULT_MAX_RATE_RAD_S,
                        help="a sample with a larger rate on any axis is skipped as implausible "
                        f"(default {iv.DEFAULT_MAX_RATE_RAD_S:g})")
    parser.add_argument("--frame", choices=("inertial", "enu"), default="inertial",
                        help="inertial: q_ib; enu: q_nb with Earth and transport rate removed")
    parser.add_argument("--latitude-deg", type=_finite, default=None, help="(enu) latitude")
    parser.add_argument("--longitude-deg", type=_finite, default=0.0, help="(enu) longitude")
    parser.add_argument("--height-m", type=_finite, default=0.0, help="(enu) height, WGS-84")
    parser.add_argument("--velocity-enu", type=lambda s: _floats(s, 3, "--velocity-enu"),
                        default=(0.0, 0.0, 0.0), metavar="E,N,U", help="(enu) velocity m/s")
    parser.add_argument("--initial-attitude", type=_initial_attitude,
                        default=(0.0, 0.0, 0.0, 1.0), metavar="X,Y,Z,W|truth|level",
                        help="attitude at the first Imu stamp (default identity); 'truth': the "
                        "truth topic interpolated at the first Imu stamp it covers; 'level': "
                        "roll and pitch from the accelerometer over the initial rest, heading "
                        "from --initial-heading-deg or --heading-source gyrocompass")
    parser.add_argument("--initial-heading-deg", type=_finite, default=0.0,
                        help="(level) heading, clockwise from north (default 0)")
    parser.add_argument("--heading-source", choices=("parameter", "gyrocompass"),
                        default="parameter",
                        help="(level) heading from --initial-heading-deg, or found by "
                        "gyrocompassing (needs --frame enu or --latitude-deg, a fixed "
                        "--gyro-bias and --gyro-bias-sigma; refused when the gyro cannot find "
                        "north)")
    parser.add_argument("--gyro-bias", type=_gyro_bias, default="auto", metavar="auto|none|X,Y,Z",
                        help="auto (default): estimated at every rest and subtracted; none; or "
                        "a fixed bias in rad/s")
    parser.add_argument("--gyro-bias-sigma", type=_finite, default=0.0,
                        help="1-sigma of a fixed or unestimated gyro bias [rad/s] (covariance, "
                        "gyrocompassing)")
    parser.add_argument("--aiding", choices=("none", "gravity"), default="none",
                        help="gravity: tilt corrected toward the accelerometer's vertical (heading "
                        "stays gyro-only and drifts without a magnetometer)")
    parser.add_argument("--truth-topic", default=TRUTH_TOPIC,
                        help=f"QuaternionStamped truth to compare with (default {TRUTH_TOPIC})")
    parser.add_argument("--compression", choices=COMPRESSIONS, default=DEFAULT_COMPRESSION,
                        type=lambda s: "" if s == "none" else s, metavar="{zstd,lz4,none}",
                        help=f"chunk compression of OUT (default {DEFAULT_COMPRESSION})")
    parser.add_argument("--json", action="store_true", help="print the summary as JSON")
    parser.add_argument("--plot", metavar="PNG", default=None, help="write an error plot")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def _nav(args) -> NavFrame | None:
    if args.frame != "enu":
        return None
    if args.latitude_deg is None:
        raise ValueError("--frame enu needs --latitude-deg")
    return NavFrame(latitude_rad=np.radians(args.latitude_deg),
                    longitude_rad=np.radians(args.longitude_deg), height_m=args.height_m,
                    velocity_enu=np.asarray(args.velocity_enu))


def _progress_bar(args):
    in_path = Path(args.input)
    size = in_path.stat().st_size if in_path.is_file() else 0
    if args.no_progress or args.json or size < _PROGRESS_MIN_BYTES or not sys.stderr.isatty():
        return None, None
    from tqdm import tqdm  # only for large files on a terminal

    bar = tqdm(total=100, unit="%", desc="read", file=sys.stderr, leave=False)

    def update(done, total):
        bar.n = int(100 * done / max(total, 1))
        bar.refresh()

    return bar, update


# warning words per policy event (the rest are skipped samples, named by their reason)
_EVENT_WORDS = {
    iv.GAP: "gap(s) not integrated across, attitude held",
    "time_jump": "backward time jump(s): attitude reset",
    "invalid_covariance": "invalid angular_velocity_covariance(s) treated as unknown",
    "integrator_error": "non-finite update(s): last good attitude restored",
}


def _positive_up_to(limit: float):
    def parse(text: str) -> float:
        value = _finite(text)
        if not 0 < value <= limit:
            raise argparse.ArgumentTypeError(f"must be > 0 and <= {limit:g}, got {text!r}")
        return value
    return parse


def _stream_config(args) -> StreamConfig:
    bias = args.gyro_bias
    fixed = isinstance(bias, tuple)
    return StreamConfig(max_gap_ns=int(round(args.max_gap_s * 1e9)),
                        time_jump_ns=int(round(args.time_jump_threshold_s * 1e9)),
                        max_rate_rad_s=float(args.max_rate_rad_s),
                        gyro_bias="parameter" if fixed else bias,
                        gyro_bias_rad_s=bias if fixed else (0.0, 0.0, 0.0),
                        gyro_bias_sigma_rad_s=float(args.gyro_bias_sigma),
                        initial_heading_deg=float(args.initial_heading_deg),
                        heading_source=args.heading_source,
                        latitude_rad=(None if args.latitude_deg is None
                                      else float(np.radians(args.latitude_deg))),
                        aiding=args.aiding)


def run(args) -> int:
    try:
        nav = _nav(args)
        config = _stream_config(args)
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    bar = None
    try:
        # Every output path is checked before the work (the plot is written last).
        check_output_path(args.out, inputs=[args.input], force=args.force)
        if args.plot:
            check_output_path(args.plot, inputs=[args.input, args.out], force=args.force,
                              what="plot")
        bar, update = _progress_bar(args)
        result = replay_file(
            args.input, args.out, imu_topic=args.imu_topic, algorithm=args.algorithm,
            frame=args.frame, nav=nav, initial_attitude=args.initial_attitude,
            truth_topic=args.truth_topic, compression=args.compression, force=args.force,
            progress=update, config=config)
        if bar is not None:
            bar.close()
            bar = None
        if args.plot:
            write_error_plot(result, args.plot, force=True)  # checked above
    except (ValueError, OSError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("interrupted: no output written", file=sys.stderr)
        return 130
    finally:
        if bar is not None:
            bar.close()
    out = result.summary()
    if out["input_damage"]:
        print(f"warning: input damaged, replayed everything readable: {out['input_damage']}",
              file=sys.stderr)
    # once per reason: how many, and the first case in words
    events = {**out["skipped"], iv.GAP: out["gaps"], "time_jump": out["time_jump_resets"],
              "invalid_covariance": out["invalid_covariances"],
              "integrator_error": out["integrator_errors"]}
    for reason, n in events.items():
        if n:
            what = _EVENT_WORDS.get(reason, f"sample(s) skipped ({reason})")
            print(f"warning: {n} {what}; first: {out['details'].get(reason, '')}",
                  file=sys.stderr)
    if len(out["frame_ids"]) > 1:
        print(f"warning: frame_id changes inside {out['imu_topic']} ({out['frame_ids']}): "
              "integrated as one frame", file=sys.stderr)
    if args.json:
        print(json.dumps(out, indent=2))
        return 0
    print(f"replayed {out['messages']} Imu messages from {out['imu_topic']} "
          f"({out['duration_s']:.3f} s of data) with {out['algorithm']} in the "
          f"{out['frame']} frame")
    skipped = sum(out["skipped"].values())
    print(f"  {out['attitude_messages']} attitudes; skipped {skipped}"
          + (f" ({', '.join(f'{n} {r}' for r, n in out['skipped'].items() if n)})"
             if skipped else "")
          + f"; gaps {out['gaps']}; time-jump resets {out['time_jump_resets']}"
          + (f"; {out['skipped_before_truth']} before the truth starts"
             if out["skipped_before_truth"] else ""))
    print(f"  {out['gyro_bias']}")
    if out["alignment"]:
        a = out["alignment"]
        print(f"  levelled over {a['rest_s']:.1f} s of rest: roll {a['roll_deg']:.3f}°, pitch "
              f"{a['pitch_deg']:.3f}° (expected error {a['level_error_expected_deg']:.3f}°), "
              f"heading {a['heading_deg']:.2f}° ({a['heading_source']})")
    print(f"  wall {out['wall_seconds']:.3f} s ({out['messages_per_second']:.0f} msg/s): "
          f"read {out['read_seconds']:.3f} s, integrate {out['integrate_seconds']:.3f} s, "
          f"write {out['write_seconds']:.3f} s")
    if out["truth_matched"]:
        print(f"  vs {out['truth_topic']} ({out['truth_matched']} stamps): final error "
              f"{np.degrees(out['final_error_rad']):.3e} deg, max "
              f"{np.degrees(out['max_error_rad']):.3e} deg")
    else:
        print("  no truth topic in the input: no error figures")
    print(f"  wrote {out['output']} (attitude, imu/data; compression "
          f"{out['compression'] or 'none'})" + (f", plot {args.plot}" if args.plot else ""))
    return 0
