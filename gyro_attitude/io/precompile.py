"""Build the ahead-of-time compiled form of the estimators' recording loops (the causal one's
``chain.run_rows``, the offline one's ``rest.rest_rows`` and ``validation.validate_rows``) into
the package: ``python -m gyro_attitude.io.precompile`` (``dev.sh`` runs it after installing).
See :func:`gyro_attitude.core.jit.precompiled`.

It is the same code numba's JIT compiles, built by numba's ahead-of-time compiler
(``numba.pycc``: pending deprecation since numba 0.57, and the only one numba has; if it goes,
this build fails in one line and the loops are compiled just in time as before).  The argument
types are those the JIT compiled for (:func:`.stream.compile_kernels` run first).  Needs a C
compiler; without one, one line says so and nothing else changes.
"""

from __future__ import annotations

import inspect
import os
import pickle
import shutil
import sys
import tempfile
import warnings
from pathlib import Path

from gyro_attitude.core import jit

PREFIX = "_aot_"
NO_COMPILER = "no working C compiler (install gcc, or name one in CC)"
AFTER_FAILURE = "replay compiles its loops just in time (0.7 s more at start)"


def build(func, directory: Path) -> Path:
    """Compile the kernel ``func`` ahead of time into ``directory`` (the package directory of
    :mod:`gyro_attitude.core.jit`) for the one set of argument types :func:`jit.compiled`
    has compiled it for; older builds of it there are removed."""
    from numba.core.errors import NumbaPendingDeprecationWarning

    form = jit.compiled(func)
    if len(form.signatures) != 1:
        raise RuntimeError(f"{func.__name__} was compiled for {len(form.signatures)} sets of "
                           "argument types, not one")
    signature = form.overloads[form.signatures[0]].signature
    # the export calls the JIT form: pycc compiles an exported function with its own default
    # flags (Python's error model: a ZeroDivisionError where the kernels give inf), a callee
    # with the options the JIT gave it
    names = ", ".join(inspect.signature(func).parameters)
    scope = {"target": form}
    exec(f"def entry({names}):\n    return target({names})\n", scope)
    name = jit.precompiled_name(func)
    work = Path(tempfile.mkdtemp(dir=directory, prefix=".build-"))
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", NumbaPendingDeprecationWarning)
            from numba.pycc import CC

            cc = CC(name)
            cc.output_dir = str(work)
            cc.verbose = False
            cc.export(func.__name__, signature)(scope["entry"])
            cc.compile()
        built = next(work.glob(f"{name}.*"))
        with open(work / (name + jit.ARGS_SUFFIX), "wb") as f:
            pickle.dump(_array_args(signature), f)
        for old in directory.glob(f"{PREFIX}{func.__name__}_*"):
            if not old.name.startswith(name + "."):  # builds of other source
                old.unlink(missing_ok=True)
        (work / (name + jit.ARGS_SUFFIX)).replace(directory / (name + jit.ARGS_SUFFIX))
        target = directory / built.name
        built.replace(target)  # within one file system: the module appears whole
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return target


def _compiler_works() -> bool:
    """Whether the C compiler pycc would use compiles a trivial file (pycc's own test)."""
    from numba.core.errors import NumbaPendingDeprecationWarning

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumbaPendingDeprecationWarning)
        from numba.pycc.platform import external_compiler_works

        return external_compiler_works()


def _array_args(signature) -> list:
    """Per argument of ``signature``: None (a scalar) or (np.ndarray, ndim, dtype), what
    :func:`jit.precompiled` checks before it calls the machine code."""
    import numpy as np
    from numba import types
    from numba.np.numpy_support import as_dtype

    return [(np.ndarray, t.ndim, as_dtype(t.dtype)) if isinstance(t, types.Array) else None
            for t in signature.args]


def main(argv: list[str] | None = None) -> int:
    """Build unless modules built from this source are there (``--force``: build anyway)."""
    from gyro_attitude.core.attitude import chain, rest, validation

    loops = (chain.run_rows, rest.rest_rows, validation.validate_rows)
    force = "--force" in (sys.argv[1:] if argv is None else argv)
    if not force and all(jit.precompiled(f) is not None for f in loops):
        print(f"precompile: {', '.join(map(jit.precompiled_name, loops))} are up to date",
              file=sys.stderr)
        return 0
    # compiled afresh, not loaded from numba's cache (set before numba is imported): the
    # cache is keyed on each function's own file and may hold a form built before a callee
    # changed
    cache = tempfile.mkdtemp(prefix="gyro-attitude-precompile-")
    os.environ["NUMBA_CACHE_DIR"] = cache
    try:
        return _build_fresh(loops)
    finally:
        shutil.rmtree(cache, ignore_errors=True)


def _build_fresh(loops) -> int:
    from gyro_attitude.core.attitude.stream import compile_kernels

    if jit.backend() != "numba":
        print("precompile: skipped (no numba, or GYRO_ATTITUDE_JIT=0)", file=sys.stderr)
        return 0
    if not _compiler_works():  # said before a minute of compiling, not after it
        print(f"precompile: not built ({NO_COMPILER}); {AFTER_FAILURE}", file=sys.stderr)
        return 1
    try:
        # the just-in-time form, compiled for the argument types a run passes
        os.environ["GYRO_ATTITUDE_PRECOMPILED"] = "0"
        compile_kernels()
        targets = [build(func, Path(jit.__file__).parent) for func in loops]
    except Exception as exc:  # a compiler missing, a read-only installation, pycc gone
        first = (str(exc).splitlines() or [""])[0]
        if "compiler" in first:
            first = NO_COMPILER
        print(f"precompile: not built ({type(exc).__name__}: {first}); {AFTER_FAILURE}",
              file=sys.stderr)
        return 1
    print(f"precompile: {', '.join(t.name for t in targets)}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
