"""A recording written by a node (``mcap_recorder``, ``gyro_sim record_path``): a
:class:`~.mcap_writer.Rosbag2McapWriter` under a :class:`~.safe_output.SafeOutput`, so the
file appears under its name only when finished, and a full disk ends it readable.

When a write fails (no space left), the recording so far is cut back to its last whole
chunk, ended as a valid MCAP (:meth:`~.mcap_writer.Rosbag2McapWriter.salvage`) and moved to
its name; :class:`~.safe_output.OutputWriteError` then says in one line which file, how much
space is left and where the readable recording is.
"""

from __future__ import annotations

import contextlib
from pathlib import Path

from gyro_attitude.io.mcap_writer import Rosbag2McapWriter
from gyro_attitude.io.safe_output import (
    OutputPathError,
    SafeOutput,
    is_write_error,
    write_error,
)

__all__ = ["SafeRecording"]


class SafeRecording:
    """A rosbag2 MCAP recording to ``output`` (arguments after ``force`` go to the writer).

    ``add_topic``, ``write`` and ``flush`` are the writer's; :meth:`close` finishes it and
    moves it to ``output`` (idempotent). Any of them raises ``OutputWriteError`` after a
    failed write, the recording so far being kept (see the module docstring); the recording
    is closed from then on.
    """

    def __init__(self, output, *, force: bool = False, **writer_options):
        self.output = Path(output)
        self._safe = SafeOutput(self.output, force=force)
        try:
            self.writer: Rosbag2McapWriter | None = Rosbag2McapWriter(
                self._safe.open(), **writer_options)
        except BaseException:
            self._safe.discard()
            raise
        self.partial_path = self.writer.path  # the file being written until close()
        self.message_count = 0

    @contextlib.contextmanager
    def _writing(self):
        try:
            yield
        except OSError as exc:
            if not is_write_error(exc) or self.writer is None:
                raise
            raise self._failed(exc) from exc
        finally:
            if self.writer is not None:
                self.message_count = self.writer.message_count

    def _failed(self, exc: OSError):
        kept = self.writer.salvage()
        self.writer = None
        self.message_count = kept
        try:
            where = self._safe.commit()
        except (OSError, OutputPathError):
            where = self._safe.temp_path  # the name cannot be had: say where it is
        return write_error(self.output, exc, f"the recording so far ({kept} messages) is "
                                             f"finished and readable at {where}")

    def add_topic(self, *args, **kwargs) -> int:
        with self._writing():
            return self.writer.add_topic(*args, **kwargs)

    def write(self, *args) -> None:
        if self.writer is not None:
            with self._writing():
                self.writer.write(*args)

    def flush(self) -> None:
        if self.writer is not None:
            with self._writing():
                self.writer.flush()

    @property
    def closed(self) -> bool:
        return self.writer is None

    def close(self) -> Path:
        """Finish the file (summary, footer) and move it to ``output``."""
        if self.writer is not None:
            with self._writing():
                self.writer.finish()
            self.writer = None
            self._safe.commit()
        return self.output

    def discard(self) -> None:
        """Give the recording up (an error before anything was recorded)."""
        if self.writer is not None:
            self.writer.abandon()
            self.writer = None
        self._safe.discard()
