"""Benchmark of ``gyro-attitude montecarlo`` (suite ``montecarlo``): cost per run, 1 worker against
all, and the projection to the issue's target of 1000 one-hour runs of ``lab_bench`` at 100 Hz.

Each case runs the same set of runs (``lab_bench`` at 100 Hz, fixed seed) with 1 worker (in this
process) and with every CPU (a local process pool; its start-up included in the wall time), and
compares the per-run results bit for bit.  Cases: the estimator ``causal`` (the command's
default) and ``offline``, each with ``gyro_bias none`` (the gyro integrated whole: the issue's
target case) and the default ``auto`` (rests searched, the bias filter over every sample;
shorter runs, its cost per sample being constant).

What a row holds, so that a figure measured on a shared machine can be read:

* ``speedup``: wall time with 1 worker over the wall time with all (target ≥ 1.5 with 2), and
  ``speedup_without_startup`` with the pool's start-up taken out of the latter (paid once per
  command: the forkserver imports numpy, scipy and the package; the command's process runs
  tasks meanwhile, ``parent_tasks_all_workers`` of them, so the start-up is not all lost);
* CPU seconds per run inside the run (``cpu_per_run_*``) and of every process of ours over the
  set (``total_cpu_per_run_*``: the workers' whole lives, start-up, transfer and idle waits
  included, and this process's share): their ratio ``cpu_efficiency`` says whether the pool
  wastes work (1.0: none);
* ``cores_used_*``: total CPU seconds over wall seconds, the cores the machine gave the set.
  ``speedup ≈ cpu_efficiency × cores_used_all / cores_used_1``: when other processes keep the
  cores busy (and the kernel's autogroup shares the CPU per session, not per process) the
  second worker gets little, whatever the design;
* ``projected_1000_one_hour_runs_s`` from the measured wall time of all workers, and
  ``..._idle_cores_s`` = 1000 one-hour runs at the measured total CPU per run, spread over the
  workers, plus the pool start-up: the figure of an idle machine (target < 300 s on 2 cores);
  ``..._single_process_cpu_s`` the same at the CPU per run of one process (on a busy machine
  the workers' CPU time per run is inflated: the truth on an idle one lies between);
* the 1-minute load average at the start and the end of each set, and the phases of one run
  (simulation, estimation, the errors) in this process.

The machine may be shared: rerun on a quiet machine before believing a wall-time ratio.
"""

from __future__ import annotations

import dataclasses
import os
import pathlib
import time

import numpy as np

from gyro_attitude.core.attitude.settings import StreamConfig
from gyro_attitude.core.sim_topics import DEFAULT_FRAME_ID
from gyro_attitude.io.scene_file import load_scene
from gyro_attitude.offline import montecarlo as mc
from gyro_attitude.offline.parallel import default_workers
from gyro_attitude.offline.replay import estimate_recording

TARGET_SPEEDUP = 1.5
TARGET_1000_HOURS_S = 300.0


def _setup(runs: int, duration: float, bias: str, estimator: str) -> mc.MonteCarloSetup:
    spec = load_scene("lab_bench")
    config = StreamConfig(gyro_bias=bias, initial_attitude_source="truth")
    return mc.MonteCarloSetup(mc.grades_of(spec, [], load_scene), runs, duration, 100.0, 1,
                              mc.Estimator(config=config, kind=estimator))


