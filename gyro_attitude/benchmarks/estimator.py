"""The causal estimator's cost on the shared BROAD recordings, against VQF in the same run.

``gyro-attitude bench --suite estimator`` (``docs/bench/estimator.json``).  Per recording and
aiding mode (``none``, ``tilt`` = the default ``auto``, ``magnetometer``), one row:

* ``run_samples_per_s``: :meth:`AttitudeStream.run` (what ``replay --estimator causal`` runs)
  over the whole recording, the best of :data:`REPEATS`;
* ``push_us``: :meth:`AttitudeStream.push` per sample (the node's path), the best of
  :data:`REPEATS` passes over the first :data:`PUSHED` samples;
* ``vqf_samples_per_s``: VQF real-time (6D; 9D with the magnetometer) ``updateBatch`` on the
  same data, the best of :data:`REPEATS`, and the ratio of the two.

Then a fresh process per run (``python -m gyro_attitude.cli replay``, start-up included):
``replay --estimator causal --aiding tilt`` and ``replay --aiding tilt`` (offline), wall seconds,
the best of :data:`REPEATS`.  Every kernel is loaded from numba's cache before the first row
(``compile_kernels``), as the node loads it before it subscribes.  Data: BROAD (Laidig,
Caruso, Cereatti, Seel, *Data* 6(7):72, 2021, CC BY 4.0).
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from gyro_attitude.benchmarks import best_seconds

REPEATS = 3
PUSHED = 20_000
AIDINGS = ("none", "tilt", "magnetometer")  # auto is tilt on an Imu with an accelerometer
RECORDINGS = ("broad_05_slow_rotation_with_breaks", "broad_16_fast_translation")


def _best(fn, repeats: int = REPEATS) -> float:
    return best_seconds(fn, repeats)


def rows_for(path: Path) -> list[dict]:
    from vqf import VQF

    from gyro_attitude.core.attitude.sample_alignment import latest_at
    from gyro_attitude.core.attitude.stream import AttitudeStream, StreamConfig
    from gyro_attitude.io.cdr_arrays import IMU_TYPE, MAGNETIC_FIELD_TYPE
    from gyro_attitude.io.imu_fast import read_topic_arrays

    arrays = read_topic_arrays(path, {"/imu/data_raw": IMU_TYPE, "/imu/mag": MAGNETIC_FIELD_TYPE})
    imu, field = arrays["/imu/data_raw"], arrays["/imu/mag"]
    t, g, a = imu.stamp_ns, imu.angular_velocity, imu.linear_acceleration
    mag = latest_at(t, field.stamp_ns, field.magnetic_field, 50_000_000)
    dt = float(np.median(np.diff(t))) * 1e-9
    gc, ac = np.ascontiguousarray(g), np.ascontiguousarray(a)
    mc = np.ascontiguousarray(np.nan_to_num(mag) * 1e6)  # µT, VQF's unit-free field
    tl = t.tolist()
    rows = []
    for aiding in AIDINGS:
        cfg = StreamConfig(aiding=aiding)
        m = mag if aiding == "magnetometer" else None
        run_s = _best(lambda cfg=cfg, m=m: AttitudeStream(config=cfg).run(t, g, "imu_link",
                                                                          None, a, m))

        def pushed(cfg=cfg, m=m):
            s = AttitudeStream(config=cfg)
            for k in range(PUSHED):
                s.push(tl[k], g[k], "imu_link", None, a[k], None if m is None else m[k])

        push_s = _best(pushed)
        if aiding == "magnetometer":
            vqf_s = _best(lambda: VQF(dt).updateBatch(gc, ac, mc))
        else:
            vqf_s = _best(lambda: VQF(dt).updateBatch(gc, ac))
        rows.append({"recording": path.stem, "aiding": aiding, "samples": int(t.size),
                     "run_samples_per_s": t.size / run_s, "push_us": push_s / PUSHED * 1e6,
                     "vqf_samples_per_s": t.size / vqf_s,
                     "run_over_vqf": vqf_s / run_s})
    return rows


def fresh_process_rows(path: Path) -> list[dict]:
    """Wall seconds of a fresh ``gyro-attitude replay`` process (start-up included)."""
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for label, flags in (("replay --estimator causal --aiding tilt",
                              ["--estimator", "causal", "--aiding", "tilt"]),
                             ("replay --aiding tilt (offline)", ["--aiding", "tilt"])):
            cmd = [sys.executable, "-m", "gyro_attitude.cli", "replay", str(path), "--out",
                   str(Path(tmp) / "o.mcap"), "--force", "--no-progress", *flags]
            subprocess.run(cmd, check=True, capture_output=True)  # caches warm
            wall = _best(lambda cmd=cmd: subprocess.run(cmd, check=True, capture_output=True))
            rows.append({"recording": path.stem, "mode": label, "fresh_process_wall_s": wall})
    return rows


def run(quick: bool = False, out_dir=None) -> list[dict]:
    from gyro_attitude.benchmarks.real import real_dir
    from gyro_attitude.core.attitude.stream import compile_kernels

    compile_kernels()
    directory = real_dir()
    rows = []
    for name in RECORDINGS[:1] if quick else RECORDINGS:
        path = directory / f"{name}.mcap"
        if not path.exists():
            print(f"estimator: {path} missing, skipped")
            continue
        rows += rows_for(path) + fresh_process_rows(path)
    print(f"{'recording':36s} {'aiding':13s} {'run M/s':>8s} {'VQF M/s':>8s} {'ratio':>6s} "
          f"{'push us':>8s}")
    for r in rows:
        if "aiding" in r:
            print(f"{r['recording']:36s} {r['aiding']:13s} {r['run_samples_per_s'] / 1e6:8.2f} "
                  f"{r['vqf_samples_per_s'] / 1e6:8.2f} {r['run_over_vqf']:6.2f} "
                  f"{r['push_us']:8.2f}")
        else:
            print(f"{r['recording']:36s} {r['mode']:44s} {r['fresh_process_wall_s']:6.2f} s")
    return rows
