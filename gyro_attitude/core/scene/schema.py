"""Scene schema: the YAML mapping of a scene validated into a SceneSpec, each error naming the key's path.

A scene is a plain dict (the YAML files in ``config/scenes/`` are loaded by
:mod:`gyro_attitude.io.scene_file`); :meth:`SceneSpec.from_dict` validates it and refuses an
unknown key, a missing required value or a value out of range with a ``ValueError`` whose
message starts with the key's path (``earth.latitude_deg``, ``motion.segments[1].duration_s``).

Schema (SI units; angles in the file are degrees where the key says ``_deg``)::

    description: one line                 # required
    seed: 42                              # required, int >= 0: every scene is reproducible
    start_time_ns: 0                      # stamp of the first sample (default 0)
    rate_hz: 200.0                        # suggested output rate (default 200, <= 1 MHz)
    duration_s: 60.0                      # suggested run length (default 60, <= 1e7 s)
    earth:
      latitude_deg: 45.0                  # required, [-90, 90]
      longitude_deg: 0.0                  # [-180, 180]
      height_m: 0.0                       # WGS-84 ellipsoidal height
      rotation: true                      # Earth rate ω_ie
      transport_rate: true                # ω_en from the carrier velocity
    motion:
      type: stationary | constant_velocity | coordinated_turn | ship | coning
            | spinning_projectile | profile
      ...                                 # per type, below
    gyro:                                 # optional (ideal gyro triad)
      model: ideal | rate_gyro | integrating_gyro   # single-gimbal gyro per axis
      rate_gyro: {...}                    # fields of core.gyro.rate_gyro.RateGyroParams
      integrating_gyro: {...}             # fields of core.gyro.rate_gyro.IntegratingGyroParams
      errors: {bias_rad_s, scale_factor, misalignment_rad, arw_rad_sqrt_s,
               bias_instability_rad_s, bias_instability_tau_s, quantization_rad,
               arw, bias_instability, rate_random_walk}   # last three: datasheet terms
    accelerometer:                        # optional: only then is specific force computed
      gravity: true
      errors: {bias_m_s2, scale_factor, misalignment_rad, vrw_m_s_sqrt_s,
               bias_instability_m_s2, bias_instability_tau_s, quantization_m_s,
               vrw, bias_instability, acceleration_random_walk}
    # Datasheet terms take a number (SI) or a string with units ("0.15 deg/sqrt(h)",
    # "3 deg/h", "12 deg/h/sqrt(h)"; gyro_attitude.core.units), scalar or 3 values;
    # bias_instability is the Allan floor B (not a Gauss–Markov σ: that is *_rad_s + tau).
    free_gyro: {...}                      # optional: fields of core.gyro.free_gyro.FreeGyroParams
    instrument:                           # optional (not with free_gyro): one of the book's
      type: gyrocompass | vertical_gyro | directional_gyro | spinning_shell  # keys per type below
      max_step_s: 10.0                    # solver step limit (< the shortest manoeuvre)

Motion keys per type (``attitude: {roll_deg, pitch_deg, yaw_deg}`` is ROS roll/pitch/yaw,
``q_nb = Rz(yaw) Ry(pitch) Rx(roll)``, yaw counter-clockwise from East; see
:mod:`gyro_attitude.core.motion` for the closed forms)::

    stationary:          attitude
    constant_velocity:   speed_mps (along body x), attitude
    coordinated_turn:    speed_mps, turn_rate_deg_s (+ = left), yaw_deg, bank_deg (default:
                         coordinated against standard gravity)
    ship:                speed_mps, yaw_deg (course), roll / pitch / yaw_oscillation:
                         {amplitude_deg, period_s, phase_deg}, heave: {amplitude_m, period_s,
                         phase_deg}
    coning:              half_angle_deg, frequency_hz, attitude (of the cone axis frame)
    spinning_projectile: spin_rate_hz, half_angle_deg, coning_frequency_hz, speed_mps,
                         attitude (of the cone axis frame)
    profile:             attitude, velocity_enu_mps, segments: [{duration_s,
                         angular_rate_deg_s (body), acceleration_enu_mps2}, ...]

Instrument keys per type (the instrument sees the full Earth: rotation and transport rate;
its joints, published on ``gyro/joint_states``, are named in :mod:`gyro_attitude.core.instruments`)::

    gyrocompass:       angular_momentum (N·m·s, required); exactly one of pendulous_moment (kg·m),
                       schuler_tuned: true (at the scene latitude) or period_s; damping_ratio (0);
                       latitude_correction (true); azimuth0_deg (0), elevation0_deg (default: the
                       static tilt) or start_settled: true (the settle point of the initial velocity)
    vertical_gyro:     erection_law (proportional | constant_rate), erection_gain (1/s),
                       erection_rate_deg_s, linear_zone_deg, spin_axis0 (ENU, default up)
    directional_gyro:  latitude_nut_deg (none: no nut), leveling_gain (1/s)
    spinning_shell:    spin_inertia, transverse_inertia (kg·m²), spin_rate (rad/s), exactly one of
                       overturning_moment (N·m) or stability_factor; theta0_deg (2); the Earth
                       and the carrier do not enter (a flight of seconds, velocity fixed in space)

Sizes that drive allocation or work are bounded here, so that a valid scene cannot ask for
unbounded memory: ``rate_hz`` (at most :data:`MAX_RATE_HZ`), ``duration_s`` (at most
:data:`MAX_DURATION_S`), ``start_time_ns`` (at most :data:`MAX_START_TIME_NS`, so int64
stamps cannot overflow), the number of profile segments, harmonic torques and impacts
(at most :data:`MAX_LIST_ITEMS` each), and every array is checked for its shape before
it is converted.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from gyro_attitude.core.gyro.free_gyro import FreeGyroParams, HarmonicTorque, ImpactTorque
from gyro_attitude.core.gyro.rate_gyro import IntegratingGyroParams, RateGyroParams
from gyro_attitude.core.instruments.directional_gyro import DirectionalGyro, DirectionalGyroParams
from gyro_attitude.core.instruments.gyrocompass import (
    Gyrocompass,
    GyrocompassParams,
    gyrocompass_settle_point,
)
from gyro_attitude.core.instruments.stability import ShellParams, SpinningShell
from gyro_attitude.core.instruments.vertical_gyro import (
    ERECTION_LAWS,
    VerticalGyro,
    VerticalGyroParams,
)
from gyro_attitude.core.motion import (
    ClassicalConing,
    ConstantVelocity,
    CoordinatedTurn,
    Motion,
    ProfileSegment,
    SegmentProfile,
    ShipMotion,
    SpinningProjectile,
    Stationary,
)
from gyro_attitude.core.sensor_errors import SensorErrorParams
from gyro_attitude.core.units import to_si

__all__ = [
    "SceneSpec",
    "InstrumentSpec",
    "INSTRUMENT_TYPES",
    "EarthSpec",
    "MOTION_TYPES",
    "MAX_RATE_HZ",
    "MAX_DURATION_S",
    "MAX_START_TIME_NS",
    "MAX_LIST_ITEMS",
]

#: Highest sample rate a scene may ask for (Hz). Simulated IMUs run at 100 Hz…10 kHz; 1 MHz
#: leaves room for stress tests while a block of a fraction of a second stays small.
MAX_RATE_HZ = 1.0e6
#: Longest suggested run (s): about 116 days.
MAX_DURATION_S = 1.0e7
#: Latest first stamp (ns), about 146 years: leaves as much again before int64 stamps overflow.
MAX_START_TIME_NS = 2**62
#: Most entries in any list of a scene (profile segments, harmonic torques, impacts).
MAX_LIST_ITEMS = 10_000

_REQUIRED = object()

MOTION_TYPES = (
    "stationary",
    "constant_velocity",
    "coordinated_turn",
    "ship",
    "coning",
    "spinning_projectile",
    "profile",
)

# Allowed keys per motion type (besides "type").
MOTION_KEYS = {
    "stationary": ("attitude",),
    "constant_velocity": ("speed_mps", "attitude"),
    "coordinated_turn": ("speed_mps", "turn_rate_deg_s", "yaw_deg", "bank_deg"),
    "ship": ("speed_mps", "yaw_deg", "roll", "pitch", "yaw_oscillation", "heave"),
    "coning": ("half_angle_deg", "frequency_hz", "attitude"),
    "spinning_projectile": (
        "spin_rate_hz", "half_angle_deg", "coning_frequency_hz", "speed_mps", "attitude",
    ),
    "profile": ("attitude", "velocity_enu_mps", "segments"),
}

INSTRUMENT_TYPES = ("gyrocompass", "vertical_gyro", "directional_gyro", "spinning_shell")

# Allowed keys per instrument type (besides "type" and "max_step_s").
INSTRUMENT_KEYS = {
    "gyrocompass": ("angular_momentum", "pendulous_moment", "schuler_tuned", "period_s",
                    "damping_ratio", "latitude_correction", "azimuth0_deg", "elevation0_deg",
                    "start_settled"),
    "vertical_gyro": ("erection_law", "erection_gain", "erection_rate_deg_s", "linear_zone_deg",
                      "spin_axis0"),
    "directional_gyro": ("latitude_nut_deg", "leveling_gain"),
    "spinning_shell": ("spin_inertia", "transverse_inertia", "spin_rate", "overturning_moment",
                       "stability_factor", "theta0_deg"),
}

# YAML error keys -> SensorErrorParams field, per instrument.
_GYRO_ERROR_KEYS = {
    "bias_rad_s": "bias",
    "scale_factor": "scale_factor",
    "misalignment_rad": "misalignment",
    "arw_rad_sqrt_s": "noise_density",
    "bias_instability_rad_s": "bias_instability_sigma",
    "bias_instability_tau_s": "bias_instability_tau",
    "quantization_rad": "quantum",
}
_ACCEL_ERROR_KEYS = {
    "bias_m_s2": "bias",
    "scale_factor": "scale_factor",
    "misalignment_rad": "misalignment",
    "vrw_m_s_sqrt_s": "noise_density",
    "bias_instability_m_s2": "bias_instability_sigma",
    "bias_instability_tau_s": "bias_instability_tau",
    "quantization_m_s": "quantum",
}
# Datasheet error keys with units in the value -> (SensorErrorParams field, quantity kind,
# the SI-number key for the same field that must not be given too).
_GYRO_DATASHEET_KEYS = {
    "arw": ("noise_density", "angle random walk", "arw_rad_sqrt_s"),
    "bias_instability": ("bias_instability_floor", "angular rate", None),
    "rate_random_walk": ("rate_random_walk", "rate random walk", None),
}
_ACCEL_DATASHEET_KEYS = {
    "vrw": ("noise_density", "velocity random walk", "vrw_m_s_sqrt_s"),
    "bias_instability": ("bias_instability_floor", "acceleration", None),
    "acceleration_random_walk": ("rate_random_walk", "acceleration random walk", None),
}


# --------------------------------------------------------------------------- validation
class _Fields:
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

    def raw(self, k: str, default=_REQUIRED):
        if self.d.get(k) is None:
            if default is _REQUIRED:
                raise ValueError(f"{self.key(k)}: required value is missing")
            return default
        return self.d[k]

    def number(self, k, default=_REQUIRED, lo=None, hi=None, lo_open=False, hi_open=False):
        v = self.raw(k, default)
        if v is default and default is not _REQUIRED:
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

    def integer(self, k, default=_REQUIRED, lo=None, hi=None):
        v = self.raw(k, default)
        if isinstance(v, bool) or not isinstance(v, int | np.integer):
            raise ValueError(f"{self.key(k)}: must be an integer, got {v!r}")
        if lo is not None and v < lo:
            raise ValueError(f"{self.key(k)}: must be >= {lo}, got {v}")
        if hi is not None and v > hi:
            raise ValueError(f"{self.key(k)}: must be <= {hi}, got {v}")
        return int(v)

    def boolean(self, k, default=_REQUIRED) -> bool:
        v = self.raw(k, default)
        if not isinstance(v, bool):
            raise ValueError(f"{self.key(k)}: must be true or false, got {v!r}")
        return v

    def string(self, k, default=_REQUIRED, choices=None) -> str:
        v = self.raw(k, default)
        if not isinstance(v, str):
            raise ValueError(f"{self.key(k)}: must be a string, got {v!r}")
        if choices is not None and v not in choices:
            raise ValueError(f"{self.key(k)}: must be one of {', '.join(choices)}; got {v!r}")
        return v

    def array(self, k, shape, default=_REQUIRED, scalar_ok=False, nonnegative=False):
        v = self.raw(k, default)
        if scalar_ok and _is_number(v):
            a = np.full(shape, float(v))
        else:
            # The nesting is checked before numpy sees the value: a YAML alias bomb or a
            # huge list must be refused, not expanded into an array first.
            _check_nested_shape(v, shape, self.key(k))
            a = np.asarray(v, dtype=np.float64)
        if not np.all(np.isfinite(a)):
            raise ValueError(f"{self.key(k)}: must be finite")
        if nonnegative and np.any(a < 0):
            raise ValueError(f"{self.key(k)}: must be >= 0, got {a.tolist()}")
        return a

    def section(self, k, allowed, required=False) -> _Fields | None:
        if not self.has(k):
            if required:
                raise ValueError(f"{self.key(k)}: required section is missing")
            return None
        return _Fields(self.d[k], self.key(k), allowed)


def _is_number(v) -> bool:
    return not isinstance(v, bool) and isinstance(v, int | float | np.integer | np.floating)


def _check_nested_shape(v, shape: tuple[int, ...], key: str) -> None:
    """Refuse ``v`` unless it is (nested) lists of numbers of exactly ``shape``."""
    if isinstance(v, np.ndarray):
        if v.shape != shape:
            raise ValueError(f"{key}: must have shape {shape}, got {v.shape}")
        return

    def walk(x, depth: int) -> None:
        if depth == len(shape):
            if not _is_number(x):
                raise ValueError(f"{key}: must be numbers of shape {shape}, got {x!r:.80}")
            return
        if not isinstance(x, list | tuple) or len(x) != shape[depth]:
            got = f"a list of {len(x)}" if isinstance(x, list | tuple) else f"{x!r:.80}"
            raise ValueError(f"{key}: must have shape {shape}, got {got}")
        for item in x:
            walk(item, depth + 1)

    walk(v, 0)


def _list_items(f: _Fields, k: str) -> list:
    """The list under ``k`` (a single mapping counts as one item), at most MAX_LIST_ITEMS."""
    v = f.raw(k)
    items = v if isinstance(v, list) else [v]
    if len(items) > MAX_LIST_ITEMS:
        raise ValueError(f"{f.key(k)}: at most {MAX_LIST_ITEMS} entries, got {len(items)}")
    return items


def _attitude(f: _Fields) -> tuple[float, float, float]:
    a = f.section("attitude", ("roll_deg", "pitch_deg", "yaw_deg"))
    if a is None:
        return (0.0, 0.0, 0.0)
    return (
        math.radians(a.number("roll_deg", 0.0, -180.0, 180.0)),
        math.radians(a.number("pitch_deg", 0.0, -90.0, 90.0)),
        math.radians(a.number("yaw_deg", 0.0, -360.0, 360.0)),
    )


def _oscillation(f: _Fields, k: str, unit: str) -> tuple[float, float, float]:
    s = f.section(k, (f"amplitude_{unit}", "period_s", "phase_deg"))
    if s is None:
        return (0.0, 0.0, 0.0)
    amp = s.number(f"amplitude_{unit}", lo=0.0)
    period = s.number("period_s", lo=0.0, lo_open=True)
    phase = math.radians(s.number("phase_deg", 0.0))
    if unit == "deg":
        amp = math.radians(amp)
    return (amp, period, phase)


def _build_motion(f: _Fields) -> Motion:
    kind = f.string("type", choices=MOTION_TYPES)
    # Re-check the keys for this type (the section was opened with all keys allowed).
    _Fields(f.d, f.path, ("type",) + MOTION_KEYS[kind])
    if kind == "stationary":
        return Stationary(_attitude(f))
    if kind == "constant_velocity":
        return ConstantVelocity(f.number("speed_mps", lo=0.0), _attitude(f))
    if kind == "coordinated_turn":
        bank = f.number("bank_deg", None, -89.0, 89.0)
        return CoordinatedTurn(
            f.number("speed_mps", lo=0.0),
            math.radians(f.number("turn_rate_deg_s", lo=-360.0, hi=360.0)),
            math.radians(f.number("yaw_deg", 0.0, -360.0, 360.0)),
            None if bank is None else math.radians(bank),
        )
    if kind == "ship":
        return ShipMotion(
            f.number("speed_mps", 0.0, lo=0.0),
            math.radians(f.number("yaw_deg", 0.0, -360.0, 360.0)),
            {
                "roll": _oscillation(f, "roll", "deg"),
                "pitch": _oscillation(f, "pitch", "deg"),
                "yaw": _oscillation(f, "yaw_oscillation", "deg"),
                "heave": _oscillation(f, "heave", "m"),
            },
        )
    if kind == "coning":
        return ClassicalConing(
            math.radians(f.number("half_angle_deg", lo=0.0, hi=180.0)),
            2.0 * math.pi * f.number("frequency_hz", lo=-MAX_RATE_HZ, hi=MAX_RATE_HZ),
            _attitude(f),
        )
    if kind == "spinning_projectile":
        return SpinningProjectile(
            2.0 * math.pi * f.number("spin_rate_hz", lo=-MAX_RATE_HZ, hi=MAX_RATE_HZ),
            math.radians(f.number("half_angle_deg", lo=0.0, hi=180.0)),
            2.0 * math.pi * f.number("coning_frequency_hz", lo=-MAX_RATE_HZ, hi=MAX_RATE_HZ),
            f.number("speed_mps", 0.0, lo=0.0),
            _attitude(f),
        )
    # profile
    segs = f.raw("segments")
    if not isinstance(segs, list) or not segs:
        raise ValueError(f"{f.key('segments')}: must be a non-empty list of segments")
    segs = _list_items(f, "segments")
    segments = []
    for i, s in enumerate(segs):
        sf = _Fields(s, f"{f.key('segments')}[{i}]",
                     ("duration_s", "angular_rate_deg_s", "acceleration_enu_mps2"))
        segments.append(
            ProfileSegment(
                sf.number("duration_s", lo=0.0, lo_open=True),
                tuple(np.radians(sf.array("angular_rate_deg_s", (3,), np.zeros(3)))),
                tuple(sf.array("acceleration_enu_mps2", (3,), np.zeros(3))),
            )
        )
    return SegmentProfile(segments, _attitude(f), f.array("velocity_enu_mps", (3,), np.zeros(3)))


def _datasheet_terms(f: _Fields, datasheet: dict[str, tuple]) -> dict[str, np.ndarray]:
    """Datasheet keys (value with units, scalar or 3 values) -> SI fields, >= 0."""
    kw: dict[str, np.ndarray] = {}
    for key, (field_name, kind, si_key) in datasheet.items():
        if not f.has(key):
            continue
        if si_key is not None and f.has(si_key):
            raise ValueError(f"{f.key(key)}: give either {key} or {si_key}, not both")
        v = f.raw(key)
        items = v if isinstance(v, list) else [v]
        if len(items) not in (1, 3):
            raise ValueError(f"{f.key(key)}: must be one value or 3 (x, y, z), got {len(items)}")
        si = np.array([to_si(x, kind, f.key(key) if len(items) == 1 else f"{f.key(key)}[{i}]")
                       for i, x in enumerate(items)])
        if np.any(si < 0):
            raise ValueError(f"{f.key(key)}: must be >= 0, got {v!r}")
        kw[field_name] = np.broadcast_to(si, (3,)).copy()
    return kw


def _error_params(f: _Fields | None, keys: dict[str, str],
                  datasheet: dict[str, tuple] | None = None) -> SensorErrorParams:
    if f is None:
        return SensorErrorParams()
    kw: dict[str, Any] = _datasheet_terms(f, datasheet or {})
    for yaml_key, field_name in keys.items():
        if not f.has(yaml_key):
            continue
        if field_name == "misalignment":
            m = f.array(yaml_key, (3, 3))
            if np.any(np.diag(m) != 0):
                raise ValueError(f"{f.key(yaml_key)}: diagonal must be zero (use scale_factor)")
            kw[field_name] = m
        elif field_name == "bias_instability_tau":
            kw[field_name] = f.array(yaml_key, (3,), scalar_ok=True)
            if np.any(kw[field_name] <= 0):
                raise ValueError(f"{f.key(yaml_key)}: must be > 0")
        else:
            kw[field_name] = f.array(
                yaml_key, (3,), scalar_ok=True,
                nonnegative=field_name in ("noise_density", "bias_instability_sigma", "quantum"),
            )
    return SensorErrorParams(**kw)


def _instrument_params(cls, d: Any, path: str):
    """Build an instrument's parameter dataclass from a YAML mapping, naming bad keys."""
    names = tuple(fl.name for fl in dataclasses.fields(cls))
    f = _Fields({} if d is None else d, path, names)
    kw = dict(f.d)
    # Nested torque lists of the free gyro: mappings -> HarmonicTorque / ImpactTorque.
    for key, item_cls in (("harmonic_torques", HarmonicTorque), ("impacts", ImpactTorque)):
        if f.has(key):
            built = []
            for i, item in enumerate(_list_items(f, key)):
                item_path = f"{path}.{key}[{i}]"
                fi = _Fields(item, item_path, tuple(fl.name for fl in dataclasses.fields(item_cls)))
                try:
                    built.append(item_cls(**fi.d))
                except (TypeError, ValueError) as exc:
                    raise ValueError(f"{item_path}: {exc}") from exc
            kw[key] = tuple(built)
    try:
        return cls(**kw)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{path}: {exc}") from exc


