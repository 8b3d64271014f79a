"""The one ``main()`` life cycle every gyro_attitude node shares (demo_nodes_py style).

init → build the node and its executor → ``gc.freeze()`` → rclpy's signal handlers → spin →
rclpy's signal handlers off → the executor's shutdown → the node's own ``finish`` → destroy
→ shutdown (:func:`run_node` says why in this order; a signalled process exits once its
output is finished, without the destroy and shutdown). Exit status: 0 when the node is done
or on SIGINT/SIGTERM/SIGHUP (a closed terminal is an orderly shutdown too; also when the
signal is repeated during shutdown: ``ros2 launch`` forwards the terminal's Ctrl-C, so every
node gets it twice); 2 with one line on an invalid parameter
(:class:`~gyro_attitude.ros.params.ParameterError`, also a missing or unreadable
``--params-file``); 1 with one line when the node's input is unusable (:class:`InputError`)
or its output cannot be written (a full disk:
:class:`~gyro_attitude.io.safe_output.OutputWriteError`). Never a traceback for any of these.
"""

from __future__ import annotations

import gc
import os
import signal
import sys
import threading
from collections.abc import Callable

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.signals import (
    SignalHandlerOptions,
    install_signal_handlers,
    uninstall_signal_handlers,
)

from gyro_attitude.io.ament_prefix import ensure_ament_prefix_path
from gyro_attitude.io.safe_output import OutputWriteError
from gyro_attitude.ros.params import ParameterError

RCLError = _rclpy.RCLError

__all__ = ["run_node", "InputError", "ShutdownSignals", "EXIT_OK", "EXIT_INPUT",
           "EXIT_OUTPUT", "EXIT_PARAMETER", "EXECUTORS", "INPUT_THREAD", "make_executor",
           "spin_executor"]

EXIT_OK = 0
EXIT_INPUT = 1  # the input (a recording) cannot be used
EXIT_OUTPUT = 1  # the output (a recording) cannot be written
EXIT_PARAMETER = 2  # a parameter (or the parameter file) is invalid


class InputError(ValueError):
    """The node's input (e.g. the recording to play) cannot be used; the message says why."""


class ShutdownSignals:
    """SIGINT/SIGTERM/SIGHUP handlers that turn the first signal into an orderly shutdown
    request and ignore every later one.

    Python's default SIGINT handler raises ``KeyboardInterrupt`` wherever the main thread is,
    including inside ``destroy_node`` or a file's ``finish`` when the signal repeats; its
    default SIGTERM kills the process without finishing anything. These handlers raise
    nothing: they only record the signal. The wake-up comes from rclpy's own C-level handler
    (installed by :func:`run_node` after these, so it chains to them): its signal thread
    triggers every executor's signal guard condition and shuts the contexts down, which ends
    ``spin`` with ``ExternalShutdownException`` and makes ``rclpy.ok()`` false for
    hand-written loops. A shutdown must not be started from here: a Python handler runs
    between two bytecodes of the main thread, possibly while it holds the context's
    (non-reentrant) lock.

    SIGHUP (the terminal was closed) would kill the process without finishing anything, and
    rclpy has no handler for it: its handler sends this process a SIGTERM, which rclpy's
    handler turns into the same shutdown.
    """

    SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)

    def __init__(self) -> None:
        self.received: int | None = None

    def install(self) -> bool:
        """Install on the main thread (signals are delivered there only); False elsewhere."""
        if threading.current_thread() is not threading.main_thread():
            return False
        for sig in self.SIGNALS:
            signal.signal(sig, self._handle)
        return True

    def _handle(self, signum, _frame) -> None:
        if self.received is None:
            self.received = signum
            if signum == signal.SIGHUP:
                os.kill(os.getpid(), signal.SIGTERM)

    def _unraisable(self, info) -> None:
        # After a shutdown signal, rclpy objects whose construction the shutdown cut short
        # (an executor created just as the context went invalid) complain from __del__;
        # that is noise about the shutdown the user asked for, not an error to report.
        if self.received is None:
            self._previous_unraisable(info)

    def silence_unraisable_after_signal(self) -> None:
        self._previous_unraisable = sys.unraisablehook
        sys.unraisablehook = self._unraisable

    def ignore_from_now_on(self) -> None:
        """Ignore the signals for the rest of the process (only once it is exiting).

        Interpreter finalization resets signals that have a Python handler to the default
        action, so a repeat arriving then would kill the process with -SIGINT; an ignored
        signal stays ignored.
        """
        if threading.current_thread() is threading.main_thread():
            for sig in self.SIGNALS:
                signal.signal(sig, signal.SIG_IGN)


def _params_file_problem(args: list[str] | None) -> str | None:
    """A reason when a ``--params-file`` named on the command line cannot be read.

    rcl parses the arguments inside ``rclpy.init`` and fails on a missing file with an
    ``RCLError`` whose text is a C source location; checking first gives one plain line.
    """
    argv = sys.argv if args is None else args
    for i, arg in enumerate(argv[:-1]):
        if arg == "--params-file":
            path = argv[i + 1]
            try:
                with open(path, "rb"):
                    pass
            except OSError as exc:
                return f"--params-file {path}: {exc.strerror or exc}"
    return None


