"""Replay on jittered stamps: every shared BROAD recording, its Imu stamps moved by up to ±1/3
of the sample period (a real driver's timing), against the evenly stamped file, same run.

``gyro-attitude bench --suite jitter`` or ``run(quick, out_dir)``.  Per recording the jittered
copy is written to a temporary directory (the Imu and magnetometer stamps jittered alike, the
truth untouched: it runs on its own clock), then :func:`~gyro_attitude.offline.replay.replay_file`
runs on both files with replay's defaults (``default``) and with ``--initial-attitude truth``
(``truth``).  Row per recording and mode: the error angle at the last truth stamp and the RMS
error against the truth for the even and the jittered file, their ratios, and the rests found.
The defaults are replay's own (no setting pinned): ``aiding auto`` and the tilt from the first
accelerometer sample; the offline estimator integrates on the clock the stamps jitter about
(:mod:`gyro_attitude.core.attitude.sample_clock`).
Done when: every ratio of end errors within 1.2 (issue 38, item 1).
"""

from __future__ import annotations

import pathlib
import tempfile

import numpy as np

from gyro_attitude.benchmarks.real import real_dir

JITTER_FRACTION = 1.0 / 3.0  # of the median sample period, uniform in ±that
SEED = 38
MODES = {"default": {}, "truth": {"initial_attitude": "truth"}}


def jittered_copy(src: pathlib.Path, dst: pathlib.Path, fraction: float = JITTER_FRACTION,
                  seed: int = SEED) -> float:
    """Write ``dst``: ``src``'s Imu (``/imu/data_raw``) and magnetometer (``/imu/mag``, same
    rows) with their stamps moved by a uniform ±``fraction`` of the median period, the truth
    (``/truth/attitude``) as recorded.  Returns the largest shift (s)."""
    from gyro_attitude.io.cdr_arrays import (
        IMU_TYPE,
        MAGNETIC_FIELD_TYPE,
        QUATERNION_STAMPED_TYPE,
        imu_batch,
        magnetic_field_batch,
        quaternion_stamped_batch,
    )
    from gyro_attitude.io.imu_fast import read_topic_arrays
    from gyro_attitude.io.mcap_writer import Rosbag2McapWriter

    topics = {"/imu/data_raw": IMU_TYPE, "/imu/mag": MAGNETIC_FIELD_TYPE,
              "/truth/attitude": QUATERNION_STAMPED_TYPE}
    arrays = read_topic_arrays(src, topics, fields={"/imu/data_raw": (
        "angular_velocity", "linear_acceleration", "angular_velocity_covariance",
        "linear_acceleration_covariance")})
    imu, mag, truth = (arrays[k] for k in topics)
    t = imu.stamp_ns
    period = float(np.median(np.diff(t)))
    shift = np.round(np.random.default_rng(seed).uniform(-fraction, fraction, t.size)
                     * period).astype(np.int64)
    tj = t + shift
    mag_shift = shift[np.searchsorted(t, mag.stamp_ns).clip(0, t.size - 1)]
    with Rosbag2McapWriter(dst) as w:
        for topic, type_name in topics.items():
            w.add_topic(topic, type_name)
        w.write_batches([
            imu_batch("/imu/data_raw", tj, imu.angular_velocity, imu.linear_acceleration,
                      frame_id=imu.frame_id,
                      angular_velocity_covariance=imu.angular_velocity_covariance,
                      linear_acceleration_covariance=imu.linear_acceleration_covariance),
            magnetic_field_batch("/imu/mag", mag.stamp_ns + mag_shift, mag.magnetic_field,
                                 frame_id=mag.frame_id),
            quaternion_stamped_batch("/truth/attitude", truth.stamp_ns, truth.quaternion,
                                     frame_id=truth.frame_id),
        ])
    return float(np.abs(shift).max() * 1e-9)


def _replay(path, out, mode) -> dict:
    from gyro_attitude.offline.replay import replay_file

    r = replay_file(path, out, force=True, truth_topic="/truth/attitude",
                    imu_topic="/imu/data_raw", **MODES[mode])
    return {"end_deg": float(np.degrees(r.final_error_rad)),
            "rms_deg": float(np.degrees(r.rms_error_rad)), "gyro_bias": r.gyro_bias}


def run(quick: bool = False, out_dir=None) -> list[dict]:
    directory = real_dir()
    files = sorted(directory.glob("broad_*.mcap"))
    if not files:
        raise FileNotFoundError(f"no BROAD recordings in {directory} (GYRO_ATTITUDE_REAL_DIR)")
    if quick:
        files = files[:2]
    rows = []
    with tempfile.TemporaryDirectory(prefix="jitter_") as tmp:
        tmp = pathlib.Path(tmp)
        for src in files:
            jit = tmp / src.name
            max_shift = jittered_copy(src, jit)
            for mode in MODES:
                even = _replay(src, tmp / "even_out.mcap", mode)
                jittered = _replay(jit, tmp / "jit_out.mcap", mode)
                row = {"suite": "jitter", "recording": src.stem, "mode": mode,
                       "max_shift_ms": max_shift * 1e3,
                       "even_end_deg": even["end_deg"], "jittered_end_deg": jittered["end_deg"],
                       "end_ratio": jittered["end_deg"] / max(even["end_deg"], 1e-12),
                       "even_rms_deg": even["rms_deg"], "jittered_rms_deg": jittered["rms_deg"],
                       "rms_ratio": jittered["rms_deg"] / max(even["rms_deg"], 1e-12),
                       "even_bias": even["gyro_bias"], "jittered_bias": jittered["gyro_bias"]}
                rows.append(row)
                print(f"{src.stem:42s} {mode:8s} end {row['even_end_deg']:7.3f}° even, "
                      f"{row['jittered_end_deg']:7.3f}° jittered (×{row['end_ratio']:.3f}); "
                      f"RMS {row['even_rms_deg']:7.3f}° / {row['jittered_rms_deg']:7.3f}° "
                      f"(×{row['rms_ratio']:.3f})",
                      flush=True)
    worst = max(r["end_ratio"] for r in rows)
    print(f"worst end-error ratio jittered/even: {worst:.3f} (target ≤ 1.2); worst RMS ratio "
          f"{max(r['rms_ratio'] for r in rows):.3f}")
    return rows
