"""Independent tasks on a local process pool or a Dask cluster, with progress, retries and Ctrl-C.

One engine for the Monte Carlo runs (:mod:`.montecarlo`) and the fleet replay (:mod:`.fleet`):
:func:`run_tasks` calls a module-level function on each argument of a list, in worker processes,
and hands every result to the caller's ``on_result(i, value)`` in the caller's process as it
arrives (in completion order: the caller files it under ``i``).

* ``workers == 1`` and no scheduler: the tasks run one after the other in this process (no
  pool start-up, and exceptions and Ctrl-C arrive directly).
* ``workers > 1``: :class:`concurrent.futures.ProcessPoolExecutor` with the ``forkserver``
  start method (``spawn`` where there is none): a worker starts from a clean interpreter, not
  from a copy of this process (its threads, its open files, the one-shot signal handler of the
  command line).  Workers ignore SIGINT: a Ctrl-C on the terminal reaches the whole process
  group, and only this process decides what happens; SIGTERM (how it stops them) ends a
  worker's task with SystemExit, so the task's clean-up runs.  A worker that dies (killed, out of
  memory) breaks the pool: the tasks not yet finished are run again in a new pool, at most
  :data:`POOL_RESTARTS` times.
* ``help_while_starting``: while the pool's first worker is being started (the forkserver
  importing numpy, scipy and the task's module: seconds, once per call), this process runs
  tasks itself, from the end of the list (single-threaded, as a worker would); it stops
  taking tasks once the workers exist (the one it is in finishes: at most one task beside
  the workers).  For short tasks of equal cost (Monte Carlo runs); a long task would keep
  this process from collecting the others' results meanwhile.
* Every worker process and every Dask task composes attitudes single-threaded
  (:func:`gyro_attitude.core.attitude.compose.set_prepare_threads` 0, and one BLAS/OpenMP
  thread in the pool): the workers are the parallelism, and threads of their own beside them
  on the same cores only add switching.
* Every local worker process keeps the memory of freed arrays for the next ones
  (:func:`gyro_attitude.offline.allocator.keep_freed_memory`, as the command-line process
  does): a task's chunk-sized arrays would otherwise be mapped and faulted in afresh each
  time, and most of all in a new worker.  Dask's workers do the same while the set runs (a
  worker plugin, :mod:`.dask_allocator`, removed at the end: they give the memory back); the
  caller's process is left as it is.
* ``scheduler``: a running ``dask.distributed`` scheduler at that address; Dask is imported only
  then.  The scheduler itself re-runs the tasks of a lost worker (its ``allowed-failures``
  setting, 3 by default); a task that killed too many workers is reported as failed.  Lost
  workers are reported on stderr as they go; when the cluster has had no worker for
  ``no_worker_timeout_s`` the set ends with :class:`WorkersLost` (what finished was handed
  over already).

A task function should catch its own errors (a run that fails is a result); an exception that
still escapes is given to ``on_error(i, message)`` and the other tasks go on.  On
KeyboardInterrupt the tasks not finished are cancelled, the local workers terminated (Dask's
cancelled), and the KeyboardInterrupt re-raised: what ``on_result`` received so far is what
finished.
"""

from __future__ import annotations

import contextlib
import functools
import multiprocessing
import multiprocessing.forkserver
import os
import resource
import signal
import sys
import threading
import time
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass

from gyro_attitude.core.attitude.compose import set_prepare_threads
from gyro_attitude.io.safe_output import raise_if_stop_requested
from gyro_attitude.offline.allocator import keep_freed_memory

__all__ = ["POOL_RESTARTS", "CONNECT_TIMEOUT_S", "NO_WORKER_TIMEOUT_S", "default_workers",
           "run_tasks", "SchedulerUnreachable", "TaskCost", "WorkersLost"]

POOL_RESTARTS = 2
#: Seconds to wait for a Dask scheduler before giving up (one line, exit 1).
CONNECT_TIMEOUT_S = 10.0
#: Seconds a Dask set waits while the cluster has no worker before it ends (:class:`WorkersLost`).
NO_WORKER_TIMEOUT_S = 30.0
#: Seconds between two looks at the cluster's workers during a Dask set.
WORKER_POLL_S = 1.0


class SchedulerUnreachable(OSError):
    """No Dask scheduler answered at the address within the timeout."""


