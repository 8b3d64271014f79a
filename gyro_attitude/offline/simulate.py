"""Offline scene simulation to MCAP: the topics gyro_sim publishes, no ROS graph, as fast as it goes."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from gyro_attitude.core.scene import MAX_RATE_HZ, SceneSimulator, SceneSpec
from gyro_attitude.core.scene.magnetometer import magnetometer_covariance
from gyro_attitude.core.sim_topics import (
    DEFAULT_FRAME_ID,
    DEFAULT_WORLD_FRAME_ID,
    IMU_TOPIC,
    JOINT_TOPIC,
    MAG_TOPIC,
    ODOM_TOPIC,
    TOPICS,
    TRUTH_TOPIC,
    SimTopics,
)
from gyro_attitude.core.trajectory import TrajectoryMotion
from gyro_attitude.io.cdr_arrays import (
    MessageBatch,
    imu_batch,
    joint_state_batch,
    magnetic_field_batch,
    odometry_batch,
    quaternion_stamped_batch,
)
from gyro_attitude.io.mcap_writer import DEFAULT_COMPRESSION, Rosbag2McapWriter, normalize_topic
from gyro_attitude.io.safe_output import SafeOutput, check_output_path, raise_if_stop_requested
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
    saturated: dict[str, int] = field(default_factory=dict)

    @property
    def samples_per_s(self) -> float:
        return self.samples / self.wall_s if self.wall_s > 0 else math.inf


def _diag9(var) -> np.ndarray:
    """Row-major 3x3 covariance with per-axis variances on the diagonal (as gyro_sim)."""
    return np.diag(np.asarray(var, dtype=np.float64)).reshape(9)


def simulate(scene: str | SceneSpec, duration_s: float | None, out, *,
             rate_hz: float | None = None, seed: int | None = None, force: bool = False,
             publish_truth: bool = True, frame_id: str = DEFAULT_FRAME_ID,
             world_frame_id: str = DEFAULT_WORLD_FRAME_ID, progress: bool = False,
             trajectory=None, trajectory_options: dict | None = None) -> SimulateResult:
    """Simulate ``scene`` (name, path or :class:`SceneSpec`) for ``duration_s`` and write the
    topics gyro_sim publishes to ``out`` (rosbag2 MCAP, zstd chunks), stamped with the
    scene's own sample times (``start_time_ns`` + k/rate), log time = stamp.

    Same messages as gyro_sim with the same scene, rate, seed and frames (its stamps are
    shifted by its wall-clock start). Every block's messages of all topics go through one
    :meth:`~.Rosbag2McapWriter.write_batches` call, so the file is in log-time order across
    channels. Checked by :func:`~.safe_output.check_output_path` (never the scene file,
    never an existing file without ``force``) and written through :class:`~.SafeOutput`
    (temporary name, renamed when complete), so ``out`` is never half-written.
    ``ValueError`` (one line) on a bad scene, duration, rate, seed or output.

    ``trajectory`` (a pose file) puts it under the scene's sensors and instruments
    (:func:`~gyro_attitude.io.scene_file.load_scene`); a trajectory is stamped in its own
    time base, and ``duration_s=None`` covers the whole span of its poses.
    """
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int | np.integer)
                             or seed < 0):
        raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
    opts = trajectory_options or {}
    if isinstance(scene, str):
        # a seed given here stands in for the file's (which may then be left out)
        spec = load_scene(scene, trajectory, seed=seed, **opts)
    else:
        from gyro_attitude.io.trajectory_file import resolve_trajectory

        spec = resolve_trajectory(scene, None, trajectory, **opts) if isinstance(
            scene, SceneSpec) else scene
    if not isinstance(spec, SceneSpec):
        raise ValueError(f"scene must be a name, a path or a SceneSpec, got {type(scene).__name__}")
    if rate_hz is not None and (isinstance(rate_hz, bool)
                                or not isinstance(rate_hz, int | float | np.number)):
        raise ValueError(f"rate must be a number of Hz, got {rate_hz!r}")
    rate = float(spec.rate_hz if rate_hz is None else rate_hz)
    if not (math.isfinite(rate) and 0 < rate <= MAX_RATE_HZ):
        raise ValueError(f"rate must be a finite number of Hz in (0, {MAX_RATE_HZ:g}], "
                         f"got {rate_hz!r}")
    span = spec.motion.span_s if isinstance(spec.motion, TrajectoryMotion) else None
    if duration_s is None and span is None:
        raise ValueError("--duration is required (the scene's motion is not a trajectory)")
    if duration_s is not None and (
            isinstance(duration_s, bool) or not isinstance(duration_s, int | float | np.number)
            or not (math.isfinite(duration_s) and duration_s > 0)):
        raise ValueError(f"duration must be a finite number of seconds > 0, got {duration_s!r}")
    if span is not None:
        # stamps k/rate from the first pose, up to the last one
        covered = int(math.floor(span * rate * (1 + 1e-12))) + 1
        if duration_s is not None and duration_s * rate > covered + 1e-9:
            raise ValueError(f"duration {duration_s:g} s is longer than the {span:.6g} s the "
                             f"trajectory covers ({spec.motion.source})")
        n_total = covered if duration_s is None else int(round(duration_s * rate))
    else:
        n_total = int(round(duration_s * rate))
    if n_total < 1:
        raise ValueError(f"duration {duration_s:g} s at {rate:g} Hz gives no sample")
    if n_total > MAX_SAMPLES:
        raise ValueError(f"duration {duration_s:g} s at {rate:g} Hz is {n_total:.3g} samples; "
                         f"the limit is {MAX_SAMPLES}")
    inputs = _scene_inputs(scene) + ([trajectory] if trajectory is not None else [])
    out = check_output_path(out, inputs=inputs, force=force)

    sim = SceneSimulator(spec, rate, seed=seed)
    gyro_var, accel_var = sim.imu_variances()
    gyro_cov = _diag9(gyro_var)
    accel_cov = None if accel_var is None else _diag9(accel_var)
    mag_cov = None if spec.magnetometer is None else magnetometer_covariance(spec.magnetometer)
    topics = SimTopics()
    names = {t: normalize_topic(t) for t in TOPICS}
    counts = dict.fromkeys(names.values(), 0)
    t0 = time.perf_counter()
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=n_total, unit="sample", unit_scale=True, desc=f"simulate {spec.name}")
    try:
        with SafeOutput(out, force=force) as tmp, \
                Rosbag2McapWriter(tmp, compression=DEFAULT_COMPRESSION) as writer:
            writer.add_topic(names[IMU_TOPIC], TOPICS[IMU_TOPIC])
            if spec.free_gyro_params is not None or spec.instrument is not None:
                writer.add_topic(names[JOINT_TOPIC], TOPICS[JOINT_TOPIC])
            if mag_cov is not None:
                writer.add_topic(names[MAG_TOPIC], TOPICS[MAG_TOPIC])
            if publish_truth:
                writer.add_topic(names[TRUTH_TOPIC], TOPICS[TRUTH_TOPIC])
                writer.add_topic(names[ODOM_TOPIC], TOPICS[ODOM_TOPIC])
            done = 0
            while done < n_total:
                raise_if_stop_requested()
                n = min(BLOCK_SAMPLES, n_total - done)
                f = topics.fields(sim.next_block(n), truth=publish_truth)
                stamps = f.t_rel_ns + topics.t0_ns
                batches = _block_batches(f, stamps, names, frame_id, world_frame_id, gyro_cov,
                                         accel_cov, publish_truth, mag_cov)
                # One call per block with every topic: the writer merges them by log time
                # (all share the stamps here, so message k of every topic sits together).
                writer.write_batches(batches)
                for b in batches:
                    counts[b.topic] += len(b)
                done += n
                if bar is not None:
                    bar.update(n)
    finally:
        if bar is not None:
            bar.close()
    return SimulateResult(out, spec.name, rate, sim.seed, n_total,
                          {k: v for k, v in counts.items() if v},
                          time.perf_counter() - t0, dict(sim.saturated))


def _scene_inputs(scene) -> list:
    """The scene file, when ``scene`` names one: an output must never overwrite it."""
    return [scene] if isinstance(scene, str) and Path(scene).exists() else []


def _block_batches(f, stamps: np.ndarray, names: dict, frame_id: str, world_frame_id: str,
                   gyro_cov: np.ndarray, accel_cov: np.ndarray | None,
                   publish_truth: bool, mag_cov: np.ndarray | None = None) -> list[MessageBatch]:
    """Every topic's messages of one block, in gyro_sim's publishing order per sample."""
    batches = [imu_batch(names[IMU_TOPIC], stamps, f.angular_velocity, f.specific_force,
                         frame_id=frame_id, angular_velocity_covariance=gyro_cov,
                         linear_acceleration_covariance=accel_cov)]
    if f.gimbal_angles is not None:
        batches.append(joint_state_batch(names[JOINT_TOPIC], stamps, f.gimbal_names,
                                         f.gimbal_angles, f.gimbal_rates, frame_id=frame_id))
    if f.magnetic_field is not None:
        batches.append(magnetic_field_batch(names[MAG_TOPIC], stamps, f.magnetic_field,
                                            frame_id=frame_id, magnetic_field_covariance=mag_cov))
    if publish_truth:
        batches.append(quaternion_stamped_batch(names[TRUTH_TOPIC], stamps, f.q_nb,
                                                frame_id=world_frame_id))
        batches.append(odometry_batch(names[ODOM_TOPIC], stamps, f.position_enu, f.q_nb,
                                      f.velocity_body, f.omega_nb_b, frame_id=world_frame_id,
                                      child_frame_id=frame_id))
    return batches
