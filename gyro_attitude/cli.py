"""The ``gyro-attitude`` console command: ``demo | replay | bench | scenes | simulate | allan |
montecarlo``.

Each subcommand lives in ``gyro_attitude.commands.<name>`` with two functions,
``configure(parser)`` (adds its arguments) and ``run(args) -> int`` (exit status); the
module is imported only when its subcommand runs, so ``--help`` stays fast and a
subcommand's heavy imports (rclpy, matplotlib) are paid only by that subcommand.
"""

from __future__ import annotations

import argparse
import importlib
import os
import signal
import sys
import threading

from gyro_attitude import __version__
from gyro_attitude.commands import EXIT_INTERRUPTED, one_line_parser_errors
from gyro_attitude.io.ament_prefix import ensure_ament_prefix_path
from gyro_attitude.io.safe_output import request_stop, stop_handled
from gyro_attitude.offline.allocator import keep_freed_memory

# name -> one-line help; the module gyro_attitude.commands.<name> implements it.
SUBCOMMANDS: dict[str, str] = {
    "demo": "run gyro_sim + attitude_integrator on a scene, record MCAP, summarize, plot",
    "replay": "integrate every Imu message of an MCAP recording offline (no ROS graph)",
    "bench": "accuracy versus cost of every attitude algorithm (table, Pareto plot, JSON)",
    "scenes": "list the shipped scenes with one line each, or show one",
    "simulate": "run a scene offline (no ROS graph) into an MCAP file of gyro_sim's topics",
    "allan": "Allan deviation and IEEE 952 noise terms (ARW, bias instability, RRW) of a recording",
    "montecarlo": "error budget over many noise draws of a scene (percentiles, NEES; local or Dask)",
}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="gyro-attitude",
        description="Gyroscope mechanics and attitude for ROS 2 Jazzy.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, help_text in SUBCOMMANDS.items():
        sub.add_parser(name, help=help_text, description=help_text, add_help=False)
    return parser


class _Interrupt:
    """SIGINT/SIGTERM → one ``KeyboardInterrupt`` in the running subcommand (which cleans up
    as on Ctrl-C); repeated signals during that clean-up are ignored."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self, process_main: bool = False) -> None:
        self.received = False
        self.process_main = process_main
        self._previous: dict[int, object] = {}

    def _handle(self, _signum, _frame) -> None:
        if not self.received:
            self.received = True
            # whatever becomes of the exception below, no output is committed (a repeat is
            # ignored: it must not undo what a command that handled the stop still writes)
            request_stop()
            raise KeyboardInterrupt

    def __enter__(self):
        if threading.current_thread() is threading.main_thread():
            self._previous = {s: signal.signal(s, self._handle) for s in self.SIGNALS}
        return self

    @staticmethod
    def _default_in_child() -> None:
        """A forked worker (multiprocessing) must not inherit the one-shot handler: its
        terminate() would raise there instead of ending it."""
        for sig in _Interrupt.SIGNALS:
            signal.signal(sig, signal.SIG_DFL)

    def __exit__(self, *exc) -> bool:
        if self.received and self.process_main:
            # the process is stopping: a repeated signal arriving after this block must not
            # find the default handler again (a traceback, or death by the signal)
            self.ignore_from_now_on()
            return False
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)
        return False

    @staticmethod
    def ignore_from_now_on() -> None:
        """The process is exiting: finalization would reset Python handlers to the default
        action (a repeat then kills it); ignored signals stay ignored."""
        if threading.current_thread() is threading.main_thread():
            for sig in _Interrupt.SIGNALS:
                signal.signal(sig, signal.SIG_IGN)




def main(argv: list[str] | None = None) -> int:
    """Run a subcommand. SIGINT/SIGTERM stop it cleanly (no partial output, no traceback) with
    one line and exit status 130: the work was not completed. ``argv`` None = this is the
    process's entry point."""
    is_process_main = argv is None
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = build_parser()
    if not argv or argv[0] not in SUBCOMMANDS:
        parser.parse_args(argv)  # exits for --help, --version and unknown subcommands
        parser.print_help()  # no subcommand given
        return 2
    name = argv[0]
    interrupt = _Interrupt(process_main=is_process_main)
    if is_process_main:
        os.register_at_fork(after_in_child=_Interrupt._default_in_child)
        keep_freed_memory()
    try:
        # the handler is in place before the subcommand's (slow) imports: a Ctrl-C at any time
        # ends the same way
        with interrupt:
            ensure_ament_prefix_path()  # before any subcommand loads rclpy or starts nodes
            module = importlib.import_module(f"gyro_attitude.commands.{name}")
            sub = argparse.ArgumentParser(prog=f"gyro-attitude {name}",
                                          description=SUBCOMMANDS[name])
            one_line_parser_errors(sub)  # one line, not usage + error, for every command
            module.configure(sub)
            args = sub.parse_args(argv[1:])
            status = int(module.run(args) or 0)
    except KeyboardInterrupt:  # stopped outside the subcommand's own clean-up
        print(f"gyro-attitude {name}: interrupted; no output written under the requested names",
              file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenPipeError:
        # the reader of our output went away (`... --json | head`): nothing more to say
        if is_process_main:
            sys.stdout = open(os.devnull, "w")  # no second error when Python flushes at exit
        return 1
    except Exception:
        if not interrupt.received:
            raise
        # The interrupt surfaced as another exception: a C extension whose initialisation the
        # KeyboardInterrupt broke re-raises it as "ImportError: initialization failed" (scipy's
        # HiGHS module during the subcommand's imports). It is still the user's Ctrl-C.
        print(f"gyro-attitude {name}: interrupted; no output written under the requested names",
              file=sys.stderr)
        return EXIT_INTERRUPTED
    finally:
        stop_handled()  # the stop ends here: a library caller of main() may write again
        if is_process_main:
            _Interrupt.ignore_from_now_on()
    if interrupt.received:
        if status != EXIT_INTERRUPTED:  # the subcommand did not say it was interrupted
            print(f"gyro-attitude {name}: interrupted; no output written under the requested "
                  "names", file=sys.stderr)
        return EXIT_INTERRUPTED
    return status


if __name__ == "__main__":
    sys.exit(main())
