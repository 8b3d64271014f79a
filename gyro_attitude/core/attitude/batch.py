"""Batch attitude integration over a whole record (the front of every algorithm): the causal
ones step their streaming kernel in a compiled loop, the offline one is vectorized."""

from __future__ import annotations

import numpy as np

from gyro_attitude.core.attitude.algorithm import RateAlgorithm
from gyro_attitude.core.attitude.coning import IncrementAlgorithm, get_quadrature
from gyro_attitude.core.attitude.inputs import check_q0, check_rates, check_times
from gyro_attitude.core.attitude.nav_frame import NavFrame, nav_rate_for
from gyro_attitude.core.attitude.registry import DEFAULT_ALGORITHM, get_algorithm
from gyro_attitude.core.attitude.streaming import integrate_rows
from gyro_attitude.core.rotation import as_vector_array


def integrate_batch(t_ns, omega_ib_b, q0=(0.0, 0.0, 0.0, 1.0),
                    algorithm: str = DEFAULT_ALGORITHM, nav: NavFrame | None = None,
                    quadrature: str = "trapezoid", singular_tol: float = 1e-3,
                    fallbacks: list | None = None, out: np.ndarray | None = None) -> np.ndarray:
    """Attitudes ``q[k]`` (N, 4) at ``t_ns[k]`` from rate samples ``ω_ib^b`` (N, 3).

    ``q[0] = q0``; ``q_ib`` when ``nav`` is None, else ``q_nb`` with the nav-frame rate
    removed.  Increment algorithms (``coning*``) get their increments from ``quadrature``
    (see :func:`~gyro_attitude.core.attitude.increments_from_rates`).  ``singular_tol``
    applies to the Euler-angle baselines only.  Raises ``ValueError`` for non-increasing
    times, wrong shapes, non-finite input, unknown names.

    ``fallbacks``: a list that collects, as int arrays, the intervals k (sample k-1 to k)
    whose rate fit could not be trusted and whose step fell back to the exponential map
    (algorithms that check their fit: ``rotvec_cubic``, ``magnus6_quintic``;
    :func:`~gyro_attitude.core.attitude.interpolation.untrusted_fits`).

    ``out``: a C-contiguous float64 (N, 4) array the attitudes are written into and which is
    returned (a caller assembling several runs into one array spares a run-sized copy).
    """
    alg = get_algorithm(algorithm)
    t = check_times(t_ns)
    w = check_rates(omega_ib_b, t.size)
    q0 = check_q0(q0)
    quad = get_quadrature(quadrature)
    rate_n = nav_rate_for(nav, t.size)
    if rate_n is not None and not alg.supports_nav:
        raise ValueError(f"{alg.name} integrates q_ib only; nav frames need a quaternion "
                         "algorithm")
    if out is not None and not (isinstance(out, np.ndarray) and out.shape == (t.size, 4)
                                and out.dtype == np.float64 and out.flags.c_contiguous
                                and out.flags.writeable):
        raise ValueError(f"out must be a writeable C-contiguous float64 array of shape "
                         f"({t.size}, 4)")
    try:
        if isinstance(alg, RateAlgorithm | IncrementAlgorithm):  # the streaming step, looped
            return _finite(integrate_rows(alg, t, w, q0, rate_n, quad.code, fallbacks, out))
        kw = {"fallbacks": fallbacks} if fallbacks is not None and alg.checks_rate_fit else {}
        if out is not None:
            if not alg.integrates_into:
                out[:] = alg.integrate(t, w, q0, rate_n, quad, float(singular_tol), **kw)
                return _finite(out)
            kw["out"] = out
        return _finite(alg.integrate(t, w, q0, rate_n, quad, float(singular_tol), **kw))
    except (ValueError, OverflowError) as exc:
        if "math" not in str(exc) and not isinstance(exc, OverflowError):
            raise
        raise ValueError(f"{alg.name}: the rates or intervals are beyond what float64 can "
                         f"integrate ({exc})") from None


def _finite(q: np.ndarray, size: int = 1 << 16) -> np.ndarray:
    """``q``, or ValueError naming its first non-finite row (rates of 1e150 rad/s and more,
    or stamps whose differences float64 cannot hold, overflow the steps)."""
    for c0 in range(0, q.shape[0], size):
        bad = ~np.isfinite(q[c0:c0 + size]).all(axis=1)
        if bad.any():
            k = c0 + int(np.argmax(bad))
            raise ValueError(f"attitude not finite from sample {k} on: the rates or intervals "
                             "are beyond what float64 can integrate")
    return q


def integrate_increments_batch(t_ns, delta_theta, q0=(0.0, 0.0, 0.0, 1.0),
                               algorithm: str = "coning4",
                               nav: NavFrame | None = None) -> np.ndarray:
    """Attitudes (N, 4) from angle increments ``delta_theta`` (N-1, 3) of an increment
    algorithm; ``delta_theta[k-1] = ∫ ω_ib^b dt`` over ``(t_ns[k-1], t_ns[k]]``."""
    alg = get_algorithm(algorithm)
    if not isinstance(alg, IncrementAlgorithm):
        raise ValueError(f"{alg.name} consumes rate samples; use integrate_batch")
    t = check_times(t_ns)
    d = as_vector_array(delta_theta, "delta_theta")
    if d.shape != (t.size - 1, 3):
        raise ValueError(f"delta_theta must have shape ({t.size - 1}, 3) (one per interval), "
                         f"got {d.shape}")
    q0 = check_q0(q0)
    rate_n = nav_rate_for(nav, t.size)
    return integrate_rows(alg, t, d, q0, rate_n, increments=True)