class WorkersLost(OSError):
    """The Dask cluster had no worker for the timeout (every worker lost, none came back):
    the tasks not finished are cancelled; what finished was handed to ``on_result``."""


@dataclass(frozen=True)
class TaskCost:
    """What running a list of tasks cost, as :func:`run_tasks` measured it.

    ``cpu_s``: CPU seconds (user + system, all threads) of the processes that ran the tasks:
    in this process, its CPU during the tasks; on a local pool, each worker's whole life since
    it was forked (start-up, unpickling and idle waits included; this process's own share,
    submitting and collecting, is not); None on Dask (its workers are not ours to measure).
    ``processes``: worker processes that ran tasks.  ``startup_s``: seconds from creating the
    local pool until the last of its workers began its first task (0 in this process, None on
    Dask).  ``parent_tasks``: tasks a pool's caller ran itself while its workers started
    (``help_while_starting``; their CPU is this process's, not in ``cpu_s``)."""

    cpu_s: float | None
    processes: int
    startup_s: float | None
    parent_tasks: int = 0


def _process_cpu_s() -> float:
    """CPU seconds of this process so far, every thread (``getrusage(RUSAGE_SELF)``; a forked
    worker's count starts at its fork)."""
    u = resource.getrusage(resource.RUSAGE_SELF)
    return u.ru_utime + u.ru_stime


def default_workers() -> int:
    """CPUs this process may run on (the affinity mask, which a container or taskset narrows;
    ``os.cpu_count()`` counts the machine's)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


_stopping = False  # set in a worker by SIGTERM: it takes no further task
_in_task = False  # a worker is running a task's code (SIGTERM then raises in it)


def _stop_on_sigterm(_signum, _frame) -> None:
    global _stopping
    _stopping = True
    if not _in_task:  # between tasks: nothing to clean up, and no exception to escape
        os._exit(128 + signal.SIGTERM)
    raise SystemExit(128 + signal.SIGTERM)


def _call(fn, arg):
    """A task in a pool worker: ``(fn(arg), (pid, the worker's CPU seconds after it, the
    monotonic time it began))``.  A worker whose task SIGTERM ended goes on to the next item
    already queued to it (the executor catches the exception of a task): it ends instead."""
    global _in_task
    if _stopping:
        os._exit(128 + signal.SIGTERM)
    began = time.monotonic()
    _in_task = True
    try:
        value = fn(arg)
    finally:
        _in_task = False
    return value, (os.getpid(), _process_cpu_s(), began)


def _dask_call(fn, arg):
    """A task on a Dask worker: composed single-threaded (the cluster's workers are the
    parallelism; idempotent, so every task may set it)."""
    set_prepare_threads(0)
    return fn(arg)


def _worker_init(not_the_users: dict | None = None) -> None:
    """A worker ignores Ctrl-C (the command decides) and ends its task on SIGTERM by an
    exception, so that the task's clean-up runs (a half-written output is removed) before
    the process ends; it composes attitudes single-threaded and keeps freed array memory for
    reuse (the module docstring; ``not_the_users``: environment variables set by Dask, see
    :func:`_dask_set_environment`)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, _stop_on_sigterm)
    set_prepare_threads(0)
    keep_freed_memory(not_the_users or {})


def _dask_set_environment() -> dict:
    """Variables a ``distributed.LocalCluster`` of this process set in its environment (its
    in-process nannies write Dask's ``MALLOC_TRIM_THRESHOLD_`` into ``os.environ`` for good):
    a pool's workers inherit them, and must not take them for the user's choice.  Empty when
    Dask was never imported here."""
    if "distributed" not in sys.modules:
        return {}
    from gyro_attitude.offline.dask_allocator import _dask_environment

    return _dask_environment()


def _context():
    methods = multiprocessing.get_all_start_methods()
    return multiprocessing.get_context("forkserver" if "forkserver" in methods else "spawn")


#: Thread counts of the BLAS/OpenMP libraries numpy may load, read once at their import: one
#: thread per worker process (the workers are the parallelism; BLAS threads spinning beside
#: them on the same cores slowed a 2-worker set down instead of up).  A value the user set wins.
_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


@contextlib.contextmanager
def _single_threaded_children():
    """The environment of the worker processes started inside (and of the forkserver, which
    passes its own on to the workers it forks), without changing this process's for good."""
    added = [k for k in _THREAD_VARIABLES if k not in os.environ]
    for k in added:
        os.environ[k] = "1"
    try:
        yield
    finally:
        for k in added:
            os.environ.pop(k, None)


