"""The scene registry: every motion type and instrument type of a scene as one entry.

An entry names its keys (:class:`~gyro_attitude.core.scene.fields.Field`: kind, unit,
default, bounds, factor to SI) and its builder, which gets the validated SI values and
returns the core object. Adding a motion: its class in :mod:`gyro_attitude.core.motion`
and one entry in :data:`MOTIONS`; an instrument: one entry in :data:`INSTRUMENTS`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

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
from gyro_attitude.core.limits import (
    MAX_ACCEL_MPS2,
    MAX_DURATION_S,
    MAX_HEAVE_M,
    MAX_PERIOD_S,
    MAX_ROTATION_HZ,
    MAX_SPEED_MPS,
    MAX_TILT_AMPLITUDE_DEG,
    MAX_YAW_AMPLITUDE_DEG,
    MIN_PERIOD_S,
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
from gyro_attitude.core.scene.fields import (
    REQUIRED,
    Field,
    Fields,
    Kind,
    degrees,
    keys_of,
    read_fields,
)
from gyro_attitude.core.trajectory import (
    DEFAULT_MAX_GAP_S,
    TRAJECTORY_FORMATS,
    TrajectoryRequest,
)

TWO_PI = 2.0 * math.pi


@dataclass(frozen=True)
class MotionKind:
    """One motion type: its keys (besides ``type``) and ``build(values) -> Motion``."""

    name: str
    fields: tuple[Field, ...]
    build: Callable[[dict[str, Any]], Motion]
    help: str = ""
    #: bounds that involve several keys: ``check(values, section)`` raises naming the key
    check: Callable[[dict[str, Any], Fields], None] | None = None

    @property
    def keys(self) -> tuple[str, ...]:
        return keys_of(self.fields)


@dataclass(frozen=True)
class InstrumentContext:
    """What an instrument builder needs besides its own keys: the section (for key paths),
    the scene latitude (rad), the motion, and the solver step limit."""

    section: Fields
    latitude_rad: float
    motion: Motion
    max_step: float


@dataclass(frozen=True)
class InstrumentKind:
    """One instrument type: keys (besides ``type`` and ``max_step_s``), the default
    ``max_step_s``, whether it needs the full Earth, and ``build(values, context)`` returning
    ``(instrument, initial_state_kwargs, max_step)``."""

    name: str
    fields: tuple[Field, ...]
    build: Callable[[dict[str, Any], InstrumentContext], tuple[object, dict, float]]
    default_max_step_s: float = 10.0
    needs_earth: bool = True
    help: str = ""

    @property
    def keys(self) -> tuple[str, ...]:
        return keys_of(self.fields)


# --------------------------------------------------------------------------- shared keys
def _rpy(v: dict) -> tuple[float, float, float]:
    return (v["roll_deg"], v["pitch_deg"], v["yaw_deg"])


ATTITUDE = Field(
    "attitude", Kind.SECTION, default=(0.0, 0.0, 0.0), make=_rpy,
    fields=(degrees("roll_deg", 0.0, -180.0, 180.0), degrees("pitch_deg", 0.0, -90.0, 90.0),
            degrees("yaw_deg", 0.0, -360.0, 360.0)),
    help="ROS roll/pitch/yaw, q_nb = Rz(yaw) Ry(pitch) Rx(roll)",
)


def _speed(default: Any = REQUIRED) -> Field:
    return Field("speed_mps", Kind.NUMBER, "m/s", default, lo=0.0, hi=MAX_SPEED_MPS,
                 help="speed along body x")


def _oscillation(key: str, unit: str, scale: float, max_amplitude: float) -> Field:
    def make(v: dict) -> tuple[float, float, float]:
        return (v[f"amplitude_{unit}"], v["period_s"], v["phase_deg"])

    return Field(key, Kind.SECTION, default=(0.0, 0.0, 0.0), make=make, fields=(
        Field(f"amplitude_{unit}", Kind.NUMBER, unit, lo=0.0, hi=max_amplitude, scale=scale),
        Field("period_s", Kind.NUMBER, "s", lo=MIN_PERIOD_S, hi=MAX_PERIOD_S),
        degrees("phase_deg", 0.0, -360.0, 360.0),
    ))


def _cycles(key: str, help: str) -> Field:
    """A frequency in Hz (rev/s) read into rad/s."""
    return Field(key, Kind.NUMBER, "Hz", lo=-MAX_ROTATION_HZ, hi=MAX_ROTATION_HZ, scale=TWO_PI,
                 help=help)


def _check_ship(v: dict, f: Fields) -> None:
    """Heave acceleration a (2π/T)² within the acceleration limit (tilts are bounded by their
    amplitude and period limits alone: 90° at 1 ms is 1.6e3 rad/s)."""
    amp, period, _ = v["heave"]
    if amp > 0.0 and amp * (TWO_PI / period) ** 2 > MAX_ACCEL_MPS2:
        raise ValueError(f"{f.key('heave')}.period_s: amplitude {amp:g} m at period {period:g} s "
                         f"is a peak acceleration of {amp * (TWO_PI / period) ** 2:.3g} m/s², "
                         f"above the {MAX_ACCEL_MPS2:g} m/s² limit (20,000 g)")


def _check_profile(v: dict, f: Fields) -> None:
    """The velocity is piecewise linear, so its largest value is at a segment end."""
    vel = np.array(v["velocity_enu_mps"], dtype=np.float64)
    t = 0.0
    for i, seg in enumerate(v["segments"]):
        t += seg.duration
        if t > MAX_DURATION_S:
            raise ValueError(f"{f.key('segments')}[{i}].duration_s: the segments last more "
                             f"than {MAX_DURATION_S:g} s in all")
        vel = vel + seg.duration * np.asarray(seg.acceleration_enu, dtype=np.float64)
        speed = float(np.linalg.norm(vel))
        if speed > MAX_SPEED_MPS:
            raise ValueError(f"{f.key('segments')}[{i}]: the speed reaches {speed:.3g} m/s at "
                             f"the end of this segment (t = {t:g} s), above the "
                             f"{MAX_SPEED_MPS:g} m/s limit")


# --------------------------------------------------------------------------- motions
def _segment(v: dict) -> ProfileSegment:
    return ProfileSegment(v["duration_s"], tuple(v["angular_rate_deg_s"]),
                          tuple(v["acceleration_enu_mps2"]))


def _build_profile(v: dict) -> Motion:
    return SegmentProfile(v["segments"], v["attitude"], v["velocity_enu_mps"])


MOTIONS: dict[str, MotionKind] = {m.name: m for m in (
    MotionKind("stationary", (ATTITUDE,), lambda v: Stationary(v["attitude"]),
               "at rest in the navigation frame"),
    MotionKind("constant_velocity", (_speed(), ATTITUDE),
               lambda v: ConstantVelocity(v["speed_mps"], v["attitude"]),
               "straight line at constant speed"),
    MotionKind(
        "coordinated_turn",
        (_speed(), degrees("turn_rate_deg_s", REQUIRED, -360.0, 360.0, help="+ = left"),
         degrees("yaw_deg", 0.0, -360.0, 360.0),
         degrees("bank_deg", None, -89.0, 89.0, help="default: coordinated at standard g")),
        lambda v: CoordinatedTurn(v["speed_mps"], v["turn_rate_deg_s"], v["yaw_deg"],
                                  v["bank_deg"]),
        "level turn at constant rate",
    ),
    MotionKind(
        "ship",
        (_speed(0.0), degrees("yaw_deg", 0.0, -360.0, 360.0, help="course"),
         _oscillation("roll", "deg", math.pi / 180.0, MAX_TILT_AMPLITUDE_DEG),
         _oscillation("pitch", "deg", math.pi / 180.0, MAX_TILT_AMPLITUDE_DEG),
         _oscillation("yaw_oscillation", "deg", math.pi / 180.0, MAX_YAW_AMPLITUDE_DEG),
         _oscillation("heave", "m", 1.0, MAX_HEAVE_M)),
        lambda v: ShipMotion(v["speed_mps"], v["yaw_deg"], {
            "roll": v["roll"], "pitch": v["pitch"], "yaw": v["yaw_oscillation"],
            "heave": v["heave"]}),
        "course at constant speed with harmonic roll, pitch, yaw and heave",
        _check_ship,
    ),
    MotionKind(
        "coning",
        (degrees("half_angle_deg", REQUIRED, 0.0, 180.0),
         _cycles("frequency_hz", "coning frequency"), ATTITUDE),
        lambda v: ClassicalConing(v["half_angle_deg"], v["frequency_hz"], v["attitude"]),
        "classical coning about the axis frame's z",
    ),
    MotionKind(
        "spinning_projectile",
        (_cycles("spin_rate_hz", "spin about body x"),
         degrees("half_angle_deg", REQUIRED, 0.0, 180.0),
         _cycles("coning_frequency_hz", "coning frequency"), _speed(0.0), ATTITUDE),
        lambda v: SpinningProjectile(v["spin_rate_hz"], v["half_angle_deg"],
                                     v["coning_frequency_hz"], v["speed_mps"], v["attitude"]),
        "spin with coning and forward speed",
    ),
    MotionKind(
        "profile",
        (ATTITUDE,
         Field("velocity_enu_mps", Kind.VECTOR3, "m/s", default=np.zeros(3),
               lo=-MAX_SPEED_MPS, hi=MAX_SPEED_MPS),
         Field("segments", Kind.LIST, make=_segment, fields=(
             Field("duration_s", Kind.NUMBER, "s", lo=0.0, lo_open=True, hi=MAX_DURATION_S),
             Field("angular_rate_deg_s", Kind.VECTOR3, "deg/s", default=np.zeros(3),
                   lo=-360.0 * MAX_ROTATION_HZ, hi=360.0 * MAX_ROTATION_HZ,
                   scale=math.pi / 180.0, help="body rate"),
             Field("acceleration_enu_mps2", Kind.VECTOR3, "m/s^2", default=np.zeros(3),
                   lo=-MAX_ACCEL_MPS2, hi=MAX_ACCEL_MPS2),
         ))),
        _build_profile,
        "scripted segments of constant body rate and ENU acceleration",
        _check_profile,
    ),
    MotionKind(
        "trajectory",
        (Field("file", Kind.STRING, default=None,
               help="pose file (relative to the scene file); or simulate --trajectory"),
         Field("format", Kind.STRING, default=None, choices=TRAJECTORY_FORMATS,
               help="default: from the extension (.csv, .mcap or a bag directory, else TUM)"),
         Field("topic", Kind.STRING, default=None, help="MCAP: the pose topic"),
         Field("child_frame_id", Kind.STRING, default=None,
               help="MCAP tf2_msgs/TFMessage: the body frame"),
         # 1 m and 0.5 rad: beyond that the "poses" are not a trajectory a fit can follow
         Field("position_sigma_m", Kind.NUMBER, "m", 0.0, lo=0.0, hi=1.0,
               help="expected position noise per axis; 0 interpolates"),
         Field("attitude_sigma_rad", Kind.NUMBER, "rad", 0.0, lo=0.0, hi=0.5,
               help="expected attitude noise per axis; 0 interpolates"),
         Field("max_gap_s", Kind.NUMBER, "s", DEFAULT_MAX_GAP_S, lo=0.0, lo_open=True,
               hi=3600.0, help="longer gaps between poses are refused")),
        lambda v: TrajectoryRequest(**v),
        "the user's own poses (TUM, CSV, MCAP), fitted by smoothing splines",
    ),
)}


# --------------------------------------------------------------------------- instruments
def _wrap(ctx: InstrumentContext, key: str, fn: Callable[[], Any]) -> Any:
    """``fn()`` with a ValueError prefixed by the key's path."""
    try:
        return fn()
    except ValueError as exc:
        raise ValueError(f"{ctx.section.key(key)}: {exc}") from exc


