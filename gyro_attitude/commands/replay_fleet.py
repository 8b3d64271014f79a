"""``gyro-attitude replay IN... --out-dir DIR``: the fleet replay's flags and printing (the engine
is :mod:`gyro_attitude.offline.fleet`); one summary line per file and a total.

Exit status: 0 every file replayed, 1 some failed (each named with its error; the others are
written), 2 bad arguments, 130 interrupted (the files finished are kept, the others not written).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time

from gyro_attitude.commands import error_line
from gyro_attitude.offline.parallel import CONNECT_TIMEOUT_S, default_workers

__all__ = ["add_fleet_flags", "run_fleet"]


def add_fleet_flags(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group("fleet replay (several inputs)")
    group.add_argument("--out-dir", metavar="DIR", default=None,
                       help="replay every input into DIR/<input name>.mcap")
    group.add_argument("--workers", type=int, default=None, metavar="J",
                       help=f"local worker processes (default: the CPUs, here "
                       f"{default_workers()}; 1 runs in this process)")
    group.add_argument("--scheduler", default=None, metavar="ADDRESS",
                       help="replay on the Dask cluster of this scheduler (tcp://host:port)")
    group.add_argument("--connect-timeout", type=float, default=CONNECT_TIMEOUT_S, metavar="S",
                       help=f"seconds to wait for the scheduler (default {CONNECT_TIMEOUT_S:g})")


def _line(f) -> str:
    s = f.summary
    err = s.get("final_error_rad")
    note = (s.get("truth_overlap") or {}).get("note")
    return (f"ok     {f.input}: {s['messages']} msgs, {s['duration_s']:.1f} s, {s['algorithm']}"
            + (f", final error {math.degrees(err):.3g}° (tilt "
               f"{math.degrees(s['final_tilt_error_rad']):.3g}°, heading "
               f"{math.degrees(s['final_heading_error_rad']):+.3g}°)" if err is not None else "")
            + (f"; {note}" if note else "")
            + ("; accelerometer not in m/s²: not used" if s.get("accel_problem") else "")
            + f" -> {f.output}")


def run_fleet(args, config) -> int:
    from gyro_attitude.offline.fleet import fleet_pairs, replay_fleet

    if args.out is not None or args.plot:
        error_line("replay", "with several inputs give --out-dir DIR (not --out or --plot)")
        return 2
    if args.out_dir is None:
        error_line("replay", "several inputs need --out-dir DIR")
        return 2
    workers = args.workers or default_workers()
    if workers < 1 or not math.isfinite(args.connect_timeout) or args.connect_timeout <= 0:
        error_line("replay", "--workers must be >= 1 and --connect-timeout > 0")
        return 2
    try:
        pairs = fleet_pairs(args.input, args.out_dir, force=args.force)
    except (ValueError, OSError) as exc:
        error_line("replay", exc)
        return 1

    def report(f):
        if not args.json:
            print(_line(f) if f.error is None else f"FAILED {f.input}: {f.error}", flush=True)

    t0 = time.perf_counter()
    try:
        files, interrupted = replay_fleet(
            pairs, workers=workers, scheduler=args.scheduler,
            connect_timeout_s=args.connect_timeout, on_file=report, imu_topic=args.imu_topic,
            algorithm=args.algorithm, truth_topic=args.truth_topic,
            compression=args.compression, force=args.force, config=config,
            estimator=args.estimator, mag_topic=args.mag_topic,
            odometry_topic=args.odometry_topic, truth_child_frame=args.truth_child_frame)
    except (ValueError, OSError) as exc:
        error_line("replay", exc)
        return 1
    wall = time.perf_counter() - t0
    ok = [f for f in files if f.summary is not None]
    failed = [f for f in files if f.error is not None]
    if args.json:
        print(json.dumps([{"input": f.input, "output": f.output, "summary": f.summary,
                           "error": f.error} for f in files], indent=2))
    if interrupted:
        # a worker may have renamed its output into place as the stop came, its summary lost
        kept = [f for f in files if f.error is None and os.path.exists(f.output)]
        print(f"interrupted: {len(kept)} of {len(files)} file(s) replayed and kept"
              + (f" ({len(kept) - len(ok)} finished as the command stopped, no summary)"
                 if len(kept) > len(ok) else "") + "; the others not written", file=sys.stderr)
        return 130
    msgs = sum(f.summary["messages"] for f in ok)
    total = (f"total: {len(ok)} of {len(files)} file(s) replayed, {msgs} Imu messages in "
             f"{wall:.2f} s on {'Dask at ' + args.scheduler if args.scheduler else f'{workers} worker(s)'}"
             + (f"; {len(failed)} failed" if failed else ""))
    print(total, file=sys.stderr if args.json else sys.stdout)
    return 1 if failed else 0
