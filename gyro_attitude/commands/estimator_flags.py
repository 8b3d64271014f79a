"""Command-line flags of the estimator settings, made from the one table
(:data:`gyro_attitude.core.attitude.settings.SETTINGS`): every setting is ``--name-with-dashes``
with its type, range and help.

Flags not given stay out of the namespace (``argparse.SUPPRESS``), so :func:`config_from_args`
knows which settings the user set and leaves the rest at the table's defaults.  Shorthands kept
from earlier releases, each one line below: ``--initial-attitude truth|level|accelerometer|auto``
(the source),
``--gyro-bias X,Y,Z`` (a fixed bias), ``--latitude-deg`` / ``--longitude-deg`` (degrees), and
``--gyro-bias-sigma``.
"""

from __future__ import annotations

import argparse
import math

from gyro_attitude.core.attitude.modes import GyroBiasMode, InitialAttitudeSource, SettingError
from gyro_attitude.core.attitude.settings import SETTINGS, Setting, StreamConfig

__all__ = ["add_estimator_flags", "config_from_args", "given_settings"]

_DEST = "setting__"  # namespace prefix of the settings' values


def _parse(setting: Setting, text: str):
    """A flag's text as the setting's value, checked against the table row."""
    kind = setting.kind
    try:
        if kind == "vector":
            value = tuple(float(c) for c in text.split(","))
        elif kind in ("float", "int"):
            value = float(text)
        elif kind == "bool":
            low = text.strip().lower()
            if low not in ("true", "false", "1", "0", "yes", "no"):
                raise ValueError(f"{setting.name} must be true or false, got {text!r}")
            value = low in ("true", "1", "yes")
        else:
            value = text
        return setting.check(value)
    except SettingError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"{setting.name} must be {_expected(setting)}, got {text!r}") from None


def _expected(setting: Setting) -> str:
    """What a flag's text must be, in words ("N" alone reads as a typo)."""
    m = _metavar(setting)
    return "a number" if m == "N" else ("numbers " + m if "," in m else m)


def _metavar(setting: Setting) -> str:
    if setting.kind == "vector":
        return ",".join(["N"] * (setting.length or 1))
    if setting.choices is not None:
        return "|".join(m.value for m in setting.choices)
    return "N"


class _Shorthand(argparse.Action):
    """``--initial-attitude truth|level|accelerometer|auto`` and ``--gyro-bias X,Y,Z``: one
    flag setting two
    settings, as earlier releases took them."""

    def __call__(self, parser, namespace, values, option_string=None):
        name, (mode_setting, mode) = self.dest[len(_DEST):], self.const
        text = values.strip().lower()
        if name == "initial_attitude" and text in (m.value for m in InitialAttitudeSource) \
                and text != InitialAttitudeSource.PARAMETER:
            setattr(namespace, _DEST + mode_setting, InitialAttitudeSource(text))
            return
        if name == "gyro_bias" and text in (m.value for m in GyroBiasMode):
            setattr(namespace, _DEST + "gyro_bias", GyroBiasMode(text))
            return
        target = "gyro_bias_rad_s" if name == "gyro_bias" else name
        setting = next(s for s in SETTINGS if s.name == target)
        try:
            value = _parse(setting, values)
        except argparse.ArgumentTypeError as exc:
            parser.error(f"argument {option_string}: {exc}")
        setattr(namespace, _DEST + target, value)
        setattr(namespace, _DEST + mode_setting, mode)


def _degrees(setting: Setting):
    def parse(text: str):
        try:
            return setting.check(math.radians(float(text)))
        except SettingError as exc:
            raise argparse.ArgumentTypeError(f"{exc} (given in degrees: {text})") from None
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be a number of degrees, got {text!r}") from None
    return parse


def add_estimator_flags(parser: argparse.ArgumentParser, settings=SETTINGS) -> None:
    """One flag per setting of ``settings`` (plus the shorthands of the module docstring)."""
    group = parser.add_argument_group("estimator settings (the attitude_integrator node's "
                                      "parameters, same names)")
    for s in settings:
        kwargs = dict(dest=_DEST + s.name, default=argparse.SUPPRESS, metavar=_metavar(s),
                      # argparse formats help with %: a literal one ("0.3-1 %") must be doubled
                      help=f"{s.describe()}; default {_default_text(s)}".replace("%", "%%"))
        if s.name == "initial_attitude":
            group.add_argument(s.flag, action=_Shorthand,
                               const=("initial_attitude_source", InitialAttitudeSource.PARAMETER),
                               **{**kwargs, "metavar": "X,Y,Z,W|truth|level|accelerometer",
                                  "help": kwargs["help"] + "; 'truth', 'level', "
                                  "'accelerometer' or 'auto' set --initial-attitude-source"})
        elif s.name == "gyro_bias":
            group.add_argument(s.flag, action=_Shorthand,
                               const=("gyro_bias", GyroBiasMode.PARAMETER),
                               **{**kwargs, "metavar": "auto|none|parameter|X,Y,Z",
                                  "help": kwargs["help"] + "; X,Y,Z: a fixed bias in rad/s"})
        else:
            group.add_argument(s.flag, type=lambda text, s=s: _parse(s, text), **kwargs)
        if s.name in ("latitude_rad", "longitude_rad"):
            group.add_argument(s.flag.replace("-rad", "-deg"), type=_degrees(s),
                               dest=_DEST + s.name, default=argparse.SUPPRESS, metavar="DEG",
                               help=f"{s.flag} in degrees")
        if s.name == "gyro_bias_sigma_rad_s":
            group.add_argument("--gyro-bias-sigma", type=lambda text, s=s: _parse(s, text),
                               dest=_DEST + s.name, default=argparse.SUPPRESS,
                               metavar="N", help=f"same as {s.flag}")


def _default_text(s: Setting) -> str:
    d = s.default
    if s.choices is not None:
        return d.value
    if isinstance(d, tuple):
        return ",".join(f"{c:g}" for c in d)
    return f"{d:g}" if isinstance(d, float) else str(d)


def given_settings(args: argparse.Namespace) -> dict:
    """``{name: value}`` of the settings given on the command line."""
    return {k[len(_DEST):]: v for k, v in vars(args).items() if k.startswith(_DEST)}


def config_from_args(args: argparse.Namespace, **overrides) -> StreamConfig:
    """The :class:`StreamConfig` of the given flags (the rest at the table's defaults), with
    ``overrides`` on top; ``SettingError`` naming the setting when a combination is refused."""
    return StreamConfig(**{**given_settings(args), **overrides})