def _exactly_one(ctx: InstrumentContext, v: dict, keys: tuple[str, ...]) -> str:
    given = [k for k in keys if v[k] is not None]
    if len(given) != 1:
        raise ValueError(f"{ctx.section.path}: give exactly one of {', '.join(keys)} "
                         f"(got {', '.join(given) or 'none'})")
    return given[0]


def _build_gyrocompass(v: dict, ctx: InstrumentContext):
    h, zeta, corr, lat = v["angular_momentum"], v["damping_ratio"], v["latitude_correction"], \
        ctx.latitude_rad
    which = _exactly_one(ctx, v, ("pendulous_moment", "schuler_tuned", "period_s"))
    if which == "schuler_tuned":
        if not v["schuler_tuned"]:
            raise ValueError(f"{ctx.section.key('schuler_tuned')}: must be true when given")
        params = _wrap(ctx, which, lambda: GyrocompassParams.schuler_tuned(h, lat, zeta, corr))
    elif which == "period_s":
        params = _wrap(ctx, which, lambda: GyrocompassParams.with_period(
            h, v["period_s"], lat, zeta, corr))
    else:
        params = _wrap(ctx, which, lambda: GyrocompassParams.with_damping_ratio(
            h, v["pendulous_moment"], lat, zeta, corr))
    if v["start_settled"]:
        if v["azimuth0_deg"] is not None or v["elevation0_deg"] is not None:
            raise ValueError(f"{ctx.section.key('start_settled')}: not with "
                             "azimuth0_deg/elevation0_deg")
        v0 = ctx.motion.evaluate(np.zeros(1)).velocity_enu[0]
        a0, b0 = _wrap(ctx, "start_settled", lambda: gyrocompass_settle_point(params, lat, v0))
        initial = {"azimuth0": a0, "elevation0": b0}
    else:
        initial = {"azimuth0": 0.0 if v["azimuth0_deg"] is None else v["azimuth0_deg"]}
        if v["elevation0_deg"] is not None:
            initial["elevation0"] = v["elevation0_deg"]
    return Gyrocompass(params), initial, ctx.max_step


