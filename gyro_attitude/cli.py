"""The ``gyro-attitude`` console command: ``demo | replay | bench | scenes | simulate | allan``.

Each subcommand lives in ``gyro_attitude.commands.<name>`` with two functions,
``configure(parser)`` (adds its arguments) and ``run(args) -> int`` (exit status); the
module is imported only when its subcommand runs, so ``--help`` stays fast and a
subcommand's heavy imports (rclpy, matplotlib) are paid only by that subcommand.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from gyro_attitude import __version__

# name -> one-line help; the module gyro_attitude.commands.<name> implements it.
SUBCOMMANDS: dict[str, str] = {
    "demo": "run gyro_sim + attitude_integrator on a scene, record MCAP, summarize, plot",
    "replay": "integrate every Imu message of an MCAP recording offline (no ROS graph)",
    "bench": "accuracy versus cost of every attitude algorithm (table, Pareto plot, JSON)",
    "scenes": "list the shipped scenes with one line each, or show one",
    "simulate": "run a scene offline (no ROS graph) into an MCAP file of gyro_sim's topics",
    "allan": "Allan deviation and IEEE 952 noise terms (ARW, bias instability, RRW) of a recording",
}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="gyro-attitude",
        description="Gyroscope mechanics and attitude for ROS 2 Jazzy.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, help_text in SUBCOMMANDS.items():
        sub.add_parser(name, help=help_text, description=help_text, add_help=False)
    return parser


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = build_parser()
    if not argv or argv[0] not in SUBCOMMANDS:
        parser.parse_args(argv)  # exits for --help, --version and unknown subcommands
        parser.print_help()  # no subcommand given
        return 2
    name = argv[0]
    module = importlib.import_module(f"gyro_attitude.commands.{name}")
    sub = argparse.ArgumentParser(prog=f"gyro-attitude {name}", description=SUBCOMMANDS[name])
    module.configure(sub)
    args = sub.parse_args(argv[1:])
    try:
        return int(module.run(args) or 0)
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
