"""Safe output files: refuse to overwrite an input or an existing file, write through a
temporary file in the same directory and rename it into place only when complete.

Used by ``replay`` and the recorder: a failed or interrupted run never leaves a
half-written file under the requested name, and never destroys its own input (also when
the output names it through a symlink, a relative path or the bag directory).
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterable
from pathlib import Path

__all__ = ["OutputPathError", "check_output_path", "SafeOutput"]


class OutputPathError(ValueError):
    """The requested output path cannot be used (names an input, exists, unwritable)."""


def _identity(path: Path) -> set:
    """Real paths a path stands for: itself, and for a bag directory its .mcap files."""
    real = Path(os.path.realpath(path))
    out = {real}
    if real.is_dir():
        out.update(Path(os.path.realpath(p)) for p in real.glob("*.mcap"))
    return out


def check_output_path(out, *, inputs: Iterable = (), force: bool = False,
                      what: str = "output") -> Path:
    """Check ``out`` before any work: not one of ``inputs`` (after resolving symlinks,
    relative parts and bag directories), not an existing file unless ``force``, not a
    directory, and its directory exists and is writable.  Returns ``out`` as a Path;
    raises :class:`OutputPathError` naming what is wrong."""
    if not isinstance(out, str | os.PathLike) or not str(out):
        raise OutputPathError(f"{what} path must be a non-empty path, got {out!r}")
    out = Path(out)
    real = Path(os.path.realpath(out))
    for inp in inputs:
        ids = _identity(Path(inp))
        same = real in ids or (out.exists() and any(
            p.exists() and os.path.samefile(real, p) for p in ids))
        if same:
            raise OutputPathError(f"{what} {out} is the input {inp}: refusing to overwrite it")
    if real.is_dir():
        raise OutputPathError(f"{what} {out} is a directory")
    if out.exists() or out.is_symlink():
        if not force:
            raise OutputPathError(f"{what} {out} exists (use --force to overwrite it)")
    parent = real.parent
    if not parent.is_dir():
        raise OutputPathError(f"{what} directory {parent} does not exist")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise OutputPathError(f"{what} directory {parent} is not writable")
    return out


class SafeOutput:
    """A temporary file beside ``path`` that becomes ``path`` on :meth:`commit`.

    ``with SafeOutput(path) as tmp: write(tmp); ...`` commits when the block ends without
    an exception (or KeyboardInterrupt) and removes the temporary file otherwise.  The
    rename is atomic (same directory, same file system); an existing ``path`` is replaced
    only at that moment.  A symlink at ``path`` is replaced by the file, its target left
    alone.
    """

    def __init__(self, path, *, suffix: str | None = None):
        self.path = Path(path)
        directory = Path(os.path.realpath(self.path)).parent
        fd, tmp = tempfile.mkstemp(prefix=f".{self.path.name}.", suffix=suffix or ".partial",
                                   dir=directory)
        os.close(fd)
        self.tmp_path = Path(tmp)
        self._done = False

    def commit(self) -> Path:
        if not self._done:
            os.replace(self.tmp_path, self.path)
            self._done = True
        return self.path

    def discard(self) -> None:
        if not self._done:
            self._done = True
            try:
                self.tmp_path.unlink()
            except FileNotFoundError:
                pass

    def __enter__(self) -> Path:
        return self.tmp_path

    def __exit__(self, exc_type, exc, tb):
        if exc_type is None:
            self.commit()
        else:
            self.discard()
        return False
