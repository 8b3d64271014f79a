"""Peak memory of the offline estimator against the recording's length (``bench --suite
offline-memory``).

Each size runs in a fresh process: a 1 kHz noisy MEMS recording (rest, a slow tumble with
accelerations, rest; gyro and accelerometer) is made in memory and estimated with tilt
aiding, its arrays of the recording's length taken from a :class:`~gyro_attitude.io.spool.Spool`
as replay takes them.  The peak RSS (Linux ``VmHWM``) is reset after the input is made, so the
figures are the estimation's own: peak RSS, peak anonymous RSS (``RssAnon``, sampled every
10 ms: the memory the process needs; file-backed pages the kernel can write back and drop),
the bytes of the input and of the output the estimator returns (index, q, variance, verdicts),
and what is left -- the working memory.

The replay rows measure the whole ``gyro-attitude replay`` process instead (read, estimate,
write, truth comparison): a ``handheld_mems`` recording at 1 kHz with its 1 kHz truth is
simulated to a temporary MCAP per length, replayed with each estimator in a fresh process, its
peak RSS taken from the kernel (``os.wait4``'s ``ru_maxrss``) and its ``RssAnon`` and
``RssFile`` sampled from ``/proc`` every 10 ms while it runs; the slope between the lengths is
the memory replay needs per Imu message, and the replay's own summary says how many bytes of
working arrays it kept on disk.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

RATE_HZ = 1000
SIZES_S = {"10 min": 600, "1 h": 3600, "6 h": 6 * 3600}
REPLAY_SCENE = "handheld_mems"
ESTIMATORS = ("causal", "offline")

_CHILD = r"""
import json, sys, tempfile, threading, time
import numpy as np
from gyro_attitude.core.attitude.offline import estimate_offline
from gyro_attitude.core.attitude.settings import StreamConfig
from gyro_attitude.io.spool import Spool
n = int(sys.argv[1]); rate = float(sys.argv[2])


def status(key):
    with open("/proc/self/status") as f:
        return next(int(line.split()[1]) * 1024 for line in f if line.startswith(key))


anon_peak = [0]
done = threading.Event()


def sample():
    while not done.wait(0.01):
        anon_peak[0] = max(anon_peak[0], status("RssAnon:"))


from gyro_attitude.benchmarks.offline_memory import rest_tumble_rest
t, w, a = rest_tumble_rest(n, rate)
inputs = t.nbytes + w.nbytes + a.nbytes
import gc
gc.collect()
with open("/proc/self/clear_refs", "w") as f:  # Linux: reset the peak (VmHWM) to the current RSS
    f.write("5")
before = status("VmRSS:")
anon_before = anon_peak[0] = status("RssAnon:")
spool = Spool(tempfile.gettempdir())
th = threading.Thread(target=sample, daemon=True)
th.start()
t0 = time.perf_counter()
res = estimate_offline(t, w, a, config=StreamConfig(aiding="tilt"), empty=spool.empty)
sec = time.perf_counter() - t0
done.set()
th.join()
peak = status("VmHWM:")
anon_peak[0] = max(anon_peak[0], status("RssAnon:"))
out = res.index.nbytes + res.q.nbytes + res.variance.nbytes + res.action.nbytes
print(json.dumps({"samples": n, "peak_rss_bytes": peak, "rss_before_bytes": before,
                  "rss_before_includes": "the Python process and the input arrays",
                  "peak_rss_anon_bytes": anon_peak[0], "rss_anon_before_bytes": anon_before,
                  "working_anon_bytes": anon_peak[0] - anon_before,
                  "spooled_bytes": spool.spooled_bytes,
                  "input_bytes": inputs, "output_bytes": out, "seconds": sec}))