@dataclass(frozen=True)
class InstrumentSpec:
    """One of the book's instruments in a scene: ``type``, the ``instrument`` object (with
    ``JOINTS``, ``initial_state``, ``rhs``, ``outputs``), the keyword arguments of its
    ``initial_state`` and the solver's ``max_step`` (s)."""

    type: str
    instrument: object
    initial: dict
    max_step: float


def _build_instrument(f: _Fields, earth_spec: EarthSpec, motion: Motion) -> InstrumentSpec:
    kind = f.string("type", choices=INSTRUMENT_TYPES)
    _Fields(f.d, f.path, ("type", "max_step_s") + INSTRUMENT_KEYS[kind])
    max_step = f.number("max_step_s", 10.0 if kind != "vertical_gyro" else 1.0,
                        lo=1e-6, hi=3600.0)
    lat = earth_spec.latitude_rad
    if kind == "spinning_shell":
        return _build_shell(f, max_step)
    if not (earth_spec.rotation and earth_spec.transport_rate):
        raise ValueError(f"{f.path}: the instruments always see the Earth's rotation and the "
                         "transport rate; set earth.rotation and earth.transport_rate true")

    def built(fn, key):
        try:
            return fn()
        except ValueError as exc:
            raise ValueError(f"{f.key(key)}: {exc}") from exc

    initial: dict = {}
    if kind == "gyrocompass":
        h = f.number("angular_momentum", lo=0.0, lo_open=True)
        zeta = f.number("damping_ratio", 0.0, lo=0.0, hi=10.0)
        corr = f.boolean("latitude_correction", True)
        given = [k for k in ("pendulous_moment", "schuler_tuned", "period_s") if f.has(k)]
        if len(given) != 1:
            raise ValueError(f"{f.path}: give exactly one of pendulous_moment, schuler_tuned, "
                             f"period_s (got {', '.join(given) or 'none'})")
        if given[0] == "schuler_tuned":
            if not f.boolean("schuler_tuned"):
                raise ValueError(f"{f.key('schuler_tuned')}: must be true when given")
            params = built(lambda: GyrocompassParams.schuler_tuned(h, lat, zeta, corr),
                           "schuler_tuned")
        elif given[0] == "period_s":
            period = f.number("period_s", lo=0.0, lo_open=True, hi=1.0e6)
            params = built(lambda: GyrocompassParams.with_period(h, period, lat, zeta, corr),
                           "period_s")
        else:
            ml = f.number("pendulous_moment", lo=0.0, lo_open=True)
            params = built(lambda: GyrocompassParams.with_damping_ratio(h, ml, lat, zeta, corr),
                           "pendulous_moment")
        if f.boolean("start_settled", False):
            if f.has("azimuth0_deg") or f.has("elevation0_deg"):
                raise ValueError(f"{f.key('start_settled')}: not with azimuth0_deg/elevation0_deg")
            v0 = motion.evaluate(np.zeros(1)).velocity_enu[0]
            a0, b0 = built(lambda: gyrocompass_settle_point(params, lat, v0), "start_settled")
            initial = {"azimuth0": a0, "elevation0": b0}
        else:
            initial = {"azimuth0": math.radians(f.number("azimuth0_deg", 0.0, -180.0, 180.0))}
            if f.has("elevation0_deg"):
                initial["elevation0"] = math.radians(f.number("elevation0_deg", lo=-80.0, hi=80.0))
        instrument = Gyrocompass(params)
    elif kind == "vertical_gyro":
        law = f.string("erection_law", "proportional", choices=ERECTION_LAWS)
        kw = {"erection_law": law}
        if f.has("erection_gain"):
            kw["erection_gain"] = f.number("erection_gain", lo=0.0, lo_open=True, hi=1.0e3)
        if f.has("erection_rate_deg_s"):
            kw["erection_rate"] = math.radians(f.number("erection_rate_deg_s", lo=0.0,
                                                        lo_open=True, hi=1.0e3))
        if f.has("linear_zone_deg"):
            kw["linear_zone"] = math.radians(f.number("linear_zone_deg", lo=0.0, lo_open=True,
                                                      hi=89.0))
        instrument = VerticalGyro(built(lambda: VerticalGyroParams(**kw), "erection_law"))
        if f.has("spin_axis0"):
            s0 = f.array("spin_axis0", (3,))
            if not np.linalg.norm(s0) > 0.0 or s0[2] <= 0.0:
                raise ValueError(f"{f.key('spin_axis0')}: must point above the horizon")
            initial = {"spin_axis0": tuple(s0)}
    else:
        nut = (math.radians(f.number("latitude_nut_deg", lo=-90.0, hi=90.0))
               if f.has("latitude_nut_deg") else None)
        instrument = DirectionalGyro(built(lambda: DirectionalGyroParams(
            nut, f.number("leveling_gain", 0.0, lo=0.0, hi=1.0e3)), "leveling_gain"))
    return InstrumentSpec(kind, instrument, initial, max_step)