def _build_vertical_gyro(v: dict, ctx: InstrumentContext):
    kw = {"erection_law": v["erection_law"]}
    for key, name in (("erection_gain", "erection_gain"),
                      ("erection_rate_deg_s", "erection_rate"),
                      ("linear_zone_deg", "linear_zone")):
        if v[key] is not None:
            kw[name] = v[key]
    instrument = VerticalGyro(_wrap(ctx, "erection_law", lambda: VerticalGyroParams(**kw)))
    initial: dict = {}
    s0 = v["spin_axis0"]
    if s0 is not None:
        if not np.linalg.norm(s0) > 0.0 or s0[2] <= 0.0:
            raise ValueError(f"{ctx.section.key('spin_axis0')}: must point above the horizon")
        initial = {"spin_axis0": tuple(s0)}
    return instrument, initial, ctx.max_step


def _build_directional_gyro(v: dict, ctx: InstrumentContext):
    params = _wrap(ctx, "leveling_gain", lambda: DirectionalGyroParams(
        v["latitude_nut_deg"], v["leveling_gain"]))
    return DirectionalGyro(params), {}, ctx.max_step


def _build_shell(v: dict, ctx: InstrumentContext):
    c, a, n = v["spin_inertia"], v["transverse_inertia"], v["spin_rate"]
    if _exactly_one(ctx, v, ("overturning_moment", "stability_factor")) == "stability_factor":
        params = ShellParams.with_stability_factor(v["stability_factor"], c, a, n)
    else:
        params = ShellParams(c, a, v["overturning_moment"], n)
    # a flight of seconds: the step is held to 0.1 s whatever the scene allows
    return SpinningShell(params), {"theta0": v["theta0_deg"]}, min(ctx.max_step, 0.1)


