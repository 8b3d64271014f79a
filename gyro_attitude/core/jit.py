"""One source, two speeds: per-sample steps written once in the subset of Python that numba
compiles, run compiled where speed matters and as plain Python otherwise.

A function marked :func:`kernel` is ordinary Python: floats, ints, tuples and numpy arrays, no
objects.  :func:`compiled` gives its compiled form (numba's ``njit``), with every marked
function it calls compiled too, so that a loop over samples runs without the interpreter.
Nothing is copied: the compiled form is built from the same code object.

The backend is chosen once (:func:`backend`): ``numba`` when it is installed, ``python`` when it
is not or when ``GYRO_ATTITUDE_JIT=0`` (then :func:`compiled` returns the function itself: the
same results, slower).  numba is imported on the first :func:`compiled` call only, so commands
that never run a per-sample chain do not pay its import.  Compiled code is cached on disk
(numba's ``cache=True``, beside the source in ``__pycache__``): the first run of a new
installation compiles (seconds), later ones load.  Where numba finds no writable place for
its cache (a read-only installation, no writable home), the kernels are compiled in every
process, said once as a warning.

:func:`precompiled` gives the ahead-of-time compiled form of a kernel when the installation
holds one built from this very source (``python -m gyro_attitude.io.precompile``, run by
``dev.sh``): the same code in an extension module that needs no numba in the process, so a
fresh process skips numba's import and the first load of its cache (0.7 s, more than a whole
replay of a 3-minute recording takes without them).
"""

from __future__ import annotations

import functools
import hashlib
import importlib
import os
import pickle
import types
import warnings

__all__ = ["backend", "compiled", "direct", "kernel", "precompiled", "precompiled_name"]

_MARK = "__gyro_attitude_kernel__"


def kernel(func=None, *, inline: bool = False):
    """Mark ``func`` as written in numba's nopython subset (see the module docstring).
    ``@kernel(inline=True)``: a small leaf step whose compiled form is inlined into its
    callers (a call that passes arrays costs their reference counts; the whole chain inlined
    would take minutes to compile)."""
    def mark(f):
        setattr(f, _MARK, "inline" if inline else True)
        return f
    return mark if func is None else mark(func)


@functools.cache
def backend() -> str:
    """``"numba"`` or ``"python"`` (chosen once per process)."""
    if _jit_off():
        return "python"
    try:
        import numba  # noqa: F401
    except ImportError:
        return "python"
    return "numba"


@functools.cache
def compiled(func):
    """The compiled form of the kernel ``func`` (itself with the python backend)."""
    if not getattr(func, _MARK, False):
        raise TypeError(f"{func.__qualname__} is not marked as a kernel")
    if backend() == "python":
        return func
    import numba

    # the callees it names, compiled: numba calls compiled functions only
    names = dict(func.__globals__)
    for name in func.__code__.co_names:
        callee = names.get(name)
        if callee is not func and getattr(callee, _MARK, False):
            names[name] = compiled(callee)
    twin = types.FunctionType(func.__code__, names, func.__name__, func.__defaults__,
                              func.__closure__)
    twin.__module__, twin.__qualname__ = func.__module__, func.__qualname__
    # numpy's error model: no zero-division check per division (the steps guard their
    # divisions themselves; the numbers are the same)
    options = {"error_model": "numpy",
               "inline": "always" if getattr(func, _MARK) == "inline" else "never"}
    try:
        return numba.njit(cache=True, **options)(twin)
    except RuntimeError as exc:  # no writable cache beside the source nor in the user's home
        _warn_uncached(exc)
        return numba.njit(cache=False, **options)(twin)


def _jit_off() -> bool:
    return os.environ.get("GYRO_ATTITUDE_JIT", "1").strip() == "0"


def precompiled_name(func) -> str:
    """The module name of the ahead-of-time form of the kernel ``func``: it names a digest of
    every source file of the core (the kernels and the constants numba freezes into them),
    of the build script, and of numpy's and numba's versions, so a module built from other
    code, or by another numba than the JIT's, is never taken."""
    return f"_aot_{func.__name__}_{_source_digest()}"


@functools.cache
def _source_digest() -> str:
    """The digest of :func:`precompiled_name`, computed once a process (it reads the core)."""
    import importlib.metadata
    import pathlib

    import numpy

    digest = hashlib.sha256(numpy.__version__.encode())
    digest.update(importlib.metadata.version("numba").encode())
    core = pathlib.Path(__file__).parent
    for path in sorted([*core.rglob("*.py"), core.parent / "io" / "precompile.py"]):
        digest.update(str(path.relative_to(core.parent)).encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


@functools.cache
def precompiled(func):
    """The ahead-of-time compiled ``func`` from this package's directory, or None (not built
    for this source, ``GYRO_ATTITUDE_PRECOMPILED=0`` or ``GYRO_ATTITUDE_JIT=0``).  Called
    with arrays of other dtypes, dimensions or layouts than it was built for, or read-only
    ones (the machine code would read them wrongly or write into them: it does not check), it
    hands the call to :func:`compiled`."""
    if _jit_off() or os.environ.get("GYRO_ATTITUDE_PRECOMPILED", "1").strip() == "0" or \
            not getattr(func, _MARK, False):
        return None
    try:
        name = precompiled_name(func)  # (reads the source files: none in a frozen install)
        module = importlib.import_module(f"{__package__}.{name}")
        with open(os.path.join(os.path.dirname(__file__), name + ARGS_SUFFIX), "rb") as f:
            arrays = pickle.load(f)  # written by the build beside the module
    except (ImportError, OSError, pickle.UnpicklingError, EOFError):
        return None
    machine_code = getattr(module, func.__name__)

    def call(*args):
        for a, spec in zip(args, arrays, strict=True):
            if spec is not None and not (isinstance(a, spec[0]) and a.ndim == spec[1]
                                         and a.dtype == spec[2] and a.flags.c_contiguous
                                         and a.flags.aligned and a.flags.writeable):
                return compiled(func)(*args)
        return machine_code(*args)

    return call


#: beside a precompiled module: per argument None (a scalar) or (ndarray, ndim, dtype)
ARGS_SUFFIX = ".args.pickle"


def direct(kernel_form):
    """The machine code behind the compiled ``kernel_form`` (:func:`compiled`) when numba has
    compiled it for exactly one set of argument types, called without numba's dispatch (which
    works out the types of every argument again on every call: a few µs for a kernel of sixty
    arguments); ``kernel_form`` itself otherwise (none or several sets of types yet, or the
    python backend).  Only for a caller that passes the same argument types on every call:
    the machine code converts what it gets to the types it was compiled for."""
    signatures = getattr(kernel_form, "signatures", None)
    if signatures is None or len(signatures) != 1:
        return kernel_form
    return kernel_form.overloads[signatures[0]].entry_point


_warned: list[str] = []


def _warn_uncached(exc: Exception) -> None:
    """Say once that the kernels are compiled in every process (numba found no place to cache
    them: a read-only installation and no writable home; NUMBA_CACHE_DIR names one)."""
    if not _warned:
        _warned.append(str(exc))
        warnings.warn(f"gyro_attitude: numba cannot cache the compiled kernels ({exc}); they "
                      "are compiled again in every process (set NUMBA_CACHE_DIR to a writable "
                      "directory)", UserWarning, stacklevel=3)
