"""The cases of the causal estimator's golden regression test (:mod:`record` writes them,
``test_golden.py`` compares): what the estimator gives, in plain arrays and JSON-able figures."""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
sys.path.insert(0, str(REPO / "test" / "core" / "attitude"))

from sim_static import rest_motion_rest  # noqa: E402

from gyro_attitude.core.attitude import DEFAULT_ALGORITHM  # noqa: E402
from gyro_attitude.core.attitude.stream import AttitudeStream, StreamConfig  # noqa: E402

# the modes and hostile inputs as they were recorded (test_stream_real and its neighbours use these)
MODES = {
    "default": StreamConfig(),  # aiding auto: the AHRS filter, the tilt from the first sample
    "auto": StreamConfig(aiding="none"),
    "auto_noise": StreamConfig(gyro_noise_density=1e-4, gyro_bias_sigma_rad_s=0.01,
                               aiding="none"),
    "parameter": StreamConfig(gyro_bias="parameter", gyro_bias_rad_s=(0.02, -0.01, 0.05),
                              gyro_bias_sigma_rad_s=1e-3, gyro_bias_rw=1e-4,
                              gyro_noise_density=1e-4, aiding="none"),
    "none_rw": StreamConfig(gyro_bias="none", gyro_bias_sigma_rad_s=0.05, gyro_bias_rw=1e-3,
                            aiding="none"),
    "level": StreamConfig(initial_attitude_source="level", initial_heading_deg=30.0,
                          aiding="none"),
    "gravity_retired": StreamConfig(aiding="gravity", gyro_noise_density=1e-4),
    # the Earth rate taken out of the rest averages at the current attitude (frame enu)
    "auto_enu": StreamConfig(frame="enu", latitude_rad=0.9, gyro_noise_density=1e-4,
                             aiding="none"),
    "level_enu": StreamConfig(frame="enu", latitude_rad=0.9, initial_attitude_source="level",
                              initial_heading_deg=30.0, aiding="none"),
    # the AHRS stage, and aiding with the Earth rate taken out of the bias at the attitude the
    # aiding corrects (the loop of run() carries the coupling sample by sample)
    "tilt": StreamConfig(aiding="tilt", gyro_noise_density=1e-4),
    "level_tilt": StreamConfig(initial_attitude_source="level", aiding="tilt"),
    "magnetometer": StreamConfig(aiding="magnetometer", gyro_noise_density=1e-4),
    "level_magnetometer_enu": StreamConfig(frame="enu", latitude_rad=0.9, aiding="magnetometer",
                                           initial_attitude_source="level"),
    "tilt_enu": StreamConfig(frame="enu", latitude_rad=0.9, aiding="tilt",
                             gyro_noise_density=1e-4),
}


def hostile_rest_motion_rest():
    """rest–motion–rest–motion–rest at 200 Hz with, in the middle of the first rest (2.0–2.2 s)
    and the second one: NaN and 1e300 rates, a NaN and a 1e300 accelerometer sample, a duplicate
    and an out-of-order stamp, a zero stamp, a 0.3 s gap and a 2 s backward jump."""
    t, g, a, _ = rest_motion_rest(rests=(4.0, 3.0, 3.0))
    g, a = g.copy(), a.copy()
    g[400] = [np.nan, 0, 0]
    g[405] = [1e300, 0, 0]
    a[410] = [np.nan, 0, 0]
    a[415] = [0, 1e300, 0]
    t[420] = t[419]
    t[425] = t[424] - 2_000_000
    t[430] = 0
    second_rest = 800 + 300  # 4 s rest + 1... inside the second rest (after the first motion)
    a[second_rest] = [np.inf, 0, 0]
    t[second_rest + 50:] += 300_000_000  # gap
    t[-200:] -= 2_500_000_000  # backward jump
    cov = np.tile(np.diag([4e-6, 4e-6, 4e-6]).reshape(9), (t.size, 1))
    return t, g, a, cov


def hostile_field(n):
    """A field fixed in the body (the motion of rest_motion_rest turns and comes back) with
    noise, rows without a field (NaN), a NaN component and an absurd reading."""
    rng = np.random.default_rng(7)
    mag = np.array([20e-6, 5e-6, -40e-6]) + 2e-7 * rng.standard_normal((n, 3))
    mag[300:340] = np.nan
    mag[700, 1] = np.nan
    mag[1200] = [1e300, 0.0, 0.0]
    return mag



AIDINGS = ("none", "auto", "magnetometer")  # (auto is tilt on an Imu with an accelerometer)
BROAD_STRIDE = 25
SHARED_REAL = REPO.parent / "shared" / "real"
# the replay summary's fields that the estimator's results are (replay's own figures -- the
# error against the truth, timings, paths -- are not)
ESTIMATOR_RESULTS = ("messages", "attitude_messages", "frame_ids", "skipped", "gaps",
                     "time_jump_resets", "invalid_covariances", "integrator_errors",
                     "missing_samples", "saturated", "rate_fit_fallbacks", "details",
                     "skipped_before_truth", "gyro_bias", "gyro_bias_rad_s", "alignment",
                     "estimator_notes", "magnetometer")


