"""``gyro-attitude bench``: run benchmark suites, print tables, write PNGs and JSON.

``--suite NAME`` (repeatable; default ``attitude``) picks suites from :data:`SUITES`; each
maps to a module with ``run(quick, out_dir) -> list[dict]``, imported only when asked
for.  A suite whose module is not there is reported as missing, not a crash.  ``--json``
writes ``{"meta": {...}, "rows": [...]}`` with one row per measurement (every row has a
``suite`` key).
"""

from __future__ import annotations

import argparse
import importlib
import json
import math
import os
import pathlib
import time
import traceback

from gyro_attitude.benchmarks import machine_description
from gyro_attitude.commands import error_line
from gyro_attitude.commands.usage_errors import output_file
from gyro_attitude.io.safe_output import (
    OutputPathError,
    SafeOutput,
    check_output_path,
    raise_if_stop_requested,
)

SUITES: dict[str, str] = {
    "attitude": "gyro_attitude.benchmarks.attitude",
    "gyro": "gyro_attitude.benchmarks.gyro_fidelity",
    "replay": "gyro_attitude.benchmarks.replay",
    "nodes": "gyro_attitude.benchmarks.nodes",
    "scenes": "gyro_attitude.benchmarks.scenes",
    "real": "gyro_attitude.benchmarks.real",
    "estimator": "gyro_attitude.benchmarks.estimator",
    "jitter": "gyro_attitude.benchmarks.jitter",
    "offline-memory": "gyro_attitude.benchmarks.offline_memory",
    "nyquist": "gyro_attitude.benchmarks.nyquist",
    "instruments": "gyro_attitude.benchmarks.instruments",
    "trajectory": "gyro_attitude.benchmarks.trajectory",
    "montecarlo": "gyro_attitude.benchmarks.montecarlo",
    "montecarlo-dask": "gyro_attitude.benchmarks.montecarlo_dask",
    "vqf": "gyro_attitude.benchmarks.vqf_parity",
}


PROG = "gyro-attitude bench"


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--suite", action="append", choices=sorted(SUITES), metavar="NAME",
                        help=f"suite to run (repeatable): {', '.join(SUITES)}; "
                             "default: attitude")
    parser.add_argument("--quick", action="store_true",
                        help="small sizes (each suite aims at under a minute)")
    parser.add_argument("--json", metavar="PATH",
                        type=lambda text: pathlib.Path(output_file(text)),
                        help="write all rows as JSON to PATH")
    parser.add_argument("--out-dir", metavar="DIR", type=pathlib.Path,
                        default=pathlib.Path("bench_out"),
                        help="directory for plots (default: bench_out/)")
    parser.add_argument("--force", action="store_true",
                        help="overwrite an existing --json file")


def _load_suite(name: str):
    """The suite module, or None when it is not there (yet)."""
    module_name = SUITES[name]
    try:
        return importlib.import_module(module_name)
    except ModuleNotFoundError as err:
        if err.name is not None and module_name.startswith(err.name):
            return None
        raise


def _clean(value):
    """JSON-safe: NaN/inf become null, numpy scalars become Python numbers."""
    if isinstance(value, dict):
        return {str(k): _clean(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_clean(v) for v in value]
    if hasattr(value, "item") and not isinstance(value, str | bytes):
        try:
            value = value.item()
        except (TypeError, ValueError):
            return str(value)
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, str | int | float | bool) or value is None:
        return value
    return str(value)


def _prepare_outputs(args: argparse.Namespace) -> str | None:
    """Check (and create) the output locations before any work; a reason when unusable."""
    if args.json:
        path = pathlib.Path(args.json)
        try:
            if not path.is_dir():  # a directory is refused by the check, not created
                path.parent.mkdir(parents=True, exist_ok=True)
            check_output_path(path, force=args.force, what="--json")
        except FileExistsError:
            return f"--json {path}: its directory {path.parent} is not a directory"
        except (OutputPathError, OSError) as exc:
            return str(exc)
    out_dir = pathlib.Path(args.out_dir)
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        return f"--out-dir {out_dir}: not a directory"
    except OSError as exc:
        return f"--out-dir {out_dir}: {exc.strerror or exc}"
    if not os.access(out_dir, os.W_OK | os.X_OK):
        return f"--out-dir {out_dir}: not writable"
    return None


def run(args: argparse.Namespace) -> int:
    suites = list(dict.fromkeys(args.suite or ["attitude"]))
    problem = _prepare_outputs(args)
    if problem is not None:
        error_line("bench", problem)
        return 2
    out_dir = pathlib.Path(args.out_dir)
    rows: list[dict] = []
    status: dict[str, str] = {}
    for name in suites:
        try:
            module = _load_suite(name)
        except Exception:  # the suite exists but one of its imports failed
            raise_if_stop_requested()  # unless the error is a Ctrl-C swallowed on its way
            traceback.print_exc()
            status[name] = "error"
            continue
        if module is None:
            print(f"suite {name}: missing (module {SUITES[name]} is not there yet)")
            status[name] = "missing"
            continue
        print(f"=== suite {name} ===", flush=True)
        t0 = time.perf_counter()
        try:
            suite_rows = module.run(bool(args.quick), out_dir)
        except Exception:  # one broken suite must not hide the others' figures
            raise_if_stop_requested()  # unless the error is a Ctrl-C swallowed on its way
            traceback.print_exc()
            status[name] = "error"
            continue
        for row in suite_rows:
            row.setdefault("suite", name)
        rows += suite_rows
        status[name] = "ok"
        print(f"=== suite {name}: {len(suite_rows)} rows in {time.perf_counter() - t0:.1f} s ===")
    if args.json:
        meta = {
            "created_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
            "quick": bool(args.quick), "suites": status, **machine_description(),
        }
        path = pathlib.Path(args.json)
        try:
            # written beside the output and renamed into place when complete
            with SafeOutput(path, force=args.force) as tmp:
                tmp.write_text(json.dumps(_clean({"meta": meta, "rows": rows}), indent=1))
        except (OutputPathError, OSError) as exc:
            error_line("bench", f"--json {path}: {exc}")
            return 1
        print(f"wrote {len(rows)} rows to {path}")
    return 1 if "error" in status.values() else 0
