"""Benchmark ``montecarlo-dask``: the same Monte Carlo set on the local pool and on a Dask cluster.

The set of the ``montecarlo`` suite's target case (``lab_bench`` at 100 Hz, causal estimator,
``gyro_bias none``, fixed seed) runs on a local pool of 2 worker processes and on a
``distributed.LocalCluster`` of 2 worker processes of 1 thread each, bound to 127.0.0.1 (started
before the clock starts: a user's cluster is running before the command).  Target: the Dask set
takes at most :data:`TARGET_RATIO` times the pool's wall time, with the same runs to the bit.

Sets, each its wall time, the CPU seconds per run inside the runs (``cpu_s`` of every run: the
CPU of the whole process that ran it over the run, so on Dask the worker's own threads too) and
whether its runs equal the first pool set's bit for bit.  Rounds of two, alternating, so that
a machine whose load drifts weighs on both sides alike:

* ``pool_k``: the local pool (its start-up, the forkserver's imports, counted: the command
  starts one every time);
* ``dask_k``: the same set on the cluster (round 1: the fresh cluster, its workers import numpy,
  scipy, the package and load the compiled kernels during it);

then on the warm cluster ``dask_untuned`` (without the allocator plugin: what this release did
before, every chunk-sized array faulted in afresh, Dask's nanny setting
``MALLOC_TRIM_THRESHOLD_``) and ``dask_tuned`` (the plugin back).  The target is checked on the
median over the rounds of the Dask set's wall time over the pool's of the same round, and on
round 1 alone (the fresh cluster) as well.

The machine may be shared: the 1-minute load average is written beside each set; rerun on a quiet
machine before believing a ratio.
"""

from __future__ import annotations

import contextlib
import os
import pathlib
import time

import numpy as np

from gyro_attitude.benchmarks.montecarlo import _same, _setup
from gyro_attitude.offline import dask_allocator
from gyro_attitude.offline import montecarlo as mc

TARGET_RATIO = 1.3
WORKERS = 2


@contextlib.contextmanager
def _no_plugin(_client):
    yield False


@contextlib.contextmanager
def _environment(clean: dict):
    """``os.environ`` as ``clean`` inside (a LocalCluster's nannies, living in this process, set
    Dask's ``MALLOC_TRIM_THRESHOLD_`` here for good: a pool started after them would inherit
    it, and its workers would take it for the user's choice and skip their allocator setting)."""
    saved = dict(os.environ)
    os.environ.clear()
    os.environ.update(clean)
    try:
        yield
    finally:
        os.environ.clear()
        os.environ.update(saved)


def _set(label: str, setup: mc.MonteCarloSetup, reference, **where) -> dict:
    load0 = os.getloadavg()[0]
    res = mc.run_montecarlo(setup, **where)
    failed = [r["error"] for r in res.runs if "error" in r]
    if failed:
        raise RuntimeError(f"{label}: {len(failed)} run(s) failed, first: {failed[0]}")
    return {"set": label, "wall_s": res.wall_s,
            "cpu_per_run_s": float(np.mean([r["cpu_s"] for r in res.runs])),
            "same_as_pool": True if reference is None else _same(reference.runs, res.runs),
            "load_average_1min": [load0, os.getloadavg()[0]], "_result": res}


def run(quick: bool, out_dir: pathlib.Path) -> list[dict]:
    import distributed

    runs, duration, rounds = (16, 600.0, 2) if quick else (16, 3600.0, 3)
    setup = _setup(runs, duration, "none", "causal")
    sets = []
    pool = None
    clean = dict(os.environ)  # before the cluster: the pool runs as the command would
    t0 = time.perf_counter()
    with distributed.LocalCluster(n_workers=WORKERS, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address=None) as cluster:
        cluster_start_s = time.perf_counter() - t0
        at = {"scheduler": cluster.scheduler_address}
        for k in range(1, rounds + 1):
            with _environment(clean):
                sets.append(_set(f"pool_{k}", setup, pool, workers=WORKERS))
            pool = pool or sets[-1]["_result"]
            sets.append(_set(f"dask_{k}", setup, pool, **at))
        tuned = dask_allocator.kept_on_workers
        dask_allocator.kept_on_workers = _no_plugin  # the release before: no plugin
        try:
            sets.append(_set("dask_untuned", setup, pool, **at))
        finally:
            dask_allocator.kept_on_workers = tuned
        sets.append(_set("dask_tuned", setup, pool, **at))
    by = {s["set"]: s for s in sets}
    ratios = [by[f"dask_{k}"]["wall_s"] / by[f"pool_{k}"]["wall_s"] for k in range(1, rounds + 1)]
    row = {"case": f"lab_bench causal gyro_bias none, {runs} x {duration:g} s at 100 Hz",
           "runs": runs, "duration_s": duration, "workers": WORKERS, "rounds": rounds,
           "cluster_start_s": cluster_start_s, "target_ratio": TARGET_RATIO,
           "ratios_dask_over_pool": ratios, "ratio_median": float(np.median(ratios)),
           "ratio_fresh_cluster": ratios[0]}
    for s in sets:
        tag = s["set"]
        row[f"wall_{tag}_s"] = s["wall_s"]
        row[f"cpu_per_run_{tag}_s"] = s["cpu_per_run_s"]
        row[f"same_{tag}"] = s["same_as_pool"]
        row[f"load_average_{tag}"] = s["load_average_1min"]
    row["untuned_over_tuned_cpu_per_run"] = (row["cpu_per_run_dask_untuned_s"]
                                             / row["cpu_per_run_dask_tuned_s"])
    row["untuned_over_tuned_wall"] = row["wall_dask_untuned_s"] / row["wall_dask_tuned_s"]
    row["same_runs"] = all(s["same_as_pool"] for s in sets)
    row["meets_target"] = bool(row["ratio_median"] <= TARGET_RATIO and row["same_runs"])
    print(f"{'set':<14} {'wall':>8} {'CPU/run':>8} {'same':>5} {'load':>9}")
    for s in sets:
        load = s["load_average_1min"]
        print(f"{s['set']:<14} {s['wall_s']:>7.2f}s {s['cpu_per_run_s']:>7.3f}s "
              f"{str(s['same_as_pool']):>5} {min(load):>4.1f}-{max(load):<4.1f}")
    print(f"(cluster of {WORKERS} workers, 1 thread each, started in {cluster_start_s:.1f} s "
          "before the sets; CPU/run: inside the runs, of the process that ran them)")
    print(f"target: Dask <= {TARGET_RATIO} x the pool's wall time with {WORKERS} workers, the "
          f"same runs: Dask/pool per round {', '.join(f'{r:.2f}' for r in ratios)}, median "
          f"{row['ratio_median']:.2f} {'met' if row['meets_target'] else 'NOT met'} (fresh "
          f"cluster {ratios[0]:.2f}); without the allocator plugin a Dask set takes "
          f"{row['untuned_over_tuned_wall']:.2f} x the wall time and "
          f"{row['untuned_over_tuned_cpu_per_run']:.2f} x the CPU per run")
    return [row]
