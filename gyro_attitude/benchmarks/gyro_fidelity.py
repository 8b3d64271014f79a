"""Gyro-dynamics fidelity versus cost (suite ``gyro`` of ``gyro-attitude bench``).

Two-gimbal free gyro, 24 000 rpm class rotor on light gimbals, on a ship base (yaw rate,
roll oscillation, Earth rate at 45°N), gimbals started at rest relative to the case so that
the full model nutates.  For each fidelity level the wall-clock cost per simulated second
is measured next to its angle error against the precession-only solution (the model the
full equations converge to as H grows) and against a resolved full-model reference
(explicit RK4 at 80 steps per nutation period: the numerical error of the level itself).
Levels:

* ``precession``: technical equations, RK4 (cost independent of the rotor speed);
* ``full/midpoint``: gimbal inertia, implicit midpoint with steps longer than a nutation
  period (stable, cost independent of the rotor speed; the unresolved nutation is
  carried with the right amplitude but an aliased phase);
* ``full/rk4``: gimbal inertia, explicit RK4 resolving the nutation (20 steps per period;
  cost grows with H); and the same with a step longer than a nutation period, which
  diverges (reported as such) — the reason the default full-model integrator is implicit.

Also the single-gimbal rate-gyro triad (cost per sample, step-response error against the
closed form) and the heavy symmetric top (invariant drift after many steps, implicit
midpoint versus classical RK4 at the same step).  Figures depend on the machine and its
load: compare ratios within one run.
"""

from __future__ import annotations

import math
import pathlib
import time

import numpy as np

from gyro_attitude.core.earth import earth_rate_enu
from gyro_attitude.core.gyro.free_gyro import FreeGyroParams, FreeGyroSimulator
from gyro_attitude.core.gyro.rate_gyro import RateGyroParams, RateGyroTriad, rate_gyro_step_response
from gyro_attitude.core.rigid_body import (
    HeavyTop,
    heavy_top_invariants,
    heavy_top_state_from_euler,
    integrate_heavy_top,
)
from gyro_attitude.core.rotation import quat_conjugate, quat_from_rotvec, quat_rotate

SUITE = "gyro"
RPM = 2 * math.pi / 60.0
ROTOR = dict(spin_inertia=1e-4, transverse_inertia=5e-5)
LIGHT_GIMBALS = dict(inner_gimbal_inertia=(1e-5, 1.2e-5, 1e-5),
                     outer_gimbal_inertia=(2e-5, 2e-5, 3e-5))


def ship_base(lat_rad: float = math.radians(45.0), yaw_rate: float = 0.05,
              roll_amp: float = math.radians(8.0), roll_hz: float = 0.15):
    """ω_ib^b(t) of a ship yawing at ``yaw_rate`` and rolling ``roll_amp·sin(2π f t)``."""
    w_in = earth_rate_enu(lat_rad)
    wr = 2 * math.pi * roll_hz

    def omega(t):
        t = np.asarray(t, dtype=np.float64)
        yaw = quat_from_rotvec(np.outer(yaw_rate * t, [0.0, 0.0, 1.0]))
        roll_angle = roll_amp * np.sin(wr * t)
        roll = quat_from_rotvec(np.outer(roll_angle, [1.0, 0.0, 0.0]))
        # q_nb = yaw ⊗ roll; ω_in^b = C_bn ω_in^n; ω_nb^b = C(roll)ᵀ yaw_rate e_z + roll_rate e_x
        w_in_yaw = quat_rotate(quat_conjugate(yaw), np.broadcast_to(w_in, t.shape + (3,)))
        w_b = quat_rotate(quat_conjugate(roll), w_in_yaw + np.array([0.0, 0.0, yaw_rate]))
        w_b[:, 0] += roll_amp * wr * np.cos(wr * t)
        return w_b

    return omega


