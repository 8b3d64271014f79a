"""``gyro-attitude montecarlo SCENE --runs N``: error budgets over many noise draws (the engine is
:mod:`gyro_attitude.offline.montecarlo`; where it runs, :mod:`gyro_attitude.offline.parallel`).

Exit status: 0 every run finished, 1 unusable input or output, an unreachable scheduler, a Dask
cluster left without a worker, or some runs failed (the others are in the output, the failed
ones named), 2 bad arguments, 130 interrupted (``--json`` then holds the runs that finished,
marked ``"complete": false``, as when the cluster lost its workers).
"""

from __future__ import annotations

import argparse
import json
import math
import sys

from gyro_attitude.commands import EXIT_INTERRUPTED, error_line
from gyro_attitude.commands.estimator_flags import (
    add_estimator_flags,
    config_from_args,
    given_settings,
)
from gyro_attitude.commands.usage_errors import output_file
from gyro_attitude.core.attitude import ALGORITHMS
from gyro_attitude.core.attitude.modes import InitialAttitudeSource
from gyro_attitude.core.attitude.settings import SETTINGS
from gyro_attitude.io.safe_output import SafeOutput, check_output_path, plot_format
from gyro_attitude.io.scene_file import load_scene
from gyro_attitude.offline import montecarlo as mc
from gyro_attitude.offline.parallel import CONNECT_TIMEOUT_S, NO_WORKER_TIMEOUT_S, default_workers

__all__ = ["configure", "run"]

PROG = "gyro-attitude montecarlo"


def _int_from(lo: int, hi: int):
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be an integer, got {text!r}") from None
        if not lo <= value <= hi:
            raise argparse.ArgumentTypeError(f"must be an integer from {lo} to {hi}, got {text!r}")
        return value
    return parse


def _positive(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"must be a finite number > 0, got {text!r}")
    return value


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scene", help="scene name (gyro-attitude scenes) or YAML path")
    parser.add_argument("--runs", type=_int_from(1, mc.MAX_RUNS), required=True, metavar="N",
                        help="noise draws per grade")
    parser.add_argument("--duration", type=_positive, default=None, metavar="S",
                        help="simulated duration of each run [s] (default: the scene's)")
    parser.add_argument("--rate", type=_positive, default=None, metavar="HZ",
                        help="sample rate [Hz] (default: the scene's rate_hz)")
    parser.add_argument("--seed", type=_int_from(0, 2**63 - 1), default=None, metavar="S",
                        help="seed of the set (default: the scene's seed); run i uses child i of "
                        "numpy SeedSequence(S).spawn, its seed is in the JSON")
    parser.add_argument("--workers", type=_int_from(1, 4096), default=None, metavar="J",
                        help=f"local worker processes (default: the CPUs, here "
                        f"{default_workers()}; 1 runs in this process)")
    parser.add_argument("--scheduler", default=None, metavar="ADDRESS",
                        help="run on the Dask cluster of this scheduler (tcp://host:port) "
                        "instead of local processes")
    parser.add_argument("--connect-timeout", type=_positive, default=CONNECT_TIMEOUT_S,
                        metavar="S", help=f"seconds to wait for the scheduler (default "
                        f"{CONNECT_TIMEOUT_S:g})")
    parser.add_argument("--worker-timeout", type=_positive, default=NO_WORKER_TIMEOUT_S,
                        metavar="S", help="Dask: seconds the set waits while the cluster has "
                        "no worker (all lost) before it ends with the runs that finished "
                        f"(default {NO_WORKER_TIMEOUT_S:g})")
    parser.add_argument("--grade", action="append", default=[], metavar="NAME|NAME*F|*F",
                        help="sensor grade to compare (repeat for several): the gyro and "
                        "accelerometer errors of scene NAME, scaled by F, or the scene's own "
                        "scaled by F (default: the scene's own)")
    parser.add_argument("--algorithm", default=None, choices=sorted(ALGORITHMS),
                        help="attitude update algorithm (default: replay's choice)")
    parser.add_argument("--estimator", default="causal", choices=("causal", "offline"),
                        help="causal (default): as the live node estimates; offline: as replay "
                        "does by default, over the whole recording")
    # replay's estimator flags from the one settings table, but those the scene decides
    # (frame, position, velocity); the initial attitude defaults to the truth
    add_estimator_flags(parser, [s for s in SETTINGS if s.name not in mc.SCENE_SETTINGS])
    parser.add_argument("--grid-points", type=_int_from(2, 100_000), default=mc.GRID_POINTS,
                        help=f"times of the statistics (default {mc.GRID_POINTS})")
    parser.add_argument("--json", metavar="OUT", default=None, type=output_file,
                        help="write runs, percentile bands and the NEES check as JSON")
    parser.add_argument("--plot", metavar="IMAGE", default=None,
                        help="percentile bands over time per grade, predicted 1σ/3σ")
    parser.add_argument("--force", action="store_true", help="overwrite --json / --plot files")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def _estimator(args) -> mc.Estimator:
    overrides = {}
    if "initial_attitude_source" not in given_settings(args):
        overrides["initial_attitude_source"] = InitialAttitudeSource.TRUTH
    return mc.Estimator(algorithm=args.algorithm, config=config_from_args(args, **overrides),
                        kind=args.estimator)


