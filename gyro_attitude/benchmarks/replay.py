"""Replay throughput: ``gyro-attitude bench --suite replay``.

Input: a 1 kHz, 10-minute recording (600 k ``sensor_msgs/Imu`` on ``/imu/data_raw`` plus
``/truth/attitude`` at 10 Hz), closed-form classical coning from docs/equations.md (half-angle 1°,
1 Hz), written by the array writer (zstd chunks, topics merged by log time) into a
temporary directory (deleted afterwards).  ``--quick`` uses 60 s (60 k messages).

Figures (one JSON row each):
* ``write_input``: array writer, messages per second;
* ``replay/<algorithm>/cold``: end-to-end ``gyro-attitude replay --aiding none --json`` in a fresh
  process (read + integrate + write ``attitude`` and ``imu/data``; the wall time is
  measured inside the command, so interpreter start-up and imports are excluded -- they are
  in ``process_wall_seconds``, the whole process timed from here), with the read /
  integrate / write split and the final and max error against the truth;
* ``replay/<algorithm>/warm``: the same, called twice in this process, the second kept;
* ``peer/mcap_read``: the ``mcap`` package's plain read loop over the whole file
  (``NonSeekingReader.iter_messages``: records only, no CDR decoding, no integration, no
  writing), touching every Imu payload's length like a consumer would;
* ``peer/mcap_ros2_decode``: ``mcap`` + ``mcap-ros2-support`` decoding the Imu topic,
  measured on the first ``PEER_SUBSET`` messages and extrapolated per message.
The replay rows carry ``ratio_vs_mcap_read`` = peer seconds / replay seconds (> 1: the
replay, with integration and writing, is faster than mcap's bare read loop) and
``speedup_vs_decode`` against the decoding peer.

The machine is shared: figures are noisy, the ratio measured in the same run is the
robust number.  The file is in the page cache when read (it was just written).
"""

from __future__ import annotations

import json
import os
import pathlib
import platform
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np
from mcap.reader import NonSeekingReader

import gyro_attitude
from gyro_attitude.core.attitude.settings import StreamConfig
from gyro_attitude.core.earth import STANDARD_GRAVITY
from gyro_attitude.io.cdr_arrays import imu_batch, quaternion_stamped_batch
from gyro_attitude.io.mcap_writer import Rosbag2McapWriter
from gyro_attitude.offline.replay import replay_file

RATE_HZ = 1000
#: the gyro integrated alone (the closed-form coning's specific force is a placeholder)
GYRO_ONLY = StreamConfig(aiding="none")
FULL_SECONDS = 600
QUICK_SECONDS = 60
TRUTH_EVERY = 100  # truth at 10 Hz
PEER_SUBSET = 20_000
ALGORITHMS = ("rotvec_cubic", "magnus6_quintic")  # the node's default and replay's default
HALF_ANGLE = np.radians(1.0)
CONE_HZ = 1.0