def _run(params: FreeGyroParams, omega, t: np.ndarray) -> tuple[np.ndarray, float, FreeGyroSimulator]:
    """Simulate; wall time is the best of up to 3 runs while a run takes < 0.3 s (the
    machine is shared, so the minimum is the least disturbed figure)."""
    best = math.inf
    for _ in range(3):
        sim = FreeGyroSimulator(params, omega)
        t0 = time.perf_counter()
        angles, _ = sim.run_until(t)
        wall = time.perf_counter() - t0
        best = min(best, wall)
        if wall > 0.3:
            break
    return angles, best, sim


def _max_angle_err(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(np.angle(np.exp(1j * (a - b))))))


def _free_gyro_rows(quick: bool) -> list[dict]:
    omega = ship_base()
    duration = 0.5 if quick else 2.0
    t = np.linspace(0.0, duration, 51)  # outputs every 10 ms (quick) / 40 ms
    spins_rpm = (6000.0, 24000.0) if quick else (6000.0, 24000.0, 96000.0)
    rows = []
    for rpm in spins_rpm:
        rotor = dict(ROTOR, spin_rate=rpm * RPM)
        prec_ref, _, _ = _run(FreeGyroParams(**rotor, max_step=1e-3), omega, t)
        full_kw = dict(rotor, **LIGHT_GIMBALS, model="full", initial_rates=(0.0, 0.0))
        full_ref_p = FreeGyroParams(**full_kw, integrator="rk4", steps_per_nutation=80.0)
        full_ref, _, _ = _run(full_ref_p, omega, t)
        nut_hz = full_ref_p.nutation_frequency_rad_s() / (2 * math.pi)
        levels = [
            ("precession", "rk4", FreeGyroParams(**rotor, max_step=1e-2)),
            ("full", "midpoint", FreeGyroParams(**full_kw, max_step=1e-2)),
            ("full", "midpoint", FreeGyroParams(**full_kw, max_step=2e-3)),
            ("full", "midpoint", FreeGyroParams(**full_kw, max_step=1 / (20 * nut_hz))),
            ("full", "rk4", FreeGyroParams(**full_kw, integrator="rk4", steps_per_nutation=20.0)),
            # explicit RK4 with a step of ~1.5 nutation periods: what the implicit rule avoids
            ("full", "rk4", FreeGyroParams(**full_kw, integrator="rk4", steps_per_nutation=0.7)),
        ]
        for model, integ, p in levels:
            try:
                angles, wall, sim = _run(p, omega, t)
            except ValueError as exc:  # blew up: non-finite state or runaway into gimbal lock
                rows.append({
                    "suite": SUITE, "case": "free_gyro_ship", "model": model,
                    "integrator": integ, "spin_rpm": rpm, "nutation_hz": nut_hz,
                    "step_s": 1 / (nut_hz * p.steps_per_nutation), "sim_seconds": duration,
                    "diverged": True, "error": str(exc), "wall_per_sim_s": float("nan"),
                    "err_vs_precession_rad": float("inf"), "err_vs_full_reference_rad": float("inf"),
                })
                continue
            rows.append({
                "suite": SUITE, "case": "free_gyro_ship", "model": model, "integrator": integ,
                "spin_rpm": rpm, "nutation_hz": nut_hz, "step_s": duration / max(sim.steps, 1),
                "sim_seconds": duration, "steps": sim.steps, "rhs_evaluations": sim.rhs_evaluations,
                "wall_s": wall, "wall_per_sim_s": wall / duration,
                "err_vs_precession_rad": _max_angle_err(angles, prec_ref),
                "err_vs_full_reference_rad": _max_angle_err(angles, full_ref),
                "diverged": not bool(np.all(np.isfinite(angles))),
            })
    base = {r["spin_rpm"]: r["wall_per_sim_s"] for r in rows if r["model"] == "precession"}
    for r in rows:
        r["cost_ratio_vs_precession"] = r["wall_per_sim_s"] / base[r["spin_rpm"]]
    return rows


