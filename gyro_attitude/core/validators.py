"""Scalar parameter checks shared by the core models: one ValueError naming the parameter."""

from __future__ import annotations

import math

import numpy as np

__all__ = ["check_finite", "check_nonnegative", "check_positive", "pair", "triple"]


def _as_float(value, name: str) -> float:
    # bool is an int to Python and float("1.5") parses: a True or a string where a number
    # belongs is a mistake, not a value
    if isinstance(value, bool | str | bytes):
        raise ValueError(f"{name} must be a number, got {type(value).__name__} {value!r}")
    try:
        return float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {value!r}") from None


def check_finite(value, name: str) -> float:
    """``value`` as a float; ValueError naming it unless it is a finite number."""
    v = _as_float(value, name)
    if not math.isfinite(v):
        raise ValueError(f"{name} must be finite, got {v!r}")
    return v


def check_positive(value, name: str) -> float:
    """``value`` as a float; ValueError naming it unless finite and > 0."""
    v = check_finite(value, name)
    if v <= 0.0:
        raise ValueError(f"{name} must be > 0, got {v!r}")
    return v


def check_nonnegative(value, name: str) -> float:
    """``value`` as a float; ValueError naming it unless finite and >= 0."""
    v = check_finite(value, name)
    if v < 0.0:
        raise ValueError(f"{name} must be >= 0, got {v!r}")
    return v


def _entries(value, name: str, count: int, labels: str) -> list:
    try:
        vals = np.asarray(value, dtype=np.float64).reshape(-1).tolist()
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be {count} numbers ({labels}), got {value!r}") from None
    if len(vals) != count:
        raise ValueError(f"{name} must have {count} entries ({labels}), got {value!r}")
    return vals


def pair(value, name: str, check=check_finite) -> tuple[float, float]:
    """Two numbers (outer, inner gimbal axis), each passed through ``check``."""
    vals = _entries(value, name, 2, "outer, inner")
    return tuple(check(v, f"{name}[{i}]") for i, v in enumerate(vals))


def triple(value, name: str, check=check_nonnegative) -> tuple[float, float, float]:
    """Three numbers (x, y, z), each passed through ``check`` (default: finite and >= 0)."""
    vals = _entries(value, name, 3, "x, y, z")
    return tuple(check(v, f"{name}[{i}]") for i, v in enumerate(vals))
