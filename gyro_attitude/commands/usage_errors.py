"""argparse types of the commands' output names: refused at parse time, in one line (the cli
makes every argument error one line: :func:`gyro_attitude.commands.one_line_parser_errors`).
Light to import: ``--help`` stays fast."""

from __future__ import annotations

import argparse

__all__ = ["figure_file", "output_file"]


def output_file(text: str) -> str:
    """argparse type of an output file name: not ``-`` (which would be a file named ``-``
    where standard output was meant) and not empty."""
    if text == "-" or not text.strip():
        raise argparse.ArgumentTypeError(
            f"give a file name, got {text!r} (standard output is not supported)")
    return text


#: What a figure can be written as (matplotlib's Agg backend with Pillow), by the name's suffix.
FIGURE_SUFFIXES = (".png", ".pdf", ".svg", ".svgz", ".jpg", ".jpeg", ".tif", ".tiff", ".webp",
                   ".eps", ".ps")


def figure_file(suffixes: tuple[str, ...] = FIGURE_SUFFIXES):
    """argparse type of a figure's file name: its suffix names a format written as such
    (never PNG bytes in a ``.jpg``, never a failure after the other outputs are written)."""
    def parse(text: str) -> str:
        output_file(text)
        suffix = text[text.rfind("."):].lower() if "." in text.rsplit("/", 1)[-1] else ""
        if suffix not in suffixes:
            raise argparse.ArgumentTypeError(
                f"must end in {', '.join(suffixes)} (the format is taken from it), got {text!r}")
        return text
    return parse
