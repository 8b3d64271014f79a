"""Real MEMS recordings with optical truth (BROAD, CC BY 4.0): bias, levelling, tilt aiding, peers.

``gyro-attitude bench --suite real`` or ``run(quick, out_dir)``.  Data:
``shared/real/*.mcap`` in the working directory or above (``../shared/real``), or
``$GYRO_ATTITUDE_REAL_DIR`` (Laidig, Caruso,
Cereatti, Seel, "BROAD", Data 6(7):72, 2021).  Per recording and mode one row: error angle at the
end of the motion, RMS error over the motion, tilt error at the end, cost per sample.

End of the motion: the start of the final rest found by the rest detector (rest.py) on the data
itself (the first sample of the last rest run that reaches the end of the recording), evaluated
at the last truth sample at or before it.  Every mode runs :meth:`AttitudeStream.run
<gyro_attitude.core.attitude.stream.AttitudeStream.run>` (the policy of the node and of replay,
so these are the figures users get), in the ENU frame at the recording's latitude (TU Berlin,
52.5°N: the Earth rate is taken out of the bias), from the truth at the first Imu stamp
(``initial_attitude_from_truth``) except ``level``: ``none`` raw gyro (batch path); ``auto``
bias from rests; ``level`` roll/pitch from the initial rest's specific force, heading from the
truth (the truth's north is magnetic), auto bias; ``tilt`` auto bias + tilt aiding (the AHRS filter);
``level+tilt`` both.  ``none/push`` is ``none`` through the per-sample path (the cost of the
sequential path against the batch one, same numbers); likewise ``<aided mode>/push``, the
node's per-sample cost of the aided modes against ``run()``'s (``form``: which form ran); the
compiled kernels are loaded before the first row, as the node loads them before it subscribes.
Peers in the same run on the same data: naive exponential map without bias, ``vqf`` (VQF 6D,
no magnetometer) and ``imufusion`` (Madgwick's Fusion AHRS, 6D); their heading is not
observable, so their full-attitude error is taken after aligning the heading at the start and
their tilt error is the fair comparison.

Offline rows (``offline/<mode>``): the whole-recording estimator
(:func:`~gyro_attitude.core.attitude.offline.estimate_offline`, what ``replay`` runs by
default) with the settings of ``<mode>``; ``oracle/initial_rest_bias`` integrates the gyro with
the bias = its mean over the initial rest (the reference of the gyro-only target);
``peer/offline_vqf_6d`` is offlineVQF (forward-backward VQF) in the same run.  The fast rows
are timed as the best of :data:`REPEATS` runs.  ``ratios`` rows: offline RMS tilt over
offlineVQF's (also against the truth re-timed onto the gyro's clock, :func:`truth_lag`: the
shared BROAD stamps put the truth ~3 ms behind the gyro, which penalises every estimator's
1-10 Hz error), gyro-only end error over the oracle's, speed over offlineVQF's, offline 9D RMS
heading over offlineVQF 9D's.  Then the same
comparison on simulated ``handheld_mems`` recordings (:func:`simulated`) and ``replay``'s own
speed inside the command and for the whole process (:func:`replay_speed`).
"""

from __future__ import annotations

import os
import pathlib
import time

import numpy as np

from gyro_attitude.core.angles import wrap_pi
from gyro_attitude.core.attitude import NavFrame, integrate_batch
from gyro_attitude.core.attitude.offline import estimate_offline
from gyro_attitude.core.attitude.rest import detect_rest, rest_segments
from gyro_attitude.core.attitude.stream import AttitudeStream, StreamConfig
from gyro_attitude.core.attitude.truth import initial_attitude_from_truth
from gyro_attitude.core.earth import STANDARD_GRAVITY
from gyro_attitude.core.rotation import (
    quat_angle_between,
    quat_as_matrix,
    quat_conjugate,
    quat_multiply,
)
from gyro_attitude.io.imu_fast import (
    read_imu_arrays,
    read_magnetic_field_arrays,
    read_quaternion_stamped_arrays,
)