#: ``executor`` parameter values: ``input_thread`` takes a node's input subscriptions on a
#: thread of its own (:mod:`gyro_attitude.ros.input_thread`) and leaves the rest (timers,
#: parameter services) to rclpy's SingleThreadedExecutor; ``single_threaded`` is that executor
#: for everything; ``events`` is rclpy.experimental.EventsExecutor (Jazzy), which waits on the
#: middleware's per-entity events instead of rebuilding a wait set for every callback.
#: ``events`` is not the default: with the pinned Jazzy wheels (ros-jazzy-rclpy 7.1.6) its
#: ``spin()`` holds the GIL while it waits: a 10 Hz timer did not fire once in 2 s, a
#: publishing thread never ran, and ``spin_once`` hung on a queue of 20 000 messages (checked
#: by hand, 2026-12-01).
INPUT_THREAD = "input_thread"
EXECUTORS = (INPUT_THREAD, "single_threaded", "events")


def make_executor(kind: str, say: Callable[[str], None] | None = None):
    """The executor ``kind`` (one of :data:`EXECUTORS`; ``input_thread``: the single-threaded
    one, beside the node's input thread); ``events`` falls back to the
    single-threaded one (with a line through ``say``) where this rclpy has no events executor
    or it cannot be built."""
    from rclpy.executors import SingleThreadedExecutor

    if kind == "events":
        try:
            from rclpy.experimental import EventsExecutor

            executor = EventsExecutor()
            if say is not None:
                say("executor 'events' is experimental in Jazzy (its spin holds the GIL: "
                    "timers and threads may starve)")
            return executor
        except Exception as exc:  # ImportError on an older rclpy, or a failed construction
            if say is not None:
                say(f"events executor unavailable ({type(exc).__name__}: {exc}); "
                    "using the single-threaded executor")
    return SingleThreadedExecutor()


def spin_executor(node: Node, executor) -> None:
    """Spin ``executor`` (which holds ``node``) until shutdown: what :func:`run_node` does by
    default. A node's own ``spin`` gets the same two arguments and must leave the executor to
    :func:`run_node` (no ``shutdown``): see there why."""
    executor.spin()


#: how long tearing the node down (destroying its entities, shutting rclpy down) may take once
#: its work is finished before the process exits without waiting for it
TEARDOWN_TIMEOUT_S = 15.0


def _exit_if_teardown_hangs(name: str, status: int) -> threading.Timer:
    """A timer that ends the process with ``status`` after :data:`TEARDOWN_TIMEOUT_S`, saying
    so in one line; cancelled when the teardown returns in time.

    Under load, a node signalled twice has been seen blocked in rclpy's ``destroy_node``, inside
    the middleware's destruction of a publisher (a C call that never returned; twice in the
    clean-clone CI runs of test_signals on 2026-12-04, with no other Python thread left). Nothing is
    left to save by then (an output is finished before the teardown starts), so the process
    exits as the user asked instead of hanging; the operating system frees what the
    middleware held."""

    def give_up():
        try:
            print(f"[{name}] the middleware did not tear the node down within "
                  f"{TEARDOWN_TIMEOUT_S:g} s; exiting without waiting for it", file=sys.stderr,
                  flush=True)
            sys.stdout.flush()
        finally:
            os._exit(status)

    timer = threading.Timer(TEARDOWN_TIMEOUT_S, give_up)
    timer.daemon = True
    timer.start()
    return timer


def _exit_without_teardown(status: int) -> None:
    """End a signalled process now that its output is finished, without destroying the node.

    The middleware's destruction of a publisher after a signal has been seen to block inside
    a C call that holds the GIL (clean-clone CI, 2026-12-07: ``publisher.destroy`` still
    running 60 s after one SIGINT), so no Python watchdog thread can run to end it. The user
    asked the process to stop and nothing is left to save, so it exits here as after a
    crash-free ``exit``: stdio flushed, the operating system freeing what the middleware
    held (DDS peers see the participant go when its lease ends)."""
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(status)


def _destroy(node: Node) -> None:
    """``destroy_node`` that tolerates a context already shut down by a signal."""
    try:
        node.destroy_node()
    except Exception:  # handles of an invalid context: nothing left to free
        pass


def _quiesce_signal_handling() -> None:
    """Stop rclpy's signal thread and hand SIGINT/SIGTERM back to :class:`ShutdownSignals`.

    rclpy (7.1, Jazzy) answers a signal from a thread of its own that walks a global list of
    raw guard-condition pointers (one per executor) and triggers each, with no lock against
    an executor registering or destroying its guard condition meanwhile: a signal that
    arrives while an executor is created or shut down makes that thread trigger freed memory
    (a segfault; reproduced in seconds by creating and destroying executors under a stream of
    SIGTERMs). A repeated signal is exactly that case, since the first one starts the
    teardown. Uninstalling rclpy's handlers joins that thread (after any trigger it is in)
    and restores the handlers it chained to, ours, which ignore repeats; from then on no
    thread touches a guard condition behind our back."""
    try:
        uninstall_signal_handlers()
    except Exception:  # nothing installed (init failed): nothing to stop
        pass


