"""Parameter declaration and checking shared by the gyro_attitude nodes.

Each node lists its parameters once as :class:`ParamSpec` rows (name, default, description,
numeric range or allowed strings, whether it may change at runtime). From that list
:func:`declare_all` declares them with ``ParameterDescriptor`` (``FloatingPointRange`` /
``IntegerRange``, so ``ros2 param describe`` shows the limits) and :func:`check_value`
validates a value the same way at start and in the ``add_on_set_parameters_callback``.
A bad value at start raises :class:`ParameterError`, whose message names the parameter;
the nodes' ``main()`` prints it and exits with status 2.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.exceptions import InvalidParameterValueException, ParameterException
from rclpy.parameter import Parameter

__all__ = ["ParamSpec", "ParameterError", "declare_all", "check_value", "check_update",
           "spec_from_setting"]


class ParameterError(ValueError):
    """A parameter value is invalid; the message names the parameter."""


@dataclass(frozen=True)
class ParamSpec:
    """One node parameter.

    low/high: inclusive numeric range (float or int parameters); choices: allowed strings;
    length: required array length (float arrays); runtime: may change after start.
    A list/tuple default of strings (non-empty: the type comes from its elements) makes a
    string-array parameter; of numbers, a float-array parameter.
    """

    name: str
    default: object
    description: str
    low: float | int | None = None
    high: float | int | None = None
    choices: tuple[str, ...] = field(default_factory=tuple)
    length: int | None = None
    runtime: bool = False

    @property
    def is_string_array(self) -> bool:
        return isinstance(self.default, list | tuple) and bool(self.default) and all(
            isinstance(v, str) for v in self.default)


def spec_from_setting(setting) -> ParamSpec:
    """The :class:`ParamSpec` of an estimator setting (``core/attitude/settings.Setting``):
    same name, default (an enum as its word), description with unit and range."""
    default = setting.default
    choices: tuple[str, ...] = ()
    if setting.choices is not None:
        choices = tuple(m.value for m in setting.choices)
        default = default.value
    vector = setting.kind == "vector"
    return ParamSpec(setting.name, default, setting.describe(),
                     low=None if vector else setting.low, high=None if vector else setting.high,
                     choices=choices, length=setting.length, runtime=setting.runtime)


def _descriptor(spec: ParamSpec) -> ParameterDescriptor:
    desc = ParameterDescriptor(description=spec.description, read_only=False)
    extra = []
    if spec.choices:
        extra.append("one of: " + ", ".join(spec.choices))
    if not spec.runtime:
        extra.append("fixed after start")
    if extra:
        desc.additional_constraints = "; ".join(extra)
    if isinstance(spec.default, float) and not isinstance(spec.default, bool):
        # Accept `-p rate_hz:=500` (an INTEGER on the command line) for a float parameter;
        # check_value() still enforces number-ness and the range, and declare_all() makes
        # it a DOUBLE (at start and on every set: its pre-set callback).
        desc.dynamic_typing = True
    if spec.low is not None and spec.high is not None:
        if isinstance(spec.default, bool):
            pass
        elif isinstance(spec.default, int):
            desc.integer_range = [IntegerRange(from_value=int(spec.low), to_value=int(spec.high),
                                               step=0)]
        elif isinstance(spec.default, float):
            desc.floating_point_range = [
                FloatingPointRange(from_value=float(spec.low), to_value=float(spec.high), step=0.0)
            ]
    return desc


def check_value(spec: ParamSpec, value) -> str | None:
    """``None`` when ``value`` is valid for ``spec``, else a reason naming the parameter."""
    name = spec.name
    default = spec.default
    if isinstance(default, bool):
        if not isinstance(value, bool):
            return f"parameter '{name}' must be a bool, got {value!r}"
        return None
    if isinstance(default, str):
        if not isinstance(value, str):
            return f"parameter '{name}' must be a string, got {value!r}"
        if spec.choices and value not in spec.choices:
            return f"parameter '{name}' must be one of {list(spec.choices)}, got {value!r}"
        return None
    if isinstance(default, int | float):
        if isinstance(value, bool) or not isinstance(value, int | float):
            return f"parameter '{name}' must be a number, got {value!r}"
        if isinstance(default, int) and not isinstance(value, int):
            return f"parameter '{name}' must be an integer, got {value!r}"
        if not math.isfinite(value):
            return f"parameter '{name}' must be finite, got {value!r}"
        if spec.low is not None and value < spec.low:
            return f"parameter '{name}' must be >= {spec.low}, got {value!r}"
        if spec.high is not None and value > spec.high:
            return f"parameter '{name}' must be <= {spec.high}, got {value!r}"
        return None
    if spec.is_string_array:
        if isinstance(value, str) or not isinstance(value, list | tuple) or not all(
                isinstance(v, str) for v in value):
            return f"parameter '{name}' must be an array of strings, got {value!r}"
        return None
    if isinstance(default, list | tuple):
        try:
            values = [float(v) for v in value]
        except (TypeError, ValueError):
            return f"parameter '{name}' must be an array of numbers, got {value!r}"
        if spec.length is not None and len(values) != spec.length:
            return f"parameter '{name}' must have {spec.length} elements, got {len(values)}"
        if not all(math.isfinite(v) for v in values):
            return f"parameter '{name}' must be finite, got {values}"
        return None
    return None


def declare_all(node, specs: list[ParamSpec]) -> dict[str, object]:
    """Declare every parameter (overrides from --ros-args/YAML apply) and validate all.

    Returns ``{name: value}``. Raises :class:`ParameterError` naming the first bad one.
    """
    values: dict[str, object] = {}
    floats = {s.name for s in specs if isinstance(s.default, float)
              and not isinstance(s.default, bool)}

    def as_double(params):
        # `-p max_gap_s:=1` or `ros2 param set ... 2`: an INTEGER for a double parameter is
        # taken as that double (dynamic typing lets it through; it must not stay an integer)
        return [Parameter(p.name, Parameter.Type.DOUBLE, float(p.value))
                if p.name in floats and p.type_ is Parameter.Type.INTEGER else p
                for p in params]

    node.add_pre_set_parameters_callback(as_double)
    for spec in specs:
        default = spec.default
        if spec.is_string_array:
            default = list(default)  # declares a STRING_ARRAY
        elif isinstance(default, list | tuple):
            default = [float(v) for v in default]  # declares a DOUBLE_ARRAY
        try:
            param = node.declare_parameter(spec.name, default, _descriptor(spec))
        except InvalidParameterValueException as exc:
            # rclpy's own range check (FloatingPointRange / IntegerRange) refused it
            raise ParameterError(f"parameter '{spec.name}': {exc}") from exc
        except ParameterException as exc:  # e.g. wrong type in YAML / --ros-args
            raise ParameterError(f"parameter '{spec.name}': {exc}") from exc
        value = param.value
        if spec.is_string_array:
            value = list(value) if isinstance(value, list | tuple) else value
        elif isinstance(value, tuple | list) or type(value).__name__ == "array":
            value = [float(v) for v in value]
        reason = check_value(spec, value)
        if reason is not None:
            raise ParameterError(reason)
        if isinstance(spec.default, float) and not isinstance(value, bool):
            value = float(value)
            if param.type_ is Parameter.Type.INTEGER:  # an override given as an integer
                node.set_parameters([Parameter(spec.name, Parameter.Type.DOUBLE, value)])
        values[spec.name] = value
    return values


def check_update(specs: dict[str, ParamSpec], params) -> str | None:
    """Reason to refuse a runtime set of ``params`` (rclpy ``Parameter`` list), or None."""
    for p in params:
        spec = specs.get(p.name)
        if spec is None:
            continue
        if not spec.runtime:
            return f"parameter '{p.name}' cannot change at runtime (restart the node)"
        value = p.value
        if type(value).__name__ == "array" or isinstance(value, tuple):
            value = list(value)
        reason = check_value(spec, value)
        if reason is not None:
            return reason
    return None
