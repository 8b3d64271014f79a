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

Also the single-gimbal rate-gyro triad: cost per sample and step-response error against
the closed form.  Figures depend on the machine and its load: compare ratios within one run.
"""

from __future__ import annotations

import math
import pathlib
import time

import numpy as np

from gyro_attitude.core.earth import earth_rate_enu
from gyro_attitude.core.gyro import (
    FreeGyroParams,
    FreeGyroSimulator,
    RateGyroParams,
    RateGyroTriad,
    rate_gyro_step_response,
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
    for r in rows:
        if r.get("diverged"):
            continue
        label = f"{r['model']}/{r['integrator']} {r['spin_rpm']:.0f} rpm h={r['step_s']:.1e}"
        ax.scatter(r["wall_per_sim_s"], max(r["err_vs_full_reference_rad"], 1e-16), label=label)
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
    _print_table(free_rows, rate_rows)
    path = _plot(free_rows, pathlib.Path(out_dir))
    if path is not None:
        print(f"plot: {path}")
    return free_rows + rate_rows


if __name__ == "__main__":  # pragma: no cover
    import json
    import sys

    out = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else "bench_out")
    rows = run(quick="--quick" in sys.argv, out_dir=out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "gyro_fidelity.json").write_text(json.dumps(rows, indent=1))