def _rate_gyro_rows(quick: bool) -> list[dict]:
    rows = []
    n = 20_000 if quick else 200_000
    dt = 1e-3
    for hold in ("zoh", "foh"):
        p = RateGyroParams(30.0, 0.6, hold=hold)
        gyro = RateGyroTriad(p, dt, initial="rest")
        u = np.ones((n, 3))
        t0 = time.perf_counter()
        out = gyro.step_block(u)
        wall = time.perf_counter() - t0
        t = np.arange(n) * dt
        # starting at rest with the input 1 from t = 0 on: a unit step for both holds
        err = float(np.max(np.abs(out - rate_gyro_step_response(t, 30.0, 0.6)[:, None])))
        rows.append({
            "suite": SUITE, "case": "rate_gyro_step", "model": "rate_gyro", "integrator": hold,
            "samples": n, "wall_s": wall, "us_per_sample_triad": 1e6 * wall / n,
            "step_response_err": err,
        })
    return rows


def _heavy_top_rk4(top: HeavyTop, h0, g0, dt: float, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Classical RK4 on the same heavy-top equations, only as the non-structure-preserving
    comparison for :func:`integrate_heavy_top` (floats, like the midpoint loop)."""
    ijt, ijs, mgl = 1.0 / top.transverse_inertia, 1.0 / top.spin_inertia, top.mgl

    def f(x):
        h1, h2, h3, g1, g2, g3 = x
        w1, w2, w3 = h1 * ijt, h2 * ijt, h3 * ijs
        return (h2 * w3 - h3 * w2 + mgl * g2, h3 * w1 - h1 * w3 - mgl * g1, h1 * w2 - h2 * w1,
                g2 * w3 - g3 * w2, g3 * w1 - g1 * w3, g1 * w2 - g2 * w1)

    x = tuple(np.concatenate((h0, g0)).tolist())
    for _ in range(n):
        k1 = f(x)
        k2 = f(tuple(a + 0.5 * dt * b for a, b in zip(x, k1, strict=True)))
        k3 = f(tuple(a + 0.5 * dt * b for a, b in zip(x, k2, strict=True)))
        k4 = f(tuple(a + dt * b for a, b in zip(x, k3, strict=True)))
        x = tuple(a + dt / 6.0 * (b + 2 * c + 2 * d + e)
                  for a, b, c, d, e in zip(x, k1, k2, k3, k4, strict=True))
    return np.array([x[:3]]), np.array([x[3:]])


def _heavy_top_rows(quick: bool) -> list[dict]:
    """Invariant drift of the heavy symmetric top after many steps: implicit midpoint
    (conserves every quadratic invariant) against classical RK4 at the same step."""
    top = HeavyTop(transverse_inertia=1.0, spin_inertia=0.5, mgl=1.0)
    h0, g0 = heavy_top_state_from_euler(top, 0.6, 0.3, 0.5, 18.0)
    inv0 = heavy_top_invariants(top, h0, g0)
    n = 20_000 if quick else 100_000
    rows = []
    for dt in (1e-3, 1e-2):
        for name in ("midpoint", "rk4"):
            t0 = time.perf_counter()
            if name == "midpoint":
                h, g = integrate_heavy_top(top, h0, g0, dt, n, record_every=n)
            else:
                h, g = _heavy_top_rk4(top, h0, g0, dt, n)
            wall = time.perf_counter() - t0
            inv = heavy_top_invariants(top, h[-1], g[-1])
            rows.append({
                "suite": SUITE, "case": "heavy_top", "integrator": name, "step_s": dt,
                "steps": n, "wall_s": wall, "us_per_step": 1e6 * wall / n,
                **{f"rel_drift_{k}": float(abs(inv[k] - inv0[k]) / abs(inv0[k]))
                   for k in ("energy", "p_psi", "p_phi", "gamma_norm")},
            })
    return rows


def _print_table(free_rows: list[dict], rate_rows: list[dict]) -> None:
    print("Free gyro on a ship base (24 000 rpm class rotor, light gimbals, nutation excited)")
    head = (f"{'rpm':>7} {'nut Hz':>7} {'model':>10} {'integrator':>9} {'step s':>9} "
            f"{'wall/sim s':>10} {'x prec':>7} {'err vs prec':>11} {'err vs ref':>10}")
    print(head)
    print("-" * len(head))
    for r in free_rows:
        if r.get("diverged"):
            print(f"{r['spin_rpm']:7.0f} {r['nutation_hz']:7.0f} {r['model']:>10} "
                  f"{r['integrator']:>9} {r['step_s']:9.2e}   DIVERGED ({r.get('error', '')[:40]})")
            continue
        print(f"{r['spin_rpm']:7.0f} {r['nutation_hz']:7.0f} {r['model']:>10} {r['integrator']:>9} "
              f"{r['step_s']:9.2e} {r['wall_per_sim_s']:10.3g} {r['cost_ratio_vs_precession']:7.1f} "
              f"{r['err_vs_precession_rad']:11.2e} {r['err_vs_full_reference_rad']:10.2e}")
    print("\nRate-gyro triad (30 Hz, ζ = 0.6), unit step")
    for r in rate_rows:
        print(f"  hold={r['integrator']}: {r['us_per_sample_triad']:.2f} µs/sample (3 axes), "
              f"step-response error {r['step_response_err']:.2e}")


def _plot(rows: list[dict], out_dir: pathlib.Path) -> pathlib.Path | None:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return None
    fig, ax = plt.subplots(figsize=(7, 4.5))
    markers = {rpm: m for rpm, m in zip(sorted({r["spin_rpm"] for r in rows}), "os^dv",
                                         strict=False)}
    level = {}  # same colour for the same level at every rotor speed
    per_rpm: dict[float, int] = {}
    for r in rows:
        per_rpm[r["spin_rpm"]] = per_rpm.get(r["spin_rpm"], -1) + 1
        if r.get("diverged"):
            continue
        k = per_rpm[r["spin_rpm"]]
        level.setdefault(k, f"C{k}")
        label = f"{r['model']}/{r['integrator']} {r['spin_rpm']:.0f} rpm h={r['step_s']:.1e}"
        ax.scatter(r["wall_per_sim_s"], max(r["err_vs_full_reference_rad"], 1e-16),
                   color=level[k], marker=markers[r["spin_rpm"]], label=label)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("wall-clock seconds per simulated second")
    ax.set_ylabel("max gimbal-angle error vs resolved full model (rad)")
    ax.set_title("Free gyro: fidelity versus cost")
    ax.legend(fontsize=6)
    fig.tight_layout()
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / "gyro_fidelity.png"
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def run(quick: bool, out_dir: pathlib.Path) -> list[dict]:
    """Run the suite, print its table, write ``gyro_fidelity.png``; return the JSON rows."""
    free_rows = _free_gyro_rows(quick)
    rate_rows = _rate_gyro_rows(quick)
    top_rows = _heavy_top_rows(quick)
    _print_table(free_rows, rate_rows)
    print(f"\nHeavy symmetric top (J_t = 1, J_s = 0.5, mgl = 1, spin 18 rad/s), "
          f"{top_rows[0]['steps']} steps: relative invariant drift")
    print(f"  {'integrator':>10} {'step s':>7} {'µs/step':>8} {'energy':>9} {'p_psi':>9} "
          f"{'p_phi':>9} {'|Γ|':>9}")
    for r in top_rows:
        print(f"  {r['integrator']:>10} {r['step_s']:7.0e} {r['us_per_step']:8.2f} "
              f"{r['rel_drift_energy']:9.1e} {r['rel_drift_p_psi']:9.1e} "
              f"{r['rel_drift_p_phi']:9.1e} {r['rel_drift_gamma_norm']:9.1e}")
    path = _plot(free_rows, pathlib.Path(out_dir))
    if path is not None:
        print(f"plot: {path}")
    return free_rows + rate_rows + top_rows


if __name__ == "__main__":  # pragma: no cover
    import json
    import sys

    out = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else "bench_out")
    rows = run(quick="--quick" in sys.argv, out_dir=out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "gyro_fidelity.json").write_text(json.dumps(rows, indent=1))
