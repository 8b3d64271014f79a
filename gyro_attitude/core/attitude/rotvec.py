"""Rotation-vector (Magnus) steps: trapezoid + commutation term; 4th order on the causal cubic."""

from __future__ import annotations

import math

from gyro_attitude.core.attitude.algorithm import RateAlgorithm
from gyro_attitude.core.attitude.compose import exp_scalar
from gyro_attitude.core.attitude.interpolation import GAUSS2, causal_fit_two
from gyro_attitude.core.jit import kernel

_SQRT3_12 = math.sqrt(3.0) / 12.0
_GA, _GB = GAUSS2


@kernel
def trapezoid_increment(ts, ws, k, n):
    """``φ = ½(ω_{k-1}+ω_k)h + h²/12 ω_{k-1}×ω_k``: the rotation vector of the linear rate
    model (trapezoid increment plus its exact commutation term).  The trapezoid limits it to
    order 2 on general motion; the coning drift falls as h⁴.  (exp(φ), False)."""
    h = (ts[k] - ts[k - 1]) * 1e-9
    ax, ay, az = ws[k - 1, 0], ws[k - 1, 1], ws[k - 1, 2]
    bx, by, bz = ws[k, 0], ws[k, 1], ws[k, 2]
    half, c = 0.5 * h, h * h / 12.0
    return exp_scalar(half * (ax + bx) + c * (ay * bz - az * by),
                      half * (ay + by) + c * (az * bx - ax * bz),
                      half * (az + bz) + c * (ax * by - ay * bx)), False


@kernel(inline=True)
def cubic_increment(ts, ws, k, n):
    """4th-order Magnus step on the causal cubic through the ``n`` samples held (k-3..k;
    Lagrange, any spacing): rates ``ω_a, ω_b`` at the two Gauss points,
    ``φ = h/2 (ω_a+ω_b) + √3/12 h² ω_a×ω_b`` (Gauss quadrature is exact for the cubic's
    increment; the cross term is its commutation correction).  The first two intervals take
    the linear/quadratic fit.  (exp(φ), whether the fit was not trusted: then φ moves toward
    the exponential map of the endpoint mean)."""
    a, b, h, held = causal_fit_two(ts, ws, k, n, _GA, _GB)
    ax, ay, az = a
    bx, by, bz = b
    half, c = 0.5 * h, _SQRT3_12 * (h * h)
    px = half * (ax + bx) + c * (ay * bz - az * by)
    py = half * (ay + by) + c * (az * bx - ax * bz)
    pz = half * (az + bz) + c * (ax * by - ay * bx)
    if held > 0.0:  # toward the exponential map of the endpoint mean (hold_untrusted)
        u, v = ws[k - 1], ws[k]
        keep = 1.0 - held
        px = keep * px + held * (0.5 * (u[0] + v[0]) * h)
        py = keep * py + held * (0.5 * (u[1] + v[1]) * h)
        pz = keep * pz + held * (0.5 * (u[2] + v[2]) * h)
    return exp_scalar(px, py, pz), held > 0.0


ROTVEC_TRAPEZOID = RateAlgorithm(
    "rotvec_trapezoid", 2, "rotation vector: trapezoid increment + h^2/12 w0 x w1 commutation",
    "1 cross + exp map + product per sample", code=3)
ROTVEC_CUBIC = RateAlgorithm(
    "rotvec_cubic", 4, "4th-order Magnus on the causal cubic (2 Gauss points + commutation)",
    "cubic weights + cross + exp map + product per sample", code=4, fits_rate_polynomial=True)
