"""Scenes: a base motion on the Earth plus the instrument effects it calls for (numpy only).

A scene is a plain dict (the YAML files in ``config/scenes/`` are loaded by
:mod:`gyro_attitude.io.scene_file`); :meth:`SceneSpec.from_dict` validates it and refuses an
unknown key, a missing required value or a value out of range with a ``ValueError`` whose
message starts with the key's path (``earth.latitude_deg``, ``motion.segments[1].duration_s``).

Schema (SI units; angles in the file are degrees where the key says ``_deg``)::

    description: one line                 # required
    seed: 42                              # required, int >= 0: every scene is reproducible
    start_time_ns: 0                      # stamp of the first sample (default 0)
    rate_hz: 200.0                        # suggested output rate (default 200)
    duration_s: 60.0                      # suggested run length (default 60)
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
      model: ideal | rate_gyro            # rate_gyro: single-gimbal rate gyro per axis
      rate_gyro: {...}                    # fields of gyro_attitude.core.gyro.RateGyroParams
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
    free_gyro: {...}                      # optional: fields of gyro.FreeGyroParams

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

:class:`SceneSimulator` composes exactly the effects named, once, and evaluates nothing
else; ``effects_run`` records the names of the effects actually evaluated. The gyro
measures ``ω_ib^b = C_bn (ω_ie^n + ω_en^n) + ω_nb^b`` (DESIGN.md), then the instrument
(rate-gyro dynamics, then the error model of :mod:`gyro_attitude.core.sensor_errors`).
Accelerometers measure the specific force ``f^b = C_bn (dv^n/dt + (2ω_ie^n + ω_en^n) × v^n
− g^n)`` with WGS-84 normal gravity (gravitation plus centrifugal); a term whose effect is
switched off (Earth rotation, transport rate, gravity) is left out of that sum.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from gyro_attitude.core import earth
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
from gyro_attitude.core.rotation import quat_conjugate, quat_rotate
from gyro_attitude.core.sensor_errors import SensorErrorModel, SensorErrorParams
from gyro_attitude.core.units import to_si

__all__ = [
    "SceneSpec",
    "EarthSpec",
    "SceneSimulator",
    "SimBlock",
    "GimbalBlock",
    "MOTION_TYPES",
    "integrate_position",
]

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

    def integer(self, k, default=_REQUIRED, lo=None):
        v = self.raw(k, default)
        if isinstance(v, bool) or not isinstance(v, int | np.integer):
            raise ValueError(f"{self.key(k)}: must be an integer, got {v!r}")
        if lo is not None and v < lo:
            raise ValueError(f"{self.key(k)}: must be >= {lo}, got {v}")
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
        try:
            a = np.asarray(v, dtype=np.float64)
        except (TypeError, ValueError):
            raise ValueError(f"{self.key(k)}: must be numbers of shape {shape}, got {v!r}") from None
        if scalar_ok and a.shape == ():
            a = np.full(shape, float(a))
        if a.shape != shape:
            raise ValueError(f"{self.key(k)}: must have shape {shape}, got {a.shape}")
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
            2.0 * math.pi * f.number("frequency_hz"),
            _attitude(f),
        )
    if kind == "spinning_projectile":
        return SpinningProjectile(
            2.0 * math.pi * f.number("spin_rate_hz"),
            math.radians(f.number("half_angle_deg", lo=0.0, hi=180.0)),
            2.0 * math.pi * f.number("coning_frequency_hz"),
            f.number("speed_mps", 0.0, lo=0.0),
            _attitude(f),
        )
    # profile
    segs = f.raw("segments")
    if not isinstance(segs, list) or not segs:
        raise ValueError(f"{f.key('segments')}: must be a non-empty list of segments")
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


def _c2_params(cls_name: str, d: Any, path: str):
    """Build one of C2's parameter dataclasses from a YAML mapping, naming bad keys."""
    try:
        from gyro_attitude.core import gyro as gyro_module
    except ImportError as exc:
        raise ValueError(f"{path}: gyro dynamics (gyro_attitude.core.gyro) unavailable: {exc}") \
            from exc
    cls = getattr(gyro_module, cls_name, None)
    if cls is None:
        raise ValueError(f"{path}: gyro_attitude.core.gyro has no {cls_name}")
    names = tuple(fl.name for fl in dataclasses.fields(cls))
    f = _Fields({} if d is None else d, path, names)
    kw = dict(f.d)
    # Nested torque lists of the free gyro: mappings -> C2's HarmonicTorque / ImpactTorque.
    for key, item_cls_name in (("harmonic_torques", "HarmonicTorque"), ("impacts", "ImpactTorque")):
        if key in kw:
            item_cls = getattr(gyro_module, item_cls_name)
            items = kw[key] if isinstance(kw[key], list) else [kw[key]]
            built = []
            for i, item in enumerate(items):
                item_path = f"{path}.{key}[{i}]"
                fi = _Fields(item, item_path, tuple(fl.name for fl in dataclasses.fields(item_cls)))
                try:
                    built.append(item_cls(**fi.d))
                except (TypeError, ValueError) as exc:
                    raise ValueError(f"{item_path}: {exc}") from exc
            kw[key] = tuple(built)
    try:
        return cls(**kw)
    except TypeError as exc:
        raise ValueError(f"{path}: {exc}") from exc
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from exc


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
    rate_gyro_params: Any = None
    gyro_errors: SensorErrorParams = dataclasses.field(default_factory=SensorErrorParams)
    accelerometer: bool = False
    gravity: bool = True
    accel_errors: SensorErrorParams = dataclasses.field(default_factory=SensorErrorParams)
    free_gyro_params: Any = None
    source: dict = dataclasses.field(default_factory=dict)

    @classmethod
    def from_dict(cls, d: dict, name: str = "scene") -> SceneSpec:
        """Validate a scene mapping; ``ValueError`` names the offending key's path."""
        top = _Fields(d, "", (
            "description", "seed", "start_time_ns", "rate_hz", "duration_s", "earth", "motion",
            "gyro", "accelerometer", "free_gyro",
        ))
        description = top.string("description")
        seed = top.integer("seed", lo=0)
        start_time_ns = top.integer("start_time_ns", 0, lo=0)
        rate_hz = top.number("rate_hz", 200.0, lo=0.0, lo_open=True)
        duration_s = top.number("duration_s", 60.0, lo=0.0, lo_open=True)

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

        g = top.section("gyro", ("model", "rate_gyro", "errors"))
        gyro_model, rate_params, gyro_errors = "ideal", None, SensorErrorParams()
        if g is not None:
            gyro_model = g.string("model", "ideal", choices=("ideal", "rate_gyro"))
            if gyro_model == "rate_gyro":
                rate_params = _c2_params("RateGyroParams", g.raw("rate_gyro"), g.key("rate_gyro"))
            elif g.has("rate_gyro"):
                raise ValueError(f"{g.key('rate_gyro')}: given but gyro.model is 'ideal'")
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
            free_params = _c2_params("FreeGyroParams", top.raw("free_gyro"), "free_gyro")

        return cls(
            name=name, description=description, seed=seed, earth=earth_spec, motion=motion,
            motion_type=motion.name, start_time_ns=start_time_ns, rate_hz=rate_hz,
            duration_s=duration_s, gyro_model=gyro_model, rate_gyro_params=rate_params,
            gyro_errors=gyro_errors, accelerometer=accel, gravity=gravity,
            accel_errors=accel_errors, free_gyro_params=free_params, source=dict(d),
        )


