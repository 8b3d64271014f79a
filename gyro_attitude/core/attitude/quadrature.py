"""Angle increments from rate samples: the stated quadratures that feed the coning algorithms."""

from __future__ import annotations

import numpy as np

from gyro_attitude.core.attitude.inputs import check_rates, check_times
from gyro_attitude.core.attitude.interpolation import (
    GAUSS2,
    causal_fit_points,
    causal_rates_at,
)


class Quadrature:
    """One rule for ``Δθ_k ≈ ∫_{t_{k-1}}^{t_k} ω dt``: batch kernel and scalar step."""

    name = ""
    #: True when the rule fits a polynomial: interval 1 is redone once sample 2 is in.
    fits_polynomial = False

    def increments(self, t_ns, omega, k, lookahead=False) -> np.ndarray:
        """Increments (len(k), 3) of intervals ``k`` (batch)."""
        raise NotImplementedError

    def increment_scalar(self, ts, ws, k, nodes):
        """Increment of interval ``k`` from plain-float histories (streaming)."""
        raise NotImplementedError


class Trapezoid(Quadrature):
    """``½(ω_{k-1}+ω_k) h``: error O(h³) per interval → order 2."""

    name = "trapezoid"

    def increments(self, t_ns, omega, k, lookahead=False):
        h = ((t_ns[k] - t_ns[k - 1]) * 1e-9)[:, None]
        return 0.5 * (omega[k - 1] + omega[k]) * h

    def increment_scalar(self, ts, ws, k, nodes):
        h = (ts[k] - ts[k - 1]) * 1e-9
        (ax, ay, az), (bx, by, bz) = ws[k - 1], ws[k]
        return (0.5 * (ax + bx) * h, 0.5 * (ay + by) * h, 0.5 * (az + bz) * h)


class CausalCubic(Quadrature):
    """The causal cubic through samples k-3..k integrated exactly (two-point Gauss): error
    O(h⁵) per interval → order 4 (first two intervals: linear/quadratic)."""

    name = "cubic"
    fits_polynomial = True

    def increments(self, t_ns, omega, k, lookahead=False):
        h = ((t_ns[k] - t_ns[k - 1]) * 1e-9)[:, None]
        g = causal_rates_at(t_ns, omega, k, GAUSS2, lookahead)
        return 0.5 * h * (g[:, 0] + g[:, 1])

    def increment_scalar(self, ts, ws, k, nodes):
        half = 0.5 * (ts[k] - ts[k - 1]) * 1e-9
        (ax, ay, az), (bx, by, bz), _ = causal_fit_points(ts, ws, k, len(nodes), *GAUSS2)
        return (half * (ax + bx), half * (ay + by), half * (az + bz))


QUADRATURES: dict[str, Quadrature] = {q.name: q for q in (Trapezoid(), CausalCubic())}


def get_quadrature(name: str) -> Quadrature:
    if name not in QUADRATURES:
        raise ValueError(f"unknown quadrature {name!r}; choose one of {tuple(QUADRATURES)}")
    return QUADRATURES[name]


def increments_from_rates(t_ns, omega_ib_b, quadrature: str = "trapezoid") -> np.ndarray:
    """Angle increments ``Δθ_k ≈ ∫_{t_{k-1}}^{t_k} ω dt`` from rate samples, (N-1, 3).

    ``"trapezoid"``: ``½(ω_{k-1}+ω_k) h`` (error O(h³) per interval → order 2).
    ``"cubic"``: the causal cubic through samples k-3..k integrated exactly (two-point
    Gauss), error O(h⁵) per interval → order 4 (first two intervals: linear/quadratic).
    """
    t = check_times(t_ns)
    w = check_rates(omega_ib_b, t.size)
    rule = get_quadrature(quadrature)
    return rule.increments(t, w, np.arange(1, t.size), lookahead=True)
