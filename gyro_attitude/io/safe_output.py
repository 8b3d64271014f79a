"""Safe output files: refuse to overwrite an input or an existing file, write under a temporary
name beside the output and rename it into place only when complete.

Used by ``replay``, ``simulate``, ``allan`` and the recorder: a failed or interrupted run never
leaves a half-written file under the requested name (a ``kill -9`` leaves the partial output in
a hidden ``.<name>.*.partial`` folder beside it), and never destroys its own input (also when the
output names it through a symlink, a relative path or the bag directory).
"""

from __future__ import annotations

import contextlib
import errno
import os
import secrets
import shutil
import signal
import threading
from collections.abc import Iterable
from pathlib import Path

__all__ = ["OutputPathError", "OutputWriteError", "write_error", "is_write_error",
           "check_output_path", "SafeOutput", "request_stop", "stop_handled",
           "stop_requested", "raise_if_stop_requested", "PLOT_FORMATS", "plot_format"]

# What writing (not reading) an output fails with: no space, no quota, a file too large.
_WRITE_ERRNOS = (errno.ENOSPC, errno.EDQUOT, errno.EFBIG)


class OutputPathError(ValueError):
    """The requested output path cannot be used (names an input, exists, unwritable)."""


class OutputWriteError(OSError):
    """Writing an output failed (a full disk): the message is one line naming the file, the
    free space left and what became of the data (see :func:`write_error`)."""


def is_write_error(exc: BaseException) -> bool:
    """True for an OSError that says the output could not be written (full disk, quota)."""
    return isinstance(exc, OSError) and not isinstance(exc, OutputWriteError) \
        and exc.errno in _WRITE_ERRNOS


def _free_space(path: Path) -> str:
    try:
        free = shutil.disk_usage(Path(os.path.abspath(path)).parent).free
    except OSError:
        return "free space unknown"
    for unit in ("B", "kB", "MB", "GB"):
        if free < 1000 or unit == "GB":
            return f"{free:.0f} {unit} free" if unit == "B" else f"{free:.1f} {unit} free"
        free /= 1000
    return ""  # not reached


def write_error(path, exc: OSError, outcome: str) -> OutputWriteError:
    """One line for a failed write of ``path``: ``"<path>: No space left on device (0 B free
    in <dir>); <outcome>"``."""
    directory = Path(os.path.abspath(path)).parent
    return OutputWriteError(f"{path}: {exc.strerror or exc} ({_free_space(path)} in "
                            f"{directory}); {outcome}")


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
    if not isinstance(out, str | os.PathLike) or not str(out).strip():
        raise OutputPathError(f"{what} path must be a non-empty path, got {out!r}")
    if str(out).strip() == "-":
        # the shell convention for standard output: these outputs are files renamed into
        # place when complete (MCAP needs seeking), never a stream
        raise OutputPathError(f"{what} '-' (standard output) is not supported: give a file name")
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
    if real.exists() and not real.is_file():
        # a device (/dev/null), FIFO or socket: renaming a file over it would replace the node
        raise OutputPathError(f"{what} {out} is not a regular file (a device, FIFO or socket): "
                              "refusing to replace it, even with --force")
    if (out.exists() or out.is_symlink()) and not force:
        raise OutputPathError(f"{what} {out} exists (use --force, or force:=true for a node, "
                              "to overwrite it)")
    parent = Path(os.path.abspath(out)).parent
    if not parent.is_dir():
        raise OutputPathError(f"{what} directory {parent} does not exist")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise OutputPathError(f"{what} directory {parent} is not writable")
    return out


# Whether the user asked the process to stop (SIGINT/SIGTERM taken by the command line,
# :func:`request_stop`) and no code has yet said it handled that (:func:`stop_handled`).  The
# handler's KeyboardInterrupt can be swallowed before it reaches any clean-up: a C extension
# whose initialisation it broke re-raises it as ImportError, and an optional import
# (``try: import isal ... except ImportError``) then carries on as if nothing happened.  While a
# stop is pending no output is committed, whatever became of the exception
# (:meth:`SafeOutput.commit`).
_stop_pending = False


def request_stop() -> None:
    """Record that the user asked the process to stop (called from the signal handler)."""
    global _stop_pending
    _stop_pending = True


def stop_handled() -> None:
    """Called by code that caught the stop's KeyboardInterrupt and deliberately writes what
    finished (Monte Carlo's partial ``--json``): outputs may be committed again."""
    global _stop_pending
    _stop_pending = False


def stop_requested() -> bool:
    """Whether a stop is pending (:func:`request_stop`, not yet :func:`stop_handled`)."""
    return _stop_pending


def raise_if_stop_requested() -> None:
    """KeyboardInterrupt while a stop is pending: a long loop calls this between blocks or
    tasks, and a handler of ``Exception`` before it reports an error, so that the work ends
    soon even when the signal's own exception was swallowed somewhere."""
    if _stop_pending:
        raise KeyboardInterrupt