def _positive(key: str, unit: str, default: Any = REQUIRED, hi: float | None = None,
              help: str = "") -> Field:
    return Field(key, Kind.NUMBER, unit, default, lo=0.0, hi=hi, lo_open=True, help=help)


INSTRUMENTS: dict[str, InstrumentKind] = {i.name: i for i in (
    InstrumentKind(
        "gyrocompass",
        (_positive("angular_momentum", "N·m·s", hi=1.0e4),
         _positive("pendulous_moment", "kg·m", None, hi=1.0e3),
         Field("schuler_tuned", Kind.BOOLEAN, default=None),
         _positive("period_s", "s", None, hi=1.0e6),  # Schuler: 5064 s
         Field("damping_ratio", Kind.NUMBER, "", 0.0, lo=0.0, hi=10.0),
         Field("latitude_correction", Kind.BOOLEAN, default=True),
         degrees("azimuth0_deg", None, -180.0, 180.0),
         degrees("elevation0_deg", None, -80.0, 80.0, help="default: the static tilt"),
         Field("start_settled", Kind.BOOLEAN, default=False)),
        _build_gyrocompass,
        help="pendulous gyrocompass",
    ),
    InstrumentKind(
        "vertical_gyro",
        (Field("erection_law", Kind.STRING, default="proportional", choices=ERECTION_LAWS),
         _positive("erection_gain", "1/s", None, hi=1.0e3),
         Field("erection_rate_deg_s", Kind.NUMBER, "deg/s", None, lo=0.0, hi=1.0e3,
               lo_open=True, scale=math.pi / 180.0),
         Field("linear_zone_deg", Kind.NUMBER, "deg", None, lo=0.0, hi=89.0, lo_open=True,
               scale=math.pi / 180.0),
         # a direction (normalized by the instrument): components of a unit-scale vector
         Field("spin_axis0", Kind.VECTOR3, "ENU", None, lo=-1.0e3, hi=1.0e3,
               help="default: up")),
        _build_vertical_gyro,
        default_max_step_s=1.0,
        help="vertical gyro with erection",
    ),
    InstrumentKind(
        "directional_gyro",
        (degrees("latitude_nut_deg", None, -90.0, 90.0, help="none: no nut"),
         Field("leveling_gain", Kind.NUMBER, "1/s", 0.0, lo=0.0, hi=1.0e3)),
        _build_directional_gyro,
        help="directional gyro with latitude nut",
    ),
    InstrumentKind(
        "spinning_shell",
        (_positive("spin_inertia", "kg·m²", hi=1.0e3),
         _positive("transverse_inertia", "kg·m²", hi=1.0e3),
         _positive("spin_rate", "rad/s", hi=1.0e5),
         _positive("overturning_moment", "N·m", None, hi=1.0e6),
         _positive("stability_factor", "", None, hi=1.0e6),
         degrees("theta0_deg", math.radians(2.0), 0.0, 179.0)),
        _build_shell,
        needs_earth=False,
        help="spin-stabilized shell (the Earth and the carrier do not enter)",
    ),
)}

