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
            | spinning_projectile | profile | trajectory
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
      sampling: {bandwidth: {filter: mean | lowpass, order, cutoff_hz}, range_rad_s,
                 turn_on_bias_rad_s, g_sensitivity_rad_s_per_m_s2}   # core.sensor_sampling
    # accelerometer.sampling: {bandwidth, range_m_s2, turn_on_bias_m_s2}
    # kalibr_imu: imu.yaml  (top level; read by io.scene_file: Kalibr's four noise terms)
    # Datasheet terms take a number (SI) or a string with units ("0.15 deg/sqrt(h)",
    # "3 deg/h", "12 deg/h/sqrt(h)"; gyro_attitude.core.units), scalar or 3 values;
    # bias_instability is the Allan floor B (not a Gauss–Markov σ: that is *_rad_s + tau).
    free_gyro: {...}                      # optional: fields of core.gyro.free_gyro.FreeGyroParams
    instrument:                           # optional (not with free_gyro): one of the book's
      type: gyrocompass | vertical_gyro | directional_gyro | spinning_shell  # keys per type below
      max_step_s: 10.0                    # solver step limit (< the shortest manoeuvre)
    magnetometer:                         # optional: imu/mag (core/scene/magnetometer.py)
      model: wmm | given                  # WMM-2025 at the start position, or the three below
      decimal_year, declination_deg, inclination_deg, intensity_ut, hard_iron_ut, soft_iron,
      noise_ut, disturbances: [{start_s, duration_s, field_ut, frame: enu | body}]

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
    trajectory:          file (relative to the scene file), format (tum | csv | mcap), topic,
                         child_frame_id, position_sigma_m, attitude_sigma_rad, max_gap_s
                         (core.trajectory; the file is read by io.scene_file.load_scene)

Every number is bounded at validation (:mod:`gyro_attitude.core.limits`, the choice of
each limit stated there); the motion and instrument keys are declared in
:mod:`gyro_attitude.core.scene.registry`.

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
from gyro_attitude.core.limits import (
    ACCEL_ERROR_LIMITS,
    GYRO_ERROR_LIMITS,
    MAX_DESCRIPTION_CHARS,
    MAX_DURATION_S,
    MAX_HEIGHT_M,
    MAX_RATE_HZ,
    MAX_SEED,
    MIN_HEIGHT_M,
    PARAM_LIMITS,
)
from gyro_attitude.core.motion import Motion
from gyro_attitude.core.scene.fields import MAX_LIST_ITEMS, Fields, is_number, list_items
from gyro_attitude.core.scene.magnetometer import (
    MAGNETOMETER_KEYS,
    MagnetometerSpec,
    parse_magnetometer,
)
from gyro_attitude.core.scene.registry import (
    INSTRUMENT_TYPES,
    INSTRUMENTS,
    MOTION_TYPES,
    MOTIONS,
    build_instrument,
    build_motion,
)
from gyro_attitude.core.sensor_errors import SensorErrorParams
from gyro_attitude.core.sensor_sampling import BANDWIDTH_FILTERS, SamplingParams
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

#: Latest first stamp (ns), about 146 years: leaves as much again before int64 stamps overflow.
MAX_START_TIME_NS = 2**62

MOTION_KEYS = {name: kind.keys for name, kind in MOTIONS.items()}
INSTRUMENT_KEYS = {name: kind.keys for name, kind in INSTRUMENTS.items()}

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


def _datasheet_terms(f: Fields, datasheet: dict[str, tuple]) -> dict[str, np.ndarray]:
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


def _check_limits(key: str, value, lo: float, hi: float, unit: str = "") -> None:
    """Every number in ``value`` (number or nested lists/arrays) within [lo, hi]."""
    a = np.asarray(value, dtype=np.float64)
    if a.size and (np.any(a < lo) or np.any(a > hi)):
        bad = a[(a < lo) | (a > hi)].flat[0]
        raise ValueError(f"{key}: must lie in [{lo:g}, {hi:g}]{' ' + unit if unit else ''}, "
                         f"got {bad:g}")


def _error_params(f: Fields | None, keys: dict[str, str],
                  datasheet: dict[str, tuple] | None = None,
                  limits: dict[str, tuple[float, float]] | None = None) -> SensorErrorParams:
    if f is None:
        return SensorErrorParams()
    limits = limits or {}
    kw: dict[str, Any] = _datasheet_terms(f, datasheet or {})
    for key, (field_name, _, _) in (datasheet or {}).items():
        if field_name in kw and key in limits:
            _check_limits(f.key(key), kw[field_name], *limits[key], "(SI)")
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
        if yaml_key in limits:
            _check_limits(f.key(yaml_key), kw[field_name], *limits[yaml_key])
    return SensorErrorParams(**kw)


