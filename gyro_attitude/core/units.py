"""Datasheet quantities with units in the value ("0.15 deg/sqrt(h)") converted to SI (numpy only).

Rule: a value is either a plain number, taken as SI (rad, m, s), or a string
``"<number> <unit expression>"``. The unit expression is unit names joined by ``/`` (left to
right: ``deg/h/sqrt(h)`` = deg / h / √h) and ``*``, each optionally raised with ``^`` and
``sqrt(...)`` (or ``√``) around any sub-expression. Its dimension (powers of angle, length
and time) must be the one the key asks for, so ``"3 deg/h"`` is refused as an angle random
walk. Known units:

* angle: ``rad mrad urad deg arcmin arcsec``
* length: ``m mm``;  acceleration: ``g mg ug`` (standard gravity 9.80665 m/s²)
* time: ``s ms min h hr``;  frequency: ``Hz`` (= 1/s, so ``deg/s/sqrt(Hz)`` = ``deg/sqrt(s)``)

Spectral densities and random-walk coefficients are the same number in SI
(rad/s/√Hz = rad/√s): the usual datasheet convention that Allan analysis also uses.
"""

from __future__ import annotations

import math
import re
from fractions import Fraction

from gyro_attitude.core.earth import STANDARD_GRAVITY

__all__ = ["DIMENSIONS", "to_si", "format_si"]

# Dimension = (angle, length, time) exponents.
_UNITS: dict[str, tuple[float, tuple[Fraction, Fraction, Fraction]]] = {}


def _unit(names, factor, angle=0, length=0, time=0):
    for n in names:
        _UNITS[n] = (factor, (Fraction(angle), Fraction(length), Fraction(time)))


_G0 = STANDARD_GRAVITY
_unit(("rad",), 1.0, angle=1)
_unit(("mrad",), 1e-3, angle=1)
_unit(("urad", "µrad"), 1e-6, angle=1)
_unit(("deg", "°"), math.pi / 180.0, angle=1)
_unit(("arcmin",), math.pi / (180.0 * 60.0), angle=1)
_unit(("arcsec",), math.pi / (180.0 * 3600.0), angle=1)
_unit(("m",), 1.0, length=1)
_unit(("mm",), 1e-3, length=1)
_unit(("g",), _G0, length=1, time=-2)
_unit(("mg",), 1e-3 * _G0, length=1, time=-2)
_unit(("ug", "µg"), 1e-6 * _G0, length=1, time=-2)
_unit(("s", "sec"), 1.0, time=1)
_unit(("ms",), 1e-3, time=1)
_unit(("min",), 60.0, time=1)
_unit(("h", "hr"), 3600.0, time=1)
_unit(("Hz",), 1.0, time=-1)

_H = Fraction(1, 2)
# Quantity kinds the error keys ask for: dimension and an example for the error message.
DIMENSIONS: dict[str, tuple[tuple[Fraction, Fraction, Fraction], str]] = {
    "angular rate": ((1, 0, -1), "deg/h, rad/s"),
    "angle random walk": ((1, 0, -_H), "deg/sqrt(h), deg/s/sqrt(Hz), rad/sqrt(s)"),
    "rate random walk": ((1, 0, -3 * _H), "deg/h/sqrt(h), rad/s/sqrt(s)"),
    "acceleration": ((0, 1, -2), "mg, ug, m/s^2"),
    "velocity random walk": ((0, 1, -3 * _H), "m/s/sqrt(h), ug/sqrt(Hz), m/s/sqrt(s)"),
    "acceleration random walk": ((0, 1, -5 * _H), "m/s^2/sqrt(h), m/s^2/sqrt(s)"),
}
DIMENSIONS = {k: (tuple(Fraction(x) for x in d), ex) for k, (d, ex) in DIMENSIONS.items()}

_NUMBER = re.compile(r"\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(.*)$", re.S)
_TOKEN = re.compile(r"\s*(sqrt\(|√|\(|\)|/|\*|·|\^|[-+]?\d+(?:\.\d+)?|[A-Za-zµ°]+)")


