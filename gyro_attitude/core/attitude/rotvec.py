"""Rotation-vector (Magnus) updates: trapezoid + commutation term, 4th order on the causal cubic."""

from __future__ import annotations

import math

import numpy as np

from gyro_attitude.core.attitude.algorithm import RateAlgorithm
from gyro_attitude.core.attitude.compose import exp_scalar
from gyro_attitude.core.attitude.interpolation import (
    GAUSS2,
    causal_fit_two,
    causal_rates_at,
    causal_window,
    hold_untrusted,
)
from gyro_attitude.core.jit import kernel
from gyro_attitude.core.rotation import _exp_rotvec

_SQRT3_12 = math.sqrt(3.0) / 12.0
_GA, _GB = GAUSS2


class RotvecTrapezoid(RateAlgorithm):
    """``φ = ½(ω_{k-1}+ω_k)h + h²/12 ω_{k-1}×ω_k``: the rotation vector of the linear rate
    model (trapezoid increment plus its exact commutation term).  The trapezoid limits it
    to order 2 on general motion; the coning drift falls as h⁴."""

    def body_increments(self, t_ns, omega, k, lookahead=False):
        h = ((t_ns[k] - t_ns[k - 1]) * 1e-9)[:, None]
        w0, w1 = omega[k - 1], omega[k]
        return _exp_rotvec(0.5 * (w0 + w1) * h + (h * h / 12.0) * np.cross(w0, w1))

    def body_increment_scalar(self, ts, ws, k, nodes):
        h = (ts[k] - ts[k - 1]) * 1e-9
        (ax, ay, az), (bx, by, bz) = ws[k - 1], ws[k]
        return _magnus4_scalar(ax, ay, az, bx, by, bz, 0.5 * h, h * h / 12.0)


class RotvecCubic(RateAlgorithm):
    """4th-order Magnus step on the causal cubic through samples k-3..k (Lagrange, any
    spacing): rates ``ω_a, ω_b`` at the two Gauss points,
    ``φ = h/2 (ω_a+ω_b) + √3/12 h² ω_a×ω_b`` (Gauss quadrature is exact for the cubic's
    increment; the cross term is its commutation correction).  The first two intervals fall
    back to the linear/quadratic fit."""

    fits_rate_polynomial = True
    checks_rate_fit = True

    def body_increments(self, t_ns, omega, k, lookahead=False, fallbacks=None):
        h = ((t_ns[k] - t_ns[k - 1]) * 1e-9)[:, None]
        g = causal_rates_at(t_ns, omega, k, GAUSS2, lookahead)
        wa, wb = g[:, 0], g[:, 1]
        phi = 0.5 * h * (wa + wb) + _SQRT3_12 * (h * h) * np.cross(wa, wb)
        hold_untrusted(t_ns, omega, k, g, phi, h, causal_window(t_ns.size, lookahead), fallbacks)
        return _exp_rotvec(phi)

    def body_increment_scalar(self, ts, ws, k, nodes):
        return self.body_increment_checked(ts, ws, k, nodes)[0]

    def body_increment_checked(self, ts, ws, k, nodes):
        return cubic_increment(ts, ws, k, nodes)


@kernel(inline=True)
def cubic_increment(ts, ws, k, nodes):
    """The causal cubic's step over interval ``k`` of the histories ``ts, ws`` fitted on
    ``nodes``: (increment quaternion, whether the fit was not trusted).  A kernel
    (:mod:`gyro_attitude.core.jit`): the streaming integrator and the compiled chain step
    with it."""
    a, b, h, held = causal_fit_two(ts, ws, k, len(nodes), _GA, _GB)
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


def _magnus4_scalar(ax, ay, az, bx, by, bz, half, c):
    """``exp(half·(a+b) + c·a×b)`` in plain floats."""
    return exp_scalar(half * (ax + bx) + c * (ay * bz - az * by),
                      half * (ay + by) + c * (az * bx - ax * bz),
                      half * (az + bz) + c * (ax * by - ay * bx))


ROTVEC_TRAPEZOID = RotvecTrapezoid(
    "rotvec_trapezoid", 2, "rotation vector: trapezoid increment + h^2/12 w0 x w1 commutation",
    "1 cross + exp map + product per sample")
ROTVEC_CUBIC = RotvecCubic(
    "rotvec_cubic", 4, "4th-order Magnus on the causal cubic (2 Gauss points + commutation)",
    "cubic weights + cross + exp map + product per sample")
