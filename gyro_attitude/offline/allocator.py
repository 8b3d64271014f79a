"""The C allocator of our own batch processes: freed array memory kept for reuse.

A replay or a Monte Carlo run makes and frees numpy arrays of a chunk's or a recording's
size, megabytes each, thousands of times.  glibc's ``malloc`` serves a block above its mmap
threshold (128 KiB at the start of a process) with a fresh ``mmap``: the kernel faults it in
page by page (each page zeroed) and ``munmap`` gives it back when the array is freed, so the
next array of that size pays the faults again; free space at the heap's top above the trim
threshold goes back to the kernel too.  glibc raises the thresholds by itself only as such
blocks are freed, and every new worker process starts over.  The faults are a large part of a
run's CPU time (docs/montecarlo.md has the measurement).

:func:`keep_freed_memory` raises the mmap threshold to :data:`MMAP_THRESHOLD_BYTES` (32 MiB,
the largest glibc before 2.35 accepts on 64-bit), the trim threshold to
:data:`TRIM_THRESHOLD_BYTES` and the top pad to :data:`TOP_PAD_BYTES`: the process keeps its
peak memory until it exits.  So it is only for processes that are ours and short-lived: the
command-line process (``cli.main``) and the pool's worker processes
(:mod:`.parallel`), never a caller's process or a Dask worker.  It changes where memory comes
from, never a number computed.  Only with glibc (elsewhere it does nothing), and not where the
user set glibc's own ``MALLOC_*_`` variables or malloc tunables (theirs win).  Written with
``ctypes`` because Python exposes no ``mallopt``.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import platform

__all__ = ["MMAP_THRESHOLD_BYTES", "TOP_PAD_BYTES", "TRIM_THRESHOLD_BYTES", "keep_freed_memory"]

MMAP_THRESHOLD_BYTES = 32 << 20
TRIM_THRESHOLD_BYTES = 1 << 30
TOP_PAD_BYTES = 64 << 20

# glibc <malloc.h>
_M_TRIM_THRESHOLD = -1
_M_TOP_PAD = -2
_M_MMAP_THRESHOLD = -3

_applied: bool | None = None


def _user_chose() -> bool:
    """Whether the environment already sets glibc's malloc parameters."""
    return any(k.startswith("MALLOC_") and k.endswith("_") for k in os.environ) or \
        "glibc.malloc." in os.environ.get("GLIBC_TUNABLES", "")


def keep_freed_memory() -> bool:
    """Set this process's allocator as the module docstring says, once; True when every
    parameter is so set (now or by an earlier call), False where it cannot be (not glibc, a
    value refused) or the user chose otherwise."""
    global _applied
    if _applied is not None:
        return _applied
    _applied = False
    if platform.system() != "Linux" or platform.libc_ver()[0] != "glibc" or _user_chose():
        return False
    name = ctypes.util.find_library("c")
    try:
        mallopt = ctypes.CDLL(name).mallopt
    except (OSError, AttributeError, TypeError):
        return False
    mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
    mallopt.restype = ctypes.c_int
    # each set on its own (mallopt returns 1 on success); setting the mmap threshold also
    # stops glibc's own adjustment of the two thresholds
    ok = [mallopt(param, value) == 1 for param, value in (
        (_M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES), (_M_TRIM_THRESHOLD, TRIM_THRESHOLD_BYTES),
        (_M_TOP_PAD, TOP_PAD_BYTES))]
    _applied = all(ok)
    return _applied