RECORDINGS = ("broad_05_slow_rotation_with_breaks", "broad_16_fast_translation")
LATITUDE_RAD = np.radians(52.5)  # TU Berlin, where BROAD was recorded
MODES = ("none", "none/push", "auto", "level", "tilt", "level+tilt", "magnetometer",
         "level+magnetometer", "tilt/push", "magnetometer/push", "level+magnetometer/push")
# the offline (whole-recording) estimator, core/attitude/offline.py, same settings as the
# causal mode after the "+"
OFFLINE_MODES = ("offline/auto", "offline/level", "offline/tilt", "offline/level+tilt",
                 "offline/magnetometer", "offline/level+magnetometer")


def stream_config(mode: str, heading_deg: float = 0.0) -> StreamConfig:
    """The StreamConfig of a benchmark mode (what node parameters / replay flags give)."""
    kw: dict = {"gyro_bias": "none"} if mode.startswith("none") else {}
    kw["aiding"] = "none"  # unless the mode names one
    if "level" in mode:
        kw |= {"initial_attitude_source": "level", "initial_heading_deg": heading_deg}
    for aiding in ("tilt", "magnetometer"):
        if aiding in mode:
            kw["aiding"] = aiding
    return StreamConfig(**kw)


def real_dir() -> pathlib.Path:
    env = os.environ.get("GYRO_ATTITUDE_REAL_DIR")
    if env:
        return pathlib.Path(env)
    # The repository's sibling ``shared/real`` (``../shared/real``), looked for from the working
    # directory upwards (the package may be installed elsewhere, so not from __file__).
    cwd = pathlib.Path.cwd().resolve()
    for base in (cwd, *cwd.parents):
        if (base / "shared" / "real").is_dir():
            return base / "shared" / "real"
    return cwd.parent / "shared" / "real"


def load(name: str, directory: pathlib.Path | None = None):
    """(t_ns, gyro, accel, truth_t_ns, truth_q) of one recording."""

    path = (directory or real_dir()) / f"{name}.mcap"
    imu = read_imu_arrays(path, "/imu/data_raw")
    truth = read_quaternion_stamped_arrays(path, "/truth/attitude")
    return (imu.stamp_ns, imu.angular_velocity, imu.linear_acceleration, truth.stamp_ns,
            truth.quaternion)


def load_mag(name: str, directory: pathlib.Path | None = None) -> np.ndarray:
    """The magnetometer (N, 3) tesla of one recording, on the Imu stamps (same stamps there)."""
    from gyro_attitude.core.attitude.sample_alignment import latest_at

    path = (directory or real_dir()) / f"{name}.mcap"
    imu = read_imu_arrays(path, "/imu/data_raw")
    mag = read_magnetic_field_arrays(path, "/imu/mag")
    return latest_at(imu.stamp_ns, mag.stamp_ns, mag.magnetic_field, 0)


def heading_error(q_est, q_true) -> np.ndarray:
    """|rotation about the vertical| of the error ``q_est ⊗ q_true⁻¹`` (its twist about nav up,
    rad): the heading part of the error, whatever the tilt."""
    e = quat_multiply(q_est, quat_conjugate(q_true))
    return np.abs(wrap_pi(2.0 * np.arctan2(e[..., 2], e[..., 3])))


def end_of_motion(t, g, a) -> int:
    """Index of the first sample of the final rest (the rest run reaching the last sample)."""
    segs = rest_segments(detect_rest(t, g, a).covered)
    if not segs or segs[-1][1] != t.size - 1:
        raise ValueError("the recording does not end at rest: no end of motion found")
    return segs[-1][0]


