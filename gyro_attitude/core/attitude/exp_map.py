"""Exact exponential map of the trapezoid increment (rate held at the endpoint mean)."""

from __future__ import annotations

from gyro_attitude.core.attitude.algorithm import RateAlgorithm
from gyro_attitude.core.attitude.compose import exp_scalar
from gyro_attitude.core.jit import kernel


@kernel
def exp_map_increment(ts, ws, k, n):
    """``b_k = exp(½(ω_{k-1}+ω_k) h)``: exact for a constant rate of any magnitude; ignores
    non-commutativity (coning).  (b_k, False): no fit to distrust."""
    h = (ts[k] - ts[k - 1]) * 1e-9
    return exp_scalar(0.5 * (ws[k - 1, 0] + ws[k, 0]) * h, 0.5 * (ws[k - 1, 1] + ws[k, 1]) * h,
                      0.5 * (ws[k - 1, 2] + ws[k, 2]) * h), False


EXP_MAP = RateAlgorithm("exp_map", 2, "exact exponential map of the trapezoid increment (rate "
                        "held at the endpoint mean)", "1 exp map + product per sample", code=2)
