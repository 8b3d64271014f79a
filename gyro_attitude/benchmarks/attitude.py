"""Benchmark suite ``attitude``: accuracy versus cost of every attitude algorithm.

For every algorithm × case × sample rate, both interfaces (batch and streaming), and peers
measured in the same run (a scipy ``Rotation`` composition loop, ``ahrs`` AngularRate and
numpy-quaternion's adaptive integrator), it records the attitude error against
closed-form (or scipy ``solve_ivp``) truth — final and maximum — the drift rate (slope of
the body-frame error rotation vector, least squares) and the cost in ns per sample.

Cases:

* ``coning``: classical coning (docs/equations.md) over a grid of half-angle α and frequency;
  rate algorithms get the rates, increment algorithms both exact increments
  (``coningN[exact]``) and trapezoid increments from the rates (``coningN[trapezoid]``).
* ``spinning_coning``: a fast spin about body z on top of coning,
  ``q = q_cone(t) ⊗ exp(s t z)``: RK4's truncation of the spin angle and low-order
  quadrature show here.
* ``smooth_random``: sums of sinusoids on all axes; truth from ``solve_ivp`` (DOP853,
  rtol 1e-13).
* ``near_singular`` / ``nearer_singular``: constant-rate tumble whose body z passes
  0.02 / 0.002 rad from the vertical (z-x-z θ dips to that): the z-x-z Euler baseline
  loses accuracy or is flagged (GimbalLockError), the quaternion methods sail through.
  (Classical coning itself takes body z through the vertical: z-x-z is flagged there.)
* ``earth_rate_24h``: a body at rest in ENU at 45° latitude for 24 simulated hours at
  100 Hz, integrated in the navigation frame (truth: the attitude stays put); also the
  quaternion norm error.
* ``order_slope``: the ``spinning_projectile`` scene's motion (spin 50 rev/s about body x,
  2° coning at 5 Hz; closed form in :class:`gyro_attitude.core.motion.SpinningProjectile`)
  for 10 s at several sample rates: the final error of the offline ``magnus6_quintic`` and
  of ``rotvec_cubic`` per rate, and the measured order (slope of log error over log h).

Offline algorithms (``causal`` False) run in batch only: they need samples after each
interval, which a stream does not have.

Plus the coning drift of N = 1..4 (and one-sample-plus-previous) against theory
ρ_N α² Ω (Ωh)^{2N} with exact increments, and throughput figures for the targets.
Timings on a shared machine are noisy: each row carries ns per sample, and the summary
quotes ratios against the scipy loop measured in the same run.
"""

from __future__ import annotations

import math
import pathlib
import signal
import time
import warnings

import numpy as np
from scipy.integrate import solve_ivp
from scipy.spatial.transform import Rotation

from gyro_attitude.benchmarks import machine_description
from gyro_attitude.core.attitude import (
    ALGORITHMS,
    CONING_DRIFT_RHO,
    DEFAULT_ALGORITHM,
    DEFAULT_OFFLINE_ALGORITHM,
    GimbalLockError,
    NavFrame,
    StreamingIntegrator,
    integrate_batch,
    integrate_increments_batch,
)
from gyro_attitude.core.earth import earth_rate_enu
from gyro_attitude.core.motion import SpinningProjectile

SUITE = "attitude"

# Problem sizes; the CLI smoke test shrinks "quick" further by patching this dict.
SIZES: dict[str, dict] = {
    "quick": dict(rates=(100.0, 1000.0), duration=2.0, stream_cap=400, euler_cap=2001,
                  peer_cap=2001, npq_duration=0.5, npq_timeout=5.0,
                  grid=((0.1, 1.0), (0.1, 10.0)), spins=(300.0,), earth_hours=24.0,
                  earth_algs=("rotvec_cubic",), theory_pers=(12, 24), throughput_n=500_000,
                  stream_n=20_000, slope_rates=(500.0, 1000.0, 2000.0), slope_duration=10.0),
    "full": dict(rates=(100.0, 1000.0, 10000.0), duration=10.0, stream_cap=5000,
                 euler_cap=20001, peer_cap=20001, npq_duration=2.0, npq_timeout=20.0,
                 grid=((0.1, 1.0), (0.1, 10.0), (0.01, 1.0), (0.01, 10.0), (0.5, 5.0)),
                 spins=(100.0, 600.0), earth_hours=24.0,
                 earth_algs=("rotvec_cubic", "exp_map", "quat_rk4", "coning2"),
                 theory_pers=(12, 24, 48, 96), throughput_n=2_000_000, stream_n=100_000,
                 slope_rates=(250.0, 500.0, 1000.0, 2000.0, 4000.0), slope_duration=10.0),
}


