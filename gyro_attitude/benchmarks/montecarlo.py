"""Benchmark of ``gyro-attitude montecarlo`` (suite ``montecarlo``): cost per run, 1 worker against
all, and the projection to the issue's target of 1000 one-hour runs of ``lab_bench`` at 100 Hz.

The same set of runs (``lab_bench`` at 100 Hz, fixed seed) is run with 1 worker (in this process)
and with every CPU (a local process pool; pool start-up included in the wall time), and the
per-run results are compared bit for bit.  Two estimator settings: ``gyro_bias none`` (the batch
path: the gyro integrated whole) and the default ``auto`` (the rest filter runs sample by sample;
shorter runs, as its cost per sample is constant).  Per run the compute time splits into the
simulation and the rest (estimation, errors), measured in this process.  Targets: a speed-up of
at least 1.5 with 2 workers, and 1000 one-hour runs in under 300 s on 2 cores.  The machine may
be shared: rerun before believing a ratio.
"""

from __future__ import annotations

import dataclasses
import os
import pathlib
import time

import numpy as np

from gyro_attitude.core.attitude.settings import StreamConfig
from gyro_attitude.io.scene_file import load_scene
from gyro_attitude.offline import montecarlo as mc
from gyro_attitude.offline.parallel import default_workers

TARGET_SPEEDUP = 1.5
TARGET_1000_HOURS_S = 300.0


def _setup(runs: int, duration: float, bias: str) -> mc.MonteCarloSetup:
    spec = load_scene("lab_bench")
    config = StreamConfig(gyro_bias=bias, initial_attitude_source="truth")
    return mc.MonteCarloSetup(mc.grades_of(spec, [], load_scene), runs, duration, 100.0, 1,
                              mc.Estimator(config=config))


def _phases(setup: mc.MonteCarloSetup) -> tuple[float, float]:
    """(simulation, total) seconds of run 0 in this process (best of 2)."""
    spec = setup.grades[0].spec
    seed = mc.run_seeds(setup.seed, 1)[0]
    sim = total = np.inf
    for _ in range(2):
        t0 = time.perf_counter()
        s = spec
        if not mc._uses_accelerometer(setup.estimator.config):  # as run_one simulates it
            s = dataclasses.replace(spec, accelerometer=False)
        mc.simulate_run(s, setup.rate_hz, setup.samples, seed)
        t1 = time.perf_counter()
        mc.run_one(spec, setup, 0, seed, "x")
        t2 = time.perf_counter()
        sim, total = min(sim, t1 - t0), min(total, t2 - t1)
    return sim, total


def _same(a: mc.MonteCarloResult, b: mc.MonteCarloResult) -> bool:
    def key(r):
        return ({k: v for k, v in r.items() if k not in ("wall_s", "cpu_s", "_grid")},
                {k: np.asarray(v).tobytes() for k, v in r["_grid"].items()})
    return [key(r) for r in a.runs] == [key(r) for r in b.runs]


def _measure(label: str, setup: mc.MonteCarloSetup, workers: int) -> dict:
    sim_s, run_s = _phases(setup)
    one = mc.run_montecarlo(setup, workers=1)
    many = mc.run_montecarlo(setup, workers=workers)
    hours = setup.duration_s / 3600.0
    per_run_many = many.wall_s / setup.runs
    failed = [r["error"] for r in one.runs + many.runs if "error" in r]
    if failed:
        raise RuntimeError(f"{len(failed)} run(s) failed, first: {failed[0]}")
    cpu = float(np.mean([r["cpu_s"] for r in many.runs]))
    return {
        "case": label, "runs": setup.runs, "duration_s": setup.duration_s, "rate_hz": 100.0,
        "workers": workers, "wall_1_worker_s": one.wall_s, "wall_all_workers_s": many.wall_s,
        "speedup": one.wall_s / many.wall_s, "identical_runs": _same(one, many),
        "cost_per_run_1_worker_s": one.wall_s / setup.runs,
        "cost_per_run_all_workers_s": per_run_many,
        "run_simulate_s": sim_s, "run_total_s": run_s,
        # runs scale with their length (both paths are linear in the samples)
        "projected_1000_one_hour_runs_s": 1000 * per_run_many / hours,
        # what the same set needs on idle cores: CPU time per run, shared by the workers
        "cpu_per_run_s": cpu,
        "projected_1000_one_hour_runs_idle_cores_s": 1000 * cpu / hours / workers,
        "load_average_1min": os.getloadavg()[0],
    }


def _print(rows: list[dict]) -> None:
    print(f"{'case':<38} {'runs':>4} {'dur [s]':>7} {'1 worker':>9} {'all':>8} {'speed-up':>8} "
          f"{'same':>5} {'sim/run':>8} {'run':>7} {'1000 x 1 h':>11}")
    for r in rows:
        print(f"{r['case']:<38} {r['runs']:>4} {r['duration_s']:>7g} "
              f"{r['wall_1_worker_s']:>8.2f}s {r['wall_all_workers_s']:>7.2f}s "
              f"{r['speedup']:>8.2f} {str(r['identical_runs']):>5} {r['run_simulate_s']:>7.3f}s "
              f"{r['run_total_s']:>6.3f}s {r['projected_1000_one_hour_runs_s']:>10.0f}s")
    for r in rows:
        ok = r["speedup"] >= TARGET_SPEEDUP
        print(f"target speed-up >= {TARGET_SPEEDUP} with {r['workers']} workers ({r['case']}): "
              f"{r['speedup']:.2f} {'met' if ok else 'NOT met'}")
    r = rows[0]
    p, idle = r["projected_1000_one_hour_runs_s"], r["projected_1000_one_hour_runs_idle_cores_s"]
    print(f"target 1000 one-hour runs of lab_bench at 100 Hz in < {TARGET_1000_HOURS_S:g} s "
          f"({r['case']}): projected {p:.0f} s from the wall time "
          f"{'met' if p < TARGET_1000_HOURS_S else 'NOT met'}; {idle:.0f} s from the CPU time "
          f"per run ({r['cpu_per_run_s'] / (r['duration_s'] / 3600):.3f} s per hour of data) "
          f"on {r['workers']} idle cores; load average {r['load_average_1min']:.1f}")


def run(quick: bool, out_dir: pathlib.Path) -> list[dict]:
    workers = default_workers()
    if quick:
        cases = [("lab_bench, gyro_bias none (batch)", _setup(32, 600.0, "none")),
                 ("lab_bench, gyro_bias auto (per sample)", _setup(8, 60.0, "auto"))]
    else:
        cases = [("lab_bench, gyro_bias none (batch)", _setup(32, 3600.0, "none")),
                 ("lab_bench, gyro_bias auto (per sample)", _setup(16, 300.0, "auto"))]
    rows = [_measure(label, setup, workers) for label, setup in cases]
    _print(rows)
    return rows