def _phases(setup: mc.MonteCarloSetup, repeats: int = 3) -> dict:
    """CPU seconds of run 0's phases in this process (best of ``repeats``): the simulation,
    the estimator, and the whole run (the errors are the rest)."""
    spec = setup.grades[0].spec
    seed = mc.run_seeds(setup.seed, 1)[0]
    s = spec
    if not setup.estimator.config.uses_accelerometer:  # as run_one simulates it
        s = dataclasses.replace(spec, accelerometer=False)
    best = {"simulate": np.inf, "estimate": np.inf, "run": np.inf}
    for _ in range(repeats):
        c0 = time.process_time()
        block, gyro_var = mc.simulate_run(s, setup.rate_hz, setup.samples, seed)
        c1 = time.process_time()
        n = block.t_ns.shape[0]
        cov = np.broadcast_to(np.diag(gyro_var).reshape(9), (n, 9))
        config, nav = mc._scene_frame(s, block, setup.estimator.config)
        c2 = time.process_time()
        estimate_recording(block.t_ns, block.omega_ib_b, block.specific_force_b, cov,
                           DEFAULT_FRAME_ID, config=config, nav=nav,
                           algorithm=setup.estimator.algorithm, estimator=setup.estimator.kind,
                           truth=(block.t_ns, block.truth_q_nb))
        c3 = time.process_time()
        del block
        mc.run_one(spec, setup, 0, seed, "x")
        c4 = time.process_time()
        for k, v in (("simulate", c1 - c0), ("estimate", c3 - c2), ("run", c4 - c3)):
            best[k] = min(best[k], v)
    return {"run_simulate_cpu_s": best["simulate"], "run_estimate_cpu_s": best["estimate"],
            "run_errors_cpu_s": max(0.0, best["run"] - best["simulate"] - best["estimate"]),
            "run_cpu_s": best["run"]}


def _same(a: list[dict], b: list[dict]) -> bool:
    """Whether two lists of runs hold the same per-run results (times left out), bit for bit."""
    def key(r):
        return ({k: v for k, v in r.items() if k not in ("wall_s", "cpu_s", "_grid")},
                {k: np.asarray(v).tobytes() for k, v in r["_grid"].items()})
    return [key(r) for r in a] == [key(r) for r in b]


def _set_figures(res: mc.MonteCarloResult, tag: str) -> dict:
    failed = [r["error"] for r in res.runs if "error" in r]
    if failed:
        raise RuntimeError(f"{len(failed)} run(s) failed, first: {failed[0]}")
    n = len(res.runs)
    total = res.total_cpu_s()
    return {f"wall_{tag}_s": res.wall_s,
            f"cost_per_run_{tag}_s": res.wall_s / n,
            f"cpu_per_run_{tag}_s": float(np.mean([r["cpu_s"] for r in res.runs])),
            f"total_cpu_per_run_{tag}_s": total / n,
            f"cores_used_{tag}": total / res.wall_s,
            f"pool_startup_{tag}_s": res.cost.startup_s,
            # tasks this process ran itself while the pool's workers started
            f"parent_tasks_{tag}": res.cost.parent_tasks,
            f"load_average_{tag}": list(res.load_average)}


def _measure(label: str, setup: mc.MonteCarloSetup, workers: int) -> dict:
    row = {"case": label, "estimator": setup.estimator.kind.value,
           "gyro_bias": setup.estimator.config.gyro_bias.value, "runs": setup.runs,
           "duration_s": setup.duration_s, "rate_hz": setup.rate_hz, "workers": workers}
    row.update(_phases(setup))
    one = mc.run_montecarlo(setup, workers=1)
    many = mc.run_montecarlo(setup, workers=workers)
    row.update(_set_figures(one, "1_worker"))
    row.update(_set_figures(many, "all_workers"))
    hours = setup.duration_s / 3600.0
    row["speedup"] = one.wall_s / many.wall_s
    # the pool's start-up (the forkserver imports numpy, scipy and the package once per
    # command) is paid once per set: what it is worth against the runs themselves
    row["speedup_without_startup"] = one.wall_s / (many.wall_s - row["pool_startup_all_workers_s"])
    row["identical_runs"] = _same(one.runs, many.runs)
    row["cpu_efficiency"] = (row["total_cpu_per_run_1_worker_s"]
                             / row["total_cpu_per_run_all_workers_s"])
    row["cores_ratio"] = row["cores_used_all_workers"] / row["cores_used_1_worker"]
    # runs scale with their length (every path is linear in the samples)
    row["projected_1000_one_hour_runs_s"] = 1000 * row["cost_per_run_all_workers_s"] / hours
    row["projected_1000_one_hour_runs_idle_cores_s"] = (
        1000 * row["total_cpu_per_run_all_workers_s"] / hours / workers
        + row["pool_startup_all_workers_s"])
    # the same at the CPU cost of a run in one process (what the workers would spend if
    # sharing the machine did not inflate their CPU time: caches, descheduling)
    row["projected_1000_one_hour_runs_idle_cores_single_process_cpu_s"] = (
        1000 * row["total_cpu_per_run_1_worker_s"] / hours / workers
        + row["pool_startup_all_workers_s"])
    row["cpu_per_hour_of_data_s"] = row["total_cpu_per_run_all_workers_s"] / hours
    row["load_average_1min"] = os.getloadavg()[0]
    return row


