"""Subcommands of the ``gyro-attitude`` console command (one module each).

Every command's failure is one line on stderr in one form, argparse's:
``gyro-attitude <command>: error: <message>`` (:func:`error_line`; argument errors too, without
the usage block: :func:`one_line_parser_errors`)."""

from __future__ import annotations

import sys

EXIT_INTERRUPTED = 130  # 128 + SIGINT, what a shell reports for a command stopped by Ctrl-C


def error_line(command: str, message) -> None:
    """Print ``gyro-attitude <command>: error: <message>`` on stderr."""
    print(f"gyro-attitude {command}: error: {message}", file=sys.stderr)


def one_line_parser_errors(parser) -> None:
    """Argument errors of ``parser`` as one line (argparse prints the usage block first)."""
    def error(message: str):
        parser.exit(2, f"{parser.prog}: error: {message}\n")
    parser.error = error