def coning_closed_form(t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Classical coning (docs/equations.md): (ω_b (N,3), q (N,4) x, y, z, w)."""
    a, om = HALF_ANGLE, 2 * np.pi * CONE_HZ
    s, c = np.sin(om * t_s), np.cos(om * t_s)
    w = np.stack([np.full_like(t_s, -2 * om * np.sin(a / 2) ** 2), -om * np.sin(a) * s,
                  om * np.sin(a) * c], axis=1)
    q = np.stack([np.zeros_like(t_s), np.sin(a / 2) * c, np.sin(a / 2) * s,
                  np.full_like(t_s, np.cos(a / 2))], axis=1)
    return w, q


def write_input(path: pathlib.Path, seconds: int) -> dict:
    n = seconds * RATE_HZ
    t_ns = 1_700_000_000_000_000_000 + (np.arange(n, dtype=np.int64) * 10**9) // RATE_HZ
    start = time.perf_counter()
    with Rosbag2McapWriter(path, chunk_size=4 * 1024 * 1024) as w:
        w.add_topic("imu/data_raw", "sensor_msgs/msg/Imu")
        w.add_topic("truth/attitude", "geometry_msgs/msg/QuaternionStamped")
        block = 600_000  # generate in blocks: bounded memory for the closed form
        for lo in range(0, n, block):
            hi = min(n, lo + block)
            ts = (t_ns[lo:hi] - t_ns[0]) * 1e-9
            omega, q = coning_closed_form(ts)
            accel = np.broadcast_to([0.0, 0.0, STANDARD_GRAVITY], (hi - lo, 3))
            k = np.arange(lo, hi)
            sel = k % TRUTH_EVERY == 0
            w.write_batches([
                imu_batch("imu/data_raw", t_ns[lo:hi], omega, accel, frame_id="imu_link"),
                quaternion_stamped_batch("truth/attitude", t_ns[lo:hi][sel], q[sel],
                                         frame_id="inertial"),
            ])
    wall = time.perf_counter() - start
    return {"name": "write_input", "messages": n, "wall_seconds": wall,
            "messages_per_second": n / wall, "bytes": path.stat().st_size}


def peer_read(path: pathlib.Path, n_imu: int) -> dict:
    """The ``mcap`` package's plain read loop over every record of the file."""
    k = 0
    nbytes = 0
    start = time.perf_counter()
    with open(path, "rb") as f:
        for _, channel, message in NonSeekingReader(f).iter_messages(log_time_order=False):
            if channel.topic == "/imu/data_raw":
                nbytes += len(message.data)
                k += 1
    wall = time.perf_counter() - start
    if k != n_imu:
        raise RuntimeError(f"mcap read {k} Imu messages, expected {n_imu}")
    return {"name": "peer/mcap_read", "messages": k, "wall_seconds": wall,
            "seconds_per_message": wall / k, "messages_per_second": k / wall}


def peer_decode(path: pathlib.Path, subset: int) -> dict:
    # mcap-ros2-support is a test/benchmark requirement (requirements-test.txt), not a
    # runtime one: imported only when this peer runs.
    from mcap_ros2.decoder import DecoderFactory

    k = 0
    acc = 0.0
    start = time.perf_counter()
    with open(path, "rb") as f:
        # The streaming reader: on this 1.3 GB file mcap's seeking reader (make_reader)
        # was ~7x slower to deliver the first messages, which would flatter our ratio.
        reader = NonSeekingReader(f, decoder_factories=[DecoderFactory()])
        for _, _, _, msg in reader.iter_decoded_messages(topics=["/imu/data_raw"],
                                                         log_time_order=False):
            acc += msg.angular_velocity.x  # touch the data like a consumer would
            k += 1
            if k >= subset:
                break
    wall = time.perf_counter() - start
    return {"name": "peer/mcap_ros2_decode", "messages": k, "wall_seconds": wall,
            "seconds_per_message": wall / k, "messages_per_second": k / wall,
            "note": f"measured on the first {k} messages, extrapolated per message"}


def replay_cli(src: pathlib.Path, out: pathlib.Path, algorithm: str) -> dict:
    """``gyro-attitude replay ... --json`` in a fresh interpreter; its JSON summary."""
    env = dict(os.environ)
    root = str(pathlib.Path(gyro_attitude.__file__).resolve().parents[1])
    env["PYTHONPATH"] = root + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    start = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, "-m", "gyro_attitude.cli", "replay", str(src), "--out", str(out),
         "--algorithm", algorithm, "--initial-attitude", "truth", "--aiding", "none", "--json",
         "--no-progress"],
        env=env, capture_output=True, text=True, timeout=600, check=False)
    process_wall = time.perf_counter() - start
    if proc.returncode != 0:
        raise RuntimeError(f"replay CLI failed ({proc.returncode}): {proc.stderr[-2000:]}")
    return {**json.loads(proc.stdout), "process_wall_seconds": process_wall}


def _warm(src: pathlib.Path, out: pathlib.Path, algorithm: str) -> dict:
    best = None
    for _ in range(2):  # the first call warms up; keep the second
        s = replay_file(src, out, algorithm=algorithm, initial_attitude="truth",
                        config=GYRO_ONLY).summary()
        out.unlink()
        best = s
    return best


