"""Tilt accuracy against VQF on every shared BROAD recording, peers in the same run (issue 40).

``gyro-attitude bench --suite vqf [--json docs/bench/vqf.json]`` or ``run(quick, out_dir,
aiding)``.  Data: every ``*.mcap`` of the shared real directory (:func:`.real.real_dir`:
``$GYRO_ATTITUDE_REAL_DIR`` or ``shared/real`` from the working directory up; BROAD, Laidig,
Caruso, Cereatti, Seel, *Data* 6(7):72, 2021, CC BY 4.0).  ``quick``: the two recordings of
the ``real`` suite only.

Per recording, four estimators on the same arrays, in the same run:

* ``causal``: what ``replay --estimator causal --aiding <aiding>`` gives with no initial
  attitude (``initial_attitude_source`` auto: aided, the tilt of the first accelerometer
  sample; ``gyro_bias`` auto, the node's default algorithm):
  :func:`~gyro_attitude.offline.replay.estimate_recording`, i.e.
  :meth:`AttitudeStream.run <gyro_attitude.core.attitude.stream.AttitudeStream.run>` over the
  arrays, frame ``enu`` at BROAD's latitude (52.5°N, as the ``real`` suite: the Earth rate is
  taken out of the bias);
* ``vqf``: VQF 6D real-time (``VQF(dt).updateBatch``, default parameters);
* ``offline``: what ``replay --aiding <aiding>`` gives (the whole-recording estimator,
  core/attitude/offline.py), same settings;
* ``offline_vqf``: offlineVQF 6D (forward-backward VQF).

``aiding`` is the word of the ``aiding`` setting (``StreamConfig(aiding=...)``); ``None``
runs the settings table's default.  Heading is not observable without a magnetometer, so the
comparison is the **tilt** error: the angle between the estimated and the true up direction in
the body (:func:`.real.tilt_error`; heading-free, no alignment needed), against the optical
truth at its own stamps as shared (the truth stamps are Imu stamps).

**The motion** (as the ``real`` suite): the truth samples from the first one to the last one at
or before the start of the final rest, the final rest being the last run of the rest detector
(core/attitude/rest.py, default thresholds) on the data itself that reaches the end of the
recording (:func:`.real.end_of_motion`).  So the initial rest (and the filters' start there)
is included, the final rest is not.  Over it: the RMS
tilt error and the peak (largest) tilt error.

Per recording the ratios ours / peer; then the median and worst over recordings and whether
the targets of issue 40 are met (:data:`TARGETS`): causal median RMS ratio ≤ 0.75, none above
1.0, peak ≤ 1.5× VQF's on every recording; offline median RMS ratio ≤ 0.75, none above 1.0.
"""

from __future__ import annotations

import time

import numpy as np

RECORDINGS_QUICK = ("broad_05_slow_rotation_with_breaks", "broad_16_fast_translation")
DEFAULT_AIDING: str | None = None  # None: the settings table's default aiding (auto)
TARGETS = {"causal_rms_median": 0.75, "causal_rms_worst": 1.0, "causal_peak_worst": 1.5,
           "offline_rms_median": 0.75, "offline_rms_worst": 1.0}
ESTIMATORS = ("causal", "vqf", "offline", "offline_vqf")


def config(aiding: str | None = DEFAULT_AIDING):
    """The settings of the run: the defaults with ``aiding`` (None: its default), frame enu at
    BROAD's latitude."""
    from gyro_attitude.benchmarks.real import LATITUDE_RAD
    from gyro_attitude.core.attitude.stream import StreamConfig

    kw = {} if aiding is None else {"aiding": aiding}
    return StreamConfig(frame="enu", latitude_rad=float(LATITUDE_RAD), **kw)


def recordings(directory=None) -> list:
    """The ``*.mcap`` paths of the shared real directory, sorted by name."""
    from gyro_attitude.benchmarks.real import real_dir

    return sorted((directory or real_dir()).glob("*.mcap"))


def motion_end(t, g, a, tt) -> int:
    """Index of the last truth sample of the motion (module docstring)."""
    from gyro_attitude.benchmarks.real import end_of_motion

    return int(np.searchsorted(tt, t[end_of_motion(t, g, a)], side="right")) - 1


def estimates(t, g, a, cfg) -> dict:
    """``{estimator: (q (N, 4) body→nav scalar last at every Imu sample, seconds)}``."""
    from vqf import VQF, offlineVQF

    from gyro_attitude.offline.replay import estimate_recording

    out = {}
    cov = np.zeros((t.size, 9))  # unknown, as BROAD's messages
    for est in ("causal", "offline"):
        t0 = time.perf_counter()
        e = estimate_recording(t, g, a, cov, "imu_link", config=cfg, nav=cfg.nav_frame(),
                               algorithm=None, estimator=est)
        seconds = time.perf_counter() - t0
        q = np.empty((t.size, 4))  # held before the first output (none is missing here)
        q[:] = e.result.q[0]
        q[e.first + np.asarray(e.result.index)] = e.result.q
        out[est] = (q, seconds)
    dt = float(np.median(np.diff(t))) * 1e-9
    gc, ac = np.ascontiguousarray(g), np.ascontiguousarray(a)
    for est, fn in (("vqf", lambda: VQF(dt).updateBatch(gc, ac)),
                    ("offline_vqf", lambda: offlineVQF(gc, ac, None, dt))):
        t0 = time.perf_counter()
        qv = fn()["quat6D"]  # w, x, y, z
        out[est] = (np.column_stack([qv[:, 1:], qv[:, :1]]), time.perf_counter() - t0)
    return out