# --------------------------------------------------------------------------- position
def _simpson_cumulative(h, f_a, f_m, f_b):
    """Cumulative Simpson sums over consecutive intervals of widths ``h``."""
    return np.cumsum(h / 6.0 * (f_a + 4.0 * f_m + f_b), axis=0)


def _hermite_mid(y_a, y_b, f_a, f_b, h):
    """Cubic Hermite value at an interval's midpoint from end values and slopes."""
    return 0.5 * (y_a + y_b) + h / 8.0 * (f_a - f_b)


def integrate_position(motion: Motion, t0: float, llh0, t) -> np.ndarray:
    """Geodetic position ``(lat, lon, h)`` (rad, rad, m) at times ``t`` (s, sorted).

    Integrates ``(L̇, λ̇, ḣ) = (v_N/(R_M+h), v_E/((R_N+h) cos L), v_U)`` from ``llh0`` at
    ``t0`` with the motion's exact velocity: Simpson's rule over each interval between
    consecutive times (velocity at the midpoints evaluated in closed form), the latitude
    dependence of the radii resolved by three Picard sweeps with cubic-Hermite midpoint
    values. The integrand varies on the scale of the Earth's radius, so each sweep shrinks
    the error by ~e²·|v|·Δt/R and three leave it at rounding level for any block length.
    """
    t = np.asarray(t, dtype=np.float64)
    nodes = np.concatenate(([t0], t))
    h = np.diff(nodes)
    mids = nodes[:-1] + 0.5 * h
    v_n = motion.velocity(nodes)
    v_m = motion.velocity(mids)
    lat0, lon0, hgt0 = (float(x) for x in llh0)

    hgt = np.concatenate(([hgt0], hgt0 + _simpson_cumulative(h, v_n[:-1, 2], v_m[:, 2],
                                                             v_n[1:, 2])))
    hgt_m = _hermite_mid(hgt[:-1], hgt[1:], v_n[:-1, 2], v_n[1:, 2], h)

    def lat_rate(lat, height, v_north):
        r_m, _ = earth.radii_of_curvature(lat)
        return v_north / (r_m + height)

    lat = np.full(nodes.shape, lat0)
    for _ in range(3):
        f_n = lat_rate(lat, hgt, v_n[:, 1])
        lat_m = _hermite_mid(lat[:-1], lat[1:], f_n[:-1], f_n[1:], h)
        f_m = lat_rate(lat_m, hgt_m, v_m[:, 1])
        lat = np.concatenate(([lat0], lat0 + _simpson_cumulative(h, f_n[:-1], f_m, f_n[1:])))

    def lon_rate(lat_, height, v_east):
        _, r_n = earth.radii_of_curvature(lat_)
        return v_east / ((r_n + height) * np.cos(lat_))

    f_n = lat_rate(lat, hgt, v_n[:, 1])
    lat_m = _hermite_mid(lat[:-1], lat[1:], f_n[:-1], f_n[1:], h)
    g_n = lon_rate(lat, hgt, v_n[:, 0])
    g_m = lon_rate(lat_m, hgt_m, v_m[:, 0])
    lon = lon0 + _simpson_cumulative(h, g_n[:-1], g_m, g_n[1:])
    # Longitude is reported wrapped into [-π, π).
    lon = (lon + np.pi) % (2.0 * np.pi) - np.pi
    return np.stack((lat[1:], lon, hgt[1:]), axis=-1)