def _build_shell(f: _Fields, max_step: float) -> InstrumentSpec:
    c = f.number("spin_inertia", lo=0.0, lo_open=True)
    a = f.number("transverse_inertia", lo=0.0, lo_open=True)
    n = f.number("spin_rate", lo=0.0, lo_open=True, hi=1.0e5)
    given = [k for k in ("overturning_moment", "stability_factor") if f.has(k)]
    if len(given) != 1:
        raise ValueError(f"{f.path}: give exactly one of overturning_moment, stability_factor "
                         f"(got {', '.join(given) or 'none'})")
    if given[0] == "stability_factor":
        params = ShellParams.with_stability_factor(
            f.number("stability_factor", lo=0.0, lo_open=True, hi=1.0e6), c, a, n)
    else:
        params = ShellParams(c, a, f.number("overturning_moment", lo=0.0, lo_open=True), n)
    theta0 = math.radians(f.number("theta0_deg", 2.0, lo=0.0, hi=179.0))
    return InstrumentSpec("spinning_shell", SpinningShell(params), {"theta0": theta0},
                          min(max_step, 0.1))


# --------------------------------------------------------------------------- spec
@dataclass(frozen=True)
class EarthSpec:
    """Initial position (rad, rad, m) and which Earth effects the scene calls for."""

    latitude_rad: float
    longitude_rad: float = 0.0
    height_m: float = 0.0
    rotation: bool = True
    transport_rate: bool = True