class _Parser:
    """Recursive descent over ``expr := factor (('/' | '*') factor)*``,
    ``factor := ('sqrt(' expr ')' | '√' factor | '(' expr ')' | name) ('^' number)?``."""

    def __init__(self, text: str):
        self.text = text
        self.tokens = []
        pos = 0
        while pos < len(text):
            if text[pos:].strip() == "":
                break
            m = _TOKEN.match(text, pos)
            if not m:
                raise ValueError(f"cannot read the unit at {text[pos:]!r}")
            self.tokens.append(m.group(1))
            pos = m.end()
        self.i = 0

    def peek(self):
        return self.tokens[self.i] if self.i < len(self.tokens) else None

    def take(self):
        tok = self.peek()
        self.i += 1
        return tok

    def expr(self):
        f, d = self.factor()
        while self.peek() in ("/", "*", "·"):
            op = self.take()
            f2, d2 = self.factor()
            sign = -1 if op == "/" else 1
            f *= f2**sign
            d = tuple(a + sign * b for a, b in zip(d, d2, strict=True))
        return f, d

    def factor(self):
        tok = self.take()
        if tok is None:
            raise ValueError("unit expression ends early")
        if tok in ("sqrt(", "("):
            f, d = self.expr()
            if self.take() != ")":
                raise ValueError("missing ')'")
            if tok == "sqrt(":
                f, d = math.sqrt(f), tuple(x / 2 for x in d)
        elif tok == "√":
            f, d = self.factor()
            f, d = math.sqrt(f), tuple(x / 2 for x in d)
        elif tok in _UNITS:
            f, d = _UNITS[tok]
        else:
            raise ValueError(f"unknown unit {tok!r} (known: {', '.join(sorted(_UNITS))})")
        if self.peek() == "^":
            self.take()
            p = self.take()
            try:
                power = Fraction(p)
            except (TypeError, ValueError):
                raise ValueError(f"'^' must be followed by a number, got {p!r}") from None
            f, d = f ** float(power), tuple(x * power for x in d)
        return f, d


def _unit_factor(unit: str) -> tuple[float, tuple]:
    p = _Parser(unit)
    f, d = p.expr()
    if p.peek() is not None:
        raise ValueError(f"unexpected {p.peek()!r}")
    return f, d


def to_si(value, kind: str, path: str) -> float:
    """SI value of one datasheet quantity of ``kind`` (a key of :data:`DIMENSIONS`).

    ``value``: a finite number (already SI) or ``"<number> <unit>"``. ``ValueError`` starting
    with ``path`` for anything else: unknown unit, wrong dimension, not finite.
    """
    dim, example = DIMENSIONS[kind]
    if isinstance(value, bool):
        raise ValueError(f"{path}: must be a number or a string with units, got {value!r}")
    if isinstance(value, int | float):
        number, si = float(value), 1.0
    elif isinstance(value, str):
        m = _NUMBER.match(value)
        if not m:
            raise ValueError(f"{path}: expected '<number> <unit>' (e.g. {example}), "
                             f"got {value!r}")
        number = float(m.group(1))
        unit = m.group(2).strip()
        if unit:
            try:
                si, got = _unit_factor(unit)
            except ValueError as exc:
                raise ValueError(f"{path}: {exc} in {value!r}") from None
            if got != dim:
                raise ValueError(f"{path}: {value!r} is not a {kind} (units like {example})")
        else:
            si = 1.0
    else:
        raise ValueError(f"{path}: must be a number or a string with units, got {value!r}")
    out = number * si
    if not math.isfinite(out):
        raise ValueError(f"{path}: must be finite, got {value!r}")
    return out


# Datasheet unit each kind is written back in (format_si), with its SI factor.
_DATASHEET_UNIT = {
    "angular rate": "deg/h",
    "angle random walk": "deg/sqrt(h)",
    "rate random walk": "deg/h/sqrt(h)",
    "acceleration": "ug",
    "velocity random walk": "m/s/sqrt(h)",
    "acceleration random walk": "m/s^2/sqrt(h)",
}


def format_si(value_si: float, kind: str, digits: int = 4) -> str:
    """``value_si`` written in the datasheet unit of ``kind`` (``to_si`` reads it back)."""
    unit = _DATASHEET_UNIT[kind]
    factor, _ = _unit_factor(unit)
    return f"{value_si / factor:.{digits}g} {unit}"
