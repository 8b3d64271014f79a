"""``gyro-attitude simulate SCENE --duration S --out OUT.mcap``: a scene to MCAP offline, no ROS graph."""

from __future__ import annotations

import argparse
import sys

from gyro_attitude.commands import error_line
from gyro_attitude.offline.simulate import simulate


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scene", help="scene name (gyro-attitude scenes) or YAML path")
    parser.add_argument("--duration", type=float, default=None, metavar="S",
                        help="simulated duration [s] (required unless the motion is a "
                             "trajectory: default its whole span)")
    parser.add_argument("--out", required=True, metavar="OUT.mcap", help="MCAP file to write")
    parser.add_argument("--rate", type=float, default=None, metavar="HZ",
                        help="sample rate [Hz] (default: the scene's rate_hz)")
    parser.add_argument("--seed", type=int, default=None, metavar="N",
                        help="random seed of the noise model (default: the scene's seed)")
    parser.add_argument("--no-truth", action="store_true",
                        help="leave out truth/attitude and truth/odom (gyro_sim's "
                             "publish_truth:=false)")
    parser.add_argument("--trajectory", default=None, metavar="PATH",
                        help="move the scene's sensors and instruments along these poses "
                             "(TUM, CSV with a header, or a rosbag2 MCAP with "
                             "--trajectory-topic); stamps in the poses' own time base")
    parser.add_argument("--trajectory-topic", default=None, metavar="TOPIC",
                        help="MCAP trajectory: nav_msgs/Odometry, geometry_msgs/PoseStamped "
                             "or tf2_msgs/TFMessage topic")
    parser.add_argument("--child-frame-id", default=None, metavar="FRAME",
                        help="TFMessage trajectory: the body frame's transform")
    parser.add_argument("--position-sigma", type=float, default=None, metavar="M",
                        help="expected position noise of the poses (m per axis; 0 "
                             "interpolates; default: the scene's, else 0)")
    parser.add_argument("--attitude-sigma", type=float, default=None, metavar="RAD",
                        help="expected attitude noise of the poses (rad per axis)")
    parser.add_argument("--force", action="store_true", help="overwrite an existing OUT")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


def _trajectory_options(args: argparse.Namespace) -> dict:
    """The pose options given on the command line, checked like the scene's keys."""
    for flag, value, hi in (("--position-sigma", args.position_sigma, 1.0),
                            ("--attitude-sigma", args.attitude_sigma, 0.5)):
        if value is not None and not (0.0 <= value <= hi):  # NaN fails too
            raise ValueError(f"{flag} must lie in [0, {hi:g}], got {value!r}")
    return {"topic": args.trajectory_topic, "child_frame_id": args.child_frame_id,
            "position_sigma_m": args.position_sigma, "attitude_sigma_rad": args.attitude_sigma}


def run(args: argparse.Namespace) -> int:

    try:
        r = simulate(args.scene, args.duration, args.out, rate_hz=args.rate, seed=args.seed,
                     force=args.force, publish_truth=not args.no_truth,
                     progress=not args.quiet and sys.stderr.isatty(),
                     trajectory=args.trajectory,
                     trajectory_options=_trajectory_options(args))
    except (ValueError, OSError) as exc:
        error_line("simulate", exc)
        return 1
    except KeyboardInterrupt:
        print("simulate: interrupted; no output written", file=sys.stderr)
        return 130
    topics = ", ".join(f"{t} {n}" for t, n in r.messages.items())
    print(f"[simulate] scene '{r.scene}' at {r.rate_hz:g} Hz, seed {r.seed}: {r.samples} samples "
          f"in {r.wall_s:.2f} s ({r.samples_per_s:,.0f} samples/s) -> {r.path}")
    print(f"[simulate] messages: {topics}")
    for sensor, count in r.saturated.items():
        print(f"[simulate] {sensor} output range reached: {count} of {r.samples} samples "
              "clipped at full scale")
    return 0
