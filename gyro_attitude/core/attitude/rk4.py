"""Classical RK4 of the quaternion kinematics ``q̇ = ½ q ⊗ [ω, 0]``."""

from __future__ import annotations

import math

from gyro_attitude.core.attitude.algorithm import RateAlgorithm
from gyro_attitude.core.attitude.compose import qmul_scalar
from gyro_attitude.core.attitude.interpolation import causal_fit_two
from gyro_attitude.core.jit import kernel


@kernel(inline=True)
def _rk4_stage(p, scale, w0, w1, w2):
    """``½ (1 + scale·p) ⊗ [w, 0]``."""
    r = qmul_scalar((scale * p[0], scale * p[1], scale * p[2], 1.0 + scale * p[3]),
                    (w0, w1, w2, 0.0))
    return (0.5 * r[0], 0.5 * r[1], 0.5 * r[2], 0.5 * r[3])


@kernel
def quat_rk4_increment(ts, ws, k, n):
    """RK4 with ``ω(t_{k-1})``, the causal-cubic mid-step ``ω``, ``ω(t_k)``; normalized.

    Truncates the spin angle: error ~θ⁵/… per step for ``θ = |ω|h`` — fast spin punishes it.
    RK4 from ``q = 1``: since the right-hand side is linear under right multiplication, the
    step from any ``q`` is ``q ⊗ p`` with this ``p``.  Where the cubic cannot be trusted (near
    the Nyquist rate) all three rates move toward the endpoint mean (one constant rate: no
    commutation term), counted as the other fitted steps count it: (b_k, fell back)."""
    wm, _, h, held = causal_fit_two(ts, ws, k, n, 0.5, 0.5)
    a0, a1, a2 = ws[k - 1, 0], ws[k - 1, 1], ws[k - 1, 2]
    b0, b1, b2 = ws[k, 0], ws[k, 1], ws[k, 2]
    m0, m1, m2 = wm
    if held > 0.0:
        keep = 1.0 - held
        c0, c1, c2 = 0.5 * (a0 + b0), 0.5 * (a1 + b1), 0.5 * (a2 + b2)
        a0, a1, a2 = keep * a0 + held * c0, keep * a1 + held * c1, keep * a2 + held * c2
        m0, m1, m2 = keep * m0 + held * c0, keep * m1 + held * c1, keep * m2 + held * c2
        b0, b1, b2 = keep * b0 + held * c0, keep * b1 + held * c1, keep * b2 + held * c2
    k1 = (0.5 * a0, 0.5 * a1, 0.5 * a2, 0.0)
    k2 = _rk4_stage(k1, 0.5 * h, m0, m1, m2)
    k3 = _rk4_stage(k2, 0.5 * h, m0, m1, m2)
    k4 = _rk4_stage(k3, h, b0, b1, b2)
    c = h / 6.0
    p0 = c * (k1[0] + 2.0 * k2[0] + 2.0 * k3[0] + k4[0])
    p1 = c * (k1[1] + 2.0 * k2[1] + 2.0 * k3[1] + k4[1])
    p2 = c * (k1[2] + 2.0 * k2[2] + 2.0 * k3[2] + k4[2])
    p3 = c * (k1[3] + 2.0 * k2[3] + 2.0 * k3[3] + k4[3]) + 1.0
    m = math.sqrt(p0 * p0 + p1 * p1 + p2 * p2 + p3 * p3)
    return (p0 / m, p1 / m, p2 / m, p3 / m), held > 0.0


QUAT_RK4 = RateAlgorithm("quat_rk4", 4, "quaternion RK4, cubic-interpolated mid-step rate, "
                         "normalized", "cubic weights + 4 quaternion products per sample",
                         code=5, fits_rate_polynomial=True)