def _instrument_params(cls, d: Any, path: str):
    """Build an instrument's parameter dataclass from a YAML mapping, naming bad keys."""
    names = tuple(fl.name for fl in dataclasses.fields(cls))
    f = Fields({} if d is None else d, path, names)
    _check_param_limits(f, cls)
    kw = dict(f.d)
    # Nested torque lists of the free gyro: mappings -> HarmonicTorque / ImpactTorque.
    for key, item_cls in (("harmonic_torques", HarmonicTorque), ("impacts", ImpactTorque)):
        if f.has(key):
            built = []
            for i, item in enumerate(list_items(f, key)):
                item_path = f"{path}.{key}[{i}]"
                fi = Fields(item, item_path, tuple(fl.name for fl in dataclasses.fields(item_cls)))
                _check_param_limits(fi, item_cls)
                try:
                    built.append(item_cls(**fi.d))
                except (TypeError, ValueError) as exc:
                    raise ValueError(f"{item_path}: {exc}") from exc
            kw[key] = tuple(built)
    try:
        return cls(**kw)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{path}: {exc}") from exc


GYRO_SAMPLING_KEYS = ("bandwidth", "range_rad_s", "turn_on_bias_rad_s",
                      "g_sensitivity_rad_s_per_m_s2")
ACCEL_SAMPLING_KEYS = ("bandwidth", "range_m_s2", "turn_on_bias_m_s2")


def _sampling(f: Fields | None, gyro: bool) -> SamplingParams:
    """``gyro.sampling`` / ``accelerometer.sampling`` (core.sensor_sampling): each key off
    unless given. Bounds: range up to 1e3 rad/s (MEMS saturate at 35–70 rad/s) or 2e5 m/s²;
    turn-on bias σ as the error bias limits; g-sensitivity up to 0.02 rad/s per m/s²
    (MEMS: 1e-4–1e-3); filter order 1–8, cut-off up to 100 kHz (below Nyquist at run time)."""
    if f is None:
        return SamplingParams()
    kw: dict[str, Any] = {}
    if f.has("bandwidth"):
        b = f.section("bandwidth", ("filter", "order", "cutoff_hz"))
        kw["bandwidth"] = b.string("filter", choices=BANDWIDTH_FILTERS)
        if kw["bandwidth"] == "lowpass":
            kw["order"] = b.integer("order", 2, lo=1, hi=8)
            kw["cutoff_hz"] = b.number("cutoff_hz", lo=0.0, lo_open=True, hi=1.0e5)
        elif b.has("order") or b.has("cutoff_hz"):
            raise ValueError(f"{b.path}: order and cutoff_hz are for filter: lowpass")
    unit, r_hi, bias_key = (("rad_s", 1.0e3, "bias_rad_s") if gyro
                            else ("m_s2", 2.0e5, "bias_m_s2"))
    if f.has(f"range_{unit}"):
        kw["range"] = f.number(f"range_{unit}", lo=0.0, lo_open=True, hi=r_hi)
    if f.has(f"turn_on_bias_{unit}"):
        sig = f.array(f"turn_on_bias_{unit}", (3,), scalar_ok=True, nonnegative=True)
        lo, hi = (GYRO_ERROR_LIMITS if gyro else ACCEL_ERROR_LIMITS)[bias_key]
        _check_limits(f.key(f"turn_on_bias_{unit}"), sig, 0.0, hi)
        kw["turn_on_bias_sigma"] = sig
    if gyro and f.has("g_sensitivity_rad_s_per_m_s2"):
        key = "g_sensitivity_rad_s_per_m_s2"
        v = f.raw(key)
        g_mat = (np.eye(3) * f.number(key) if is_number(v) else f.array(key, (3, 3)))
        _check_limits(f.key(key), g_mat, -0.02, 0.02, "rad/s per m/s²")
        kw["g_sensitivity"] = g_mat
    return SamplingParams(**kw)


def _check_param_limits(f: Fields, cls) -> None:
    """The numbers given for a parameter dataclass within :data:`~.limits.PARAM_LIMITS`
    (the dataclass's own checks, e.g. positive or non-zero, follow when it is built)."""
    for name, (lo, hi, unit) in PARAM_LIMITS.get(cls.__name__, {}).items():
        v = f.d.get(name)
        if v is None or isinstance(v, bool | str):
            continue
        items = v if isinstance(v, list | tuple) else [v]
        if len(items) <= 3 and all(is_number(x) for x in items):
            _check_limits(f.key(name), items, lo, hi, unit)


