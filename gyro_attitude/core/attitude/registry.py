"""The algorithm registry: names to algorithm objects, defaults, and queries by kind."""

from __future__ import annotations

from gyro_attitude.core.attitude.algorithm import (
    DCM_FIRST_ORDER,
    EXP_MAP,
    QUAT_FIRST_ORDER,
    QUAT_RK4,
    ROTVEC_CUBIC,
    ROTVEC_TRAPEZOID,
    Algorithm,
)
from gyro_attitude.core.attitude.coning import CONING1, CONING1_PREV, CONING2, CONING3, CONING4
from gyro_attitude.core.attitude.euler_angles import EULER_KRYLOV_RK4, EULER_ZXZ_RK4
from gyro_attitude.core.attitude.magnus6 import MAGNUS6_QUINTIC

#: Every algorithm by name (adding one: its step + one entry here).
ALGORITHMS: dict[str, Algorithm] = {a.name: a for a in (
    EULER_ZXZ_RK4, EULER_KRYLOV_RK4, DCM_FIRST_ORDER, QUAT_FIRST_ORDER, QUAT_RK4, EXP_MAP,
    ROTVEC_TRAPEZOID, ROTVEC_CUBIC, MAGNUS6_QUINTIC,
    CONING1, CONING1_PREV, CONING2, CONING3, CONING4,
)}
#: Causal default (streaming node, batch): 4th order, exact for constant spin.
DEFAULT_ALGORITHM = ROTVEC_CUBIC.name
#: Offline default (replay of a whole recording): 6th order, uses samples after each interval.
DEFAULT_OFFLINE_ALGORITHM = MAGNUS6_QUINTIC.name


def get_algorithm(name) -> Algorithm:
    """The algorithm called ``name`` (``ValueError`` naming the choices otherwise)."""
    if not isinstance(name, str) or name not in ALGORITHMS:
        raise ValueError(f"unknown algorithm {name!r}; choose one of {sorted(ALGORITHMS)}")
    return ALGORITHMS[name]


def causal_algorithms() -> dict[str, Algorithm]:
    """Algorithms that need no future samples: the ones a streaming node may run."""
    return {name: a for name, a in ALGORITHMS.items() if a.causal}


def offline_algorithms() -> dict[str, Algorithm]:
    """Algorithms that use samples after each interval: batch (replay) only."""
    return {name: a for name, a in ALGORITHMS.items() if not a.causal}
