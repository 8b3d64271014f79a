"""Dask sets: workers lost as they go and none left, and the allocator of the workers during a set.

Clusters bind to 127.0.0.1 and are closed by their context managers."""

from __future__ import annotations

import platform
import threading
import time

import numpy as np
import pytest

from gyro_attitude.offline import allocator, parallel

distributed = pytest.importorskip("distributed")


@pytest.fixture(autouse=True)
def _environment_restored():
    """A LocalCluster's in-process nannies write Dask's variables into os.environ for good: the
    tests after these must not inherit them."""
    import os

    saved = dict(os.environ)
    yield
    os.environ.clear()
    os.environ.update(saved)


def _slow_square(x: int) -> int:
    time.sleep(0.3)
    return x * x


def _cluster(n: int = 1):
    return distributed.LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                    host="127.0.0.1", dashboard_address=None)


def test_a_dask_set_without_workers_ends_in_one_error_keeping_what_finished(capsys):
    out: dict = {}
    with _cluster() as cluster:
        def on_result(i, value):
            out[i] = value
            if len(out) == 1:  # every worker goes away (their tasks go back to the scheduler)
                threading.Thread(target=cluster.scale, args=(0,), daemon=True).start()

        t0 = time.monotonic()
        with pytest.raises(parallel.WorkersLost, match="no Dask worker .* for 2 s"):
            parallel.run_tasks(_slow_square, list(range(30)), on_result,
                               scheduler=cluster.scheduler_address, no_worker_timeout_s=2.0)
        elapsed = time.monotonic() - t0
    assert elapsed < 20.0  # not the 30-45 s (then forever) of the report
    assert out and all(v == i * i for i, v in out.items()) and len(out) < 30
    err = capsys.readouterr().err
    assert "lost (0 left" in err and "no Dask worker left; waiting up to 2 s" in err, err


def test_a_dask_scheduler_without_any_worker_is_not_waited_for_forever(capsys):
    with _cluster(0) as cluster:
        with pytest.raises(parallel.WorkersLost, match="0 task|1 of 1 task"):
            parallel.run_tasks(_slow_square, [1], print, scheduler=cluster.scheduler_address,
                               no_worker_timeout_s=1.0)
    assert "has no worker; waiting up to 1 s" in capsys.readouterr().err


# chunk-sized arrays made and freed as a run makes them: minor page faults (the allocator test's)
def _faults(_=None) -> tuple[object, int]:
    import resource

    f0 = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    for _ in range(50):
        a = np.ones((61440, 4))
        b = a * 2.0
        c = np.ones((360000, 3))
        d = c + 1.0
        del a, b, c, d
    return allocator._applied, resource.getrusage(resource.RUSAGE_SELF).ru_minflt - f0


@pytest.mark.skipif(platform.system() != "Linux" or platform.libc_ver()[0] != "glibc",
                    reason="the setting is glibc's")
def test_dask_workers_keep_freed_memory_during_a_set_and_give_it_back_after():
    """What made a Dask run cost 2-4x a pool run: every array faulted in afresh (Dask's nanny
    sets MALLOC_TRIM_THRESHOLD_=65536).  During a set the worker reuses freed memory like the
    pool's workers; after it, the worker is as Dask left it."""
    got: dict = {}
    with _cluster() as cluster, distributed.Client(cluster, set_as_default=False) as client:
        [(applied_before, default)] = client.run(_faults).values()
        parallel.run_tasks(_faults, [0, 1], got.__setitem__,
                           scheduler=cluster.scheduler_address)
        [(applied_after, _)] = client.run(_faults).values()
    assert applied_before is None and applied_after is None
    (applied, tuned_first), (_, tuned) = got[0], got[1]
    assert applied is True
    # the default maps and faults in every array afresh: ~ 50 x 3.4 MB of 4-KiB pages
    assert default > 20 * min(tuned, tuned_first), (default, tuned_first, tuned)


def _allocator_state(_=None):
    import os

    return allocator._applied, os.environ.get("MALLOC_TRIM_THRESHOLD_")


@pytest.mark.skipif(platform.system() != "Linux" or platform.libc_ver()[0] != "glibc",
                    reason="the setting is glibc's")
def test_a_pool_started_after_a_local_cluster_still_keeps_freed_memory():
    """A LocalCluster's in-process nannies write Dask's MALLOC_TRIM_THRESHOLD_ into this
    process's environment for good; the pool's workers inherit it and must not take it for the
    user's choice (they skipped their allocator setting: 2x the CPU per run)."""
    got: dict = {}
    with _cluster():
        pass
    parallel.run_tasks(_allocator_state, [0, 1], got.__setitem__, workers=2)
    # (the workers inherit the variable when the pool's forkserver starts after the cluster,
    # as when this test runs alone; started earlier in a session, it has the environment of
    # then: the workers must keep freed memory either way)
    assert all(applied is True for applied, _ in got.values()), got