def _setup(args) -> mc.MonteCarloSetup:
    spec = load_scene(args.scene)
    grades = mc.grades_of(spec, args.grade, load_scene)
    duration = spec.duration_s if args.duration is None else args.duration
    seed = spec.seed if args.seed is None else args.seed
    return mc.MonteCarloSetup(grades, args.runs, duration, args.rate, seed, _estimator(args),
                              args.grid_points)


def _deg(x) -> str:
    return "—" if x is None or not math.isfinite(x) else f"{math.degrees(x):.4g}"


def _print_table(result: mc.MonteCarloResult, stats: list[dict]) -> None:
    s = result.setup
    print(f"montecarlo {s.grades[0].spec.name}: {s.runs} run(s) per grade of {s.duration_s:g} s "
          f"at {s.rate_hz:g} Hz, seed {s.seed}; {result.workers if not result.scheduler else 'Dask'}"
          f" worker(s){'' if not result.scheduler else ' at ' + result.scheduler}")
    head = (f"{'grade':<22} {'runs':>5} {'final angle p50/p95/p99 [deg]':>31} "
            f"{'heading p95':>11} {'tilt p95':>9} {'pred 1σ':>8} {'NEES final [bounds]':>24}")
    print(head)
    for st in stats:
        if "final" not in st:
            print(f"{st['label']:<22} {0:>5}  (no run finished)")
            continue
        f = st["final"]
        a = f["error_angle_rad"]
        pred = st["predicted_sigma_rad"]["angle"][-1]
        n = st["nees"]["final"]
        nees = ("—" if n["mean"] is None else
                f"{n['mean']:.3g} [{n['lower']:.3g}, {n['upper']:.3g}]"
                + ("" if n["within"] else " ✗"))
        print(f"{st['label']:<22} {st['runs_finished']:>5} "
              f"{_deg(a['p50']) + ' / ' + _deg(a['p95']) + ' / ' + _deg(a['p99']):>31} "
              f"{_deg(f['heading_error_rad']['p95']):>11} {_deg(f['tilt_error_rad']['p95']):>9} "
              f"{_deg(pred):>8} {nees:>24}")
    cost = result.cost_per_run_s()
    print(f"wall {result.wall_s:.2f} s" + (f", {cost:.3g} s per run" if cost else ""))
    for st in stats:
        n = st.get("nees", {}).get("final") or {}
        if "outside" not in n:
            continue
        why = n["explanation"]
        print(f"note: {st['label']}: the final NEES {n['mean']:.3g} lies {n['outside']} its 95 % "
              f"band [{n['lower']:.3g}, {n['upper']:.3g}]: the reported covariance is "
              + ("too small" if n["outside"] == "above" else "too large") + " here. "
              + ("; ".join(why) + "." if why else "No term of the scene explains it.")
              + " (docs/montecarlo.md: the NEES check)")


def _write_json(path, doc: dict) -> None:
    with SafeOutput(path, force=True) as tmp:  # checked before the runs
        with open(tmp, "w") as f:
            json.dump(doc, f, indent=1)
            f.write("\n")


def run(args) -> int:
    try:
        setup = _setup(args)
        for path, what in ((args.json, "json"), (args.plot, "plot")):
            if path:
                check_output_path(path, inputs=[args.scene], force=args.force, what=what)
        if args.plot:
            plot_format(args.plot)
        if args.json and args.plot and args.json == args.plot:
            raise ValueError("--json and --plot name the same file")
    except (ValueError, OSError) as exc:
        error_line("montecarlo", exc)
        return 1
    workers = args.workers or default_workers()
    try:
        result = mc.run_montecarlo(setup, workers=workers, scheduler=args.scheduler,
                                   progress=not args.no_progress and sys.stderr.isatty(),
                                   connect_timeout_s=args.connect_timeout,
                                   no_worker_timeout_s=args.worker_timeout)
    except (ValueError, OSError) as exc:
        error_line("montecarlo", exc)
        return 1
    doc = result.to_json()
    stats = doc["statistics"]
    try:
        if args.json:
            _write_json(args.json, doc)
        if args.plot and not result.interrupted and result.stopped is None:
            mc.write_plot(result, stats, args.plot)
    except (ValueError, OSError) as exc:
        error_line("montecarlo", exc)
        return 1
    if result.interrupted or result.stopped:
        done = doc["runs_finished"]
        total = setup.runs * len(setup.grades)
        what = (f"interrupted after {done} of {total} runs" if result.interrupted else
                f"error: {result.stopped}; {done} of {total} runs finished")
        print(f"{PROG}: {what}"
              + (f"; {args.json} holds them (\"complete\": false)" if args.json else "")
              + ("; no plot" if args.plot else ""), file=sys.stderr)
        return EXIT_INTERRUPTED if result.interrupted else 1
    _print_table(result, stats)
    for r in result.failed:
        print(f"{PROG}: run {r['index']} ({r['grade']}, seed {r['seed']}) failed: "
              f"{r['error']}", file=sys.stderr)
    if result.failed:
        print(f"{PROG}: {len(result.failed)} run(s) failed; the statistics are over the "
              f"{doc['runs_finished']} that finished", file=sys.stderr)
        return 1
    return 0

