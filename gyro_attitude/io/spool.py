"""Arrays of a recording's length kept on disk, not in the process's memory.

A replay holds a few arrays with one row per message (the decoded input columns, the
estimate).  In anonymous memory they make a process's RSS grow with the recording (hundreds
of bytes a message: a 24 h recording at 1 kHz would need tens of GB).  :class:`Spool` gives
such arrays backed by a file instead: numpy arrays over a shared ``mmap`` of a temporary
file, which is unlinked as soon as it is mapped.  The kernel writes their pages back and
evicts them under memory pressure like any file's (they count as ``RssFile``, not
``RssAnon``), the disk space is reserved up front (``posix_fallocate``: a full disk is an
``OSError`` at allocation, never a ``SIGBUS`` while writing into a sparse file), and an
unlinked file leaves nothing behind however the process ends, ``kill -9`` included.

Arrays below ``min_bytes`` stay ordinary memory (a short recording runs exactly as before);
where the file system cannot reserve space, arrays fall back to memory too
(:attr:`Spool.fallbacks` counts them), and with ``when_full="memory"`` so do arrays that find
no room (:attr:`Spool.full_fallbacks`: the work then needs the memory it needed before).
``keep_free`` bytes of the file system are left to others (replay: room for its output):
an array that would eat into them counts as finding no room.  The arrays are ordinary
writable ``ndarray`` s: code that takes them knows nothing of files.
"""

from __future__ import annotations

import errno
import math
import mmap
import os
import tempfile
from pathlib import Path

import numpy as np

__all__ = ["SPOOL_MIN_BYTES", "Spool", "SpoolSpaceError"]

#: Arrays this large or larger go to disk (a 1 kHz (N, 3) float64 column after ~12 min).
SPOOL_MIN_BYTES = 16 << 20

# errnos of a file system that cannot reserve space (the array then stays in memory)
_NO_FALLOCATE = {errno.EOPNOTSUPP, errno.EINVAL, errno.ENOSYS, errno.ENOTSUP}


class SpoolSpaceError(OSError):
    """No room on the disk for a spooled array (one line: the directory, what was asked,
    what is free)."""

    def __str__(self) -> str:
        return str(self.strerror)


class Spool:
    """Allocator of file-backed arrays in ``directory`` (see the module docstring); arrays
    of at least ``min_bytes`` (default :data:`SPOOL_MIN_BYTES`) go to disk.

    :meth:`empty` is ``np.empty``'s signature (shape, dtype).  ``spooled_bytes`` and
    ``spooled_arrays`` say how much went to disk; ``fallbacks`` how many large arrays stayed
    in memory because the file system cannot reserve space.
    """

    def __init__(self, directory, *, min_bytes: int | None = None, when_full: str = "raise",
                 keep_free: int = 0):
        if when_full not in ("raise", "memory"):
            raise ValueError(f"when_full must be 'raise' or 'memory', got {when_full!r}")
        if isinstance(keep_free, bool) or not isinstance(keep_free, int) or keep_free < 0:
            raise ValueError(f"keep_free must be an int >= 0, got {keep_free!r}")
        self.keep_free = keep_free
        self.when_full = when_full
        self.full_fallbacks = 0
        if min_bytes is None:
            min_bytes = SPOOL_MIN_BYTES
        if isinstance(min_bytes, bool) or not isinstance(min_bytes, int) or min_bytes < 0:
            raise ValueError(f"min_bytes must be an int >= 0, got {min_bytes!r}")
        self.directory = Path(directory)
        self.min_bytes = min_bytes
        self.spooled_bytes = 0
        self.spooled_arrays = 0
        self.fallbacks = 0

    def empty(self, shape, dtype=np.float64) -> np.ndarray:
        dtype = np.dtype(dtype)
        shape = (shape,) if isinstance(shape, int | np.integer) else tuple(shape)
        nbytes = math.prod(shape) * dtype.itemsize
        if nbytes < max(self.min_bytes, 1):
            return np.empty(shape, dtype)
        try:
            buf = self._mapped(nbytes)
        except SpoolSpaceError:
            if self.when_full == "raise":
                raise
            self.full_fallbacks += 1
            return np.empty(shape, dtype)
        if buf is None:
            self.fallbacks += 1
            return np.empty(shape, dtype)
        self.spooled_bytes += nbytes
        self.spooled_arrays += 1
        return np.frombuffer(buf, dtype=dtype, count=math.prod(shape)).reshape(shape)

    def _mapped(self, nbytes: int) -> mmap.mmap | None:
        if self.keep_free:
            import shutil

            if shutil.disk_usage(self.directory).free - nbytes < self.keep_free:
                raise SpoolSpaceError(errno.ENOSPC, self._no_room(nbytes, OSError(
                    errno.ENOSPC, f"keeping {_size(self.keep_free)} free for others")))
        fd, path = tempfile.mkstemp(prefix=".gyro_attitude-spool-", dir=self.directory)
        try:
            try:
                os.unlink(path)  # nothing left behind: the mapping keeps the file alive
            except OSError:  # a system that cannot unlink an open file: keep it in memory
                os.close(fd)
                fd = -1
                Path(path).unlink(missing_ok=True)
                return None
            reserve = getattr(os, "posix_fallocate", None)
            if reserve is None:  # no way to reserve the space here: keep it in memory
                return None
            try:
                reserve(fd, 0, nbytes)
            except OSError as exc:
                if exc.errno in _NO_FALLOCATE:
                    return None
                if exc.errno in (errno.ENOSPC, errno.EDQUOT, errno.EFBIG):
                    raise SpoolSpaceError(exc.errno, self._no_room(nbytes, exc)) from None
                raise
            return mmap.mmap(fd, nbytes, flags=mmap.MAP_SHARED,
                             prot=mmap.PROT_READ | mmap.PROT_WRITE)
        finally:
            if fd >= 0:
                os.close(fd)  # the mapping holds its own reference

    def _no_room(self, nbytes: int, exc: OSError) -> str:
        try:
            import shutil

            free = f"{_size(shutil.disk_usage(self.directory).free)} free"
        except OSError:
            free = "free space unknown"
        return (f"{self.directory}: {exc.strerror} for a working array of {_size(nbytes)} "
                f"({free}; {_size(self.spooled_bytes)} of working arrays reserved there so "
                "far)")


def _size(n: float) -> str:
    for unit in ("B", "kB", "MB"):
        if n < 1000:
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1000
    return f"{n:.1f} GB"
