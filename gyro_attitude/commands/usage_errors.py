"""A subcommand's argument errors in one line: ``gyro-attitude CMD: error: MESSAGE`` (exit 2).

argparse prints its usage block before the message; one line is the form every error of the
command line takes (the usage is in ``--help``).  Light to import: ``--help`` stays fast."""

from __future__ import annotations

import argparse

__all__ = ["one_line_errors"]


def one_line_errors(parser: argparse.ArgumentParser) -> None:
    """Make ``parser`` report a bad argument as one line and exit 2."""
    def error(message: str):
        parser.exit(2, f"{parser.prog}: error: {message}\n")
    parser.error = error
