"""Offline sixth-order Magnus step on a centered quintic fit of the rate samples (replay)."""

from __future__ import annotations

import math

import numpy as np

from gyro_attitude.core.attitude.algorithm import Algorithm
from gyro_attitude.core.attitude.compose import LeftPrefix, compose_chunked
from gyro_attitude.core.attitude.interpolation import fitted_rates, hold_untrusted, lagrange_eval
from gyro_attitude.core.attitude.nav_frame import nav_zeta
from gyro_attitude.core.rotation import _exp_rotvec

_S15 = math.sqrt(15.0)
#: Three-point Gauss–Legendre nodes in [0, 1]: ½ − √15/10, ½, ½ + √15/10.
GAUSS3 = (0.5 - _S15 / 10.0, 0.5, 0.5 + _S15 / 10.0)
_FIT_SAMPLES = 6  # quintic
_BEFORE = 2  # samples before the interval's left end in the centered window


def bracket(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Lie bracket of body rates composed on the right (``q̇ = ½ q ⊗ ω``): ``[x, y] = −x × y``
    (``+x × y`` for left-composed rates; the wrong sign errs at first order in the commutator)."""
    return np.cross(y, x)


def magnus6_rotation_vector(a1: np.ndarray, a2: np.ndarray, a3: np.ndarray,
                            h: np.ndarray) -> np.ndarray:
    """Sixth-order Magnus rotation vector over a step ``h`` from the body rates ``a1, a2, a3``
    at the three Gauss–Legendre points (docs/equations.md "Higher-order and instrument formulas"):

    ``B1 = h A2``, ``B2 = (√15 h/3)(A3 − A1)``, ``B3 = (10 h/3)(A3 − 2 A2 + A1)``,
    ``Ω = B1 + B3/12 + (1/240)·[−20 B1 − B3 + [B1,B2], B2 − (1/60)·[B1, 2 B3 + [B1,B2]]]``.
    Shapes (M, 3) with ``h`` (M, 1); ``q(t+h) = q(t) ⊗ exp(Ω)``."""
    b1 = h * a2
    b2 = (_S15 / 3.0) * h * (a3 - a1)
    b3 = (10.0 / 3.0) * h * (a3 - 2.0 * a2 + a1)
    b12 = bracket(b1, b2)
    inner = b2 - (1.0 / 60.0) * bracket(b1, 2.0 * b3 + b12)
    return b1 + b3 / 12.0 + (1.0 / 240.0) * bracket(-20.0 * b1 - b3 + b12, inner)


def quintic_window_start(k: np.ndarray, n_samples: int) -> np.ndarray:
    """First sample of the six-sample fit of intervals ``k`` (sample k-1 to k): centered,
    samples k-3..k+2 (two before the interval, three from its right end), shifted inward
    at the ends of the record (one-sided fit of the same degree)."""
    return np.clip(k - 1 - _BEFORE, 0, max(n_samples - _FIT_SAMPLES, 0))


class Magnus6Quintic(Algorithm):
    """Sixth-order Magnus step on the centered quintic through six samples around the
    interval (any spacing).  It uses two samples after the interval: batch (replay) only,
    vectorized in numpy (an offline replay imports no numba), composed with a blocked prefix
    product.  At the ends of the record the window shifts inward (one-sided, same degree);
    fewer than six samples: the polynomial through all.  Exact for any constant rate."""

    causal = False
    checks_rate_fit = True
    integrates_into = True

    def body_increments(self, t_ns, omega, k, fallbacks=None):
        """Body increments ``b_k`` (len(k), 4) of intervals ``k``."""
        h = ((t_ns[k] - t_ns[k - 1]) * 1e-9)[:, None]
        g = fitted_rates(t_ns, omega, k, GAUSS3, _BEFORE + 1, _FIT_SAMPLES,
                         lambda kk: _gathered_rates(t_ns, omega, kk))
        phi = magnus6_rotation_vector(g[:, 0], g[:, 1], g[:, 2], h)
        hold_untrusted(t_ns, omega, k, g, phi, h, lambda kk: _window(kk, t_ns.size), fallbacks)
        return _exp_rotvec(phi)

    def integrate(self, t, w, q0, rate_n, quadrature, singular_tol, fallbacks=None, out=None):
        """``q_k = exp(−ζ_k) ⊗ q_{k-1} ⊗ b_k`` over all intervals, chunk by chunk."""
        def increments(k):
            b = self.body_increments(t, w, k, fallbacks)
            if rate_n is None:
                return b, None
            if rate_n.ndim == 1:
                # A constant nav rate turns the frame about one fixed axis: the increments
                # exp(−ω h_j) commute, and their product since the chunk's start is
                # exp(−ω (t_k − t_k0−1)) in closed form (exact int ns span, no scan).
                span = ((t[k] - t[k[0] - 1]) * 1e-9)[:, None]
                return b, LeftPrefix(_exp_rotvec(-rate_n[None, :] * span))
            return b, _exp_rotvec(-nav_zeta(t, rate_n, k))

        return compose_chunked(t.size, q0, increments, out=out)


def _window(k, n_samples):
    """(first, last) sample of the fits of intervals ``k``."""
    first = quintic_window_start(k, n_samples)
    return first, first + min(_FIT_SAMPLES, n_samples) - 1


def _gathered_rates(t_ns, omega, k):
    """Gauss-point rates of intervals ``k`` with their (shifted) windows gathered row by row."""
    n_fit = min(_FIT_SAMPLES, t_ns.size)
    idx = quintic_window_start(k, t_ns.size)[:, None] + np.arange(n_fit)[None, :]
    # times from the interval's left end as int64 differences (no precision lost on long records)
    x = (t_ns[idx] - t_ns[k - 1][:, None]) * 1e-9
    h = ((t_ns[k] - t_ns[k - 1]) * 1e-9)[:, None]
    return lagrange_eval(x, omega[idx], h * np.asarray(GAUSS3)[None, :])


MAGNUS6_QUINTIC = Magnus6Quintic(
    "magnus6_quintic", 6, "offline 6th-order Magnus on the centered quintic through six "
    "samples (3 Gauss points); batch/replay only", "quintic weights + 4 crosses + exp map per "
    "sample")
