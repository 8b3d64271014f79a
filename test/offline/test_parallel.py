"""The task runner of montecarlo and fleet replay: a worker that dies, a task that raises."""

from __future__ import annotations

import os
import platform
import time

import pytest

from gyro_attitude.core.attitude import compose
from gyro_attitude.offline import allocator, parallel


def _square_or_die_once(arg):
    """Worker task: ``x²``; for ``x == 3`` the first attempt kills its worker process (as the
    kernel's OOM killer would), marked by a file so the retry lives."""
    x, marker = arg
    if x == 3 and not os.path.exists(marker):
        open(marker, "w").close()
        os._exit(9)
    return x * x


def _burn(seconds):
    """Worker task: spends ``seconds`` of its process's CPU; returns what it spent, the
    composition threads of its process, its pid and whether its allocator keeps freed memory."""
    c0 = time.process_time()
    x = 0
    while time.process_time() - c0 < seconds:
        x += 1
    return time.process_time() - c0, compose._prepare_threads, os.getpid(), allocator._applied


def _raise_on_two(x):
    if x == 2:
        raise RuntimeError("planted bug\nsecond line")
    return -x


def test_a_lost_worker_is_replaced_and_its_tasks_run_again(tmp_path, capsys):
    marker = str(tmp_path / "died")
    out = {}
    parallel.run_tasks(_square_or_die_once, [(x, marker) for x in range(8)], out.__setitem__,
                       workers=2)
    assert os.path.exists(marker)  # the worker did die
    assert out == {i: i * i for i in range(8)}
    assert "a worker process died" in capsys.readouterr().err


@pytest.mark.parametrize("workers", [1, 2])
def test_a_task_that_raises_is_reported_and_the_others_finish(workers):
    out, errors = {}, {}
    parallel.run_tasks(_raise_on_two, list(range(5)), out.__setitem__, workers=workers,
                       on_error=errors.__setitem__)
    assert out == {0: 0, 1: -1, 3: -3, 4: -4}
    assert errors == {2: "RuntimeError: planted bug"}


def test_pool_workers_compose_single_threaded_and_their_cpu_is_counted():
    out = {}
    cost = parallel.run_tasks(_burn, [0.15] * 4, out.__setitem__, workers=2)
    spent = sum(v[0] for v in out.values())
    assert {v[1] for v in out.values()} == {0}  # no chunk threads beside the workers
    on_glibc = platform.system() == "Linux" and platform.libc_ver()[0] == "glibc"
    if not allocator._user_chose():
        assert {v[3] for v in out.values()} == {on_glibc}  # freed memory kept for reuse
    assert cost.processes == len({v[2] for v in out.values()}) >= 1
    assert os.getpid() not in {v[2] for v in out.values()}
    # each worker's whole life is counted: at least what the tasks spent, not the parent's
    assert spent <= cost.cpu_s < spent + 5.0
    assert cost.startup_s is not None and cost.startup_s > 0


def test_the_caller_runs_tasks_from_the_end_while_the_pool_starts(monkeypatch):
    """help_while_starting: while the workers start (made 0.4 s slower here, so that the
    caller surely has time) this process runs tasks itself, single-threaded, from the end
    of the list; every task runs exactly once, and the caller's composition threads are
    given back."""
    started = parallel._Starter.run

    def slow_start(self):
        time.sleep(0.4)
        started(self)

    monkeypatch.setattr(parallel._Starter, "run", slow_start)
    out = {}
    calls = []
    before = compose._prepare_threads
    cost = parallel.run_tasks(_burn, [0.05] * 8, lambda i, v: (calls.append(i),
                                                               out.__setitem__(i, v)),
                              workers=2, help_while_starting=True)
    assert sorted(calls) == list(range(8))  # each once
    mine = sorted(i for i, v in out.items() if v[2] == os.getpid())
    assert 1 <= cost.parent_tasks == len(mine) <= 4
    assert mine == list(range(8 - len(mine), 8))  # taken from the end
    assert {v[1] for v in out.values()} == {0}
    assert compose._prepare_threads == before
    assert cost.processes == len({v[2] for v in out.values()} - {os.getpid()})


def test_in_process_tasks_keep_the_composition_threads_and_count_this_process():
    out = {}
    before = compose._prepare_threads
    cost = parallel.run_tasks(_burn, [0.1, 0.1], out.__setitem__, workers=1)
    assert {v[1] for v in out.values()} == {before}
    assert {v[2] for v in out.values()} == {os.getpid()}
    spent = sum(v[0] for v in out.values())
    assert cost.processes == 1 and cost.startup_s == 0.0
    assert spent <= cost.cpu_s < spent + 1.0


def test_bad_worker_counts_are_refused():
    for bad in (0, -1, 1.5, True):
        with pytest.raises(ValueError, match="workers"):
            parallel.run_tasks(_raise_on_two, [1], print, workers=bad)


def test_dask_reruns_the_task_of_a_lost_worker(tmp_path):
    distributed = pytest.importorskip("distributed")
    marker = str(tmp_path / "died")
    out = {}
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address=None) as cluster:
        parallel.run_tasks(_square_or_die_once, [(x, marker) for x in range(6)],
                           out.__setitem__, scheduler=cluster.scheduler_address)
        threads = {}
        cost = parallel.run_tasks(_burn, [0.01], threads.__setitem__,
                                  scheduler=cluster.scheduler_address)
    assert os.path.exists(marker)  # the worker did die (its nanny starts a new one)
    assert out == {i: i * i for i in range(6)}
    assert threads[0][1] == 0  # a Dask task composes single-threaded
    assert cost.cpu_s is None  # the cluster's processes are not ours to measure