# --------------------------------------------------------------------------- simulator
@dataclass
class GimbalBlock:
    """Gimbal state of a gimballed instrument: ``names (k,)``, ``angles (n,k)`` rad,
    ``rates (n,k)`` rad/s."""

    names: tuple[str, ...]
    angles: np.ndarray
    rates: np.ndarray


@dataclass
class SimBlock:
    """``n`` consecutive output samples of a scene (see module docstring for the physics).

    ``t_ns (n,)`` int64 stamps; ``omega_ib_b (n,3)`` measured gyro output (rad/s);
    ``specific_force_b (n,3)`` measured accelerometer output (m/s²) or ``None`` when the scene
    has no accelerometer; truth: ``truth_q_nb (n,4)``, ``truth_omega_nb_b (n,3)``,
    ``truth_omega_ib_b (n,3)``, ``position_llh (n,3)`` (rad, rad, m), ``velocity_enu (n,3)``;
    ``gimbal`` (free gyro) or ``None``.
    """

    t_ns: np.ndarray
    omega_ib_b: np.ndarray
    specific_force_b: np.ndarray | None
    truth_q_nb: np.ndarray
    truth_omega_nb_b: np.ndarray
    truth_omega_ib_b: np.ndarray
    position_llh: np.ndarray
    velocity_enu: np.ndarray
    gimbal: GimbalBlock | None = None