def truth_lag(t, g, tt, tq, bias, search_ms=8.0, step_ms=0.25):
    """(lag s, truth re-timed): the shift of the truth's clock that best fits its body rate
    (finite differences of the truth attitude) to the gyro's (less ``bias``), and the truth
    slerped to ``stamp + lag`` -- the truth on the gyro's clock.  Evaluation only: it says how
    far the recording's stamps put the two apart (BROAD as shared: the gyro ~3 ms ahead), never
    enters an estimator."""
    from scipy.spatial.transform import Rotation, Slerp

    ts = (tt - tt[0]) * 1e-9
    r = Rotation.from_quat(tq)
    w_truth = (r[:-1].inv() * r[1:]).as_rotvec() / np.diff(ts)[:, None]
    t_mid = 0.5 * (ts[:-1] + ts[1:])
    tg = (t - tt[0]) * 1e-9
    wb = g - bias
    best = (np.inf, 0.0)
    for lag in np.arange(-search_ms, search_ms + 1e-9, step_ms) * 1e-3:
        wi = np.column_stack([np.interp(t_mid - lag, tg, wb[:, i]) for i in range(3)])
        best = min(best, (float(np.mean(np.sum((wi - w_truth) ** 2, axis=1))), float(lag)))
    lag = best[1]
    return lag, Slerp(ts, r)(np.clip(ts + lag, ts[0], ts[-1])).as_quat()


REPEATS = 3  # fast rows: the best of this many runs (a shared machine's noise is one-sided)


def _best_of(fn, repeats: int = REPEATS):
    """(result, seconds) of the fastest of ``repeats`` calls of ``fn()``."""
    best = None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        dt = time.perf_counter() - t0
        if best is None or dt < best[1]:
            best = (out, dt)
    return best


def _rows_at(res, first: int, n: int) -> np.ndarray:
    """The per-axis variance of an estimate at every input sample (held before the first)."""
    var = np.empty((n, 3))
    var[:] = res.variance[0]
    var[first + res.index] = res.variance
    return var


def tilt_error(q_est, q_true) -> np.ndarray:
    """Angle between the estimated and true up directions in the body (rad)."""
    u = quat_as_matrix(q_est)[..., 2, :]
    v = quat_as_matrix(q_true)[..., 2, :]
    return np.arccos(np.clip(np.sum(u * v, axis=-1), -1.0, 1.0))


def _yaw_align(q_est, q_true0):
    """Rotate q_est about nav up so that its first heading matches the truth's."""
    def yaw(q):
        c = quat_as_matrix(q)
        return np.arctan2(c[1, 0], c[0, 0])
    d = yaw(q_true0) - yaw(q_est[0])
    rz = np.array([0.0, 0.0, np.sin(d / 2), np.cos(d / 2)])
    return quat_multiply(rz, q_est)


