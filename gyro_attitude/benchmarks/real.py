"""Real MEMS recordings with optical truth (BROAD, CC BY 4.0): bias, levelling, gravity aiding, peers.

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
truth (the truth's north is magnetic), auto bias; ``gravity`` auto bias + gravity aiding;
``level+gravity`` both.  ``none/push`` is ``none`` through the per-sample path (the cost of the
sequential path against the batch one, same numbers).  Peers in the same run on the same data:
naive exponential map without bias, ``vqf`` (VQF 6D, no magnetometer) and ``imufusion``
(Madgwick's Fusion AHRS, 6D); their heading is not observable, so their full-attitude error is
taken after aligning the heading at the start and their tilt error is the fair comparison.
"""

from __future__ import annotations

import os
import pathlib
import time

import numpy as np

from gyro_attitude.core.attitude import NavFrame, integrate_batch
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
MODES = ("none", "none/push", "auto", "level", "gravity", "level+gravity", "tilt", "level+tilt",
         "magnetometer", "level+magnetometer")


def stream_config(mode: str, heading_deg: float = 0.0) -> StreamConfig:
    """The StreamConfig of a benchmark mode (what node parameters / replay flags give)."""
    kw: dict = {"gyro_bias": "none"} if mode.startswith("none") else {}
    if "level" in mode:
        kw |= {"initial_attitude_source": "level", "initial_heading_deg": heading_deg}
    for aiding in ("gravity", "tilt", "magnetometer"):
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
    return np.abs((2.0 * np.arctan2(e[..., 2], e[..., 3]) + np.pi) % (2.0 * np.pi) - np.pi)


def end_of_motion(t, g, a) -> int:
    """Index of the first sample of the final rest (the rest run reaching the last sample)."""
    segs = rest_segments(detect_rest(t, g, a).covered)
    if not segs or segs[-1][1] != t.size - 1:
        raise ValueError("the recording does not end at rest: no end of motion found")
    return segs[-1][0]


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
             histories: dict | None = None) -> list[dict]:
    t, g, a, tt, tq = load(name, directory)
    mag = load_mag(name, directory)
    q_first, first, _ = initial_attitude_from_truth(t, tt, tq)
    ke_imu = end_of_motion(t, g, a)
    kt_end = int(np.searchsorted(tt, t[ke_imu], side="right")) - 1
    idx = np.searchsorted(t, tt)  # truth stamps are IMU stamps
    motion = slice(0, kt_end + 1)
    rows = []

    def row(mode, q, seconds, peer=False, valid=None, align_heading=None):
        qe = q[idx]
        if align_heading if align_heading is not None else peer:
            qe = _yaw_align(qe, tq[0])
        err = quat_angle_between(qe, tq)
        tilt = tilt_error(qe, tq)
        head = heading_error(qe, tq)
        if valid is not None:  # truth samples before the first attitude (aligning): no error
            err = np.where(valid, err, np.nan)
            tilt = np.where(valid, tilt, np.nan)
            head = np.where(valid, head, np.nan)
        if histories is not None and mode != "none/push":
            histories[(name, mode)] = ((tt - tt[0]) * 1e-9, np.degrees(err), np.degrees(tilt))
        m = err[motion][np.isfinite(err[motion])]
        mt = tilt[motion][np.isfinite(tilt[motion])]
        mh = head[motion][np.isfinite(head[motion])]
        rows.append({"recording": name, "mode": mode, "peer": peer,
                     "end_error_deg": float(np.degrees(err[kt_end])),
                     "rms_error_deg": float(np.degrees(np.sqrt(np.mean(m ** 2)))),
                     "end_tilt_deg": float(np.degrees(tilt[kt_end])),
                     "rms_tilt_deg": float(np.degrees(np.sqrt(np.mean(mt ** 2)))),
                     "peak_tilt_deg": float(np.degrees(mt.max())),
                     "rms_heading_deg": float(np.degrees(np.sqrt(np.mean(mh ** 2)))),
                     "ns_per_sample": seconds / t.size * 1e9,
                     "end_of_motion_s": float((tt[kt_end] - tt[0]) * 1e-9)})

    c0 = quat_as_matrix(q_first)
    heading = float(np.degrees(np.pi / 2 - np.arctan2(c0[1, 0], c0[0, 0])))
    nav = NavFrame(latitude_rad=LATITUDE_RAD)
    for mode in modes:
        t0 = time.perf_counter()
        stream = AttitudeStream(q0=q_first, nav=nav, config=stream_config(mode, heading))
        if mode == "none/push":
            q_rows = [stream.push(int(t[k]), g[k], "imu_link", None, a[k])[1]
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
        rows[-1]["batch_path"] = mode != "none/push" and stream.run_form()[0] == "arrays"
    if peers:
        t0 = time.perf_counter()
        q = integrate_batch(t, g, q0=tq[0], algorithm="exp_map")
        row("peer/naive_exp_map", q, time.perf_counter() - t0, peer=True)
        dt = float(np.median(np.diff(t))) * 1e-9
        try:
            from vqf import VQF
            t0 = time.perf_counter()
            out = VQF(dt).updateBatch(np.ascontiguousarray(g), np.ascontiguousarray(a))
            qv = out["quat6D"]  # w, x, y, z; maps sensor to its earth frame
            row("peer/vqf_6d", np.column_stack([qv[:, 1:], qv[:, :1]]), time.perf_counter() - t0,
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


def run(quick: bool = False, out_dir=None) -> list[dict]:
    directory = real_dir()
    names = RECORDINGS[:1] if quick else RECORDINGS
    hist: dict = {}
    rows = []
    for name in names:
        if not (directory / f"{name}.mcap").exists():
            print(f"real: {directory / name}.mcap missing, skipped")
            continue
        rows += evaluate(name, directory, histories=hist)
    print(f"{'recording':36s} {'mode':22s} {'end°':>7s} {'rms°':>7s} {'tilt°':>7s} "
          f"{'rms tilt°':>9s} {'peak tilt°':>10s} {'rms head°':>9s} {'ns/sample':>10s}")
    for r in rows:
        print(f"{r['recording']:36s} {r['mode']:22s} {r['end_error_deg']:7.2f} "
              f"{r['rms_error_deg']:7.2f} {r['end_tilt_deg']:7.3f} {r['rms_tilt_deg']:9.3f} "
              f"{r['peak_tilt_deg']:10.2f} {r['rms_heading_deg']:9.2f} "
              f"{r['ns_per_sample']:10.0f}")
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
