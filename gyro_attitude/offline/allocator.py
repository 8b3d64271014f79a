"""The C allocator of a process that runs batch tasks: freed array memory kept for reuse.

A batch run (a Monte Carlo run, a replayed file) makes and frees numpy arrays of a chunk's
size, 0.5–10 MB, thousands of times.  glibc's ``malloc`` serves a block above its mmap
threshold (128 KiB at the start of a process) with a fresh ``mmap``: the kernel faults it in
page by page (each page zeroed) and ``munmap`` gives it back when the array is freed, so the
next array of that size pays the faults again.  glibc raises the threshold by itself only as
such blocks are freed, and every new worker process starts over.  The faults are a large part
of a run's CPU time (docs/montecarlo.md has the measurement).

:func:`keep_freed_memory` raises the mmap threshold (blocks below :data:`MMAP_THRESHOLD_BYTES`
come from the heap, whose freed pages are reused) and the trim threshold (up to
:data:`TRIM_THRESHOLD_BYTES` of free heap is kept instead of returned to the system).  Larger
arrays are mapped and returned as before.  It changes where memory comes from, never a number
computed.  Only with glibc (elsewhere it does nothing), and not where the user set glibc's own
``MALLOC_MMAP_THRESHOLD_`` / ``MALLOC_TRIM_THRESHOLD_`` variables (theirs win).  It is written
with ``ctypes`` because Python exposes no ``mallopt``.
"""

from __future__ import annotations

import ctypes
import os
import platform

__all__ = ["MMAP_THRESHOLD_BYTES", "TRIM_THRESHOLD_BYTES", "keep_freed_memory"]

MMAP_THRESHOLD_BYTES = 64 << 20
TRIM_THRESHOLD_BYTES = 256 << 20

# glibc <malloc.h>
_M_TRIM_THRESHOLD = -1
_M_MMAP_THRESHOLD = -3
_USER_VARIABLES = ("MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_")

_applied: bool | None = None


def keep_freed_memory() -> bool:
    """Set this process's allocator as the module docstring says, once; True when it is so
    set (now or by an earlier call), False where it cannot be or the user chose otherwise."""
    global _applied
    if _applied is not None:
        return _applied
    _applied = False
    if platform.system() != "Linux" or platform.libc_ver()[0] != "glibc":
        return False
    if any(v in os.environ for v in _USER_VARIABLES):
        return False
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
    mallopt.restype = ctypes.c_int
    # mallopt returns 1 on success; the mmap threshold first (setting it also stops glibc's
    # own adjustment of both thresholds)
    _applied = bool(mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES)
                    and mallopt(_M_TRIM_THRESHOLD, TRIM_THRESHOLD_BYTES))
    return _applied
