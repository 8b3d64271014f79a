"""Angle wrapping, the one home of it (headings, heading differences, longitudes, Euler angles).

Plain floats go through ``math`` (the per-sample filters call these on one angle: numpy's call
overhead would be most of the cost), arrays through numpy; both take the floor modulo (Python's
``%`` and ``np.mod`` alike), so a float and an array element give the same number.
"""

from __future__ import annotations

import math

import numpy as np

from gyro_attitude.core.jit import kernel

__all__ = ["wrap_2pi", "wrap_pi", "wrap_pi_closed"]

_TWO_PI = 2.0 * math.pi


def wrap_2pi(a):
    """Angles wrapped to [0, 2π) (compass headings)."""
    if isinstance(a, float | int) and not isinstance(a, bool):
        return float(a) % _TWO_PI
    return np.mod(a, _TWO_PI)


def wrap_pi(a):
    """Angles wrapped to [−π, π) (differences of headings, longitudes)."""
    if isinstance(a, float | int) and not isinstance(a, bool):
        return wrap_pi_float(float(a))
    return np.mod(np.asarray(a) + np.pi, _TWO_PI) - np.pi


@kernel
def wrap_pi_float(a: float) -> float:
    """:func:`wrap_pi` of one float (a kernel: the compiled filters call it)."""
    return (a + math.pi) % _TWO_PI - math.pi


def wrap_pi_closed(a):
    """Angles wrapped to (−π, π] (Euler angles: +π kept, −π becomes +π)."""
    if isinstance(a, float | int) and not isinstance(a, bool):
        return math.pi - (math.pi - float(a)) % _TWO_PI
    return np.pi - np.mod(np.pi - np.asarray(a), _TWO_PI)
