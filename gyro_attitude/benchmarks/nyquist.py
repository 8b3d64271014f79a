"""Rate fits toward the Nyquist rate (``bench --suite nyquist``): classical coning sampled at
100 Hz, its frequency swept toward Nyquist (Ωh → π), RMS attitude error against the closed form
(docs/equations.md) over 1 s and 10 s for ``exp_map``, each fitting kernel without the trust rule
and with it (:func:`gyro_attitude.core.attitude.interpolation.untrusted_fits`), and the number of
intervals that fell back.  The figures that chose ``FIT_TURN_MAX_RAD``."""

from __future__ import annotations

import numpy as np

import gyro_attitude.core.attitude.interpolation as ip
import gyro_attitude.core.attitude.streaming as streaming
from gyro_attitude.core.attitude import integrate_batch
from gyro_attitude.core.motion import coning_quat_and_rate
from gyro_attitude.core.rotation import quat_conjugate, quat_multiply

RATE_HZ = 100.0
OMEGA_H = (0.5, 1.0, 1.5, 2.0, 2.2, 2.4, 2.5, 2.6, 2.7, 2.8, 2.9, 3.0, 3.1)
ALPHAS_DEG = (0.3, 1.0, 5.0)
HORIZONS_S = (1.0, 10.0)
KERNELS = ("rotvec_cubic", "magnus6_quintic")


def _rms(q, truth) -> float:
    d = quat_multiply(quat_conjugate(truth), q)
    e = 2.0 * np.arctan2(np.linalg.norm(d[:, :3], axis=1), np.abs(d[:, 3]))
    return float(np.sqrt(np.mean(e * e)))


def _without_rule(fn):
    """``fn()`` with the rule off: in the vectorized offline kernel, and in the causal step run
    as Python (compiled code keeps the functions it was compiled with)."""
    saved = ip.untrusted_fits, ip.untrusted_fit_scalar, streaming.compiled
    ip.untrusted_fits = lambda *a, **k: None
    ip.untrusted_fit_scalar = lambda *a, **k: 0.0
    streaming.compiled = lambda f: f
    try:
        return fn()
    finally:
        ip.untrusted_fits, ip.untrusted_fit_scalar, streaming.compiled = saved


def run(quick: bool = False, out_dir=None) -> list[dict]:
    rows = []
    grid = (1.0, 2.0, 2.6, 3.0) if quick else OMEGA_H
    print(f"coning at {RATE_HZ:g} Hz; RMS attitude error (rad) against the closed form; "
          f"the trust rule turns toward exp_map from {ip.FIT_TURN_MAX_RAD:g} rad")
    print(f"{'kernel':16s} {'alpha':>5s} {'T s':>4s} {'Omega h':>7s} {'exp_map':>9s} "
          f"{'no rule':>9s} {'rule':>9s} {'fallbacks':>9s}")
    for horizon in HORIZONS_S[:1] if quick else HORIZONS_S:
        n = int(horizon * RATE_HZ) + 1
        t = 1_000_000_000 + np.arange(n, dtype=np.int64) * int(round(1e9 / RATE_HZ))
        tt = (t - t[0]) * 1e-9
        for kernel in KERNELS:
            for alpha in ALPHAS_DEG:
                for oh in grid:
                    q, w = coning_quat_and_rate(np.radians(alpha), oh * RATE_HZ, tt)
                    e_exp = _rms(integrate_batch(t, w, q0=q[0], algorithm="exp_map"), q)
                    e_off = _rms(_without_rule(lambda: integrate_batch(
                        t, w, q0=q[0], algorithm=kernel)), q)  # noqa: B023 (called at once)
                    fb = []
                    e_on = _rms(integrate_batch(t, w, q0=q[0], algorithm=kernel, fallbacks=fb), q)
                    count = int(sum(f.size for f in fb))
                    print(f"{kernel:16s} {alpha:5.1f} {horizon:4.0f} {oh:7.2f} {e_exp:9.2e} "
                          f"{e_off:9.2e} {e_on:9.2e} {count:9d}")
                    rows.append({"kernel": kernel, "alpha_deg": alpha, "horizon_s": horizon,
                                 "omega_h_rad": oh, "rate_hz": RATE_HZ, "rms_exp_map_rad": e_exp,
                                 "rms_without_rule_rad": e_off, "rms_with_rule_rad": e_on,
                                 "fallbacks": count, "intervals": n - 1})
    return rows