def evaluate_arrays(name: str, t, g, a, tt, tq, aiding: str | None = DEFAULT_AIDING,
                    kt_end: int | None = None) -> dict:
    """One row: RMS and peak tilt error over the motion of each estimator, and the ratios.
    ``kt_end`` the last truth sample of the motion (default: :func:`motion_end`)."""
    from gyro_attitude.benchmarks.real import tilt_error

    cfg = config(aiding)
    if kt_end is None:
        kt_end = motion_end(t, g, a, tt)
    idx = np.searchsorted(t, tt[:kt_end + 1])  # truth stamps are Imu stamps
    if not np.array_equal(t[np.minimum(idx, t.size - 1)], tt[:kt_end + 1]):
        raise ValueError(f"{name}: truth stamps are not Imu stamps")
    row = {"recording": name, "aiding": cfg.aiding.value, "samples": int(t.size),
           "motion_s": float((tt[kt_end] - tt[0]) * 1e-9)}
    for est, (q, seconds) in estimates(t, g, a, cfg).items():
        err = np.degrees(tilt_error(q[idx], tq[:kt_end + 1]))
        row[f"{est}_rms_tilt_deg"] = float(np.sqrt(np.mean(err ** 2)))
        row[f"{est}_peak_tilt_deg"] = float(err.max())
        row[f"{est}_peak_at_s"] = float((tt[int(np.argmax(err))] - tt[0]) * 1e-9)
        row[f"{est}_samples_per_s"] = t.size / max(seconds, 1e-12)
    for ours, peer in (("causal", "vqf"), ("offline", "offline_vqf")):
        for what in ("rms", "peak"):
            row[f"{ours}_{what}_over_{peer}"] = (row[f"{ours}_{what}_tilt_deg"]
                                                 / row[f"{peer}_{what}_tilt_deg"])
    return row


def evaluate(path, aiding: str | None = DEFAULT_AIDING) -> dict:
    """:func:`evaluate_arrays` of one recording file."""
    from gyro_attitude.benchmarks.real import load

    t, g, a, tt, tq = load(path.stem, path.parent)
    return evaluate_arrays(path.stem, t, g, a, tt, tq, aiding)


def summary(rows: list[dict]) -> dict:
    """Median and worst ratios over the recordings, and each target met or not."""
    r = {k: [row[k] for row in rows] for k in ("causal_rms_over_vqf", "causal_peak_over_vqf",
                                                "offline_rms_over_offline_vqf")}
    s = {"recording": "summary", "recordings": len(rows),
         "aiding": rows[0]["aiding"] if rows else None,
         "causal_rms_median": float(np.median(r["causal_rms_over_vqf"])),
         "causal_rms_worst": float(max(r["causal_rms_over_vqf"])),
         "causal_peak_worst": float(max(r["causal_peak_over_vqf"])),
         "offline_rms_median": float(np.median(r["offline_rms_over_offline_vqf"])),
         "offline_rms_worst": float(max(r["offline_rms_over_offline_vqf"]))}
    for key, limit in TARGETS.items():
        s[f"{key}_target"] = limit
        s[f"{key}_met"] = bool(s[key] <= limit)
    s["all_targets_met"] = all(s[f"{k}_met"] for k in TARGETS)
    return s


def print_table(rows: list[dict], s: dict) -> None:
    print(f"aiding {s['aiding']}; tilt error over the motion (°), ours / peer (same run)")
    print(f"{'recording':38s} {'causal':>7s} {'VQF':>6s} {'ratio':>6s} | {'peak':>5s} "
          f"{'VQF':>5s} {'ratio':>5s} | {'offline':>7s} {'oVQF':>6s} {'ratio':>6s}")
    for r in rows:
        print(f"{r['recording']:38s} {r['causal_rms_tilt_deg']:7.3f} {r['vqf_rms_tilt_deg']:6.3f} "
              f"{r['causal_rms_over_vqf']:6.2f} | {r['causal_peak_tilt_deg']:5.2f} "
              f"{r['vqf_peak_tilt_deg']:5.2f} {r['causal_peak_over_vqf']:5.2f} | "
              f"{r['offline_rms_tilt_deg']:7.3f} {r['offline_vqf_rms_tilt_deg']:6.3f} "
              f"{r['offline_rms_over_offline_vqf']:6.2f}")

    def verdict(key):
        return f"{s[key]:.3f} (target ≤ {TARGETS[key]:g}: {'met' if s[key + '_met'] else 'NOT met'})"

    print(f"causal RMS / VQF: median {verdict('causal_rms_median')}, worst "
          f"{verdict('causal_rms_worst')}; peak / VQF worst {verdict('causal_peak_worst')}")
    print(f"offline RMS / offlineVQF: median {verdict('offline_rms_median')}, worst "
          f"{verdict('offline_rms_worst')}")


def run(quick: bool = False, out_dir=None, aiding: str | None = DEFAULT_AIDING) -> list[dict]:
    from gyro_attitude.benchmarks.real import real_dir
    from gyro_attitude.core.attitude.stream import compile_kernels

    compile_kernels()
    paths = recordings()
    if quick:
        paths = [p for p in paths if p.stem in RECORDINGS_QUICK]
    if not paths:
        print(f"vqf: no recordings (*.mcap) in {real_dir()}, nothing measured")
        return []
    rows = []
    for path in paths:
        rows.append(evaluate(path, aiding))
    s = summary(rows)
    print_table(rows, s)
    return rows + [s]
