"""Benchmark suites of ``gyro-attitude bench``.

Each suite is a module ``gyro_attitude.benchmarks.<suite>`` with
``run(quick: bool, out_dir: pathlib.Path) -> list[dict]``: it prints its own readable
table, may write PNGs into ``out_dir``, and returns one JSON-ready row per measurement.
Speed targets are measured here (figures printed and written to JSON), never in timed
unit tests.
"""

import os
import platform


def machine_description() -> dict:
    """What the figures were measured on: CPU model, core count, load, Python and numpy."""
    model = platform.processor() or "?"
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.startswith("model name"):
                    model = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    import numpy as np

    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    return {"cpu_model": model, "cpu_count": os.cpu_count(), "load_avg_1min": round(load, 2),
            "platform": platform.platform(), "python": platform.python_version(),
            "numpy": np.__version__}


def best_seconds(fn, repeats: int) -> float:
    """The shortest wall time of ``repeats`` calls of ``fn`` (a shared machine's noise only
    ever adds time)."""
    import time

    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best
