"""Benchmark suites of ``gyro-attitude bench``.

Each suite is a module ``gyro_attitude.benchmarks.<suite>`` with
``run(quick: bool, out_dir: pathlib.Path) -> list[dict]``: it prints its own readable
table, may write PNGs into ``out_dir``, and returns one JSON-ready row per measurement.
Speed targets are measured here (figures printed and written to JSON), never in timed
unit tests.
"""