def broad_files() -> list[Path]:
    return sorted(SHARED_REAL.glob("broad_*.mcap"))


def _plain(x):
    """JSON-able: arrays as lists, floats kept exact through repr in JSON."""
    if isinstance(x, dict):
        return {str(k): _plain(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_plain(v) for v in x]
    if isinstance(x, np.ndarray):
        return _plain(x.tolist())
    if isinstance(x, np.generic):
        return x.item()
    if hasattr(x, "value") and not isinstance(x, int | float | str):  # an enum
        return x.value
    return x


def _stream_figures(s: AttitudeStream) -> dict:
    rep = s.bias_report
    al = s.alignment
    return {
        "counts": _plain(s.counts),
        "details": _plain(s.details),
        "time_jump_resets": s.time_jump_resets,
        "accepted": s.accepted,
        "phase": _plain(s.phase),
        "bias": {"mode": _plain(rep.mode), "bias": _plain(rep.bias),
                 "rests_used": rep.rests_used, "rest_samples": rep.rest_samples,
                 "standard_error": _plain(rep.standard_error),
                 "earth_rate_removed": rep.earth_rate_removed, "note": rep.note},
        "alignment": None if al is None else {
            "q_nb": _plain(al.q_nb), "heading_source": al.heading_source,
            "level_error_expected": al.level_error_expected,
            "rest_start_ns": al.rest_start_ns, "rest_end_ns": al.rest_end_ns,
            "samples": al.samples, "mag_samples": al.mag_samples},
        "intervals": _plain(s.intervals.summary()),
        "final_q": _plain(s.quaternion),
    }


def hostile_outputs(mode: str, form: str) -> tuple[dict, dict]:
    """(arrays, figures) of ``mode`` on the hostile recording through ``push`` or ``run``."""
    t, g, a, cov = hostile_rest_motion_rest()
    cov = cov.copy()
    cov[450, 4] = -5.0
    cfg: StreamConfig = MODES[mode]
    mag = hostile_field(t.size) if "magnetometer" in mode else None
    s = AttitudeStream("rotvec_cubic", config=cfg)
    if form == "push":
        index, qs, var, actions = [], [], [], []
        for k in range(t.size):
            verdict, q = s.push(int(t[k]), g[k], "imu", cov[k], a[k],
                                None if mag is None else mag[k])
            actions.append(verdict.action)
            if q is not None:
                index.append(k)
                qs.append(q)
                v = s.variance
                var.append(np.full(3, np.nan) if v is None else v)
        arrays = {"index": np.array(index, np.int64), "q": np.array(qs).reshape(-1, 4),
                  "variance": np.array(var).reshape(-1, 3), "actions": np.array(actions, str)}
        return arrays, _stream_figures(s)
    res = s.run(t, g, "imu", cov, a, mag)
    var = res.variance if res.variance is not None else np.full((res.index.size, 3), np.nan)
    if res.variance_known is not None:
        var = np.where(res.variance_known[:, None], var, np.nan)
    arrays = {"index": res.index, "q": res.q, "variance": var, "action": res.action}
    figures = _stream_figures(s)
    figures.update(result_counts=_plain(res.counts), result_details=_plain(res.details),
                   result_resets=res.time_jump_resets, notes=_plain(res.notes))
    return arrays, figures


def broad_outputs(path: Path, aiding: str) -> tuple[dict, dict]:
    """(arrays, figures) of ``replay --estimator causal --aiding AIDING`` of ``path``."""
    from gyro_attitude.io.cdr_arrays import IMU_TYPE
    from gyro_attitude.io.imu_fast import read_topic_arrays
    from gyro_attitude.offline.replay import replay_file

    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "out.mcap"
        # the node's causal algorithm in every mode (what the live node runs; the causal
        # replay's array form took the offline default where no filter fed back)
        res = replay_file(path, out, estimator="causal", config=StreamConfig(aiding=aiding),
                          algorithm=DEFAULT_ALGORITHM)
        imu = read_topic_arrays(out, {"imu/data": IMU_TYPE})["imu/data"]
        cov = np.asarray(imu.orientation_covariance)[:, [0, 4, 8]]
        q_file = np.asarray(imu.orientation)
    sel = np.r_[np.arange(0, res.q.shape[0], BROAD_STRIDE), res.q.shape[0] - 1]
    arrays = {"q": res.q[sel], "q_file": q_file[sel], "variance": cov[sel],
              "t_ns": res.t_ns[sel], "index": res.index[sel]}
    summary = {k: v for k, v in res.summary().items() if k in ESTIMATOR_RESULTS}
    return arrays, _plain(summary)