@dataclass(frozen=True)
class InstrumentSpec:
    """One of the book's instruments in a scene: ``type``, the ``instrument`` object (with
    ``JOINTS``, ``initial_state``, ``rhs``, ``outputs``), the keyword arguments of its
    ``initial_state`` and the solver's ``max_step`` (s)."""

    type: str
    instrument: object
    initial: dict
    max_step: float


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
    magnetometer: MagnetometerSpec | None = None
    source: dict = dataclasses.field(default_factory=dict)
    gyro_sampling: SamplingParams = dataclasses.field(default_factory=SamplingParams)
    accel_sampling: SamplingParams = dataclasses.field(default_factory=SamplingParams)

    @classmethod
    def from_dict(cls, d: dict, name: str = "scene") -> SceneSpec:
        """Validate a scene mapping; ``ValueError`` names the offending key's path."""
        top = Fields(d, "", (
            "description", "seed", "start_time_ns", "rate_hz", "duration_s", "earth", "motion",
            "gyro", "accelerometer", "free_gyro", "instrument", "magnetometer",
        ))
        description = top.string("description")
        if len(description) > MAX_DESCRIPTION_CHARS:
            raise ValueError(f"description: at most {MAX_DESCRIPTION_CHARS} characters, got "
                             f"{len(description)}")
        seed = top.integer("seed", lo=0, hi=MAX_SEED)
        start_time_ns = top.integer("start_time_ns", 0, lo=0, hi=MAX_START_TIME_NS)
        rate_hz = top.number("rate_hz", 200.0, lo=0.0, lo_open=True, hi=MAX_RATE_HZ)
        duration_s = top.number("duration_s", 60.0, lo=0.0, lo_open=True, hi=MAX_DURATION_S)

        e = top.section("earth", ("latitude_deg", "longitude_deg", "height_m", "rotation",
                                  "transport_rate"), required=True)
        earth_spec = EarthSpec(
            math.radians(e.number("latitude_deg", lo=-90.0, hi=90.0)),
            math.radians(e.number("longitude_deg", 0.0, -180.0, 180.0)),
            e.number("height_m", 0.0, MIN_HEIGHT_M, MAX_HEIGHT_M),
            e.boolean("rotation", True),
            e.boolean("transport_rate", True),
        )

        m = top.section("motion", ("type",) + tuple({k for v in MOTION_KEYS.values() for k in v}),
                        required=True)
        motion = build_motion(m)

        g = top.section("gyro", ("model", "rate_gyro", "integrating_gyro", "errors", "sampling"))
        gyro_model, rate_params, gyro_errors = "ideal", None, SensorErrorParams()
        gyro_sampling = accel_sampling = SamplingParams()
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
                _GYRO_ERROR_KEYS, _GYRO_DATASHEET_KEYS, GYRO_ERROR_LIMITS,
            )
            gyro_sampling = _sampling(g.section("sampling", GYRO_SAMPLING_KEYS), gyro=True)

        accel, gravity, accel_errors = False, True, SensorErrorParams()
        if "accelerometer" in d:  # even an empty `accelerometer:` asks for accelerometers
            accel = True
            a = Fields(d["accelerometer"] or {}, "accelerometer",
                       ("gravity", "errors", "sampling"))
            gravity = a.boolean("gravity", True)
            accel_errors = _error_params(
                a.section("errors", tuple(_ACCEL_ERROR_KEYS) + tuple(_ACCEL_DATASHEET_KEYS)),
                _ACCEL_ERROR_KEYS, _ACCEL_DATASHEET_KEYS, ACCEL_ERROR_LIMITS,
            )
            accel_sampling = _sampling(a.section("sampling", ACCEL_SAMPLING_KEYS), gyro=False)

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
            kind, inst, initial, max_step = build_instrument(
                i, earth_spec.latitude_rad, earth_spec.rotation and earth_spec.transport_rate,
                motion)
            instrument = InstrumentSpec(kind, inst, initial, max_step)

        ea = earth_spec
        magnetometer = parse_magnetometer(top.section("magnetometer", MAGNETOMETER_KEYS),
                                          ea.latitude_rad, ea.longitude_rad, ea.height_m)

        return cls(
            name=name, description=description, seed=seed, earth=earth_spec, motion=motion,
            motion_type=motion.name, start_time_ns=start_time_ns, rate_hz=rate_hz,
            duration_s=duration_s, gyro_model=gyro_model, rate_gyro_params=rate_params,
            gyro_errors=gyro_errors, accelerometer=accel, gravity=gravity,
            accel_errors=accel_errors, free_gyro_params=free_params, instrument=instrument,
            gyro_sampling=gyro_sampling, accel_sampling=accel_sampling,
            magnetometer=magnetometer, source=dict(d),
        )
