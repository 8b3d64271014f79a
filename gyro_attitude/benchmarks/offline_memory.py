"""Peak memory of the offline estimator against the recording's length (``bench --suite
offline-memory``).

Each size runs in a fresh process: a 1 kHz noisy MEMS recording (rest, a slow tumble with
accelerations, rest; gyro and accelerometer) is made in memory and estimated with gravity
aiding.  The peak RSS (Linux ``VmHWM``) is reset after the input is made, so the figures are
the estimation's own: peak RSS, the bytes of the input and of the output the estimator must
return (index, q, variance, verdicts), and what is left -- the working memory, which the chunked
passes keep bounded (``DEFAULT_CHUNK_SAMPLES``) except for a few per-sample flags, indices and
the block clock of the verdicts and the rest search.

The replay rows measure the whole ``gyro-attitude replay`` process instead (read, estimate,
write, truth comparison): a ``handheld_mems`` recording at 1 kHz with its 1 kHz truth is
simulated to a temporary MCAP per length, replayed with each estimator in a fresh process, and
its peak RSS taken from the kernel (``os.wait4``'s ``ru_maxrss``); the slope between the
lengths is the memory replay needs per Imu message.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

RATE_HZ = 1000
SIZES_S = {"10 min": 600, "1 h": 3600, "6 h": 6 * 3600}
REPLAY_SCENE = "handheld_mems"
ESTIMATORS = ("causal", "offline")

_CHILD = r"""
import json, sys, time
import numpy as np
from gyro_attitude.core.attitude.offline import estimate_offline
from gyro_attitude.core.attitude.settings import StreamConfig
n = int(sys.argv[1]); rate = float(sys.argv[2])


def status(key):
    with open("/proc/self/status") as f:
        return next(int(line.split()[1]) * 1024 for line in f if line.startswith(key))


rng = np.random.default_rng(0)
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
inputs = t.nbytes + w.nbytes + a.nbytes
import gc
gc.collect()
with open("/proc/self/clear_refs", "w") as f:  # Linux: reset the peak (VmHWM) to the current RSS
    f.write("5")
before = status("VmRSS:")
t0 = time.perf_counter()
res = estimate_offline(t, w, a, config=StreamConfig(aiding="gravity"))
sec = time.perf_counter() - t0
peak = status("VmHWM:")
out = res.index.nbytes + res.q.nbytes + res.variance.nbytes + res.action.nbytes
print(json.dumps({"samples": n, "peak_rss_bytes": peak, "rss_before_bytes": before,
                  "rss_before_includes": "the Python process and the input arrays",
                  "input_bytes": inputs, "output_bytes": out, "seconds": sec,
                  "working_bytes": peak - before - out}))
"""


def measure(seconds: int) -> dict:
    n = int(seconds * RATE_HZ)
    r = subprocess.run([sys.executable, "-c", _CHILD, str(n), str(RATE_HZ)], capture_output=True,
                       text=True, check=True)
    return json.loads(r.stdout.strip().splitlines()[-1])


def _cli(*args, env=None) -> tuple[str, int]:
    """Run ``gyro-attitude ARGS`` in a fresh process: (its stdout, its peak RSS in bytes).
    The child is reaped with ``os.wait4`` (its own rusage, not all children's maximum);
    its output goes through files, so no pipe can fill while it runs."""
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
        p = subprocess.Popen([sys.executable, "-m", "gyro_attitude.cli", *args], env=env,
                             stdout=out, stderr=err, text=True)
        _, status, usage = os.wait4(p.pid, 0)
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
                    stdout, peak = _cli("replay", str(rec), "--out", str(Path(d) / "out.mcap"),
                                        "--estimator", est, "--json", "--no-progress",
                                        "--force", env=env)
                    s = json.loads(stdout)
                    rows.append({"kind": "replay", "code": code, "estimator": est,
                                 "length": label, "messages": s["messages"],
                                 "truth_matched": s["truth_matched"], "peak_rss_bytes": peak,
                                 "wall_seconds": s["wall_seconds"],
                                 "input_file_bytes": rec.stat().st_size})
                    print(f"replay {code:7s} {est:8s} {label:8s} {s['messages']:11d} msgs  "
                          f"peak RSS {peak * 1e-6:7.0f} MB  {s['wall_seconds']:7.1f} s",
                          flush=True)
            rec.unlink()
    for code in envs:
        for est in ESTIMATORS:
            mine = [r for r in rows if r["estimator"] == est and r["code"] == code]
            if len(mine) >= 2:
                a, b = mine[0], mine[-1]
                slope = (b["peak_rss_bytes"] - a["peak_rss_bytes"]) / (
                    b["messages"] - a["messages"])
                rows.append({"kind": "replay slope", "code": code, "estimator": est,
                             "between": [a["length"], b["length"]],
                             "bytes_per_message": slope})
                print(f"replay {code:7s} {est:8s} {slope:.0f} B/msg between {a['length']} "
                      f"and {b['length']}")
    return rows


def run(quick: bool = False, out_dir=None) -> list[dict]:
    rows = []
    sizes = {"10 min": 600} if quick else SIZES_S
    print(f"{'length':8s} {'samples':>11s} {'peak RSS MB':>12s} {'input MB':>9s} {'output MB':>10s}"
          f" {'working MB':>11s} {'B/sample':>9s} {'M samples/s':>12s}")
    for label, sec in sizes.items():
        m = measure(sec)
        m["length"] = label
        m["working_bytes_per_sample"] = m["working_bytes"] / m["samples"]
        mb = 1e-6
        print(f"{label:8s} {m['samples']:11d} {m['peak_rss_bytes'] * mb:12.0f} "
              f"{m['input_bytes'] * mb:9.0f} {m['output_bytes'] * mb:10.0f} "
              f"{m['working_bytes'] * mb:11.0f} {m['working_bytes_per_sample']:9.1f} "
              f"{m['samples'] / m['seconds'] * 1e-6:12.2f}")
        rows.append(m)
    if len(rows) >= 2:
        # the working memory per sample of the longest run, extrapolated to 24 h
        per = rows[-1]
        n24 = 24 * 3600 * RATE_HZ
        need = (per["input_bytes"] + per["output_bytes"] + max(per["working_bytes"], 0)) \
            / per["samples"] * n24
        print(f"24 h at {RATE_HZ} Hz ({n24} samples): about {need * 1e-9:.1f} GB "
              "(input + output + working memory per sample of the 6 h run)")
        rows.append({"length": "24 h (extrapolated)", "samples": n24, "needed_bytes": need})
    rows.extend(replay_rows({"10 min": 600} if quick else SIZES_S))
    return rows
