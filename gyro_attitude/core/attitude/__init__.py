"""Attitude from angular rates: the algorithm registry, batch and streaming integration, and the
attitude-stream policy (validation, gaps, resets, covariance) that the node and replay share.

Conventions (docs/conventions.md): input samples are rate-gyro outputs ``ω_ib^b`` (rad/s, body frame)
at strictly increasing int64 nanosecond times (non-uniform steps allowed), or angle
increments ``Δθ_k = ∫ ω_ib^b dt`` over ``(t_{k-1}, t_k]`` for the coning algorithms.
Quaternions are scalar-last.  Without a navigation frame the result is ``q_ib``; with
``nav=NavFrame(...)`` it is ``q_nb`` (body to local ENU), each interval updated as
``q_nb(t+T) = exp(−ζ) ⊗ q_nb(t) ⊗ exp(φ)`` with ``ζ = ∫ ω_in^n dt`` (trapezoid).
``q[k]`` is the attitude at ``t_ns[k]``.  Where the algorithms live: docs/architecture.md.
"""

from gyro_attitude.core.attitude.algorithm import Algorithm, RateAlgorithm
from gyro_attitude.core.attitude.batch import integrate_batch, integrate_increments_batch
from gyro_attitude.core.attitude.coning import (
    CONING_COEFFICIENTS,
    CONING_DRIFT_RHO,
    QUADRATURES,
    IncrementAlgorithm,
    increments_from_rates,
)
from gyro_attitude.core.attitude.nav_frame import NavFrame
from gyro_attitude.core.attitude.registry import (
    ALGORITHMS,
    DEFAULT_ALGORITHM,
    DEFAULT_OFFLINE_ALGORITHM,
    causal_algorithms,
    get_algorithm,
    offline_algorithms,
)
from gyro_attitude.core.attitude.streaming import StreamingIntegrator
from gyro_attitude.core.euler_kinematics import GimbalLockError

__all__ = [
    "ALGORITHMS",
    "Algorithm",
    "CONING_COEFFICIENTS",
    "CONING_DRIFT_RHO",
    "DEFAULT_ALGORITHM",
    "DEFAULT_OFFLINE_ALGORITHM",
    "GimbalLockError",
    "IncrementAlgorithm",
    "NavFrame",
    "QUADRATURES",
    "RateAlgorithm",
    "StreamingIntegrator",
    "causal_algorithms",
    "get_algorithm",
    "increments_from_rates",
    "integrate_batch",
    "integrate_increments_batch",
    "offline_algorithms",
]
