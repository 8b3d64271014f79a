"""Angle increments from rate samples: the stated quadratures that feed the coning algorithms."""

from __future__ import annotations

import numpy as np

from gyro_attitude.core.attitude.inputs import check_rates, check_times
from gyro_attitude.core.attitude.interpolation import GAUSS2, causal_fit_points
from gyro_attitude.core.jit import compiled, kernel

_GA, _GB = GAUSS2
TRAPEZOID, CUBIC = 0, 1  # the rules' codes


class Quadrature:
    """One rule for ``Δθ_k ≈ ∫_{t_{k-1}}^{t_k} ω dt`` (its step: :func:`quadrature_increment`
    with ``code``)."""

    def __init__(self, name: str, code: int, fits_polynomial: bool, description: str):
        self.name = name
        self.code = code
        #: True when the rule fits a polynomial: interval 1 is redone once sample 2 is in.
        self.fits_polynomial = fits_polynomial
        self.description = description


@kernel(inline=True)
def quadrature_increment(rule, ts, ws, k, n):
    """The increment over interval ``k`` of the first ``n`` samples held (``ts`` stamps, ``ws``
    rates) by the rule ``rule``: the trapezoid ``½(ω_{k-1}+ω_k) h``, or the causal cubic
    through the samples held integrated exactly (two-point Gauss)."""
    if rule == CUBIC:
        (ax, ay, az), (bx, by, bz), h = causal_fit_points(ts, ws, k, n, _GA, _GB)
        half = 0.5 * h
        return (half * (ax + bx), half * (ay + by), half * (az + bz))
    h = (ts[k] - ts[k - 1]) * 1e-9
    return (0.5 * (ws[k - 1, 0] + ws[k, 0]) * h, 0.5 * (ws[k - 1, 1] + ws[k, 1]) * h,
            0.5 * (ws[k - 1, 2] + ws[k, 2]) * h)


@kernel
def quadrature_rows(rule, t, w, out):
    """:func:`quadrature_increment` of every interval k of ``t`` (N,), ``w`` (N, 3) into
    ``out[k-1]``, each from the samples k-3..k (fewer at the start; interval 1 from samples
    0..2 when they exist, the fit the streams redo it with)."""
    for k in range(1, t.shape[0]):
        lo = max(k - 3, 0)
        hi = k + 1 if k > 1 or rule != CUBIC else min(3, t.shape[0])
        out[k - 1, 0], out[k - 1, 1], out[k - 1, 2] = quadrature_increment(
            rule, t[lo:hi], w[lo:hi], k - lo, hi - lo)


QUADRATURES: dict[str, Quadrature] = {q.name: q for q in (
    Quadrature("trapezoid", TRAPEZOID, False,
               "½(ω_{k-1}+ω_k) h: error O(h³) per interval → order 2"),
    Quadrature("cubic", CUBIC, True,
               "the causal cubic through samples k-3..k integrated exactly (two-point Gauss): "
               "error O(h⁵) per interval → order 4 (first two intervals: linear/quadratic)"))}


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
    w = np.ascontiguousarray(check_rates(omega_ib_b, t.size), dtype=np.float64)
    out = np.empty((max(t.size - 1, 0), 3))
    compiled(quadrature_rows)(get_quadrature(quadrature).code, t, w, out)
    return out
