"""``gyro-attitude simulate SCENE --duration S --out OUT.mcap``: a scene to MCAP offline, no ROS graph."""

from __future__ import annotations

import argparse
import sys

from gyro_attitude.offline.simulate import simulate


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scene", help="scene name (gyro-attitude scenes) or YAML path")
    parser.add_argument("--duration", type=float, required=True, metavar="S",
                        help="simulated duration [s]")
    parser.add_argument("--out", required=True, metavar="OUT.mcap", help="MCAP file to write")
    parser.add_argument("--rate", type=float, default=None, metavar="HZ",
                        help="sample rate [Hz] (default: the scene's rate_hz)")
    parser.add_argument("--seed", type=int, default=None, metavar="N",
                        help="random seed of the noise model (default: the scene's seed)")
    parser.add_argument("--no-truth", action="store_true",
                        help="leave out truth/attitude and truth/odom (gyro_sim's "
                             "publish_truth:=false)")
    parser.add_argument("--force", action="store_true", help="overwrite an existing OUT")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


def run(args: argparse.Namespace) -> int:

    try:
        r = simulate(args.scene, args.duration, args.out, rate_hz=args.rate, seed=args.seed,
                     force=args.force, publish_truth=not args.no_truth,
                     progress=not args.quiet and sys.stderr.isatty())
    except (ValueError, OSError) as exc:
        print(f"simulate: error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("simulate: interrupted; no output written", file=sys.stderr)
        return 130
    topics = ", ".join(f"{t} {n}" for t, n in r.messages.items())
    print(f"[simulate] scene '{r.scene}' at {r.rate_hz:g} Hz, seed {r.seed}: {r.samples} samples "
          f"in {r.wall_s:.2f} s ({r.samples_per_s:,.0f} samples/s) -> {r.path}")
    print(f"[simulate] messages: {topics}")
    return 0
