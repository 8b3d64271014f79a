"""The allocator setting of the local pool's workers, on a Dask cluster's workers while a set runs.

A run makes and frees chunk-sized numpy arrays thousands of times; with glibc's default
allocator each is mapped and faulted in afresh (:mod:`.allocator`).  A local pool's workers
keep freed memory for reuse; Dask's workers did not: Dask's nanny even sets
``MALLOC_TRIM_THRESHOLD_=65536`` in every worker it starts (its
``distributed.nanny.pre-spawn-environ``), so that a worker gives memory back at once.  A run
on Dask then cost 2–4× the CPU of the same run in the pool.

:class:`KeepFreedMemory` is a worker plugin that :func:`kept_on_workers` registers for the time
of one set: every worker (and one that joins meanwhile) keeps freed memory, as the pool's
workers do; when the set ends the plugin is removed, and its teardown restores the worker's
allocator (the environment's values, Dask's included) and gives the free memory back
(``malloc_trim``).  Dask's own ``MALLOC_TRIM_THRESHOLD_`` is not counted as the user's choice;
a value set by the user (another value, another ``MALLOC_*_`` variable, a glibc tunable)
still wins.  Imported only where Dask is used.
"""

from __future__ import annotations

import contextlib

from distributed.diagnostics.plugin import WorkerPlugin

from gyro_attitude.offline.allocator import keep_freed_memory, release_freed_memory

__all__ = ["PLUGIN_NAME", "KeepFreedMemory", "kept_on_workers"]

PLUGIN_NAME = "gyro-attitude-keep-freed-memory"


def _dask_environment() -> dict:
    """The variables Dask's nanny sets in its workers (its configuration, default
    ``MALLOC_TRIM_THRESHOLD_: 65536`` and one thread for BLAS/OpenMP)."""
    import dask

    out: dict = {}
    for key in ("distributed.nanny.environ", "distributed.nanny.pre-spawn-environ"):
        out.update(dask.config.get(key, default=None) or {})
    return out


class KeepFreedMemory(WorkerPlugin):
    """Keeps freed memory for reuse in a worker while registered (see the module docstring)."""

    name = PLUGIN_NAME

    def setup(self, worker=None) -> None:
        self.applied = keep_freed_memory(not_the_users=_dask_environment())

    def teardown(self, worker=None) -> None:
        if getattr(self, "applied", False):
            release_freed_memory()


@contextlib.contextmanager
def kept_on_workers(client):
    """The workers of ``client``'s cluster keep freed memory inside the block (a cluster that
    refuses the plugin runs the set as it is)."""
    registered = False
    try:
        client.register_plugin(KeepFreedMemory(), name=PLUGIN_NAME)
        registered = True
    except Exception:  # an older or locked-down scheduler: the set is only slower
        pass
    try:
        yield registered
    finally:
        if registered:
            with contextlib.suppress(Exception):  # the cluster may be gone by now
                client.unregister_worker_plugin(PLUGIN_NAME)
