"""Benchmark of offline ``simulate`` (part of suite ``scenes``): samples/s per scene, with peers.

For each shipped scene and an ideal gyro at rest: samples per second of
:func:`gyro_attitude.offline.simulate.simulate` writing only ``imu/data_raw`` and writing
every topic (``truth/attitude`` and ``truth/odom`` too), next to two peers measured in the
same run on the same sizes: the scene simulator alone (``SceneSimulator.next_block`` in the
same blocks) and the MCAP writer alone (zstd, the same number of samples: Imu only, and all
four topics merged by ``write_batches`` as simulate writes them). Target: >= 1 M samples/s
for the ideal gyro at rest (Imu only).
"""

from __future__ import annotations

import pathlib
import tempfile

import numpy as np

from gyro_attitude.benchmarks import best_seconds
from gyro_attitude.core.scene import SceneSimulator, SceneSpec
from gyro_attitude.core.sim_topics import (
    IMU_TOPIC,
    JOINT_TOPIC,
    ODOM_TOPIC,
    TOPICS,
    TRUTH_TOPIC,
)
from gyro_attitude.core.trajectory import TrajectoryMotion
from gyro_attitude.io.cdr_arrays import (
    imu_batch,
    joint_state_batch,
    odometry_batch,
    quaternion_stamped_batch,
)
from gyro_attitude.io.mcap_writer import DEFAULT_COMPRESSION, Rosbag2McapWriter
from gyro_attitude.io.scene_file import list_scenes, load_scene
from gyro_attitude.offline.simulate import BLOCK_SAMPLES, simulate

IDEAL_AT_REST = {"description": "ideal gyro at rest", "seed": 0,
                 "earth": {"latitude_deg": 45.0}, "motion": {"type": "stationary"}}
TARGET_SAMPLES_PER_S = 1.0e6


def _best(fn, repeats: int) -> float:
    return best_seconds(fn, repeats)


def _measure(spec: SceneSpec, rate: float, n: int, tmp: pathlib.Path, repeats: int) -> dict:
    out = tmp / "bench.mcap"
    dur = n / rate

    def sim_only():
        sim = SceneSimulator(spec, rate)
        for lo in range(0, n, BLOCK_SAMPLES):
            sim.next_block(min(BLOCK_SAMPLES, n - lo))

    t = np.arange(n, dtype=np.int64) * int(1e9 / rate)
    w = np.random.default_rng(0).normal(size=(n, 3))

    def writer_only():
        with Rosbag2McapWriter(out, compression=DEFAULT_COMPRESSION) as wr:
            wr.add_topic("imu/data_raw", "sensor_msgs/msg/Imu")
            for lo in range(0, n, BLOCK_SAMPLES):
                hi = min(n, lo + BLOCK_SAMPLES)
                wr.write_imu_array("imu/data_raw", t[lo:hi], w[lo:hi])

    joints = spec.free_gyro_params is not None or spec.instrument is not None

    def writer_all_topics():
        with Rosbag2McapWriter(out, compression=DEFAULT_COMPRESSION) as wr:
            for topic, type_name in TOPICS.items():
                if topic != JOINT_TOPIC or joints:
                    wr.add_topic(topic, type_name)
            for lo in range(0, n, BLOCK_SAMPLES):
                hi = min(n, lo + BLOCK_SAMPLES)
                tb, wb = t[lo:hi], w[lo:hi]
                q = np.broadcast_to([0.0, 0.0, 0.0, 1.0], (hi - lo, 4))
                batches = [imu_batch(IMU_TOPIC, tb, wb, wb)]
                if joints:
                    batches.append(joint_state_batch(JOINT_TOPIC, tb, ["a", "b"], wb[:, :2],
                                                     wb[:, 1:], frame_id="imu_link"))
                batches += [quaternion_stamped_batch(TRUTH_TOPIC, tb, q),
                            odometry_batch(ODOM_TOPIC, tb, wb, q, wb, wb)]
                wr.write_batches(batches)

    row = {"n": n, "rate_hz": rate}
    row["imu_only"] = n / _best(lambda: simulate(spec, dur, out, rate_hz=rate, force=True,
                                                 publish_truth=False), repeats)
    row["all_topics"] = n / _best(lambda: simulate(spec, dur, out, rate_hz=rate, force=True),
                                  repeats)
    row["peer_simulator"] = n / _best(sim_only, repeats)
    row["peer_writer"] = n / _best(writer_only, repeats)
    row["peer_writer_all_topics"] = n / _best(writer_all_topics, repeats)
    return row


def run(quick: bool, out_dir: pathlib.Path) -> list[dict]:
    """Print the table and return JSON rows (kind ``simulate``)."""
    repeats = 2 if quick else 3
    rows = []
    print("\nsimulate: offline scene -> MCAP, samples/s (best of "
          f"{repeats}); peers in the same run")
    print(f"{'scene':<26}{'samples':>10}{'Imu only':>12}{'all topics':>12}"
          f"{'sim alone':>12}{'writer Imu':>12}{'writer all':>12}{'Imu/writer':>12}"
          f"{'all/writer':>12}")
    cases = [("ideal_at_rest", SceneSpec.from_dict(IDEAL_AT_REST, "ideal_at_rest"), 1000.0,
              400_000 if quick else 2_000_000)]
    for name, _ in list_scenes():
        spec = load_scene(name)
        if isinstance(spec.motion, TrajectoryMotion):
            continue  # a pose file of fixed span: measured by suite "trajectory"
        heavy = spec.free_gyro_params is not None or spec.instrument is not None
        n = (2_000 if heavy else 40_000) if quick else (10_000 if heavy else 200_000)
        cases.append((name, spec, spec.rate_hz, n))
    with tempfile.TemporaryDirectory() as tmp:
        for name, spec, rate, n in cases:
            r = _measure(spec, rate, n, pathlib.Path(tmp), repeats)
            r.update(suite="scenes", kind="simulate", scene=name)
            if name == "ideal_at_rest":
                r["target_samples_per_s"] = TARGET_SAMPLES_PER_S
                r["meets_target"] = r["imu_only"] >= TARGET_SAMPLES_PER_S
            rows.append(r)
            print(f"{name:<26}{n:>10,}{r['imu_only']:>12,.0f}{r['all_topics']:>12,.0f}"
                  f"{r['peer_simulator']:>12,.0f}{r['peer_writer']:>12,.0f}"
                  f"{r['peer_writer_all_topics']:>12,.0f}"
                  f"{r['imu_only'] / r['peer_writer']:>11.2f}x"
                  f"{r['all_topics'] / r['peer_writer_all_topics']:>11.2f}x")
    ideal = rows[0]
    print(f"ideal gyro at rest, Imu only: {ideal['imu_only']:,.0f} samples/s "
          f"(target {TARGET_SAMPLES_PER_S:,.0f}: {'met' if ideal['meets_target'] else 'NOT met'}"
          f"; the writer alone does {ideal['peer_writer']:,.0f})")
    return rows


if __name__ == "__main__":  # pragma: no cover
    import json
    import sys

    out = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else "bench_out")
    result = run(quick="--quick" in sys.argv, out_dir=out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "simulate.json").write_text(json.dumps(result, indent=1))