def evaluate(name: str, directory=None, modes=MODES, peers=True,
             histories: dict | None = None, offline_modes=OFFLINE_MODES) -> list[dict]:
    t, g, a, tt, tq = load(name, directory)
    mag = load_mag(name, directory)
    q_first, first, _ = initial_attitude_from_truth(t, tt, tq)
    ke_imu = end_of_motion(t, g, a)
    kt_end = int(np.searchsorted(tt, t[ke_imu], side="right")) - 1
    idx = np.searchsorted(t, tt)  # truth stamps are IMU stamps
    motion = slice(0, kt_end + 1)
    rows = []
    s0, s1 = rest_segments(detect_rest(t, g, a).covered)[0]
    lag, tq_gyro_clock = truth_lag(t, g, tt, tq, g[s0:s1 + 1].mean(axis=0))

    def row(mode, q, seconds, peer=False, valid=None, align_heading=None):
        qe = q[idx]
        if align_heading if align_heading is not None else peer:
            qe = _yaw_align(qe, tq[0])
        err = quat_angle_between(qe, tq)
        tilt = tilt_error(qe, tq)
        head = heading_error(qe, tq)
        tilt_gc = tilt_error(qe, tq_gyro_clock)  # against the truth on the gyro's clock
        if valid is not None:  # truth samples before the first attitude (aligning): no error
            err = np.where(valid, err, np.nan)
            tilt = np.where(valid, tilt, np.nan)
            head = np.where(valid, head, np.nan)
        if histories is not None and not mode.endswith("/push"):
            histories[(name, mode)] = ((tt - tt[0]) * 1e-9, np.degrees(err), np.degrees(tilt))
        m = err[motion][np.isfinite(err[motion])]
        mt = tilt[motion][np.isfinite(tilt[motion])]
        mg = tilt_gc[motion][np.isfinite(tilt[motion])]
        mh = head[motion][np.isfinite(head[motion])]
        rows.append({"recording": name, "mode": mode, "peer": peer,
                     "end_error_deg": float(np.degrees(err[kt_end])),
                     "rms_error_deg": float(np.degrees(np.sqrt(np.mean(m ** 2)))),
                     "end_tilt_deg": float(np.degrees(tilt[kt_end])),
                     "rms_tilt_deg": float(np.degrees(np.sqrt(np.mean(mt ** 2)))),
                     "peak_tilt_deg": float(np.degrees(mt.max())),
                     "rms_heading_deg": float(np.degrees(np.sqrt(np.mean(mh ** 2)))),
                     "rms_tilt_deg_truth_on_gyro_clock": float(np.degrees(np.sqrt(np.mean(
                         mg ** 2)))),
                     "truth_lag_ms": lag * 1e3,
                     "ns_per_sample": seconds / t.size * 1e9,
                     "samples_per_s": t.size / max(seconds, 1e-12),
                     "end_of_motion_s": float((tt[kt_end] - tt[0]) * 1e-9)})

    c0 = quat_as_matrix(q_first)
    heading = float(np.degrees(np.pi / 2 - np.arctan2(c0[1, 0], c0[0, 0])))
    nav = NavFrame(latitude_rad=LATITUDE_RAD)
    for mode in modes:
        t0 = time.perf_counter()
        stream = AttitudeStream(q0=q_first, nav=nav, config=stream_config(mode, heading))
        if mode.endswith("/push"):  # the node's path: every sample pushed
            m = mag if "magnetometer" in mode else [None] * t.size
            q_rows = [stream.push(int(t[k]), g[k], "imu_link", None, a[k], m[k])[1]
                      for k in range(first, t.size)]
            index = first + np.flatnonzero([x is not None for x in q_rows])
            q_res = np.array([x for x in q_rows if x is not None])
        else:
            res = stream.run(t[first:], g[first:], "imu_link", None, a[first:],
                             mag[first:] if "magnetometer" in mode else None)
            index, q_res = first + res.index, res.q
        seconds = time.perf_counter() - t0
        # the attitude at every Imu sample (held before the first one: masked in the error)
        q = np.empty((t.size, 4))
        q[:] = q_res[0]
        q[index] = q_res
        has = np.zeros(t.size, bool)
        has[index[0]:] = True
        row(mode, q, seconds, valid=has[idx])
        rows[-1]["bias_note"] = stream.bias_report.note
    for mode in offline_modes:
        cfg = stream_config(mode.split("/", 1)[1], heading)
        res, seconds = _best_of(lambda cfg=cfg, mode=mode: estimate_offline(
            t[first:], g[first:], a[first:], q0=q_first, nav=nav, frame_id="imu_link",
            config=cfg, mag=mag[first:] if "magnetometer" in mode else None))
        q = np.empty((t.size, 4))
        q[:] = res.q[0]
        q[first + res.index] = res.q
        has = np.zeros(t.size, bool)
        has[first + res.index[0]:] = True
        row(mode, q, seconds, valid=has[idx])
        rows[-1]["bias_note"] = res.bias.note
        # the error within 1σ / 3σ per axis (output frame) over the motion: how honest the
        # covariance is on real data
        if res.variance is not None:
            from gyro_attitude.core.rotation import quat_as_rotvec, quat_conjugate
            qe = q[idx][motion]
            e = quat_as_rotvec(quat_multiply(tq[motion], quat_conjugate(qe)))
            sd = np.sqrt(np.maximum(_rows_at(res, first, t.size)[idx][motion], 1e-300))
            z = np.abs(e) / sd
            axes = [0, 1] if "tilt" in mode or "level" in mode else [0, 1, 2]
            if "magnetometer" in mode:
                axes = [0, 1, 2]
            rows[-1]["within_1sigma"] = float(np.mean(z[:, axes] <= 1.0))
            rows[-1]["within_3sigma"] = float(np.mean(z[:, axes] <= 3.0))
    # the rest-bias oracle: bias = the mean over the initial rest, gyro only, same frame
    segs = rest_segments(detect_rest(t, g, a).covered)
    s0, s1 = segs[0]
    q, seconds = _best_of(lambda: integrate_batch(
        t[first:], g[first:] - g[s0:s1 + 1].mean(axis=0), q0=q_first, nav=nav))
    qq = np.empty((t.size, 4))
    qq[:first] = q[0]
    qq[first:] = q
    row("oracle/initial_rest_bias", qq, seconds)
    if peers:
        t0 = time.perf_counter()
        q = integrate_batch(t, g, q0=tq[0], algorithm="exp_map")
        row("peer/naive_exp_map", q, time.perf_counter() - t0, peer=True)
        dt = float(np.median(np.diff(t))) * 1e-9
        try:
            from vqf import VQF
            gc, ac = np.ascontiguousarray(g), np.ascontiguousarray(a)
            out, seconds = _best_of(lambda: VQF(dt).updateBatch(gc, ac))
            qv = out["quat6D"]  # w, x, y, z; maps sensor to its earth frame
            row("peer/vqf_6d", np.column_stack([qv[:, 1:], qv[:, :1]]), seconds, peer=True)
        except ImportError:
            pass
        try:
            from vqf import offlineVQF
            gc, ac = np.ascontiguousarray(g), np.ascontiguousarray(a)
            out, seconds = _best_of(lambda: offlineVQF(gc, ac, None, dt))
            qv = out["quat6D"]  # w, x, y, z
            row("peer/offline_vqf_6d", np.column_stack([qv[:, 1:], qv[:, :1]]), seconds,
                peer=True)
        except ImportError:
            pass
        try:  # VQF 9D (real-time) and offlineVQF (6D, 9D): its 9D north is magnetic north
            from vqf import VQF, offlineVQF
            gc, ac, mc = (np.ascontiguousarray(x) for x in (g, a, mag * 1e6))
            t0 = time.perf_counter()
            out = VQF(dt).updateBatch(gc, ac, mc)
            seconds = time.perf_counter() - t0
            qv = out["quat9D"]
            row("peer/vqf_9d", np.column_stack([qv[:, 1:], qv[:, :1]]), seconds, peer=True,
                align_heading=False)
            t0 = time.perf_counter()
            out = offlineVQF(gc, ac, mc, dt)
            seconds = time.perf_counter() - t0
            for kind in ("6D", "9D"):
                qv = out[f"quat{kind}"]
                row(f"peer/offline_vqf_{kind.lower()}", np.column_stack([qv[:, 1:], qv[:, :1]]),
                    seconds, peer=True, align_heading=kind == "6D")
        except ImportError:
            pass
        try:
            import imufusion
            t0 = time.perf_counter()
            settings = imufusion.AhrsSettings()
            settings.sample_rate = round(1.0 / dt)
            settings.convention = imufusion.CONVENTION_ENU
            ahrs = imufusion.Ahrs()
            ahrs.set_settings(settings)
            ahrs.set_sample_period(dt)
            qf = np.empty((t.size, 4))
            gd = np.degrees(g)
            ag = a / STANDARD_GRAVITY
            for k in range(t.size):
                ahrs.update_no_magnetometer(gd[k], ag[k])
                w, x, y, z = ahrs.get_quaternion()  # scalar first
                qf[k] = (x, y, z, w)
            row("peer/imufusion_6d", qf, time.perf_counter() - t0, peer=True)
        except ImportError:
            pass
    return rows


