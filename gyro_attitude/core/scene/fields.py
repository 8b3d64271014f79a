"""Reading a scene mapping: the key-path reader (:class:`Fields`) and field declarations.

:class:`Field` declares one key of a scene section — its kind, unit, default, bounds and the
factor that takes the file's unit to SI — and :func:`read_fields` reads a mapping against a
tuple of them, refusing unknown keys and naming the key's path in every error. The motion
and instrument tables of :mod:`gyro_attitude.core.scene.registry` are built from these.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from enum import Enum
from typing import Any

import numpy as np

#: Most entries in any list of a scene (profile segments, harmonic torques, impacts).
MAX_LIST_ITEMS = 10_000

#: Marks a required value (no default).
REQUIRED: Any = object()


class Fields:
    """Reads one mapping of the scene; every error names the key's path."""

    def __init__(self, d: Any, path: str, allowed: tuple[str, ...]):
        if not isinstance(d, dict):
            raise ValueError(f"{path or 'scene'}: must be a mapping, got {type(d).__name__}")
        for k in d:
            if k not in allowed:
                raise ValueError(
                    f"{self._join(path, k)}: unknown key (allowed here: {', '.join(allowed)})"
                )
        self.d = d
        self.path = path

    @staticmethod
    def _join(path, k):
        return f"{path}.{k}" if path else str(k)

    def key(self, k: str) -> str:
        return self._join(self.path, k)

    def has(self, k: str) -> bool:
        return self.d.get(k) is not None

    def raw(self, k: str, default=REQUIRED):
        if self.d.get(k) is None:
            if default is REQUIRED:
                raise ValueError(f"{self.key(k)}: required value is missing")
            return default
        return self.d[k]

    def number(self, k, default=REQUIRED, lo=None, hi=None, lo_open=False, hi_open=False):
        v = self.raw(k, default)
        if v is default and default is not REQUIRED:
            return v
        if isinstance(v, bool) or not isinstance(v, int | float):
            raise ValueError(f"{self.key(k)}: must be a number, got {v!r}")
        v = float(v)
        if not math.isfinite(v):
            raise ValueError(f"{self.key(k)}: must be finite, got {v}")
        if lo is not None and (v < lo or (lo_open and v == lo)):
            raise ValueError(f"{self.key(k)}: must be {'>' if lo_open else '>='} {lo:g}, got {v:g}")
        if hi is not None and (v > hi or (hi_open and v == hi)):
            raise ValueError(f"{self.key(k)}: must be {'<' if hi_open else '<='} {hi:g}, got {v:g}")
        return v

    def integer(self, k, default=REQUIRED, lo=None, hi=None):
        v = self.raw(k, default)
        if isinstance(v, bool) or not isinstance(v, int | np.integer):
            raise ValueError(f"{self.key(k)}: must be an integer, got {v!r}")
        if lo is not None and v < lo:
            raise ValueError(f"{self.key(k)}: must be >= {lo}, got {v}")
        if hi is not None and v > hi:
            raise ValueError(f"{self.key(k)}: must be <= {hi}, got {v}")
        return int(v)

    def boolean(self, k, default=REQUIRED) -> bool:
        v = self.raw(k, default)
        if not isinstance(v, bool):
            raise ValueError(f"{self.key(k)}: must be true or false, got {v!r}")
        return v

    def string(self, k, default=REQUIRED, choices=None) -> str:
        v = self.raw(k, default)
        if not isinstance(v, str):
            raise ValueError(f"{self.key(k)}: must be a string, got {v!r}")
        if choices is not None and v not in choices:
            raise ValueError(f"{self.key(k)}: must be one of {', '.join(choices)}; got {v!r}")
        return v

    def array(self, k, shape, default=REQUIRED, scalar_ok=False, nonnegative=False):
        v = self.raw(k, default)
        if scalar_ok and is_number(v):
            a = np.full(shape, float(v))
        else:
            # The nesting is checked before numpy sees the value: a YAML alias bomb or a
            # huge list must be refused, not expanded into an array first.
            check_nested_shape(v, shape, self.key(k))
            a = np.asarray(v, dtype=np.float64)
        if not np.all(np.isfinite(a)):
            raise ValueError(f"{self.key(k)}: must be finite")
        if nonnegative and np.any(a < 0):
            raise ValueError(f"{self.key(k)}: must be >= 0, got {a.tolist()}")
        return a

    def section(self, k, allowed, required=False) -> Fields | None:
        if not self.has(k):
            if required:
                raise ValueError(f"{self.key(k)}: required section is missing")
            return None
        return Fields(self.d[k], self.key(k), allowed)


def is_number(v) -> bool:
    return not isinstance(v, bool) and isinstance(v, int | float | np.integer | np.floating)