def run_node(name: str, make_node: Callable[[], Node], args=None, *,
             spin: Callable[[Node, object], None] = spin_executor,
             finish: Callable[[Node], None] | None = None) -> int:
    """Run a node until it is done or signalled; returns the process exit status.

    Meant as the whole of a node process's ``main()``: it installs SIGINT/SIGTERM/SIGHUP
    handlers and leaves these signals ignored when it returns.

    The node's executor (its ``executor_kind`` attribute, default ``single_threaded``) is
    built here, before rclpy's signal handlers are installed, and shut down here, after they
    are uninstalled (:func:`_quiesce_signal_handling`): every guard condition rclpy's signal
    thread triggers exists for exactly the time that thread runs. ``spin(node, executor)``
    may spin the executor on another thread; it must have stopped and joined that thread
    when it returns.
    """
    signals = ShutdownSignals()
    signals.install()
    signals.silence_unraisable_after_signal()
    node = None
    executor = None
    watchdog = None
    initialized = False
    status = EXIT_OK

    def say(message: str) -> None:
        print(f"[{name}] {message}", file=sys.stderr, flush=True)

    ensure_ament_prefix_path()  # a venv started without any ROS environment variable
    try:
        problem = _params_file_problem(args)
        if problem is not None:
            say(f"invalid parameter file: {problem}")
            return EXIT_PARAMETER
        try:
            # rclpy's signal handlers come later (below): a signal meanwhile is recorded by
            # ours, and the node is not spun
            rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
        except RCLError as exc:  # malformed --ros-args, unparsable parameter file
            say(f"invalid ROS arguments: {str(exc).splitlines()[0]}")
            return EXIT_PARAMETER
        initialized = True
        node = make_node()
        executor = make_executor(getattr(node, "executor_kind", "single_threaded"),
                                 lambda text: node.get_logger().warning(text))
        executor.add_node(node)
        # Move everything allocated at start-up (modules, message classes, numpy) out of the
        # collector's reach: a full gen-2 collection then scans only recent objects instead
        # of ~10^5, which keeps its pauses (latency spikes at 1 kHz) well below a millisecond.
        gc.freeze()
        install_signal_handlers(SignalHandlerOptions.ALL)
        if signals.received is None:  # a signal during start-up: nothing to spin for
            spin(node, executor)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except ParameterError as exc:
        say(f"invalid parameter: {exc}")
        status = EXIT_PARAMETER
    except InputError as exc:
        say(f"unusable input: {exc}")
        status = EXIT_INPUT
    except OutputWriteError as exc:
        say(f"cannot write output: {exc}")
        status = EXIT_OUTPUT
    except Exception:
        # Publishing, waiting or creating entities on a context that a signal has just shut
        # down raises (e.g. RCLError "publisher's context is invalid"): that is the shutdown
        # the user asked for, not a failure. rclpy shuts the context down from its own
        # thread and may do so before the Python handler has run, so a context that is no
        # longer ok (only a signal shuts it down here) counts as well. Anything else is a
        # real error.
        if signals.received is None and (not initialized or rclpy.ok()):
            raise
    finally:
        try:
            if initialized:
                _quiesce_signal_handling()  # before any guard condition is destroyed
            if executor is not None:
                try:
                    executor.shutdown()
                except Exception:  # handles of a context a signal shut down
                    pass
                # An executor whose wait was cut short by the signal can leave its suspended
                # wait generator in a reference cycle (the exception's traceback) with every
                # entity's handle still entered, which destroy_node would wait for.
                # Collecting the cycle closes the generator and releases the handles first.
                # (It was the suspect of a teardown hang seen under load; the hang recurred
                # with this in place: _exit_if_teardown_hangs bounds it.)
                executor = None
                gc.collect()
            if node is not None:
                finished = False
                try:
                    if finish is not None:
                        finish(node)
                    finished = True
                except OutputWriteError as exc:  # the disk filled while finishing the file
                    say(f"cannot write output: {exc}")
                    status = EXIT_OUTPUT
                    finished = True
                finally:
                    if finished and signals.received is not None:
                        _exit_without_teardown(status)
                    watchdog = _exit_if_teardown_hangs(name, status)
                    _destroy(node)
        finally:
            if watchdog is None:
                watchdog = _exit_if_teardown_hangs(name, status)
            rclpy.try_shutdown()
            watchdog.cancel()
            # run_node is the process's main: it is exiting now, and a repeated signal must
            # not turn a clean exit into a kill.
            signals.ignore_from_now_on()
    return status