def simulated(seeds=range(5)) -> list[dict]:
    """The same comparison on simulated recordings that no setting was tuned on: the shipped
    ``handheld_mems`` scene (rest, 8 s of hand motion with accelerations, rest; MEMS gyro and
    accelerometer errors like BROAD's) with several noise seeds.  RMS tilt over the motion
    against the simulator's closed-form truth: offline (tilt) vs offlineVQF and VQF 6D."""
    import dataclasses

    from gyro_attitude.core.scene.simulator import SceneSimulator
    from gyro_attitude.io.scene_file import load_scene

    rows = []
    base = load_scene("handheld_mems")
    for seed in seeds:
        spec = dataclasses.replace(base, seed=int(seed))
        sim = SceneSimulator(spec, spec.rate_hz)
        n = int(spec.duration_s * spec.rate_hz)
        blocks = [sim.next_block(1000) for _ in range(n // 1000)]
        t, w, f, q_true = (np.concatenate([getattr(b, k) for b in blocks]) for k in
                           ("t_ns", "omega_ib_b", "specific_force_b", "truth_q_nb"))
        s = (t - t[0]) * 1e-9
        motion = (s >= 6.0) & (s <= 14.0)
        dt = float(np.median(np.diff(t))) * 1e-9
        nav = NavFrame(latitude_rad=spec.earth.latitude_rad)
        est = {}
        t0 = time.perf_counter()
        res = estimate_offline(t, w, f, q0=q_true[0], nav=nav, config=stream_config("tilt"))
        est["offline/tilt"] = (res.q, time.perf_counter() - t0)
        try:
            from vqf import VQF, offlineVQF
            t0 = time.perf_counter()
            qv = offlineVQF(np.ascontiguousarray(w), np.ascontiguousarray(f), None, dt)["quat6D"]
            est["peer/offline_vqf_6d"] = (np.column_stack([qv[:, 1:], qv[:, :1]]),
                                          time.perf_counter() - t0)
            t0 = time.perf_counter()
            qv = VQF(dt).updateBatch(np.ascontiguousarray(w), np.ascontiguousarray(f))["quat6D"]
            est["peer/vqf_6d"] = (np.column_stack([qv[:, 1:], qv[:, :1]]),
                                  time.perf_counter() - t0)
        except ImportError:
            pass
        for mode, (q, seconds) in est.items():
            tilt = tilt_error(q, q_true)[motion]
            rows.append({"recording": f"sim/handheld_mems seed {seed}", "mode": mode,
                         "peer": mode.startswith("peer/"),
                         "rms_tilt_deg": float(np.degrees(np.sqrt(np.mean(tilt ** 2)))),
                         "end_tilt_deg": float(np.degrees(tilt[-1])),
                         "samples_per_s": t.size / max(seconds, 1e-12)})
    return rows


def replay_speed(name: str, directory=None) -> list[dict]:
    """``gyro-attitude replay`` on one recording, as users run it: samples per second inside
    the command (the estimation, ``integrate_seconds``), for the in-process command (read,
    estimate, write) and for the whole process (interpreter start-up included)."""
    import subprocess
    import sys
    import tempfile

    from gyro_attitude.offline.replay import replay_file

    path = (directory or real_dir()) / f"{name}.mcap"
    rows = []
    runs = {"replay (offline, defaults)": [], "replay --aiding none (offline)":
            ["--aiding", "none"], "replay --estimator causal": ["--estimator", "causal"],
            "replay --estimator causal --aiding none": ["--estimator", "causal", "--aiding",
                                                       "none"]}
    with tempfile.TemporaryDirectory() as tmp:
        for label, flags in runs.items():
            kw = {"imu_topic": "/imu/data_raw", "truth_topic": "/truth/attitude", "force": True,
                  "estimator": "causal" if "causal" in flags else "offline"}
            if "none" in flags:
                kw["config"] = StreamConfig(aiding="none")
            res = min((replay_file(path, pathlib.Path(tmp) / "o.mcap", **kw)
                       for _ in range(REPEATS)), key=lambda r: r.integrate_seconds)
            t0 = time.perf_counter()
            subprocess.run([sys.executable, "-m", "gyro_attitude.cli", "replay", str(path),
                            "--out", str(pathlib.Path(tmp) / "p.mcap"), "--force",
                            "--imu-topic", "/imu/data_raw", "--truth-topic", "/truth/attitude",
                            "--no-progress", *flags], check=True, capture_output=True)
            process = time.perf_counter() - t0
            rows.append({"recording": name, "mode": label, "estimator": res.estimator,
                         "messages": res.messages,
                         "samples_per_s_inside": res.messages / res.integrate_seconds,
                         "samples_per_s_command": res.messages / res.wall_seconds,
                         "samples_per_s_process": res.messages / process,
                         "final_error_deg": float(np.degrees(res.final_error_rad))})
    return rows


def _offline_ratios(rows: list[dict]) -> list[dict]:
    """Per recording: offline RMS tilt over offlineVQF's, offline gyro-only end error against
    the rest-bias oracle, offline speed over offlineVQF's (all from this run)."""
    out = []
    for name in dict.fromkeys(r["recording"] for r in rows if "recording" in r):
        by = {r["mode"]: r for r in rows if r.get("recording") == name}
        ovqf = by.get("peer/offline_vqf_6d")
        gyro, oracle = by.get("offline/auto"), by.get("oracle/initial_rest_bias")
        aided = by.get("offline/tilt")
        if not (ovqf and gyro and oracle and aided):
            continue
        r = {"recording": name, "mode": "ratios",
             "offline_tilt_rms_tilt_over_offline_vqf": aided["rms_tilt_deg"]
             / ovqf["rms_tilt_deg"],
             "offline_tilt_rms_tilt_over_offline_vqf_truth_on_gyro_clock":
             aided["rms_tilt_deg_truth_on_gyro_clock"]
             / ovqf["rms_tilt_deg_truth_on_gyro_clock"],
             "offline_gyro_only_end_error_over_oracle": gyro["end_error_deg"]
             / oracle["end_error_deg"],
             "offline_tilt_speed_over_offline_vqf": aided["samples_per_s"]
             / ovqf["samples_per_s"],
             "offline_auto_speed_over_offline_vqf": gyro["samples_per_s"]
             / ovqf["samples_per_s"]}
        print(f"{name}: truth {aided['truth_lag_ms']:+.2f} ms from the gyro's clock; on the gyro's "
              "clock offline/tilt RMS tilt = "
              f"{r['offline_tilt_rms_tilt_over_offline_vqf_truth_on_gyro_clock']:.2f}× "
              "offlineVQF's")
        ovqf9, mag9 = by.get("peer/offline_vqf_9d"), by.get("offline/magnetometer")
        if ovqf9 and mag9:
            r["offline_magnetometer_rms_heading_over_offline_vqf_9d"] = (
                mag9["rms_heading_deg"] / ovqf9["rms_heading_deg"])
            print(f"{name}: offline/magnetometer RMS heading = "
                  f"{r['offline_magnetometer_rms_heading_over_offline_vqf_9d']:.2f}× offlineVQF "
                  "9D's")
        print(f"{name}: offline/tilt RMS tilt = {r[next(iter(list(r)[2:]))]:.2f}× offlineVQF; "
              f"gyro-only end error = {r['offline_gyro_only_end_error_over_oracle']:.2f}× the "
              f"rest-bias oracle; speed {r['offline_tilt_speed_over_offline_vqf']:.2f}× "
              f"(tilt), {r['offline_auto_speed_over_offline_vqf']:.2f}× (auto) offlineVQF's")
        out.append(r)
    return out


def run(quick: bool = False, out_dir=None) -> list[dict]:
    from gyro_attitude.core.attitude.stream import compile_kernels

    directory = real_dir()
    names = RECORDINGS[:1] if quick else RECORDINGS
    hist: dict = {}
    rows = []
    # the compiled per-sample kernels loaded before any row is timed, as the node loads them
    # before it subscribes (otherwise the first row with a per-sample chain pays ~1 s for it)
    compile_kernels()
    for name in names:
        if not (directory / f"{name}.mcap").exists():
            print(f"real: {directory / name}.mcap missing, skipped")
            continue
        rows += evaluate(name, directory, histories=hist)
    nan = float("nan")
    print(f"{'recording':36s} {'mode':24s} {'end°':>7s} {'rms°':>7s} {'tilt°':>7s} "
          f"{'rms tilt°':>9s} {'peak tilt°':>10s} {'rms head°':>9s} {'samples/s':>10s}")
    for r in rows:
        print(f"{r['recording']:36s} {r['mode']:24s} {r['end_error_deg']:7.2f} "
              f"{r['rms_error_deg']:7.2f} {r['end_tilt_deg']:7.3f} {r['rms_tilt_deg']:9.3f} "
              f"{r.get('peak_tilt_deg', nan):10.2f} {r.get('rms_heading_deg', nan):9.2f} "
              f"{r.get('samples_per_s', nan):10.3g}")
    rows += _offline_ratios(rows)
    speed = []
    for name in names:
        if (directory / f"{name}.mcap").exists():
            speed += replay_speed(name, directory)
    print(f"{'recording':36s} {'command':44s} {'inside/s':>9s} {'command/s':>10s} "
          f"{'process/s':>10s}")
    for r in speed:
        print(f"{r['recording']:36s} {r['mode']:44s} {r['samples_per_s_inside']:9.3g} "
              f"{r['samples_per_s_command']:10.3g} {r['samples_per_s_process']:10.3g}")
    rows += speed
    sim = simulated(range(2) if quick else range(5))
    print(f"{'simulated recording':36s} {'mode':24s} {'rms tilt°':>9s}")
    for r in sim:
        print(f"{r['recording']:36s} {r['mode']:24s} {r['rms_tilt_deg']:9.3f}")
    by = {}
    for r in sim:
        by.setdefault(r["recording"], {})[r["mode"]] = r["rms_tilt_deg"]
    ratios = [m["offline/tilt"] / m["peer/offline_vqf_6d"] for m in by.values()
              if "peer/offline_vqf_6d" in m]
    if ratios:
        print(f"simulated: offline/tilt RMS tilt over offlineVQF's: median "
              f"{np.median(ratios):.2f}, worst {max(ratios):.2f} ({len(ratios)} recordings)")
        sim.append({"recording": "sim/handheld_mems", "mode": "ratios",
                    "offline_tilt_rms_tilt_over_offline_vqf_median": float(np.median(ratios)),
                    "offline_tilt_rms_tilt_over_offline_vqf_worst": float(max(ratios))})
    rows += sim
    if out_dir is not None and hist:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, axes = plt.subplots(len(names), 1, figsize=(9, 3.5 * len(names)), squeeze=False)
        for ax, name in zip(axes[:, 0], names, strict=False):
            for (n, mode), (ts, err, tilt) in hist.items():
                if n == name:
                    ax.semilogy(ts, np.maximum(tilt if "peer/" in mode and "naive" not in mode else err,
                                               1e-3), label=mode + (" (tilt)" if "peer/" in mode
                                                                    and "naive" not in mode else ""))
            ax.set_title(name)
            ax.set_xlabel("time (s)")
            ax.set_ylabel("error (°)")
            ax.legend(fontsize=7)
        fig.tight_layout()
        path = pathlib.Path(out_dir) / "real_error.png"
        fig.savefig(path, dpi=90)
        print(f"wrote {path}")
    return rows