@contextlib.contextmanager
def _signals_held():
    """SIGINT and SIGTERM held while the pool starts its workers, and delivered after.

    A Ctrl-C in the middle of starting a worker interrupts this process after the forkserver
    forked the worker but before the executor knew its pid: the worker cannot be stopped, and
    it prints a traceback when it finds the pool gone.  Held here, the signal arrives when
    every worker is known (at most the start-up later), and the clean-up stops them all.
    Only in the main thread (where Python runs signal handlers)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    got: list[int] = []
    held = (signal.SIGINT, signal.SIGTERM)
    previous = {s: signal.signal(s, lambda sig, _frame: got.append(sig)) for s in held}
    try:
        yield
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
        if got:
            signal.raise_signal(got[0])  # to the handler it was meant for


def _describe(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[0] if text else ''}".rstrip(": ")


def run_tasks(fn: Callable, args: Sequence, on_result: Callable[[int, object], None], *,
              workers: int = 1, scheduler: str | None = None,
              on_error: Callable[[int, str], None] | None = None,
              progress: Callable[[int], None] | None = None,
              connect_timeout_s: float = CONNECT_TIMEOUT_S,
              help_while_starting: bool = False, preload: Sequence[str] = (),
              no_worker_timeout_s: float = NO_WORKER_TIMEOUT_S) -> TaskCost:
    """``on_result(i, fn(args[i]))`` for every task (see the module docstring); returns what
    they cost (:class:`TaskCost`; an interrupted run raises instead).

    ``preload``: modules the tasks import where they use them (the package imports scipy
    lazily), imported once by the forkserver beside ``fn``'s module instead of once per worker.

    ``progress(i)`` is called after each task's result or error.  Raises
    :class:`SchedulerUnreachable` when the scheduler does not answer within
    ``connect_timeout_s``, :class:`WorkersLost` when a Dask cluster has had no worker for
    ``no_worker_timeout_s`` (lost workers are reported on stderr as they go), and
    KeyboardInterrupt after cleaning up.
    """
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"workers must be an integer >= 1, got {workers!r}")

    def done(i: int, value=None, error: str | None = None) -> None:
        if error is not None:
            # an error while a stop is pending is the stop itself, swallowed on its way (an
            # interrupted import re-raised as ImportError), not the task's failure
            raise_if_stop_requested()
        if error is None:
            on_result(i, value)
        elif on_error is not None:
            on_error(i, error)
        else:
            raise RuntimeError(f"task {i}: {error}")
        if progress is not None:
            progress(i)
        # the tasks stop at the next result even when the signal's own exception was
        # swallowed inside a task of this process (what finished is kept)
        raise_if_stop_requested()

    if scheduler is not None:
        _run_dask(fn, args, done, scheduler, connect_timeout_s, no_worker_timeout_s)
        return TaskCost(None, 0, None)
    if workers == 1 or len(args) <= 1:
        cpu0 = _process_cpu_s()
        for i, a in enumerate(args):
            try:
                value = fn(a)
            except Exception as exc:  # a bug in one task must not lose the others
                done(i, error=_describe(exc))
            else:
                done(i, value)
        return TaskCost(_process_cpu_s() - cpu0, 1, 0.0)
    return _run_pool(fn, args, done, workers, help_while_starting, tuple(preload))


def _run_in_parent(fn, arg, done, i: int) -> None:
    """Task ``i`` in this process while the pool starts, single-threaded like a worker."""
    previous = set_prepare_threads(0)
    try:
        value = fn(arg)
    except Exception as exc:  # as in a worker: reported, the others go on
        done(i, error=_describe(exc))
    else:
        done(i, value)
    finally:
        set_prepare_threads(previous)


def _run_pool(fn, args, done, workers: int, help_while_starting: bool = False,
              preload: tuple[str, ...] = ()) -> TaskCost:
    pending = list(range(len(args)))
    cpu: dict[int, float] = {}  # worker pid: its CPU seconds at its latest finished task
    first_start: dict[int, float] = {}  # worker pid: when it began its first task
    startup = None
    parent_tasks = 0
    for attempt in range(POOL_RESTARTS + 1):
        created = time.monotonic()
        context = _context()
        with _single_threaded_children():
            if context.get_start_method() == "forkserver":
                # the server imports the task's module once and forks the workers from it:
                # they start with numpy and the package loaded (one import, not one each)
                context.set_forkserver_preload(["__main__", fn.__module__, *preload])
                multiprocessing.forkserver.ensure_running()
            pool = ProcessPoolExecutor(max_workers=min(workers, len(pending)),
                                       mp_context=context, initializer=_worker_init,
                                       initargs=(_dask_set_environment(),))
        futures = {}
        starter = None
        try:
            # the workers start at the first submits (the first blocks until the forkserver
            # has imported the task's module)
            if help_while_starting and len(pending) > 1:
                # The head of the list is submitted from a thread (its first submit waits
                # for the forkserver) while this thread runs tasks from the end of the
                # list; the rest of the tail is submitted when the workers exist.
                split = len(pending) - len(pending) // 2
                head, tail = pending[:split], pending[split:]
                starter = _Starter(pool, fn, args, head)
                with _single_threaded_children():
                    starter.start()
                    while starter.is_alive() and tail:
                        i = tail.pop()
                        _run_in_parent(fn, args[i], done, i)
                        pending.remove(i)
                        parent_tasks += 1
                    starter.join()
                starter.raise_error()
                futures = dict(starter.futures)
                with _single_threaded_children(), _signals_held():
                    futures.update({pool.submit(_call, fn, args[i]): i for i in tail})
            else:
                with _single_threaded_children(), _signals_held():
                    futures = {pool.submit(_call, fn, args[i]): i for i in pending}
            not_done = set(futures)
            while not_done:
                finished, not_done = wait(not_done, return_when=FIRST_COMPLETED)
                for f in finished:
                    i = futures[f]
                    exc = f.exception()
                    if isinstance(exc, BrokenProcessPool):
                        continue  # a worker died: retried in the next pool
                    pending.remove(i)
                    if exc is not None:
                        done(i, error=_describe(exc))
                    else:
                        value, (pid, cpu_s, began) = f.result()
                        cpu[pid] = max(cpu.get(pid, 0.0), cpu_s)
                        first_start[pid] = min(first_start.get(pid, began), began)
                        done(i, value)
        except BaseException:  # Ctrl-C, or on_result raised: stop the workers first
            if starter is not None:
                with _signals_held():  # every worker started and known before stopping them
                    starter.join()
            _terminate(pool)
            raise
        pool.shutdown(wait=True)
        if startup is None and first_start:
            startup = max(first_start.values()) - created
        if not pending:
            break
        if attempt < POOL_RESTARTS:
            print(f"warning: a worker process died; running its {len(pending)} unfinished "
                  f"task(s) again in a new pool", file=sys.stderr)
    for i in list(pending):
        done(i, error=f"a worker process died while running it ({POOL_RESTARTS + 1} attempts)")
    return TaskCost(sum(cpu.values()), len(cpu), startup, parent_tasks)


class _Starter(threading.Thread):
    """Submits ``indices`` to ``pool`` (starting its workers) off the calling thread."""

    def __init__(self, pool, fn, args, indices):
        super().__init__(name="pool-starter", daemon=True)
        self._work = (pool, fn, args, indices)
        self.futures: dict = {}
        self._error: BaseException | None = None

    def run(self) -> None:
        pool, fn, args, indices = self._work
        try:
            for i in indices:
                self.futures[pool.submit(_call, fn, args[i])] = i
        except BaseException as exc:  # given to the caller by raise_error
            self._error = exc

    def raise_error(self) -> None:
        if self._error is not None:
            raise self._error


def _terminate(pool: ProcessPoolExecutor) -> None:
    """Stop the pool now: queued tasks cancelled, running workers terminated (Python 3.11
    has no public call for the latter; ``_processes`` is the executor's own table)."""
    processes = list((getattr(pool, "_processes", None) or {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    for p in processes:
        if p.is_alive():
            p.terminate()
    for p in processes:
        p.join(timeout=10)
        if p.is_alive():  # its task did not end on SIGTERM within 10 s
            p.kill()
            p.join(timeout=5)


def _dask_workers(client) -> set[str] | None:
    """Addresses of the cluster's workers now, or None when the scheduler does not answer."""
    try:
        return set(client.nthreads())
    except (OSError, TimeoutError):
        return None


class _WorkerWatch:
    """Reports workers lost (and joining after a loss) as they go, and ends the set when the
    cluster has had no worker for ``no_worker_timeout_s`` (:class:`WorkersLost`)."""

    def __init__(self, client, address: str, total: int, no_worker_timeout_s: float,
                 warn: Callable[[str], None]):
        self.client, self.address, self.total = client, address, total
        self.timeout_s, self.warn = no_worker_timeout_s, warn
        self.known = _dask_workers(client) or set()
        self.lost_any = False
        self.alone_since = None if self.known else time.monotonic()
        self.next_check = time.monotonic() + WORKER_POLL_S
        if not self.known:
            warn(f"the Dask scheduler at {address} has no worker; waiting up to "
                 f"{self.timeout_s:g} s for one")

    def check(self, unfinished: int) -> None:
        now = time.monotonic()
        if now < self.next_check:
            return
        self.next_check = now + WORKER_POLL_S
        workers = _dask_workers(self.client)
        if workers is None:
            workers = set()
            if self.known:
                self.warn(f"the Dask scheduler at {self.address} does not answer")
        for w in sorted(self.known - workers):
            self.lost_any = True
            self.warn(f"Dask worker {w} lost ({len(workers)} left"
                      + ("; the scheduler runs its tasks again on the others)" if workers
                         else ")"))
        if self.lost_any:
            for w in sorted(workers - self.known):
                self.warn(f"Dask worker {w} joined ({len(workers)} now)")
        self.known = workers
        if workers:
            self.alone_since = None
            return
        if self.alone_since is None:
            self.alone_since = now
            if self.lost_any:
                self.warn(f"no Dask worker left; waiting up to {self.timeout_s:g} s for one")
        elif now - self.alone_since >= self.timeout_s:
            raise WorkersLost(
                f"no Dask worker at {self.address} for {self.timeout_s:g} s"
                + (" (every worker was lost)" if self.lost_any else "")
                + f": {unfinished} of {self.total} task(s) unfinished")


def _warn(message: str) -> None:
    print(f"warning: {message}", file=sys.stderr, flush=True)


def _run_dask(fn, args, done, address: str, timeout_s: float,
              no_worker_timeout_s: float = NO_WORKER_TIMEOUT_S,
              warn: Callable[[str], None] = _warn) -> None:
    # Dask only here: the local path does not pay its import (~1 s).
    try:
        from distributed import Client, as_completed
    except ImportError as exc:  # pragma: no cover - pinned in requirements.txt
        raise OSError(f"--scheduler needs dask.distributed: {exc}") from None
    from distributed.comm.addressing import parse_address, parse_host_port

    from gyro_attitude.offline.dask_allocator import kept_on_workers

    try:  # a malformed address fails inside Client() and again in its finalizer: check first
        parse_host_port(parse_address(address)[1])
    except (ValueError, TypeError) as exc:
        raise ValueError(f"--scheduler {address!r} is not a scheduler address "
                         f"(tcp://host:port): {exc}") from None
    try:
        client = Client(address, timeout=f"{timeout_s}s", set_as_default=False)
    except (OSError, TimeoutError, ValueError) as exc:
        raise SchedulerUnreachable(
            f"no Dask scheduler answered at {address!r} within {timeout_s:g} s "
            f"({_describe(exc)})") from None
    futures = []
    try:
        with kept_on_workers(client):
            watch = _WorkerWatch(client, address, len(args), no_worker_timeout_s, warn)
            # pure=False: every task runs (two equal arguments are still two runs to count)
            futures = client.map(functools.partial(_dask_call, fn), list(args), pure=False)
            index = {f.key: i for i, f in enumerate(futures)}
            unfinished = len(futures)
            results = as_completed(futures, loop=client.loop)
            while unfinished:
                # without blocking: the watch must run while nothing finishes (no worker);
                # it looks at the cluster once a second, results arriving or not
                watch.check(unfinished)
                batch = results.next_batch(block=False)
                if not batch:
                    time.sleep(0.02)
                    continue
                for f in batch:
                    unfinished -= 1
                    i = index[f.key]
                    try:
                        # waits: a future whose worker was lost can be handed out before its
                        # rerun ends
                        value = f.result()
                    except Exception as exc:  # the task raised, or killed too many workers
                        done(i, error=_describe(exc))
                    else:
                        done(i, value)
    except (KeyboardInterrupt, WorkersLost):
        client.cancel(futures)
        raise
    finally:
        client.close(timeout=timeout_s)
