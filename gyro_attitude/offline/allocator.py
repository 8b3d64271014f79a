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
(:mod:`.parallel`), never a caller's process; a Dask worker keeps freed memory only while a
set of ours runs on it (:func:`release_freed_memory` gives it back and restores the
allocator's settings when the set ends: :mod:`.dask_allocator`).  It changes where memory
comes from, never a number computed.  Only with glibc (elsewhere it does nothing), and not
where the user set glibc's own ``MALLOC_*_`` variables or malloc tunables (theirs win; a caller
may name variables that are not the user's, as Dask's nanny sets ``MALLOC_TRIM_THRESHOLD_`` in
every worker).  Written with ``ctypes`` because Python exposes no ``mallopt``.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import platform
from collections.abc import Mapping

__all__ = ["MMAP_THRESHOLD_BYTES", "TOP_PAD_BYTES", "TRIM_THRESHOLD_BYTES", "keep_freed_memory",
           "release_freed_memory"]

MMAP_THRESHOLD_BYTES = 32 << 20
TRIM_THRESHOLD_BYTES = 1 << 30
TOP_PAD_BYTES = 64 << 20

# glibc <malloc.h>
_M_TRIM_THRESHOLD = -1
_M_TOP_PAD = -2
_M_MMAP_THRESHOLD = -3

_applied: bool | None = None


#: glibc's own values of the three parameters (mallopt(3)), what a process has unless its
#: environment sets them (``MALLOC_MMAP_THRESHOLD_``, ``MALLOC_TRIM_THRESHOLD_``,
#: ``MALLOC_TOP_PAD_``): restored by :func:`release_freed_memory`
_GLIBC_DEFAULTS = {_M_MMAP_THRESHOLD: ("MALLOC_MMAP_THRESHOLD_", 128 * 1024),
                   _M_TRIM_THRESHOLD: ("MALLOC_TRIM_THRESHOLD_", 128 * 1024),
                   _M_TOP_PAD: ("MALLOC_TOP_PAD_", 128 * 1024)}


def _user_chose(not_the_users: Mapping[str, object] = {}) -> bool:
    """Whether the environment already sets glibc's malloc parameters (a variable set to the
    value ``not_the_users`` gives for it is someone else's choice, not the user's)."""
    def theirs(k: str) -> bool:
        return k in not_the_users and str(not_the_users[k]) == os.environ[k]
    return any(k.startswith("MALLOC_") and k.endswith("_") and not theirs(k)
               for k in os.environ) or \
        "glibc.malloc." in os.environ.get("GLIBC_TUNABLES", "")


def _libc():
    """glibc's ``mallopt`` and ``malloc_trim``, or None (not Linux with glibc)."""
    if platform.system() != "Linux" or platform.libc_ver()[0] != "glibc":
        return None
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c"))
        mallopt, trim = libc.mallopt, libc.malloc_trim
    except (OSError, AttributeError, TypeError):
        return None
    mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
    mallopt.restype = ctypes.c_int
    trim.argtypes = (ctypes.c_size_t,)
    trim.restype = ctypes.c_int
    return mallopt, trim


def keep_freed_memory(not_the_users: Mapping[str, object] = {}) -> bool:
    """Set this process's allocator as the module docstring says, once; True when every
    parameter is so set (now or by an earlier call), False where it cannot be (not glibc, a
    value refused) or the user chose otherwise (``not_the_users``: environment variables, with
    their values, that were set by someone else, see :func:`_user_chose`)."""
    global _applied
    if _applied is not None:
        return _applied
    _applied = False
    calls = _libc()
    if calls is None or _user_chose(not_the_users):
        return False
    mallopt = calls[0]
    # each set on its own (mallopt returns 1 on success); setting the mmap threshold also
    # stops glibc's own adjustment of the two thresholds
    ok = [mallopt(param, value) == 1 for param, value in (
        (_M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES), (_M_TRIM_THRESHOLD, TRIM_THRESHOLD_BYTES),
        (_M_TOP_PAD, TOP_PAD_BYTES))]
    _applied = all(ok)
    return _applied


def release_freed_memory() -> bool:
    """Undo :func:`keep_freed_memory` (when it changed anything): the parameters back to the
    environment's values or glibc's defaults, and the free memory given back to the kernel
    (``malloc_trim``).  For a long-lived process that is not ours (a Dask worker) once our
    work in it ends.  True when something was undone."""
    global _applied
    if not _applied:
        _applied = None
        return False
    _applied = None
    calls = _libc()
    if calls is None:  # pragma: no cover - applied implies glibc
        return False
    mallopt, trim = calls
    for param, (variable, default) in _GLIBC_DEFAULTS.items():
        try:
            value = int(os.environ.get(variable, default))
        except ValueError:
            value = default
        mallopt(param, value)
    trim(0)
    return True