def _print(rows: list[dict]) -> None:
    print(f"{'case':<24} {'runs':>4}x{'dur':<5} {'1 worker':>9} {'all':>8} {'speed-up':>8} "
          f"{'same':>5} {'CPU/run 1|all':>14} {'eff':>5} {'cores 1|all':>11} "
          f"{'sim|est|err /run':>18} {'load':>10}")
    for r in rows:
        load = r["load_average_1_worker"] + r["load_average_all_workers"]
        print(f"{r['case']:<24} {r['runs']:>4}x{r['duration_s']:<5g} "
              f"{r['wall_1_worker_s']:>8.2f}s {r['wall_all_workers_s']:>7.2f}s "
              f"{r['speedup']:>8.2f} {str(r['identical_runs']):>5} "
              f"{r['total_cpu_per_run_1_worker_s']:>6.3f}|{r['total_cpu_per_run_all_workers_s']:<6.3f}s"
              f" {r['cpu_efficiency']:>5.2f} "
              f"{r['cores_used_1_worker']:>5.2f}|{r['cores_used_all_workers']:<5.2f} "
              f"{r['run_simulate_cpu_s']:>5.3f}|{r['run_estimate_cpu_s']:.3f}|"
              f"{r['run_errors_cpu_s']:.3f}s {min(load):>4.1f}-{max(load):<4.1f}")
    print("(CPU/run: every process of ours over the set, per run; eff: CPU/run with 1 worker over "
          "CPU/run with all; cores: CPU seconds over wall seconds; sim|est|err: one run's phases "
          "in this process; load: 1-minute load average at the start and end of the sets)")
    for r in rows:
        ok = r["speedup"] >= TARGET_SPEEDUP
        print(f"target speed-up >= {TARGET_SPEEDUP} with {r['workers']} workers ({r['case']}): "
              f"{r['speedup']:.2f} {'met' if ok else 'NOT met'} (CPU efficiency "
              f"{r['cpu_efficiency']:.2f}, the machine gave {r['cores_used_1_worker']:.2f} and "
              f"{r['cores_used_all_workers']:.2f} cores, pool start-up "
              f"{r['pool_startup_all_workers_s']:.2f} s; {r['speedup_without_startup']:.2f} "
              f"without it)")
    for r in rows:
        if r["gyro_bias"] != "none":
            continue
        p, idle = r["projected_1000_one_hour_runs_s"], r["projected_1000_one_hour_runs_idle_cores_s"]
        single = r["projected_1000_one_hour_runs_idle_cores_single_process_cpu_s"]
        hours = r["duration_s"] / 3600.0
        print(f"target 1000 one-hour runs of lab_bench at 100 Hz in < {TARGET_1000_HOURS_S:g} s "
              f"({r['case']}): {idle:.0f} s on {r['workers']} idle cores from "
              f"{r['cpu_per_hour_of_data_s']:.3f} CPU-s per run in the pool "
              f"{'met' if idle < TARGET_1000_HOURS_S else 'NOT met'}; {single:.0f} s at the CPU "
              f"per run of one process ({r['total_cpu_per_run_1_worker_s'] / hours:.3f} s) "
              f"{'met' if single < TARGET_1000_HOURS_S else 'NOT met'}; "
              f"{p:.0f} s from this machine's wall time "
              f"{'met' if p < TARGET_1000_HOURS_S else 'NOT met'}")


