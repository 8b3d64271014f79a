"""Exact exponential map of the trapezoid increment (rate held at the endpoint mean)."""

from __future__ import annotations

from gyro_attitude.core.attitude.algorithm import RateAlgorithm
from gyro_attitude.core.attitude.compose import exp_scalar
from gyro_attitude.core.rotation import _exp_rotvec


class ExpMap(RateAlgorithm):
    """``b_k = exp(½(ω_{k-1}+ω_k) h)``: exact for a constant rate of any magnitude; ignores
    non-commutativity (coning)."""

    def body_increments(self, t_ns, omega, k, lookahead=False):
        h = ((t_ns[k] - t_ns[k - 1]) * 1e-9)[:, None]
        return _exp_rotvec(0.5 * (omega[k - 1] + omega[k]) * h)

    def body_increment_scalar(self, ts, ws, k, nodes):
        h = (ts[k] - ts[k - 1]) * 1e-9
        (ax, ay, az), (bx, by, bz) = ws[k - 1], ws[k]
        return exp_scalar(0.5 * (ax + bx) * h, 0.5 * (ay + by) * h, 0.5 * (az + bz) * h)


EXP_MAP = ExpMap("exp_map", 2, "exact exponential map of the trapezoid increment (rate held at "
                 "the endpoint mean)", "1 exp map + product per sample")
