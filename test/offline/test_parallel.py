"""The task runner of montecarlo and fleet replay: a worker that dies, a task that raises."""

from __future__ import annotations

import os

import pytest

from gyro_attitude.offline import parallel


def _square_or_die_once(arg):
    """Worker task: ``x²``; for ``x == 3`` the first attempt kills its worker process (as the
    kernel's OOM killer would), marked by a file so the retry lives."""
    x, marker = arg
    if x == 3 and not os.path.exists(marker):
        open(marker, "w").close()
        os._exit(9)
    return x * x


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
    assert os.path.exists(marker)  # the worker did die (its nanny starts a new one)
    assert out == {i: i * i for i in range(6)}