def _target_row(workers: int, runs: int, one_worker_runs: int) -> dict:
    """The issue's case itself: ``runs`` one-hour ``lab_bench`` runs at 100 Hz (``gyro_bias
    none``, causal) with all workers, the whole set's wall time measured (the pool's start-up
    in it), against the first ``one_worker_runs`` of the same runs with 1 worker (the same
    seeds: run i is the same in any set), scaled to ``runs``."""
    many_setup = _setup(runs, 3600.0, "none", "causal")
    one_setup = _setup(one_worker_runs, 3600.0, "none", "causal")
    load0 = os.getloadavg()[0]
    one = mc.run_montecarlo(one_setup, workers=1)
    many = mc.run_montecarlo(many_setup, workers=workers)
    for res in (one, many):
        failed = [r["error"] for r in res.runs if "error" in r]
        if failed:
            raise RuntimeError(f"{len(failed)} run(s) failed, first: {failed[0]}")
    one_wall_scaled = one.wall_s * runs / one_worker_runs
    return {"case": f"target: causal, gyro_bias none, {runs} x 3600 s", "runs": runs,
            "one_worker_runs": one_worker_runs, "workers": workers,
            "wall_all_workers_s": many.wall_s, "wall_1_worker_s": one.wall_s,
            "wall_1_worker_scaled_s": one_wall_scaled,
            "speedup": one_wall_scaled / many.wall_s,
            "pool_startup_all_workers_s": many.cost.startup_s,
            "total_cpu_per_run_all_workers_s": many.total_cpu_s() / runs,
            "total_cpu_per_run_1_worker_s": one.total_cpu_s() / one_worker_runs,
            "identical_runs": _same(one.runs, many.runs[:one_worker_runs]),
            "target_s": TARGET_1000_HOURS_S if runs == 1000 else None,
            "meets_target": (many.wall_s < TARGET_1000_HOURS_S) if runs == 1000 else None,
            "meets_speedup": one_wall_scaled / many.wall_s >= TARGET_SPEEDUP,
            "load_average_1min": [load0, os.getloadavg()[0]]}


def _print_target(r: dict) -> None:
    print(f"{r['case']}: {r['workers']} workers {r['wall_all_workers_s']:.1f} s wall "
          f"(target < {TARGET_1000_HOURS_S:g} s: "
          f"{'met' if r['meets_target'] else 'NOT met' if r['meets_target'] is not None else 'n/a'})"
          f"; 1 worker {r['wall_1_worker_s']:.1f} s for the first {r['one_worker_runs']} "
          f"(x{r['runs'] / r['one_worker_runs']:g}: {r['wall_1_worker_scaled_s']:.0f} s); "
          f"speed-up {r['speedup']:.2f} (target >= {TARGET_SPEEDUP}: "
          f"{'met' if r['meets_speedup'] else 'NOT met'}); same runs "
          f"{r['identical_runs']}; CPU per run {r['total_cpu_per_run_1_worker_s']:.3f} | "
          f"{r['total_cpu_per_run_all_workers_s']:.3f} s; load "
          f"{min(r['load_average_1min']):.1f}-{max(r['load_average_1min']):.1f}")


def run(quick: bool, out_dir: pathlib.Path) -> list[dict]:
    workers = default_workers()
    if quick:
        sizes = {"none": (16, 600.0), "auto": (8, 60.0)}
    else:
        sizes = {"none": (32, 3600.0), "auto": (16, 300.0)}
    rows = []
    for estimator in ("causal", "offline"):
        for bias in ("none", "auto"):
            runs, duration = sizes[bias]
            label = f"{estimator}, gyro_bias {bias}"
            rows.append(_measure(label, _setup(runs, duration, bias, estimator), workers))
            print(f"  {label}: done (load {os.getloadavg()[0]:.1f})", flush=True)
    _print(rows)
    # the issue's case as the command runs it (quick: a tenth of it, no 300-s target)
    target = _target_row(workers, 100 if quick else 1000, 10 if quick else 100)
    _print_target(target)
    return rows + [target]