"""


def rest_tumble_rest(n: int, rate: float = RATE_HZ, seed: int = 0):
    """(t_ns, gyro, accel) of a noisy MEMS recording: rest, a slow tumble with accelerations,
    rest (a tenth of the samples each)."""
    import numpy as np

    rng = np.random.default_rng(seed)
    t = 10**9 + (np.arange(n, dtype=np.int64) * 10**9) // int(rate)
    w = rng.normal(scale=2e-3, size=(n, 3))
    w += (0.004, -0.003, 0.005)
    k0, k1 = n // 10, n - n // 10
    s = np.arange(k1 - k0) / rate
    w[k0:k1, 0] += 0.3 * np.sin(0.5 * s)
    w[k0:k1, 2] += 0.2 * np.cos(0.3 * s)
    a = rng.normal(scale=0.03, size=(n, 3))
    a[:, 2] += 9.81
    a[k0:k1] += rng.normal(scale=0.5, size=(k1 - k0, 3))
    return t, w, a


def measure(seconds: int) -> dict:
    n = int(seconds * RATE_HZ)
    r = subprocess.run([sys.executable, "-c", _CHILD, str(n), str(RATE_HZ)], capture_output=True,
                       text=True, check=True)
    return json.loads(r.stdout.strip().splitlines()[-1])


def _proc_status(pid: int) -> dict[str, int]:
    out = {}
    try:
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                key, _, value = line.partition(":")
                if key in ("RssAnon", "RssFile"):
                    out[key] = int(value.split()[0]) * 1024
    except (OSError, ValueError):
        pass
    return out


def _cli(*args, env=None, peaks: dict | None = None) -> tuple[str, int]:
    """Run ``gyro-attitude ARGS`` in a fresh process: (its stdout, its peak RSS in bytes).
    The child is reaped with ``os.wait4`` (its own rusage, not all children's maximum);
    its output goes through files, so no pipe can fill while it runs.  ``peaks`` gets the
    largest ``RssAnon`` and ``RssFile`` seen while it ran (sampled every 10 ms)."""
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
        p = subprocess.Popen([sys.executable, "-m", "gyro_attitude.cli", *args], env=env,
                             stdout=out, stderr=err, text=True)
        stop = threading.Event()

        def sample():
            while not stop.is_set():
                for key, value in _proc_status(p.pid).items():
                    if peaks is not None:
                        peaks[key] = max(peaks.get(key, 0), value)
                time.sleep(0.01)

        sampler = threading.Thread(target=sample, daemon=True)
        sampler.start()
        try:
            _, status, usage = os.wait4(p.pid, 0)
        finally:
            stop.set()
            sampler.join()
        p.returncode = rc = os.waitstatus_to_exitcode(status)  # reaped: Popen must not wait
        out.seek(0)
        err.seek(0)
        if rc != 0:
            raise RuntimeError(f"gyro-attitude {' '.join(args)} exited {rc}: "
                               f"{err.read().strip()[-300:]}")
        return out.read(), usage.ru_maxrss * 1024  # Linux: KiB


def replay_rows(sizes: dict[str, int], *, envs: dict | None = None, tmp_dir=None) -> list[dict]:
    """Peak RSS of whole ``replay`` processes at each length in ``sizes`` and each estimator,
    then one slope row per estimator (bytes per Imu message between the shortest and the
    longest length). ``envs`` ``{name: environment}``: the same recordings replayed under
    each (e.g. another PYTHONPATH for a before/after; default the current code as "this")."""
    envs = envs or {"this": None}
    rows = []
    with tempfile.TemporaryDirectory(dir=tmp_dir) as d:
        for label, sec in sizes.items():
            rec = Path(d) / "in.mcap"
            _cli("simulate", REPLAY_SCENE, "--duration", str(sec), "--rate", str(RATE_HZ),
                 "--out", str(rec), "--quiet", "--force")
            for est in ESTIMATORS:
                for code, env in envs.items():
                    peaks: dict[str, int] = {}
                    stdout, peak = _cli("replay", str(rec), "--out", str(Path(d) / "out.mcap"),
                                        "--estimator", est, "--json", "--no-progress",
                                        "--force", env=env, peaks=peaks)
                    s = json.loads(stdout)
                    rows.append({"kind": "replay", "code": code, "estimator": est,
                                 "length": label, "messages": s["messages"],
                                 "truth_matched": s["truth_matched"], "peak_rss_bytes": peak,
                                 "peak_rss_anon_bytes": peaks.get("RssAnon"),
                                 "peak_rss_file_bytes": peaks.get("RssFile"),
                                 "working_bytes_on_disk": s.get("working_bytes_on_disk"),
                                 "wall_seconds": s["wall_seconds"],
                                 "input_file_bytes": rec.stat().st_size,
                                 "output_file_bytes": (Path(d) / "out.mcap").stat().st_size})
                    print(f"replay {code:7s} {est:8s} {label:8s} {s['messages']:11d} msgs  "
                          f"peak RSS {peak * 1e-6:7.0f} MB (anonymous "
                          f"{peaks.get('RssAnon', 0) * 1e-6:6.0f} MB, on disk "
                          f"{(s.get('working_bytes_on_disk') or 0) * 1e-6:6.0f} MB)  "
                          f"{s['wall_seconds']:7.1f} s", flush=True)
            rec.unlink()
    for code in envs:
        for est in ESTIMATORS:
            mine = [r for r in rows if r["estimator"] == est and r["code"] == code]
            if len(mine) >= 2:
                a, b = mine[0], mine[-1]
                dm = b["messages"] - a["messages"]
                slope = (b["peak_rss_bytes"] - a["peak_rss_bytes"]) / dm
                anon = None
                if a["peak_rss_anon_bytes"] and b["peak_rss_anon_bytes"]:
                    anon = (b["peak_rss_anon_bytes"] - a["peak_rss_anon_bytes"]) / dm
                disk = (b["working_bytes_on_disk"] or 0) / b["messages"]
                n24 = 24 * 3600 * RATE_HZ
                row = {"kind": "replay slope", "code": code, "estimator": est,
                       "between": [a["length"], b["length"]], "bytes_per_message": slope,
                       "anon_bytes_per_message": anon,
                       "disk_working_bytes_per_message": disk}
                if anon is not None:
                    # 24 h at 1 kHz from the longest run and the slope (a flat or falling
                    # slope -- the peak no longer grows -- extrapolates to the longest run's)
                    row["anon_bytes_24h"] = b["peak_rss_anon_bytes"] + max(anon, 0.0) * (
                        n24 - b["messages"])
                    row["disk_working_bytes_24h"] = disk * n24
                    row["output_file_bytes_24h"] = b["output_file_bytes"] / b["messages"] * n24
                rows.append(row)
                print(f"replay {code:7s} {est:8s} {slope:.0f} B/msg peak RSS, "
                      f"{anon if anon is not None else float('nan'):.0f} B/msg anonymous, "
                      f"{disk:.0f} B/msg working arrays on disk between {a['length']} and "
                      f"{b['length']}" + (
                          f"; 24 h at {RATE_HZ} Hz: {row['anon_bytes_24h'] * 1e-9:.1f} GB "
                          f"anonymous memory, {row['disk_working_bytes_24h'] * 1e-9:.1f} GB "
                          f"working files, {row['output_file_bytes_24h'] * 1e-9:.1f} GB output"
                          if anon is not None else ""))
    return rows


def run(quick: bool = False, out_dir=None) -> list[dict]:
    rows = []
    sizes = {"10 min": 600} if quick else SIZES_S
    print(f"{'length':8s} {'samples':>11s} {'peak RSS MB':>12s} {'anon MB':>8s} "
          f"{'input MB':>9s} {'output MB':>10s} {'working anon MB':>16s} {'on disk MB':>11s} "
          f"{'M samples/s':>12s}")
    for label, sec in sizes.items():
        m = measure(sec)
        m["length"] = label
        mb = 1e-6
        print(f"{label:8s} {m['samples']:11d} {m['peak_rss_bytes'] * mb:12.0f} "
              f"{m['peak_rss_anon_bytes'] * mb:8.0f} {m['input_bytes'] * mb:9.0f} "
              f"{m['output_bytes'] * mb:10.0f} {m['working_anon_bytes'] * mb:16.0f} "
              f"{m['spooled_bytes'] * mb:11.0f} {m['samples'] / m['seconds'] * 1e-6:12.2f}")
        rows.append(m)
    rows.extend(replay_rows({"10 min": 600} if quick else SIZES_S))
    return rows
