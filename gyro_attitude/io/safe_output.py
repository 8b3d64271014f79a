"""Output files that never clobber: refuse an existing output, write under a temporary name.

:func:`check_output_path` refuses an output that exists (unless forced) or that is one of the
inputs; :class:`AtomicOutput` hands out a temporary path next to the requested one and renames
it to the requested name only when the output is complete, so an interrupted or failed
writer leaves the requested name untouched (a ``kill -9`` leaves the partial output in a
hidden ``.<name>.*.partial`` folder beside it).
"""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

__all__ = ["check_output_path", "AtomicOutput"]


def check_output_path(out, inputs=(), force: bool = False) -> Path:
    """``out`` as a Path if it may be written; ValueError naming the problem otherwise."""
    if not isinstance(out, str | os.PathLike) or not str(out).strip():
        raise ValueError(f"output path must be a non-empty path, got {out!r}")
    path = Path(out)
    for inp in inputs:
        try:
            same = Path(inp).exists() and path.exists() and path.samefile(inp)
        except OSError:
            same = False
        if same or Path(os.path.abspath(inp)) == Path(os.path.abspath(path)):
            raise ValueError(f"output {path} is also an input")
    if path.exists() and not force:
        raise ValueError(f"output {path} exists (set force to replace it)")
    parent = path.parent
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if not parent.is_dir():
        raise ValueError(f"output {path}: {parent} is not a directory")
    return path


class AtomicOutput:
    """A temporary path in the output's directory, renamed to the output on success.

    The temporary path has the output's own base name (inside a hidden folder beside it),
    so writers that derive names from it (a rosbag2 bag directory names its file after the
    directory) produce the same content they would under the final name. Use as a context
    manager (commit on normal exit, discard on an exception) or call :meth:`open`,
    :meth:`commit`, :meth:`discard`.
    """

    def __init__(self, out, *, force: bool = False):
        self.path = Path(out)
        self.force = bool(force)
        self.temp_path: Path | None = None
        self._temp_dir: Path | None = None

    def open(self) -> Path:
        """Create the hidden folder and return the temporary path to write."""
        if self.temp_path is None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._temp_dir = Path(tempfile.mkdtemp(
                prefix=f".{self.path.name}.", suffix=".partial", dir=self.path.parent))
            self.temp_path = self._temp_dir / self.path.name
        return self.temp_path

    def commit(self) -> Path:
        """Move the finished output to its requested name (idempotent); returns that name."""
        if self.temp_path is None:
            return self.path
        if self.path.exists() or self.path.is_symlink():
            if not self.force:
                raise ValueError(f"output {self.path} appeared meanwhile; the finished output "
                                 f"stays at {self.temp_path}")
            if self.path.is_dir() and not self.path.is_symlink():
                shutil.rmtree(self.path)
        os.replace(self.temp_path, self.path)  # atomic for a file on the same file system
        shutil.rmtree(self._temp_dir, ignore_errors=True)
        self.temp_path = self._temp_dir = None
        return self.path

    def discard(self) -> None:
        """Remove the temporary output (idempotent); the requested name is untouched."""
        if self._temp_dir is not None:
            shutil.rmtree(self._temp_dir, ignore_errors=True)
        self.temp_path = self._temp_dir = None

    def __enter__(self) -> Path:
        return self.open()

    def __exit__(self, exc_type, exc, tb) -> bool:
        if exc_type is None:
            self.commit()
        else:
            self.discard()
        return False
