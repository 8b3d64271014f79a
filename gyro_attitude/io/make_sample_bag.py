"""Regenerate the sample recording ``bags/coning_200hz.mcap`` deterministically.

``python -m gyro_attitude.io.make_sample_bag [OUT.mcap] [--seconds 20] [--rate-hz 200]``

20 s of the shipped ``coning`` scene (closed-form truth) sampled at 200 Hz:
``/imu/data_raw`` (sensor_msgs/Imu, frame ``imu_link``) and ``/truth/attitude``
(geometry_msgs/QuaternionStamped, frame ``enu``), merged by log time into zstd-compressed
chunks.  The same
scene, rate, duration and seed give byte-identical files.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

from gyro_attitude.core.scene import SceneSimulator
from gyro_attitude.io.cdr_arrays import (
    IMU_TYPE,
    QUATERNION_STAMPED_TYPE,
    imu_batch,
    quaternion_stamped_batch,
)
from gyro_attitude.io.mcap_writer import DEFAULT_COMPRESSION, Rosbag2McapWriter
from gyro_attitude.io.safe_output import SafeOutput, check_output_path
from gyro_attitude.io.scene_file import load_scene

SAMPLE_NAME = "coning_200hz.mcap"
START_TIME_NS = 1_000_000_000


def default_output() -> Path:
    return Path(__file__).resolve().parents[2] / "bags" / SAMPLE_NAME


def make_sample_bag(out, *, scene: str = "coning", seconds: float = 20.0,
                    rate_hz: float = 200.0, seed: int | None = None,
                    compression: str = DEFAULT_COMPRESSION) -> dict:
    """Simulate ``scene`` and record it; returns {topic: message count}."""
    if not seconds > 0 or not rate_hz > 0:
        raise ValueError(f"seconds and rate_hz must be positive, got {seconds}, {rate_hz}")
    # stamps from 1 s: a zero header stamp means "unset" in ROS, and the attitude-stream
    # policy (node and replay alike) skips it
    spec = dataclasses.replace(load_scene(scene), start_time_ns=START_TIME_NS)
    sim = SceneSimulator(spec, rate_hz=rate_hz, seed=seed)
    n = int(round(seconds * rate_hz))
    block = sim.next_block(n)
    out = Path(out)
    check_output_path(out, force=True)
    with SafeOutput(out, force=True) as tmp, \
            Rosbag2McapWriter(tmp, compression=compression) as w:
        w.add_topic("imu/data_raw", IMU_TYPE)
        w.add_topic("truth/attitude", QUATERNION_STAMPED_TYPE)
        w.write_batches([
            imu_batch("imu/data_raw", block.t_ns, block.omega_ib_b, block.specific_force_b,
                      frame_id="imu_link"),
            quaternion_stamped_batch("truth/attitude", block.t_ns, block.truth_q_nb,
                                     frame_id="enu"),
        ])
        return w.topic_counts()


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("out", nargs="?", default=str(default_output()))
    p.add_argument("--scene", default="coning")
    p.add_argument("--seconds", type=float, default=20.0)
    p.add_argument("--rate-hz", type=float, default=200.0)
    args = p.parse_args(argv)
    counts = make_sample_bag(args.out, scene=args.scene, seconds=args.seconds,
                             rate_hz=args.rate_hz)
    size = Path(args.out).stat().st_size
    print(f"wrote {args.out} ({size} bytes): {counts}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
