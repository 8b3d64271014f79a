"""Offline scene simulation to MCAP: the topics gyro_sim publishes, no ROS graph, as fast as it goes."""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from gyro_attitude.core.scene import SceneSimulator, SceneSpec
from gyro_attitude.core.sim_topics import (
    DEFAULT_FRAME_ID,
    DEFAULT_WORLD_FRAME_ID,
    IMU_TOPIC,
    JOINT_TOPIC,
    ODOM_TOPIC,
    TOPICS,
    TRUTH_TOPIC,
    SimTopics,
)
from gyro_attitude.io.cdr_encode import encode_joint_state, encode_odometry
from gyro_attitude.io.mcap_writer import Rosbag2McapWriter, normalize_topic
from gyro_attitude.io.scene_file import load_scene

__all__ = ["SimulateResult", "simulate", "BLOCK_SAMPLES", "MAX_SAMPLES"]

# Samples simulated and written per block: large enough that per-block costs vanish, small
# enough to stay a few tens of MB.
BLOCK_SAMPLES = 1 << 15
MAX_SAMPLES = 10**9


@dataclass
class SimulateResult:
    """What :func:`simulate` wrote: ``samples`` per topic (``messages``), wall time."""

    path: Path
    scene: str
    rate_hz: float
    seed: int
    samples: int
    messages: dict[str, int] = field(default_factory=dict)
    wall_s: float = 0.0

    @property
    def samples_per_s(self) -> float:
        return self.samples / self.wall_s if self.wall_s > 0 else math.inf


def _diag9(var) -> np.ndarray:
    """Row-major 3x3 covariance with per-axis variances on the diagonal (as gyro_sim)."""
    return np.diag(np.asarray(var, dtype=np.float64)).reshape(9)


def _check_output(out: Path, force: bool) -> None:
    if out.exists() and out.is_dir():
        raise ValueError(f"output {out} is a directory")
    if out.exists() and not force:
        raise ValueError(f"output {out} exists (use --force to overwrite)")


def simulate(scene: str | SceneSpec, duration_s: float, out, *, rate_hz: float | None = None,
             seed: int | None = None, force: bool = False, publish_truth: bool = True,
             frame_id: str = DEFAULT_FRAME_ID, world_frame_id: str = DEFAULT_WORLD_FRAME_ID,
             progress: bool = False) -> SimulateResult:
    """Simulate ``scene`` (name, path or :class:`SceneSpec`) for ``duration_s`` and write the
    topics gyro_sim publishes to ``out`` (rosbag2 MCAP, zstd chunks), stamped with the
    scene's own sample times (``start_time_ns`` + k/rate), log time = stamp.

    Same messages as gyro_sim with the same scene, rate, seed and frames (its stamps are
    shifted by its wall-clock start). Written to a temporary file in the same directory and
    renamed at the end, so ``out`` is never half-written. ``ValueError`` (one line) on a bad
    scene, duration, rate or seed, or an existing ``out`` without ``force``.
    """
    spec = load_scene(scene) if isinstance(scene, str) else scene
    if not isinstance(spec, SceneSpec):
        raise ValueError(f"scene must be a name, a path or a SceneSpec, got {type(scene).__name__}")
    rate = float(spec.rate_hz if rate_hz is None else rate_hz)
    if isinstance(rate_hz, bool) or not (math.isfinite(rate) and rate > 0):
        raise ValueError(f"rate must be a finite number of Hz > 0, got {rate_hz!r}")
    if isinstance(duration_s, bool) or not isinstance(duration_s, int | float) \
            or not (math.isfinite(duration_s) and duration_s > 0):
        raise ValueError(f"duration must be a finite number of seconds > 0, got {duration_s!r}")
    n_total = int(round(duration_s * rate))
    if n_total < 1:
        raise ValueError(f"duration {duration_s} s at {rate:g} Hz gives no sample")
    if n_total > MAX_SAMPLES:
        raise ValueError(f"duration {duration_s} s at {rate:g} Hz is {n_total} samples; "
                         f"the limit is {MAX_SAMPLES}")
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int) or seed < 0):
        raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
    out = Path(out)
    _check_output(out, force)

    sim = SceneSimulator(spec, rate, seed=seed)
    gyro_var, accel_var = sim.imu_variances()
    gyro_cov = _diag9(gyro_var)
    accel_cov = None if accel_var is None else _diag9(accel_var)
    topics = SimTopics()
    names = {t: normalize_topic(t) for t in TOPICS}
    counts = dict.fromkeys(names.values(), 0)
    tmp = out.with_name(f".{out.name}.{os.getpid()}.tmp")
    t0 = time.perf_counter()
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=n_total, unit="sample", unit_scale=True, desc=f"simulate {spec.name}")
    writer = Rosbag2McapWriter(tmp, compression="zstd")
    try:
        writer.add_topic(names[IMU_TOPIC], TOPICS[IMU_TOPIC])
        if spec.free_gyro_params is not None:
            writer.add_topic(names[JOINT_TOPIC], TOPICS[JOINT_TOPIC])
        if publish_truth:
            writer.add_topic(names[TRUTH_TOPIC], TOPICS[TRUTH_TOPIC])
            writer.add_topic(names[ODOM_TOPIC], TOPICS[ODOM_TOPIC])
        done = 0
        while done < n_total:
            n = min(BLOCK_SAMPLES, n_total - done)
            f = topics.fields(sim.next_block(n), truth=publish_truth)
            stamps = f.t_rel_ns + topics.t0_ns
            writer.write_imu_array(
                names[IMU_TOPIC], stamps, f.angular_velocity, f.specific_force,
                frame_id=frame_id, angular_velocity_covariance=gyro_cov,
                linear_acceleration_covariance=accel_cov,
            )
            counts[names[IMU_TOPIC]] += n
            if f.gimbal_angles is not None:
                rows = encode_joint_state(stamps, frame_id, f.gimbal_names, f.gimbal_angles,
                                          f.gimbal_rates)
                _write_rows(writer, names[JOINT_TOPIC], rows, stamps)
                counts[names[JOINT_TOPIC]] += n
            if publish_truth:
                writer.write_quaternion_stamped_array(names[TRUTH_TOPIC], stamps, f.q_nb,
                                                      frame_id=world_frame_id)
                rows = encode_odometry(stamps, world_frame_id, frame_id, f.position_enu,
                                       f.q_nb, f.velocity_body, f.omega_nb_b)
                _write_rows(writer, names[ODOM_TOPIC], rows, stamps)
                counts[names[TRUTH_TOPIC]] += n
                counts[names[ODOM_TOPIC]] += n
            done += n
            if bar is not None:
                bar.update(n)
        writer.finish()
        _check_output(out, force)  # it may have appeared meanwhile
        os.replace(tmp, out)
    except BaseException:
        writer.abandon()
        tmp.unlink(missing_ok=True)
        raise
    finally:
        if bar is not None:
            bar.close()
    return SimulateResult(out, spec.name, rate, sim.seed, n_total,
                          {k: v for k, v in counts.items() if v},
                          time.perf_counter() - t0)


def _write_rows(writer: Rosbag2McapWriter, topic: str, rows: np.ndarray, stamps) -> None:
    """Per-message writes of fixed-size serialized rows (the writer has no array path for
    these types)."""
    data = memoryview(rows.tobytes())
    size = rows.shape[1]
    write = writer.write
    for k, t in enumerate(stamps.tolist()):
        write(topic, data[k * size:(k + 1) * size], t, t)
