"""Classical RK4 of the quaternion kinematics ``q̇ = ½ q ⊗ [ω, 0]``."""

from __future__ import annotations

import math

import numpy as np

from gyro_attitude.core.attitude.algorithm import RateAlgorithm
from gyro_attitude.core.attitude.compose import normalize_rows, qmul_scalar
from gyro_attitude.core.attitude.interpolation import (
    causal_fit_two,
    causal_rates_at,
    causal_window,
    hold_untrusted_rates,
)
from gyro_attitude.core.rotation import _qmul


def _pure(w: np.ndarray) -> np.ndarray:
    return np.concatenate((w, np.zeros(w.shape[:-1] + (1,))), axis=-1)


class QuatRK4(RateAlgorithm):
    """RK4 with ``ω(t_{k-1})``, the causal-cubic mid-step ``ω``, ``ω(t_k)``; normalized each
    step.  Truncates the spin angle: error ~θ⁵/… per step for ``θ = |ω|h`` — fast spin
    punishes it.  RK4 from ``q = 1``: since the right-hand side is linear under right
    multiplication, the step from any ``q`` is ``q ⊗ p`` with this ``p``.  Where the cubic
    cannot be trusted (near the Nyquist rate) all three rates move toward the endpoint mean,
    counted as the other fitted steps count it."""

    fits_rate_polynomial = True
    checks_rate_fit = True

    def body_increments(self, t_ns, omega, k, lookahead=False, fallbacks=None):
        h = ((t_ns[k] - t_ns[k - 1]) * 1e-9)[:, None]
        w0, w1 = omega[k - 1], omega[k]
        g = causal_rates_at(t_ns, omega, k, (0.5,), lookahead)
        wm = g[:, 0]
        hold_untrusted_rates(t_ns, omega, k, g, (w0, wm, w1),
                             causal_window(t_ns.size, lookahead), fallbacks)
        one = np.zeros(w0.shape[:-1] + (4,))
        one[..., 3] = 1.0
        p0, pm, p1 = _pure(w0), _pure(wm), _pure(w1)
        k1 = 0.5 * p0
        k2 = 0.5 * _qmul(one + 0.5 * h * k1, pm)
        k3 = 0.5 * _qmul(one + 0.5 * h * k2, pm)
        k4 = 0.5 * _qmul(one + h * k3, p1)
        return normalize_rows(one + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4))

    def body_increment_scalar(self, ts, ws, k, nodes):
        return self.body_increment_checked(ts, ws, k, nodes)[0]

    def body_increment_checked(self, ts, ws, k, nodes):
        wm, _, h, held = causal_fit_two(ts, ws, k, len(nodes), 0.5, 0.5)
        w0, w1 = ws[k - 1], ws[k]
        if held > 0.0:  # toward one constant rate, the endpoint mean (hold_untrusted_rates)
            keep = 1.0 - held
            mean = [0.5 * (w0[i] + w1[i]) for i in range(3)]
            w0, wm, w1 = ([keep * r[i] + held * mean[i] for i in range(3)] for r in (w0, wm, w1))

        def stage(p, scale, w):  # ½ (1 + scale·p) ⊗ [w, 0]
            q = (scale * p[0], scale * p[1], scale * p[2], 1.0 + scale * p[3])
            r = qmul_scalar(q, (w[0], w[1], w[2], 0.0))
            return (0.5 * r[0], 0.5 * r[1], 0.5 * r[2], 0.5 * r[3])

        k1 = (0.5 * w0[0], 0.5 * w0[1], 0.5 * w0[2], 0.0)
        k2 = stage(k1, 0.5 * h, wm)
        k3 = stage(k2, 0.5 * h, wm)
        k4 = stage(k3, h, w1)
        c = h / 6.0
        p = [c * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]) for i in range(4)]
        p[3] += 1.0
        n = math.sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2] + p[3] * p[3])
        return (p[0] / n, p[1] / n, p[2] / n, p[3] / n), held > 0.0


QUAT_RK4 = QuatRK4("quat_rk4", 4, "quaternion RK4, cubic-interpolated mid-step rate, normalized",
                   "cubic weights + 4 quaternion products per sample")