def check_nested_shape(v, shape: tuple[int, ...], key: str) -> None:
    """Refuse ``v`` unless it is (nested) lists of numbers of exactly ``shape``."""
    if isinstance(v, np.ndarray):
        if v.shape != shape:
            raise ValueError(f"{key}: must have shape {shape}, got {v.shape}")
        return

    def walk(x, depth: int) -> None:
        if depth == len(shape):
            if not is_number(x):
                raise ValueError(f"{key}: must be numbers of shape {shape}, got {x!r:.80}")
            return
        if not isinstance(x, list | tuple) or len(x) != shape[depth]:
            got = f"a list of {len(x)}" if isinstance(x, list | tuple) else f"{x!r:.80}"
            raise ValueError(f"{key}: must have shape {shape}, got {got}")
        for item in x:
            walk(item, depth + 1)

    walk(v, 0)


def list_items(f: Fields, k: str) -> list:
    """The list under ``k`` (a single mapping counts as one item), at most MAX_LIST_ITEMS."""
    v = f.raw(k)
    items = v if isinstance(v, list) else [v]
    if len(items) > MAX_LIST_ITEMS:
        raise ValueError(f"{f.key(k)}: at most {MAX_LIST_ITEMS} entries, got {len(items)}")
    return items




class Kind(Enum):
    """What a declared key holds."""

    NUMBER = "number"
    INTEGER = "integer"
    BOOLEAN = "boolean"
    STRING = "string"
    VECTOR3 = "3 numbers"
    SECTION = "mapping"
    LIST = "list of mappings"


@dataclass(frozen=True)
class Field:
    """One key of a scene section.

    ``default``: :data:`REQUIRED`, ``None`` (optional: absent reads as None) or the value
    (in SI, after ``scale``) used when the key is absent. ``lo``/``hi`` bound the value as
    written in the file (its ``unit``); ``scale`` takes it to SI (``math.pi / 180`` for
    degrees, ``2π`` for Hz to rad/s). A SECTION or LIST holds ``fields``; ``make`` turns a
    section's dict of values into the value the builder gets (a LIST applies it per item).
    """

    key: str
    kind: Kind = Kind.NUMBER
    unit: str = ""
    default: Any = REQUIRED
    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    hi_open: bool = False
    scale: float = 1.0
    choices: tuple[str, ...] = ()
    fields: tuple[Field, ...] = ()
    make: Callable[[dict], Any] | None = None
    help: str = ""

    def bounds_text(self) -> str:
        """``[lo, hi]`` as the file writes it (open ends with parentheses)."""
        if self.kind not in (Kind.NUMBER, Kind.INTEGER, Kind.VECTOR3):
            return ""
        lo = "-inf" if self.lo is None else f"{self.lo:g}"
        hi = "inf" if self.hi is None else f"{self.hi:g}"
        return f"{'(' if self.lo_open else '['}{lo}, {hi}{')' if self.hi_open else ']'}"

    def read(self, f: Fields) -> Any:
        """This key's value from ``f`` in SI (its default when absent)."""
        k = self.key
        if not f.has(k):
            if self.default is REQUIRED:
                f.raw(k)  # raises "required value is missing" with the path
            return self.default
        bounds = {"lo": self.lo, "hi": self.hi}
        if self.kind is Kind.NUMBER:
            v = f.number(k, lo=self.lo, hi=self.hi, lo_open=self.lo_open, hi_open=self.hi_open)
            return v * self.scale if self.scale != 1.0 else v
        if self.kind is Kind.INTEGER:
            return f.integer(k, **bounds)
        if self.kind is Kind.BOOLEAN:
            return f.boolean(k)
        if self.kind is Kind.STRING:
            return f.string(k, choices=self.choices or None)
        if self.kind is Kind.VECTOR3:
            a = f.array(k, (3,))
            if (self.lo is not None and np.any(a < self.lo)) or (
                    self.hi is not None and np.any(a > self.hi)):
                raise ValueError(f"{f.key(k)}: each value must lie in {self.bounds_text()}"
                                 f"{' ' + self.unit if self.unit else ''}, got {a.tolist()}")
            return a * self.scale if self.scale != 1.0 else a
        if self.kind is Kind.SECTION:
            values = read_fields(f.section(k, keys_of(self.fields)), self.fields)
            return self.make(values) if self.make else values
        # LIST of sections (a single mapping counts as one item, unless the list is required)
        if self.default is REQUIRED and not (isinstance(f.raw(k), list) and f.raw(k)):
            raise ValueError(f"{f.key(k)}: must be a non-empty list")
        items = list_items(f, k)
        out = []
        for i, item in enumerate(items):
            values = read_fields(Fields(item, f"{f.key(k)}[{i}]", keys_of(self.fields)),
                                 self.fields)
            out.append(self.make(values) if self.make else values)
        return out


def keys_of(fields: tuple[Field, ...]) -> tuple[str, ...]:
    return tuple(fl.key for fl in fields)


def read_fields(f: Fields, fields: tuple[Field, ...]) -> dict[str, Any]:
    """Every declared key of ``f`` read (in declaration order) into ``{key: SI value}``."""
    return {fl.key: fl.read(f) for fl in fields}


def degrees(key: str, default: Any = REQUIRED, lo=None, hi=None, **kw) -> Field:
    """A key in degrees read into radians."""
    return Field(key, Kind.NUMBER, "deg", default, lo, hi, scale=math.pi / 180.0, **kw)