@dataclass(frozen=True)
class SceneSpec:
    """A validated scene. Build it with :meth:`from_dict` (or ``io.scene_file.load_scene``)."""

    name: str
    description: str
    seed: int
    earth: EarthSpec
    motion: Motion
    motion_type: str
    start_time_ns: int = 0
    rate_hz: float = 200.0
    duration_s: float = 60.0
    gyro_model: str = "ideal"
    rate_gyro_params: RateGyroParams | IntegratingGyroParams | None = None
    gyro_errors: SensorErrorParams = dataclasses.field(default_factory=SensorErrorParams)
    accelerometer: bool = False
    gravity: bool = True
    accel_errors: SensorErrorParams = dataclasses.field(default_factory=SensorErrorParams)
    free_gyro_params: FreeGyroParams | None = None
    instrument: InstrumentSpec | None = None
    source: dict = dataclasses.field(default_factory=dict)

    @classmethod
    def from_dict(cls, d: dict, name: str = "scene") -> SceneSpec:
        """Validate a scene mapping; ``ValueError`` names the offending key's path."""
        top = _Fields(d, "", (
            "description", "seed", "start_time_ns", "rate_hz", "duration_s", "earth", "motion",
            "gyro", "accelerometer", "free_gyro", "instrument",
        ))
        description = top.string("description")
        seed = top.integer("seed", lo=0)
        start_time_ns = top.integer("start_time_ns", 0, lo=0, hi=MAX_START_TIME_NS)
        rate_hz = top.number("rate_hz", 200.0, lo=0.0, lo_open=True, hi=MAX_RATE_HZ)
        duration_s = top.number("duration_s", 60.0, lo=0.0, lo_open=True, hi=MAX_DURATION_S)

        e = top.section("earth", ("latitude_deg", "longitude_deg", "height_m", "rotation",
                                  "transport_rate"), required=True)
        earth_spec = EarthSpec(
            math.radians(e.number("latitude_deg", lo=-90.0, hi=90.0)),
            math.radians(e.number("longitude_deg", 0.0, -180.0, 180.0)),
            e.number("height_m", 0.0, -12000.0, 1.0e6),
            e.boolean("rotation", True),
            e.boolean("transport_rate", True),
        )

        m = top.section("motion", ("type",) + tuple({k for v in MOTION_KEYS.values() for k in v}),
                        required=True)
        motion = _build_motion(m)

        g = top.section("gyro", ("model", "rate_gyro", "integrating_gyro", "errors"))
        gyro_model, rate_params, gyro_errors = "ideal", None, SensorErrorParams()
        if g is not None:
            gyro_model = g.string("model", "ideal",
                                  choices=("ideal", "rate_gyro", "integrating_gyro"))
            for kind, cls_ in (("rate_gyro", RateGyroParams),
                               ("integrating_gyro", IntegratingGyroParams)):
                if gyro_model == kind:
                    rate_params = _instrument_params(cls_, g.raw(kind), g.key(kind))
                elif g.has(kind):
                    raise ValueError(f"{g.key(kind)}: given but gyro.model is {gyro_model!r}")
            gyro_errors = _error_params(
                g.section("errors", tuple(_GYRO_ERROR_KEYS) + tuple(_GYRO_DATASHEET_KEYS)),
                _GYRO_ERROR_KEYS, _GYRO_DATASHEET_KEYS,
            )

        accel, gravity, accel_errors = False, True, SensorErrorParams()
        if "accelerometer" in d:  # even an empty `accelerometer:` asks for accelerometers
            accel = True
            a = _Fields(d["accelerometer"] or {}, "accelerometer", ("gravity", "errors"))
            gravity = a.boolean("gravity", True)
            accel_errors = _error_params(
                a.section("errors", tuple(_ACCEL_ERROR_KEYS) + tuple(_ACCEL_DATASHEET_KEYS)),
                _ACCEL_ERROR_KEYS, _ACCEL_DATASHEET_KEYS,
            )

        free_params = None
        if top.has("free_gyro"):
            free_params = _instrument_params(FreeGyroParams, top.raw("free_gyro"), "free_gyro")

        instrument = None
        if top.has("instrument"):
            if free_params is not None:
                raise ValueError("instrument: a scene has one gimballed instrument; "
                                 "remove free_gyro or instrument")
            i = top.section("instrument", ("type", "max_step_s")
                            + tuple({k for v in INSTRUMENT_KEYS.values() for k in v}))
            instrument = _build_instrument(i, earth_spec, motion)

        return cls(
            name=name, description=description, seed=seed, earth=earth_spec, motion=motion,
            motion_type=motion.name, start_time_ns=start_time_ns, rate_hz=rate_hz,
            duration_s=duration_s, gyro_model=gyro_model, rate_gyro_params=rate_params,
            gyro_errors=gyro_errors, accelerometer=accel, gravity=gravity,
            accel_errors=accel_errors, free_gyro_params=free_params, instrument=instrument,
            source=dict(d),
        )