MOTION_TYPES = tuple(MOTIONS)
INSTRUMENT_TYPES = tuple(INSTRUMENTS)


def build_motion(f: Fields) -> Motion:
    """The motion of a ``motion:`` section (``type`` picks the registry entry)."""
    kind = MOTIONS[f.string("type", choices=MOTION_TYPES)]
    section = Fields(f.d, f.path, ("type",) + kind.keys)  # this type's keys only
    values = read_fields(section, kind.fields)
    if kind.check is not None:
        kind.check(values, section)
    return kind.build(values)


def build_instrument(f: Fields, latitude_rad: float, full_earth: bool, motion: Motion):
    """``(type, instrument, initial_state_kwargs, max_step)`` of an ``instrument:`` section."""
    kind = INSTRUMENTS[f.string("type", choices=INSTRUMENT_TYPES)]
    section = Fields(f.d, f.path, ("type", "max_step_s") + kind.keys)
    max_step = section.number("max_step_s", kind.default_max_step_s, lo=1e-6, hi=3600.0)
    if kind.needs_earth and not full_earth:
        raise ValueError(f"{f.path}: the instruments always see the Earth's rotation and the "
                         "transport rate; set earth.rotation and earth.transport_rate true")
    values = read_fields(section, kind.fields)
    ctx = InstrumentContext(section, latitude_rad, motion, max_step)
    instrument, initial, step = kind.build(values, ctx)
    return kind.name, instrument, initial, step