# ----------------------------------------------------------------------------- motions
class Motion:
    """A motion with truth attitude ``q(t)`` (scalar-last) and body rate ``ω(t)``."""

    name = "motion"
    alpha = None
    omega = None
    spin = None

    def truth(self, t: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def rate(self, t: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def increments(self, t: np.ndarray) -> np.ndarray | None:
        return None  # exact increments only where a closed form exists


class Coning(Motion):
    name = "coning"

    def __init__(self, alpha: float, omega: float, spin: float = 0.0):
        self.alpha, self.omega, self.spin = alpha, omega, spin
        if spin:
            self.name = "spinning_coning"

    def _cone(self, t):
        s, c = math.sin(self.alpha / 2), math.cos(self.alpha / 2)
        return np.stack([np.zeros_like(t), s * np.cos(self.omega * t),
                         s * np.sin(self.omega * t), np.full_like(t, c)], axis=-1)

    def _cone_rate(self, t):
        om, a = self.omega, self.alpha
        return np.stack([np.full_like(t, -2 * om * math.sin(a / 2) ** 2),
                         -om * math.sin(a) * np.sin(om * t), om * math.sin(a) * np.cos(om * t)],
                        axis=-1)

    def truth(self, t):
        r = Rotation.from_quat(self._cone(t))
        if self.spin:
            r = r * Rotation.from_rotvec(np.outer(t, [0.0, 0.0, self.spin]))
        return r.as_quat()

    def rate(self, t):
        w = self._cone_rate(t)
        if self.spin:
            # q = q_cone ⊗ q_spin: ω_b = C_spinᵀ ω_cone + s z
            w = Rotation.from_rotvec(np.outer(t, [0.0, 0.0, self.spin])).inv().apply(w)
            w[:, 2] += self.spin
        return w

    def increments(self, t):
        if self.spin:
            return None
        h = np.diff(t)
        tm = t[:-1] + h / 2
        om, a = self.omega, self.alpha
        return np.stack([-2 * om * h * math.sin(a / 2) ** 2,
                         -2 * math.sin(a) * np.sin(om * h / 2) * np.sin(om * tm),
                         2 * math.sin(a) * np.sin(om * h / 2) * np.cos(om * tm)], axis=-1)


class SmoothRandom(Motion):
    name = "smooth_random"

    def __init__(self, seed: int = 5, scale: float = 2.0, duration: float = 10.0):
        rng = np.random.default_rng(seed)
        self.amp = rng.uniform(-1, 1, (3, 4)) * scale / 2
        self.freq = rng.uniform(0.2, 3.0, (3, 4)) * 2 * np.pi
        self.phase = rng.uniform(0, 2 * np.pi, (3, 4))
        self.q0 = Rotation.from_rotvec([0.3, -0.2, 0.5]).as_quat()
        self._sol = None
        self._t_end = duration

    def rate(self, t):
        t = np.asarray(t)[..., None, None]
        return (self.amp * np.sin(self.freq * t + self.phase)).sum(-1)

    def truth(self, t):
        if self._sol is None or t[-1] > self._t_end:
            self._t_end = max(self._t_end, float(t[-1]))

            def f(tt, q):
                w = self.rate(tt)
                x, y, z, s = q
                # q̇ = ½ q ⊗ [ω, 0], written out (independent of the package's product)
                return 0.5 * np.array([s * w[0] + y * w[2] - z * w[1],
                                       s * w[1] + z * w[0] - x * w[2],
                                       s * w[2] + x * w[1] - y * w[0],
                                       -x * w[0] - y * w[1] - z * w[2]])

            self._sol = solve_ivp(f, (0.0, self._t_end), self.q0, method="DOP853", rtol=1e-13,
                                  atol=1e-14, dense_output=True).sol
        q = self._sol(t).T
        return q / np.linalg.norm(q, axis=1, keepdims=True)


class Tumble(Motion):
    """Constant body rate about body x; body z passes ``tilt`` rad from the vertical at
    t = 0.6 s/rate (z-x-z θ dips to ``tilt``, where ψ̇ ~ 1/sin θ)."""

    def __init__(self, rate: float, tilt: float, name: str):
        self.name = name
        self.w = np.array([rate, 0.0, 0.0])
        self.omega = rate
        self.q0 = (Rotation.from_rotvec([0.0, tilt, 0.0]) * Rotation.from_rotvec([-0.6, 0, 0])
                   ).as_quat()

    def truth(self, t):
        return (Rotation.from_quat(self.q0) * Rotation.from_rotvec(np.outer(t, self.w))).as_quat()

    def rate(self, t):
        return np.tile(self.w, (t.size, 1))


# ----------------------------------------------------------------------------- metrics
def _errors(q, q_true, t):
    """Final and max attitude error (rad) and drift rate (rad/s): scipy, sign-immune."""
    err = (Rotation.from_quat(q_true).inv() * Rotation.from_quat(q)).as_rotvec()
    ang = np.linalg.norm(err, axis=1)
    if t.size > 2:
        slope = np.polyfit(t - t[0], err, 1)[0]
        drift = float(np.linalg.norm(slope))
    else:
        drift = float("nan")
    return float(ang[-1]), float(ang.max()), drift


def _timed(fn, min_time=0.02, max_repeat=5):
    """Run ``fn``; repeat short runs (best of up to 5 within ~min_time) for a stable cost."""
    best, out, total, reps = float("inf"), None, 0.0, 0
    while reps < max_repeat:
        t0 = time.perf_counter()
        out = fn()
        dt = time.perf_counter() - t0
        best = min(best, dt)
        total += dt
        reps += 1
        if total > min_time:
            break
    return out, best


def _variants(motion: Motion, has_exact: bool):
    """(label, algorithm, input kind) for every algorithm and increment source."""
    out = []
    for name, info in ALGORITHMS.items():
        if info.consumes == "rate":
            out.append((name, name, "rate"))
        else:
            if has_exact:
                out.append((f"{name}[exact]", name, "exact"))
            out.append((f"{name}[trapezoid]", name, "trapezoid"))
    return out


def _row(label, interface, case, motion, rate_hz, duration, ns, errs, status="ok", **extra):
    final, mx, drift = errs if errs is not None else (None, None, None)
    row = {
        "suite": SUITE, "algorithm": label, "interface": interface, "case": case,
        "rate_hz": float(rate_hz), "alpha_rad": motion.alpha, "omega_rad_s": motion.omega,
        "spin_rad_s": motion.spin, "duration_s": float(duration),
        "ns_per_sample": None if ns is None else float(ns),
        "final_error_rad": final, "max_error_rad": mx, "drift_rad_s": drift, "status": status,
    }
    row.update(extra)
    return row


def _run_one(motion, label, alg, kind, rate_hz, duration, stream_cap, euler_cap):
    rows = []
    n = int(round(duration * rate_hz)) + 1
    info = ALGORITHMS[alg]
    truncated = {}
    if info.sequential and n > euler_cap:
        # Python loop at ~65 µs/sample: run the first euler_cap samples only (shorter
        # duration_s in the row, so compare errors with that in mind)
        truncated = {"truncated_from_n": n}
        n = euler_cap
    step = int(round(1e9 / rate_hz))
    t_ns = np.arange(n, dtype=np.int64) * step
    t = t_ns * 1e-9
    q_true = motion.truth(t)
    w = motion.rate(t)
    d = motion.increments(t) if kind == "exact" else None
    quad = kind if kind in ("trapezoid", "cubic") else "trapezoid"

    def batch():
        if kind == "exact":
            return integrate_increments_batch(t_ns, d, q_true[0], alg)
        return integrate_batch(t_ns, w, q_true[0], alg, quadrature=quad)

    try:
        q, dt = _timed(batch)
        rows.append(_row(label, "batch", motion.name, motion, rate_hz, t[-1], dt / (n - 1) * 1e9,
                         _errors(q, q_true, t), n_samples=n, **truncated))
    except GimbalLockError as err:
        rows.append(_row(label, "batch", motion.name, motion, rate_hz, t[-1], None, None,
                         status="flagged_singular", n_samples=n, message=str(err)[:160]))
    if not info.causal:
        return rows  # offline: batch only
    ns = min(n, stream_cap)
    s = StreamingIntegrator(alg, q_true[0], quadrature=quad, t0_ns=None)
    q = np.empty((ns, 4))
    try:
        t0 = time.perf_counter()
        if kind == "exact":
            s.reset(q_true[0], int(t_ns[0]))
            q[0] = q_true[0]
            for i in range(1, ns):
                q[i] = s.update_increment(int(t_ns[i]), d[i - 1])
        else:
            for i in range(ns):
                q[i] = s.update(int(t_ns[i]), w[i])
        dt = time.perf_counter() - t0
        rows.append(_row(label, "streaming", motion.name, motion, rate_hz, t[ns - 1],
                         dt / ns * 1e9, _errors(q, q_true[:ns], t[:ns]), n_samples=ns))
    except GimbalLockError as err:
        rows.append(_row(label, "streaming", motion.name, motion, rate_hz, t[ns - 1], None, None,
                         status="flagged_singular", n_samples=ns, message=str(err)[:160]))
    return rows


def _npq_child(t, w, q0, conn):
    """Child process: numpy-quaternion's integrator (see :func:`_numpy_quaternion_peer`)."""
    # A forked child inherits the parent's Python signal handlers: under the CLI, SIGTERM
    # would raise KeyboardInterrupt inside scipy's ODE callback (swallowed there, so the
    # hung loop spins on) and repeats are ignored. The default action lets terminate() end it.
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    try:
        import quaternion as npq
        from scipy.interpolate import CubicSpline
    except ImportError as err:
        conn.send(f"missing: {err}")
        return
    spline = CubicSpline(t, w)

    def omega_fixed(tt, rr):
        # numpy-quaternion integrates Ṙ = ½ Ω R with Ω in the fixed frame: Ω = R ω_b R̄
        v = rr * npq.quaternion(0.0, *spline(tt)) * rr.conjugate()
        return np.array([v.x, v.y, v.z])

    x, y, z, s = q0
    t0 = time.perf_counter()
    _, rs = npq.integrate_angular_velocity(omega_fixed, float(t[0]), float(t[-1]),
                                           npq.quaternion(s, x, y, z), tolerance=1e-10)
    dt = time.perf_counter() - t0
    f = npq.as_float_array(rs[-1])
    conn.send((np.array([f[1], f[2], f[3], f[0]]), dt))


def _numpy_quaternion_peer(t, w, q0, timeout_s):
    """Run numpy-quaternion's ``integrate_angular_velocity`` in a child process.

    Its callable-Ω path steps scipy's ``ode('dop853')`` in a ``while t < t1`` loop; on
    some inputs here (10 Hz coning) the solver stops advancing and the loop never ends
    (numpy-quaternion 2024.0.13), so the peer runs with a timeout and a hang is reported.
    """
    import multiprocessing as mp

    ctx = mp.get_context("fork")
    parent, child = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_npq_child, args=(t, w, q0, child), daemon=True)
    proc.start()
    try:
        if parent.poll(timeout_s):
            return parent.recv()
        return f"hung: no result within {timeout_s:g} s (its ode step loop stopped advancing)"
    finally:
        parent.close()
        if proc.is_alive():
            proc.terminate()
        proc.join(1.0)
        if proc.is_alive():  # SIGTERM blocked or ignored after all: SIGKILL cannot be
            proc.kill()
            proc.join(1.0)


def _peers(motion, rate_hz, duration, cap, npq_duration, npq_timeout=5.0):
    """scipy Rotation loop, ahrs AngularRate, numpy-quaternion (each where it imports)."""
    rows = []
    n = min(int(round(duration * rate_hz)) + 1, cap)
    step = int(round(1e9 / rate_hz))
    t = np.arange(n, dtype=np.int64) * step * 1e-9
    q_true = motion.truth(t)
    w = motion.rate(t)
    h = step * 1e-9

    # scipy: compose one Rotation per sample (trapezoid rotation vector, exp map).
    t0 = time.perf_counter()
    r = Rotation.from_quat(q_true[0])
    q = np.empty((n, 4))
    q[0] = r.as_quat()
    for i in range(1, n):
        r = r * Rotation.from_rotvec(0.5 * (w[i - 1] + w[i]) * h)
        q[i] = r.as_quat()
    dt = time.perf_counter() - t0
    rows.append(_row("scipy_rotation_loop", "peer", motion.name, motion, rate_hz, t[-1],
                     dt / n * 1e9, _errors(q, q_true, t), n_samples=n))
    try:
        from ahrs.filters import AngularRate
    except ImportError as err:  # pragma: no cover - depends on the environment
        rows.append(_row("ahrs_angular_rate", "peer", motion.name, motion, rate_hz, t[-1], None,
                         None, status=f"missing: {err}"))
    else:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            t0 = time.perf_counter()
            # ahrs is scalar-first; its default "closed" method uses the rate of sample k
            # held over the step into k (rectangle rule with the newer sample).
            est = AngularRate(gyr=w, q0=np.roll(q_true[0], 1), frequency=rate_hz)
            dt = time.perf_counter() - t0
        q = np.roll(np.asarray(est.Q), -1, axis=1)
        rows.append(_row("ahrs_angular_rate", "peer", motion.name, motion, rate_hz, t[-1],
                         dt / n * 1e9, _errors(q, q_true, t), n_samples=n))
    m = min(n, int(round(npq_duration * rate_hz)) + 1)
    result = _numpy_quaternion_peer(t[:m], w[:m], q_true[0], timeout_s=npq_timeout)
    if isinstance(result, str):
        rows.append(_row("numpy_quaternion_integrate", "peer", motion.name, motion, rate_hz,
                         t[m - 1], None, None, status=result, n_samples=m))
    else:
        qf, dt = result
        err = float(np.linalg.norm((Rotation.from_quat(q_true[m - 1]).inv()
                                    * Rotation.from_quat(qf)).as_rotvec()))
        rows.append(_row("numpy_quaternion_integrate", "peer", motion.name, motion, rate_hz,
                         t[m - 1], dt / m * 1e9, (err, None, None), n_samples=m,
                         note="adaptive DOP853 on a cubic spline of the samples; final only"))
    return rows


# ----------------------------------------------------------------------------- special runs
def _coning_theory(pers):
    """Drift of N-sample coning algorithms with exact increments vs ρ_N α² Ω (Ωh)^{2N}."""
    rows = []
    alpha, h_ns = 1e-3, 1_000_000
    h = h_ns * 1e-9
    for per in pers:
        omega = 2 * math.pi / (per * h)
        motion = Coning(alpha, omega)
        n = per * 20
        t_ns = np.arange(n + 1, dtype=np.int64) * h_ns
        t = t_ns * 1e-9
        q_true = motion.truth(t)
        d = motion.increments(t)
        idx = np.arange(0, n + 1, per)  # whole periods (and whole N-blocks)
        for alg, n_code in (("coning1", 1), ("coning1_prev", 0), ("coning2", 2),
                            ("coning3", 3), ("coning4", 4)):
            q = integrate_increments_batch(t_ns, d, q_true[0], alg)
            err = (Rotation.from_quat(q_true[idx]).inv() * Rotation.from_quat(q[idx])).as_rotvec()
            drift = float(np.linalg.norm(np.polyfit(t[idx], err, 1)[0]))
            rho, p = (1 / 60, 4) if n_code == 0 else (CONING_DRIFT_RHO[n_code], 2 * n_code)
            theory = rho * alpha**2 * omega * (omega * h) ** p
            row = _row(f"{alg}[exact]", "batch", "coning_theory", motion, 1 / h, t[-1], None,
                       (float(np.linalg.norm(err[-1])), None, drift), omega_h=omega * h,
                       theory_drift_rad_s=theory, drift_ratio=drift / theory,
                       above_float_floor=bool(theory * t[-1] > 1e-12))
            rows.append(row)
    return rows


def _earth_24h(hours, algs):
    rows = []
    lat = math.radians(45.0)
    q_nb = Rotation.from_euler("ZYX", [0.8, 0.05, -0.02]).as_quat()
    n = int(hours * 3600 * 100) + 1
    t_ns = np.arange(n, dtype=np.int64) * 10_000_000
    w = np.broadcast_to(Rotation.from_quat(q_nb).inv().apply(earth_rate_enu(lat)), (n, 3))
    motion = Motion()
    motion.name = "earth_rate_24h"
    motion.omega = 7.292115e-5
    for alg in algs:
        t0 = time.perf_counter()
        q = integrate_batch(t_ns, w, q_nb, alg, nav=NavFrame(lat))
        dt = time.perf_counter() - t0
        sel = np.unique(np.append(np.arange(0, n, 100), n - 1))  # 1/s for the statistics
        errs = _errors(q[sel], np.broadcast_to(q_nb, (sel.size, 4)), t_ns[sel] * 1e-9)
        norm_err = float(np.abs(np.linalg.norm(q, axis=1) - 1.0).max())
        rows.append(_row(alg, "batch", motion.name, motion, 100.0, (n - 1) / 100, dt / n * 1e9,
                         errs, latitude_rad=lat, norm_error=norm_err, n_samples=n))
        del q
    return rows


def _order_slopes(rates, duration):
    """Final error after ``duration`` s on the spinning projectile per sample rate, and the
    order between neighbouring rates: log(e_i / e_{i+1}) / log(h_i / h_{i+1})."""
    rows = []
    projectile = SpinningProjectile(2 * math.pi * 50.0, math.radians(2.0), 2 * math.pi * 5.0)
    motion = Motion()
    motion.name = "order_slope"
    motion.alpha, motion.omega, motion.spin = projectile.half_angle, projectile.omega, \
        projectile.spin_rate
    for alg in ("rotvec_cubic", DEFAULT_OFFLINE_ALGORITHM):
        prev = None
        for rate_hz in sorted(rates):
            step = int(round(1e9 / rate_hz))
            n = int(round(duration * rate_hz)) + 1
            t_ns = np.arange(n, dtype=np.int64) * step
            truth = projectile.evaluate(t_ns * 1e-9)
            q, dt = _timed(lambda t=t_ns, s=truth, a=alg: integrate_batch(
                t, s.omega_nb_b, s.q_nb[0], a))
            errs = _errors(q, truth.q_nb, t_ns * 1e-9)
            slope = None
            if prev is not None and errs[0] > 0 and prev[1] > 0:
                slope = math.log(prev[1] / errs[0]) / math.log(rate_hz / prev[0])
            rows.append(_row(alg, "batch", "order_slope", motion, rate_hz, (n - 1) * step * 1e-9,
                             dt / n * 1e9, errs, n_samples=n, order_from_previous_rate=slope,
                             nominal_order=ALGORITHMS[alg].order))
            prev = (rate_hz, errs[0])
    return rows


def _throughput(n, m):
    """Samples per second on long constant-rate runs (targets) and streaming µs/sample."""
    rows = []
    t_ns = np.arange(n, dtype=np.int64) * 1_000_000
    w = np.random.default_rng(1).normal(0, 0.5, (n, 3))
    motion = Motion()
    motion.name = "throughput"
    for alg in ("exp_map", "rotvec_trapezoid", "rotvec_cubic", "quat_rk4", "coning1_prev",
                "coning2", "coning4", DEFAULT_OFFLINE_ALGORITHM):
        _, dt = _timed(lambda a=alg: integrate_batch(t_ns, w, algorithm=a), min_time=0.0,
                       max_repeat=2)
        rows.append(_row(alg, "batch", "throughput", motion, 1000.0, n * 1e-3, dt / n * 1e9,
                         None, status="timing_only", samples_per_s=n / dt, n_samples=n))
    for alg in (DEFAULT_ALGORITHM, "exp_map", "coning2", "quat_rk4"):
        mm = m if alg in (DEFAULT_ALGORITHM, "exp_map", "quat_rk4") else m // 10
        s = StreamingIntegrator(alg)
        t0 = time.perf_counter()
        for i in range(mm):
            s.update(int(t_ns[i]), w[i])
        dt = time.perf_counter() - t0
        rows.append(_row(alg, "streaming", "throughput", motion, 1000.0, mm * 1e-3,
                         dt / mm * 1e9, None, status="timing_only", samples_per_s=mm / dt,
                         n_samples=mm))
    return rows


# ----------------------------------------------------------------------------- output
def _fmt(x, spec=".2e"):
    return "-" if x is None or (isinstance(x, float) and math.isnan(x)) else format(x, spec)


def _print_table(rows):
    head = (f"{'case':16s} {'rate':>6s} {'algorithm':26s} {'iface':9s} {'ns/sample':>10s} "
            f"{'final':>9s} {'max':>9s} {'drift':>9s}  status")
    print(head)
    print("-" * len(head))
    for r in rows:
        if r["case"] in ("coning_theory", "throughput", "order_slope"):
            continue
        extra = ""
        if r["alpha_rad"] is not None and r["case"] in ("coning", "spinning_coning"):
            extra = f" a={r['alpha_rad']:.2g} W={r['omega_rad_s']:.3g}"
            if r.get("spin_rad_s"):
                extra += f" s={r['spin_rad_s']:.3g}"
        if "norm_error" in r:
            extra = f" norm_err={r['norm_error']:.1e}"
        if r["interface"] == "streaming" or "truncated_from_n" in r:
            extra += f" (first {r['duration_s']:.3g} s)"
        print(f"{r['case']:16s} {r['rate_hz']:6.0f} {r['algorithm']:26s} {r['interface']:9s} "
              f"{_fmt(r['ns_per_sample'], '10.0f'):>10s} {_fmt(r['final_error_rad']):>9s} "
              f"{_fmt(r['max_error_rad']):>9s} {_fmt(r['drift_rad_s']):>9s}  "
              f"{r['status']}{extra}")


def _print_theory(rows):
    print("\nConing drift with exact increments vs theory rho_N a^2 W (Wh)^(2N), a = 1e-3:")
    print(f"{'algorithm':20s} {'Wh':>6s} {'measured':>10s} {'theory':>10s} {'ratio':>7s}  floor")
    for r in rows:
        print(f"{r['algorithm']:20s} {r['omega_h']:6.3f} {r['drift_rad_s']:10.3e} "
              f"{r['theory_drift_rad_s']:10.3e} {r['drift_ratio']:7.3f}  "
              f"{'above' if r['above_float_floor'] else 'BELOW (ratio meaningless)'}")


def _print_slopes(rows):
    print("\nOrder on the spinning projectile (spin 50 rev/s + 2 deg coning at 5 Hz), final "
          "error after the run; order = slope of log error over log h against the rate before:")
    print(f"{'algorithm':18s} {'rate':>6s} {'final':>9s} {'order':>6s} {'ns/sample':>10s}")
    for r in rows:
        order = r["order_from_previous_rate"]
        print(f"{r['algorithm']:18s} {r['rate_hz']:6.0f} {r['final_error_rad']:9.2e} "
              f"{_fmt(order, '6.2f'):>6s} {r['ns_per_sample']:10.0f}")


def _print_targets(throughput, earth, peers):
    print("\nTargets (this machine, shared, noisy):")
    by = {(r["algorithm"], r["interface"]): r for r in throughput}
    for alg in ("exp_map", "rotvec_cubic", "coning2", "coning4", "rotvec_trapezoid",
                "quat_rk4", "coning1_prev", DEFAULT_OFFLINE_ALGORITHM):
        r = by.get((alg, "batch"))
        if r:
            print(f"  batch {alg:18s} {r['samples_per_s'] / 1e6:6.2f} M samples/s")
    for alg in (DEFAULT_ALGORITHM, "exp_map", "coning2", "quat_rk4"):
        r = by.get((alg, "streaming"))
        if r:
            print(f"  streaming {alg:14s} {r['ns_per_sample'] / 1e3:6.2f} us/sample")
    for r in earth:
        print(f"  earth {r['duration_s'] / 3600:.3g} h @100 Hz nav frame, {r['algorithm']:14s}: max error "
              f"{r['max_error_rad']:.2e} rad, norm error {r['norm_error']:.1e}, "
              f"{r['ns_per_sample']:.0f} ns/sample")
    scipy_ns = [r["ns_per_sample"] for r in peers if r["algorithm"] == "scipy_rotation_loop"]
    if scipy_ns and by.get((DEFAULT_ALGORITHM, "batch")):
        ref = float(np.median(scipy_ns))
        print(f"  scipy Rotation loop (median over cases): {ref:.0f} ns/sample; "
              f"batch {DEFAULT_ALGORITHM} is {ref / by[(DEFAULT_ALGORITHM, 'batch')]['ns_per_sample']:.0f}x "
              f"faster, streaming "
              f"{ref / by[(DEFAULT_ALGORITHM, 'streaming')]['ns_per_sample']:.1f}x")


def _pareto_plot(rows, out_dir: pathlib.Path):
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:  # pragma: no cover
        print("matplotlib not available: no Pareto plot")
        return None
    cases = [c for c in ("smooth_random", "spinning_coning", "coning") if
             any(r["case"] == c for r in rows)]
    fig, axes = plt.subplots(1, len(cases), figsize=(6.5 * len(cases), 5.5), squeeze=False)
    names = sorted({r["algorithm"] for r in rows if r["case"] in cases})
    colors = plt.get_cmap("tab10")
    markers = "os^vDPX*<>h"
    style = {name: (colors(i % 10), markers[i % len(markers)]) for i, name in enumerate(names)}
    for ax, case in zip(axes[0], cases, strict=True):
        sel = [r for r in rows if r["case"] == case and r["final_error_rad"] is not None
               and r["ns_per_sample"] is not None and r["interface"] in ("batch", "peer")]
        for name in names:
            pts = [(r["ns_per_sample"], max(r["final_error_rad"], 1e-17))
                   for r in sel if r["algorithm"] == name]
            if not pts:
                continue
            x, y = zip(*pts, strict=True)
            color, marker = style[name]
            peer = name in {r["algorithm"] for r in sel if r["interface"] == "peer"}
            ax.scatter(x, y, s=30 if peer else 20, color=color, marker=marker,
                       facecolors="none" if peer else color, label=name)
        # Pareto front: points no other point beats in both cost and error.
        pts = sorted((r["ns_per_sample"], max(r["final_error_rad"], 1e-17)) for r in sel)
        front, best = [], float("inf")
        for x, y in pts:
            if y < best:
                front.append((x, y))
                best = y
        if front:
            fx, fy = zip(*front, strict=True)
            ax.step(fx, fy, where="post", color="k", lw=0.8, alpha=0.6, label="Pareto front")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("cost, ns per sample (batch; peers hollow)")
        ax.set_ylabel("final attitude error, rad")
        ax.set_title(f"{case}: all sample rates and parameters")
        ax.grid(True, which="both", alpha=0.3)
    handles, labels = axes[0][0].get_legend_handles_labels()
    seen = dict(zip(labels, handles, strict=True))
    for ax in axes[0][1:]:
        for h, lab in zip(*ax.get_legend_handles_labels(), strict=True):
            seen.setdefault(lab, h)
    fig.legend(list(seen.values()), list(seen.keys()), fontsize=7, loc="center right")
    fig.subplots_adjust(right=0.84)
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / "attitude_pareto.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    print(f"\nPareto plot: {path}")
    return path


# ----------------------------------------------------------------------------- entry point
def run(quick: bool, out_dir: pathlib.Path) -> list[dict]:
    """Run the suite; print tables, write ``attitude_pareto.png``, return JSON rows."""
    out_dir = pathlib.Path(out_dir)
    cfg = SIZES["quick" if quick else "full"]
    rates, duration = cfg["rates"], cfg["duration"]
    stream_cap, euler_cap, peer_cap = cfg["stream_cap"], cfg["euler_cap"], cfg["peer_cap"]
    # grid: (half-angle α rad, cone frequency Hz)
    motions: list[Motion] = [Coning(a, 2 * math.pi * f) for a, f in cfg["grid"]]
    motions += [Coning(0.05, 2 * math.pi * 2, spin=s) for s in cfg["spins"]]
    motions += [SmoothRandom(duration=duration), Tumble(1.0, 0.02, "near_singular"),
                Tumble(1.0, 0.002, "nearer_singular")]

    m = machine_description()
    print(f"attitude benchmark ({'quick' if quick else 'full'}): {m['cpu_model']}, "
          f"{m['cpu_count']} CPUs, load {m['load_avg_1min']}, numpy {m['numpy']}; "
          f"default = {DEFAULT_ALGORITHM}")
    rows: list[dict] = []
    peers: list[dict] = []
    for motion in motions:
        has_exact = motion.increments(np.array([0.0, 0.01])) is not None
        for rate_hz in rates:
            for label, alg, kind in _variants(motion, has_exact):
                rows += _run_one(motion, label, alg, kind, rate_hz,
                                 duration if not isinstance(motion, Tumble) else 2 * duration,
                                 stream_cap, euler_cap)
            peers += _peers(motion, rate_hz, duration, peer_cap, cfg["npq_duration"],
                            cfg["npq_timeout"])
    rows += peers
    earth = _earth_24h(cfg["earth_hours"], cfg["earth_algs"])
    theory = _coning_theory(cfg["theory_pers"])
    throughput = _throughput(cfg["throughput_n"], cfg["stream_n"])
    slopes = _order_slopes(cfg.get("slope_rates", (500.0, 1000.0, 2000.0)),
                           cfg.get("slope_duration", 1.0))
    _print_table(rows + earth)
    _print_theory(theory)
    _print_slopes(slopes)
    _print_targets(throughput, earth, peers)
    _pareto_plot(rows, out_dir)
    return rows + earth + theory + throughput + slopes