class SceneSimulator:
    """Generates a scene's samples at ``rate_hz`` in resumable, vectorized blocks.

    ``seed=None`` uses the scene's ``seed``; the same seed gives identical output, and the
    output does not depend on how it is split into blocks (each random process has its own
    generator). Sample k is stamped ``start_time_ns + k·10⁹/rate_hz`` ns (integer division
    when ``rate_hz`` is an integer, else rounded); truth is evaluated at exactly those stamps.
    ``effects_run`` is the set of effect names actually evaluated so far, e.g.
    ``motion.coning``, ``earth_rate``, ``transport_rate``, ``position``, ``gravity``,
    ``coriolis``, ``specific_force``, ``rate_gyro``, ``free_gyro``, ``gyro.white_noise``,
    ``accelerometer.bias``.
    """

    def __init__(self, spec: SceneSpec, rate_hz: float, seed: int | None = None):
        if isinstance(rate_hz, bool) or not (np.isfinite(rate_hz) and rate_hz > 0):
            raise ValueError(f"rate_hz must be a finite positive number, got {rate_hz!r}")
        self.spec = spec
        self.rate_hz = float(rate_hz)
        self.dt = 1.0 / self.rate_hz
        self.seed = spec.seed if seed is None else int(seed)
        self.effects_run: set[str] = set()
        self._k = 0
        ea = spec.earth
        self._anchor_t = 0.0
        self._anchor_llh = np.array([ea.latitude_rad, ea.longitude_rad, ea.height_m])
        gyro_ss, accel_ss = np.random.SeedSequence(self.seed).spawn(2)
        self._gyro_errors = (SensorErrorModel(spec.gyro_errors, self.dt, gyro_ss)
                             if spec.gyro_errors.active_effects() else None)
        self._accel_errors = (SensorErrorModel(spec.accel_errors, self.dt, accel_ss)
                              if spec.accelerometer and spec.accel_errors.active_effects()
                              else None)
        self._rate_gyro = None
        self._free_gyro = None
        self._constant_case_rate = None
        if spec.gyro_model == "rate_gyro":
            from gyro_attitude.core.gyro import RateGyroTriad

            self._rate_gyro = RateGyroTriad(spec.rate_gyro_params, self.dt)
        if spec.free_gyro_params is not None:
            from gyro_attitude.core.gyro import FreeGyroSimulator

            self._free_gyro = FreeGyroSimulator(spec.free_gyro_params, self._case_rate, t0=0.0)

    # ------------------------------------------------------------------ pieces
    def _stamps(self, n: int) -> np.ndarray:
        k = np.arange(self._k, self._k + n, dtype=np.int64)
        if self.rate_hz.is_integer():
            offset = (k * 1_000_000_000) // int(self.rate_hz)
        else:
            offset = np.rint(k * (1e9 / self.rate_hz)).astype(np.int64)
        return self.spec.start_time_ns + offset

    def _positions(self, t: np.ndarray) -> np.ndarray:
        if not self.spec.motion.moves:
            return np.broadcast_to(self._anchor_llh, (t.shape[0], 3)).copy()
        self.effects_run.add("position")
        order = np.argsort(t, kind="stable")
        out = np.empty((t.shape[0], 3))
        out[order] = integrate_position(self.spec.motion, self._anchor_t, self._anchor_llh,
                                        t[order])
        return out

    def _nav_rates(self, llh: np.ndarray, v: np.ndarray):
        """``(ω_ie^n, ω_en^n)``; ``None`` for an effect the scene does not call for."""
        ea = self.spec.earth
        w_ie = w_en = None
        if ea.rotation:
            self.effects_run.add("earth_rate")
            w_ie = earth.earth_rate_enu(llh[:, 0])
        if ea.transport_rate and self.spec.motion.moves:
            self.effects_run.add("transport_rate")
            w_en = earth.transport_rate_enu(llh[:, 0], llh[:, 2], v)
        return w_ie, w_en

    def _truth(self, t: np.ndarray, need_accel: bool):
        sample = self.spec.motion.evaluate(t, need_accel=need_accel)
        self.effects_run.add(f"motion.{self.spec.motion.name}")
        llh = self._positions(t)
        w_ie, w_en = self._nav_rates(llh, sample.velocity_enu)
        if w_ie is None and w_en is None:
            w_ib = sample.omega_nb_b.copy()
        else:
            w_in = w_ie if w_en is None else (w_en if w_ie is None else w_ie + w_en)
            w_ib = quat_rotate(quat_conjugate(sample.q_nb), w_in) + sample.omega_nb_b
        return sample, llh, w_ie, w_en, w_ib

    def _case_rate(self, t) -> np.ndarray:
        """Inertial angular velocity of the instrument case in the case (body) frame,
        ``ω_ib^b(t)`` at any times ``t`` (s since the start): the free gyro's base motion."""
        t = np.atleast_1d(np.asarray(t, dtype=np.float64))
        if isinstance(self.spec.motion, Stationary):
            # At rest ω_ib^b = C_bn ω_ie^n is constant; the free gyro asks for it at every
            # integration sub-step, one time at a time, so compute it once.
            if self._constant_case_rate is None:
                self._constant_case_rate = self._truth(np.zeros(1), need_accel=False)[4][0]
            return np.broadcast_to(self._constant_case_rate, (t.shape[0], 3)).copy()
        return self._truth(t, need_accel=False)[4]

    def _specific_force(self, sample, llh, w_ie, w_en) -> np.ndarray:
        self.effects_run.add("specific_force")
        f_n = sample.accel_enu.copy()
        if self.spec.motion.moves and (w_ie is not None or w_en is not None):
            self.effects_run.add("coriolis")
            w = np.zeros_like(f_n)
            if w_ie is not None:
                w += 2.0 * w_ie
            if w_en is not None:
                w += w_en
            f_n += np.cross(w, sample.velocity_enu)
        if self.spec.gravity:
            self.effects_run.add("gravity")
            f_n -= earth.gravity_enu(llh[:, 0], llh[:, 2])
        return quat_rotate(quat_conjugate(sample.q_nb), f_n)

    # ------------------------------------------------------------------ public
    def next_block(self, n: int) -> SimBlock:
        """The next ``n`` output samples (truth and measurements); resumable."""
        if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 0:
            raise ValueError(f"n must be a non-negative integer, got {n!r}")
        n = int(n)
        spec = self.spec
        t_ns = self._stamps(n)
        t = (t_ns - spec.start_time_ns).astype(np.float64) / 1e9
        sample, llh, w_ie, w_en, w_ib = self._truth(t, need_accel=spec.accelerometer)

        gyro_out = w_ib
        if self._rate_gyro is not None:
            self.effects_run.add("rate_gyro")
            gyro_out = np.asarray(self._rate_gyro.step_block(w_ib), dtype=np.float64)
        if self._gyro_errors is not None:
            gyro_out = self._gyro_errors.apply(gyro_out)
            self.effects_run.update(f"gyro.{e}" for e in self._gyro_errors.effects_run)
        elif gyro_out is w_ib:
            gyro_out = w_ib.copy()

        f_b = None
        if spec.accelerometer:
            f_b = self._specific_force(sample, llh, w_ie, w_en)
            if self._accel_errors is not None:
                f_b = self._accel_errors.apply(f_b)
                self.effects_run.update(f"accelerometer.{e}"
                                        for e in self._accel_errors.effects_run)

        if n:
            self._anchor_t = float(t[-1])
            self._anchor_llh = llh[-1].copy()
        self._k += n

        gimbal = None
        if self._free_gyro is not None:
            self.effects_run.add("free_gyro")
            angles, rates = self._free_gyro.run_until(t)
            gimbal = GimbalBlock(tuple(self._free_gyro.names), np.asarray(angles),
                                 np.asarray(rates))

        return SimBlock(
            t_ns=t_ns, omega_ib_b=gyro_out, specific_force_b=f_b, truth_q_nb=sample.q_nb,
            truth_omega_nb_b=sample.omega_nb_b, truth_omega_ib_b=w_ib, position_llh=llh,
            velocity_enu=sample.velocity_enu, gimbal=gimbal,
        )

    def imu_variances(self) -> tuple[np.ndarray | None, np.ndarray | None]:
        """Per-axis variance per sample of the gyro ((rad/s)²) and accelerometer ((m/s²)²)
        random errors (white noise, bias instability, quantization).

        An ideal instrument gives zeros ("known perfect"); the accelerometer entry is
        ``None`` when the scene has no accelerometer (publish −1: no estimate).
        Deterministic errors (bias, scale factor, misalignment, rate-gyro dynamics) are
        not random and are not part of the variance.
        """
        gyro = (self._gyro_errors.variances() if self._gyro_errors is not None
                else np.zeros(3))
        if not self.spec.accelerometer:
            return gyro, None
        accel = (self._accel_errors.variances() if self._accel_errors is not None
                 else np.zeros(3))
        return gyro, accel