@contextlib.contextmanager
def _signals_held():
    """SIGINT/SIGTERM wait until the block is done: a temporary folder is never created, renamed
    or removed halfway by a Ctrl-C (which would leave it behind)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    held = {signal.SIGINT, signal.SIGTERM}
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, held)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


class SafeOutput:
    """A temporary path beside ``path`` that becomes ``path`` on :meth:`commit`.

    The temporary path has the output's own base name, inside a hidden folder in the same
    directory, so writers that derive names from it (a rosbag2 bag directory names its file
    after the directory) write what they would under the final name, and the rename is atomic
    (same file system).  ``with SafeOutput(path) as tmp: write(tmp)`` commits when the block
    ends without an exception and discards otherwise; or call :meth:`open`, :meth:`commit`,
    :meth:`discard`.  An output that appeared meanwhile is replaced only with ``force``.
    """

    def __init__(self, path, *, force: bool = False):
        self.path = Path(path)
        self.force = bool(force)
        self.temp_path: Path | None = None
        self._temp_dir: Path | None = None
        self._discarded = False

    def open(self) -> Path:
        """Create the hidden folder and return the temporary path to write."""
        if self.temp_path is None:
            self._discarded = False
            # beside the requested name (not the symlink's target): the rename then stays on
            # one file system and replaces the name itself
            directory = Path(os.path.abspath(self.path)).parent
            with _signals_held():
                # The name is recorded before the folder exists: a Ctrl-C that arrived just
                # before the signals were held still raises here (Python runs its handler
                # at the next bytecode), and discard() must then know what to remove.
                # (tempfile.mkdtemp would create the folder before returning its name.)
                for _ in range(100):
                    self._temp_dir = directory / f".{self.path.name}.{secrets.token_hex(4)}.partial"
                    try:
                        os.mkdir(self._temp_dir, 0o700)
                        break
                    except FileExistsError:
                        self._temp_dir = None
                else:
                    raise FileExistsError(f"no free temporary name beside {self.path}")
                self.temp_path = self._temp_dir / self.path.name
        return self.temp_path

    def commit(self) -> Path:
        """Move the finished output to its requested name (idempotent); returns that name.
        While a stop is pending the output is discarded instead (KeyboardInterrupt); a
        discarded output cannot be committed (OutputPathError)."""
        if self.temp_path is None:
            if self._discarded:
                raise OutputPathError(f"output {self.path} was discarded: nothing to commit")
            return self.path
        if _stop_pending:
            self.discard()
            raise KeyboardInterrupt
        if self.path.exists() and not (self.path.is_file() or self.path.is_dir()):
            raise OutputPathError(f"output {self.path} is not a regular file (a device, FIFO or "
                                  f"socket); the finished output stays at {self.temp_path}")
        if self.path.exists() or self.path.is_symlink():
            if not self.force:
                raise OutputPathError(f"output {self.path} appeared meanwhile; the finished "
                                      f"output stays at {self.temp_path}")
            if self.path.is_dir() and not self.path.is_symlink():
                shutil.rmtree(self.path)
        with _signals_held():
            os.replace(self.temp_path, self.path)
            shutil.rmtree(self._temp_dir, ignore_errors=True)
            self.temp_path = self._temp_dir = None
        return self.path

    def discard(self) -> None:
        """Remove the temporary output (idempotent); the requested name is untouched."""
        with _signals_held():
            if self._temp_dir is not None:
                shutil.rmtree(self._temp_dir, ignore_errors=True)
                self._discarded = True
            self.temp_path = self._temp_dir = None

    def __enter__(self) -> Path:
        try:
            return self.open()
        except BaseException:
            # a Ctrl-C held during mkdtemp arrives as soon as signals are unblocked, still
            # inside open(): __exit__ is not called for an __enter__ that raised
            self.discard()
            raise

    def __exit__(self, exc_type, exc, tb) -> bool:
        if exc_type is None:
            self.commit()
            return False
        self.discard()
        if is_write_error(exc):  # a full disk: say which file, and the free space
            raise write_error(self.path, exc, "nothing written under that name") from exc
        return False


#: Image formats a plot is written in, by the file's suffix (matplotlib's Agg backend; JPEG
#: through Pillow, a matplotlib dependency).
PLOT_FORMATS = {".png": "png", ".pdf": "pdf", ".svg": "svg", ".jpg": "jpeg", ".jpeg": "jpeg"}


def plot_format(path) -> str:
    """The image format of a plot path from its suffix, or :class:`OutputPathError` naming
    the suffixes taken (a ``.jpg`` must not receive PNG bytes)."""
    suffix = Path(path).suffix.lower()
    if suffix not in PLOT_FORMATS:
        raise OutputPathError(f"plot {path}: unknown image format "
                              f"{suffix or '(no suffix)'}: give a name ending in "
                              f"{', '.join(PLOT_FORMATS)}")
    return PLOT_FORMATS[suffix]