def run(quick: bool, out_dir: pathlib.Path) -> list[dict]:

    seconds = QUICK_SECONDS if quick else FULL_SECONDS
    n = seconds * RATE_HZ
    out_dir = pathlib.Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    # GYRO_BENCH_TMPDIR chooses where the ~3 GB of temporary files go (default: the
    # system temp dir); it is reported in every row.
    tmp = pathlib.Path(tempfile.mkdtemp(prefix="gyro_replay_bench_",
                                        dir=os.environ.get("GYRO_BENCH_TMPDIR") or None))
    machine = {"cpus": os.cpu_count(), "python": platform.python_version(),
               "machine": platform.machine(), "tmp_dir": str(tmp.parent)}
    rows: list[dict] = []
    try:
        src = tmp / "input.mcap"
        rows.append(write_input(src, seconds))
        reader_peer = peer_read(src, n)
        rows.append(reader_peer)
        peer = peer_decode(src, min(PEER_SUBSET, n))
        peer["extrapolated_seconds_full_file"] = peer["seconds_per_message"] * n
        rows.append(peer)
        for algorithm in ALGORITHMS:
            out = tmp / f"out_{algorithm}.mcap"
            # cold: the CLI in a fresh process, as a user runs it (its first touch of every
            # big array and of the new output file's pages is part of the cost);
            # warm: the same call repeated in this process (allocator and page cache warm).
            cold = replay_cli(src, out, algorithm)
            out_bytes = out.stat().st_size
            out.unlink()
            for label, s in (("cold", cold), ("warm", _warm(src, out, algorithm))):
                row = {"name": f"replay/{algorithm}/{label}", **{k: s[k] for k in (
                    "messages", "wall_seconds", "messages_per_second", "read_seconds",
                    "integrate_seconds", "write_seconds", "fast_path_messages",
                    "fallback_messages", "final_error_rad", "max_error_rad",
                    "truth_matched")}}
                if "process_wall_seconds" in s:
                    row["process_wall_seconds"] = s["process_wall_seconds"]
                    row["process_messages_per_second"] = n / s["process_wall_seconds"]
                row["ratio_vs_mcap_read"] = reader_peer["wall_seconds"] / s["wall_seconds"]
                row["speedup_vs_decode"] = peer["seconds_per_message"] / (s["wall_seconds"] / n)
                row["output_bytes"] = out_bytes
                rows.append(row)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    for r in rows:
        r.update({"suite": "replay", "recording_seconds": seconds, "rate_hz": RATE_HZ,
                  "quick": quick, **machine})
    print(f"\nreplay benchmark: {n} Imu messages ({seconds} s at {RATE_HZ} Hz, closed-form "
          f"coning), {machine['cpus']} CPUs (shared), files in {machine['tmp_dir']}")
    print(f"{'figure':<30}{'messages':>10}{'wall s':>9}{'msg/s':>12}{'/mcap rd':>9}"
          f"{'read/int/write s':>20}{'max err deg':>13}")
    for r in rows:
        split = (f"{r['read_seconds']:.2f}/{r['integrate_seconds']:.2f}/{r['write_seconds']:.2f}"
                 if "read_seconds" in r else "")
        err = f"{np.degrees(r['max_error_rad']):.2e}" if r.get("max_error_rad") is not None \
            else ""
        vs = f"{r['ratio_vs_mcap_read']:.1f}x" if "ratio_vs_mcap_read" in r else ""
        print(f"{r['name']:<30}{r['messages']:>10}{r['wall_seconds']:>9.2f}"
              f"{r['messages_per_second']:>12.0f}{vs:>9}{split:>20}{err:>13}")
    for r in rows:
        if "process_wall_seconds" in r:
            print(f"{r['name']}: whole process (interpreter start-up and imports included) "
                  f"{r['process_wall_seconds']:.2f} s, "
                  f"{r['process_messages_per_second']:.0f} msg/s")
    print(f"decode peer measured on {rows[2]['messages']} messages and extrapolated per "
          f"message ({rows[2]['extrapolated_seconds_full_file']:.0f} s for the full file)")
    (out_dir / "replay.json").write_text(json.dumps(rows, indent=2))
    return rows


if __name__ == "__main__":
    run("--quick" in sys.argv, pathlib.Path("bench_out"))
