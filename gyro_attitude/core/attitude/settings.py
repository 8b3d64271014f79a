"""Every setting of the attitude estimator, declared once (docs/architecture.md, "Settings").

One :class:`Setting` row per setting (its name is also the ROS parameter, the YAML key and the
replay flag ``--name-with-dashes``).  From the table come :class:`StreamConfig` (one field per
row), the node's parameters, replay's flags, and ``config/attitude_integrator.yaml`` and
``docs/settings.md`` (:func:`yaml_lines`, :func:`markdown_table`; a test fails when they
drift).  Values are checked against their row once, when a :class:`StreamConfig` is made
(``ValueError`` naming the setting); cross-setting rules live in :meth:`StreamConfig.check`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, make_dataclass, replace
from enum import Enum

from gyro_attitude.core.attitude.modes import (
    Aiding,
    Frame,
    GyroBiasMode,
    HeadingSource,
    InitialAttitudeSource,
    SettingError,
    WorldFrame,
    parse_mode,
)
from gyro_attitude.core.earth import OMEGA_IE

__all__ = ["SETTINGS", "Setting", "SettingError", "StreamConfig", "markdown_table", "setting",
           "yaml_lines"]


@dataclass(frozen=True)
class Setting:
    """One estimator setting: ``default`` a float, int, bool, enum member, or a tuple of floats
    (``length`` long); ``low``/``high`` inclusive bounds of a number or of every element of a
    tuple; ``choices`` the enum whose words are allowed; ``runtime``: the node accepts a change
    while running; ``group`` its heading in the YAML file.  A filter's internal constants are
    rows too, their help starting "internal"."""

    name: str
    default: object
    help: str
    unit: str = ""
    low: float | None = None
    high: float | None = None
    choices: type[Enum] | None = None
    length: int | None = None
    runtime: bool = False
    group: str = ""

    @property
    def flag(self) -> str:
        return "--" + self.name.replace("_", "-")

    @property
    def kind(self) -> str:
        """'enum', 'bool', 'int', 'float' or 'vector'."""
        if self.choices is not None:
            return "enum"
        if isinstance(self.default, bool):
            return "bool"
        if isinstance(self.default, int):
            return "int"
        if isinstance(self.default, float):
            return "float"
        return "vector"

    def describe(self) -> str:
        """The help with unit, range and allowed words: one line for a descriptor or a flag."""
        text = self.help
        if self.unit:
            text += f" [{self.unit}]"
        if self.choices is not None:
            text += " (" + " | ".join(m.value for m in self.choices) + ")"
        elif self.low is not None and self.high is not None:
            text += f" (range {self.low:g} .. {self.high:g})"
        return text

    def check(self, value):
        """``value`` checked against this row and normalized (enum member, float, tuple of
        floats); ``ValueError`` naming the setting otherwise."""
        try:
            return self._check(value)
        except SettingError:
            raise
        except ValueError as exc:
            raise SettingError(self.name, str(exc)) from None

    def _check(self, value):
        kind = self.kind
        if kind == "enum":
            return parse_mode(self.choices, value, self.name)
        if kind == "bool":
            if not isinstance(value, bool):
                raise ValueError(f"{self.name} must be true or false, got {value!r}")
            return value
        if kind == "vector":
            if isinstance(value, str) or not hasattr(value, "__len__"):
                raise ValueError(f"{self.name} must be {self.length} numbers"
                                 f"{' (' + self.unit + ')' if self.unit else ''}, got {value!r}")
            vals = tuple(self._number(c) for c in value)
            if self.length is not None and len(vals) != self.length:
                raise ValueError(f"{self.name} must be {self.length} numbers, got {len(vals)}")
            return vals
        x = self._number(value)
        if kind == "int":
            if not float(x).is_integer():
                raise ValueError(f"{self.name} must be a whole number, got {value!r}")
            return int(x)
        return x

    def _number(self, value) -> float:
        if isinstance(value, bool) or not isinstance(value, int | float) and not hasattr(
                value, "__float__") or isinstance(value, str):
            raise ValueError(f"{self.name} must be a number, got {value!r}")
        x = float(value)
        lo = -math.inf if self.low is None else self.low
        hi = math.inf if self.high is None else self.high
        if not (math.isfinite(x) and lo <= x <= hi):
            raise ValueError(f"{self.name} must be a finite number in [{lo:g}, {hi:g}], "
                             f"got {value!r}")
        return x


_HALF_PI = math.pi / 2

def _grouped(table) -> tuple[Setting, ...]:
    """The rows of ``table``, each in the group of the heading (a string) above it."""
    rows, group = [], ""
    for x in table:
        if isinstance(x, str):
            group = x
        else:
            rows.append(replace(x, group=group))
    return tuple(rows)


#: The table (order = the order of the YAML file and the table of docs/settings.md).
SETTINGS: tuple[Setting, ...] = _grouped((
    "frame",  # and position
    Setting("frame", Frame.INERTIAL, "inertial: integrate q_ib; enu: q_nb with Earth and transport "
            "rate removed", choices=Frame),
    Setting("world_frame", WorldFrame.ENU, "frame of the published orientation: enu (REP-103), ned "
            "(x north, y east, z down) or nwu (x north, y west, z up); the body is the IMU frame "
            "in each (for an FRD body with ned, turn by 180 deg about x)", choices=WorldFrame),
    Setting("latitude_rad", 0.0, "geodetic latitude (frame enu; gyrocompassing; with frame enu the "
            "Earth rate is taken out of the gyro bias)", "rad", -_HALF_PI, _HALF_PI),
    Setting("longitude_rad", 0.0, "longitude (frame enu)", "rad", -math.pi, math.pi),
    Setting("height_m", 0.0, "height above the WGS-84 ellipsoid (frame enu)", "m", -1.0e4, 1.0e6),
    Setting("velocity_enu", (0.0, 0.0, 0.0), "carrier velocity east, north, up (frame enu; an "
            "odometry topic replaces it)", "m/s", -1.0e4, 1.0e4, length=3),
    "initial attitude",
    Setting("initial_attitude_source", InitialAttitudeSource.AUTO, "auto: accelerometer when the "
            "aiding uses the accelerometer and initial_attitude is the identity, else parameter; "
            "accelerometer: roll and pitch from the first accelerometer sample, the heading of "
            "initial_attitude; parameter: initial_attitude; truth: the truth topic slerped to the "
            "first accepted Imu stamp; level: roll and pitch from the specific force over the "
            "first rest, heading per heading_source (no attitude while aligning)",
            choices=InitialAttitudeSource),
    Setting("initial_attitude", (0.0, 0.0, 0.0, 1.0), "initial attitude quaternion x, y, z, w "
            "(normalized on use; not all zero)", length=4),
    Setting("initial_attitude_variance", 0.0, "per-axis variance of the initial attitude (level: "
            "of the given heading)", "rad^2", 0.0, 10.0),
    Setting("initial_heading_deg", 0.0, "level: heading of the body x axis, clockwise from north",
            "deg", -360.0, 360.0),
    Setting("heading_source", HeadingSource.PARAMETER, "level: initial_heading_deg, or "
            "gyrocompassing (needs gyro_bias parameter with gyro_bias_sigma_rad_s; refused above "
            "heading_error_limit_deg)", choices=HeadingSource),
    Setting("heading_error_limit_deg", 5.0, "largest expected gyrocompass heading error", "deg",
            0.0, 180.0),
    Setting("accel_bias_sigma", 0.05, "1-sigma accelerometer bias: levelling error = this / g",
            "m/s^2", 0.0, 10.0),
    "gyro bias",
    Setting("gyro_bias", GyroBiasMode.AUTO, "auto: estimated at every rest (zero-rate update) and "
            "held in motion; none; parameter: gyro_bias_rad_s", choices=GyroBiasMode),
    Setting("gyro_bias_rad_s", (0.0, 0.0, 0.0), "fixed gyro bias x, y, z (gyro_bias parameter)",
            "rad/s", -1.0e3, 1.0e3, length=3),
    Setting("gyro_bias_sigma_rad_s", 0.0, "1-sigma of the bias subtracted when not estimated "
            "(none: sensor spread; parameter: calibration; auto: before the first rest)", "rad/s",
            0.0, 10.0),
    Setting("gyro_bias_rw", 0.0, "gyro bias random walk (covariance)", "rad/s/sqrt(s)", 0.0, 1.0),
    Setting("gyro_noise_density", 0.0, "gyro noise density for the covariance when the input's "
            "angular_velocity_covariance is unknown (0 = none)", "rad/s/sqrt(Hz)", 0.0, 1.0),
    Setting("gyro_scale_factor_sigma", 0.005, "offline estimator: 1-sigma relative gyro "
            "scale-factor and misalignment error in the covariance (consumer MEMS 0.3-1 %)", "",
            0.0, 0.5),
    "rest",
    Setting("min_rest_s", 1.0, "shortest rest used for the bias and the alignment", "s", 0.01,
            3600.0),
    Setting("rest_window_s", 0.5, "rest detector window", "s", 0.01, 60.0),
    Setting("rest_gyro_std_max", 0.01, "rest: largest gyro deviation from the window mean, over 3 "
            "axes", "rad/s", 1e-6, 10.0),
    Setting("rest_gyro_mean_max", 0.011, "rest: largest window-mean rate on any axis, the largest "
            "plausible bias (a steady turn faster than sqrt(3) times this is never a rest)",
            "rad/s", 1e-6, 10.0),
    Setting("rest_accel_std_max", 0.25, "rest: largest specific-force deviation, over 3 axes",
            "m/s^2", 1e-4, 100.0),
    Setting("rest_accel_norm_tol", 1.0, "rest: largest | |f| - g |", "m/s^2", 1e-4, 100.0),
    "aiding",
    Setting("aiding", Aiding.AUTO, "auto: the AHRS filter on the accelerometer whenever the Imu "
            "carries one (REP-145: linear_acceleration_covariance[0] not -1, finite values), "
            "gyro-only without; tilt: the AHRS filter (specific force low-passed in an "
            "almost-inertial frame, acceleration rejection, settings ahrs_*); magnetometer: the "
            "same with the heading from the magnetometer (mag_*); none: gyro-only; gravity: "
            "retired, runs tilt", choices=Aiding),
    Setting("offline_tilt_tau_s", 3.0, "offline estimator (replay --estimator offline) with tilt "
            "aiding: time constant of the zero-phase low-pass of the specific force in the "
            "integration frame", "s", 0.01, 1000.0),
    Setting("offline_mag_tau_s", 30.0, "offline estimator with magnetometer aiding: time constant "
            "of the zero-phase low-pass of the field's horizontal direction (the heading "
            "correction)", "s", 0.01, 1.0e4),
    "ahrs",  # AHRS aiding (aiding tilt | magnetometer: core/attitude/ahrs.py)
    Setting("ahrs_accel_tau_s", 3.0, "tilt/magnetometer aiding: time constant of the "
            "specific-force low-pass in the almost-inertial frame", "s", 0.01, 100.0),
    Setting("ahrs_accel_reject_deg", 3.0, "tilt/magnetometer aiding: the tilt is gyro-only while "
            "the filtered vertical is further than this from the estimate (a sustained "
            "acceleration)", "deg", 0.1, 180.0),
    Setting("ahrs_accel_norm_tol", 3.0, "tilt/magnetometer aiding: gyro-only while | |f| - g | "
            "exceeds this", "m/s^2", 0.0, 1.0e3),
    Setting("ahrs_accel_recovery_s", 10.0, "tilt/magnetometer aiding: after this long rejected the "
            "tilt follows again, at ahrs_recovery_rate_deg_s at most", "s", 0.0, 1.0e6),
    Setting("ahrs_recovery_rate_deg_s", 0.2, "tilt/magnetometer aiding: largest tilt correction "
            "rate while recovering (as fast as a gyro may drift, not as an acceleration pulls)",
            "deg/s", 0.0, 1.0e3),
    Setting("ahrs_tilt_rate_max_deg_s", 1.0, "tilt/magnetometer aiding: largest tilt correction "
            "rate", "deg/s", 0.0, 1.0e4),
    Setting("ahrs_bias_gain", 0.02, "tilt/magnetometer aiding: gain of the gyro-bias integral fed "
            "by the steady corrections (0 = off)", "1/s", 0.0, 10.0),
    Setting("ahrs_mag_tau_s", 30.0, "magnetometer aiding: time constant of the heading toward the "
            "field", "s", 0.01, 1.0e4),
    Setting("magnetic_declination_deg", 0.0, "magnetometer aiding: declination east of true north; "
            "the heading then points to true north (0: to magnetic north)", "deg", -180.0, 180.0),
    Setting("mag_norm_tol", 0.1, "magnetometer aiding: a field whose norm differs from the "
            "reference by more than this fraction is a disturbance (heading gyro-only)", "", 1e-3,
            10.0),
    Setting("mag_dip_tol_deg", 10.0, "magnetometer aiding: a field whose dip differs from the "
            "reference by more than this is a disturbance", "deg", 0.1, 180.0),
    Setting("mag_recovery_s", 20.0, "magnetometer aiding: a disturbed field steady this long "
            "becomes the new reference (never one of the other dip sign)", "s", 0.0, 1.0e6),
    Setting("mag_reference_enu_t", (0.0, 0.0, 0.0), "magnetometer aiding: the expected field east, "
            "north, up for the disturbance test (zeros: learned from the first second)", "T", -0.01,
            0.01, length=3),
    Setting("mag_hard_iron_t", (0.0, 0.0, 0.0), "magnetometer aiding: hard-iron offset subtracted "
            "from the field (sensor frame)", "T", -0.01, 0.01, length=3),
    Setting("mag_hard_iron_estimate", False, "magnetometer aiding: estimate the hard iron by a "
            "sphere fit once the sensor has turned about two axes"),
    Setting("mag_max_age_s", 0.1, "magnetometer aiding: a field sample serves the Imu samples up "
            "to this long after its stamp (then heading gyro-only, counted mag_missing)", "s", 0.0,
            10.0),
    "ahrs internals",  # the AHRS filter's, tuned on real recordings and rarely worth changing
    Setting("ahrs_tilt_tau_s", 0.0, "internal, tilt/magnetometer aiding: time constant of the tilt "
            "toward the filtered vertical in motion (0: the full correction every sample, as VQF)",
            "s", 0.0, 1.0e3),
    Setting("ahrs_rest_accel_tau_s", 0.5, "internal, tilt/magnetometer aiding: time constant of "
            "the specific-force low-pass at a rest", "s", 1e-3, 1.0e3),
    Setting("ahrs_rest_rate_max", 0.05, "internal, tilt/magnetometer aiding: the filter's rest "
            "test, largest |omega|", "rad/s", 0.0, 10.0),
    Setting("ahrs_rest_accel_tol", 0.3, "internal, tilt/magnetometer aiding: the filter's rest "
            "test, largest | |f| - g |", "m/s^2", 0.0, 100.0),
    Setting("ahrs_rest_min_s", 1.0, "internal, tilt/magnetometer aiding: the filter's rest test, "
            "how long both hold", "s", 0.0, 1.0e3),
    Setting("mag_reference_s", 1.0, "internal, magnetometer aiding: seconds of field the reference "
            "is learned from (mag_reference_enu_t zeros)", "s", 0.0, 1.0e3),
    Setting("mag_hard_iron_window_s", 60.0, "internal, magnetometer aiding: memory of the "
            "hard-iron sphere fit", "s", 1.0, 1.0e6),
    "input",  # validation of the input stream
    Setting("max_gap_s", 0.1, "a forward stamp step longer than this is a gap: not integrated "
            "across, attitude held", "s", 1e-6, 1e6, runtime=True),
    Setting("time_jump_threshold_s", 1.0, "a backward stamp jump longer than this resets the "
            "attitude (shorter backward steps are skipped as out of order)", "s", 1e-6, 1e6,
            runtime=True),
    Setting("max_missing_samples", 4, "an interval spanning missing samples (a hole of more than "
            "1.5 nominal periods, the median of a time base's first 16) is counted; one missing "
            "more than this many is a gap", "samples", 0, 1e6, runtime=True),
    # far above any real gyro's range (tactical and MEMS gyros saturate at 40..200 rad/s), far
    # below what overflows a rotation angle in float64 over any step; likewise the bounds: a
    # rate limit above 1e6 rad/s or a gap/jump threshold above 1e6 s lets through steps whose
    # rotation angle no longer means anything
    Setting("max_rate_rad_s", 1.0e4, "a sample with a larger rate on any axis is implausible and "
            "skipped", "rad/s", 1e-3, 1.0e6, runtime=True),
))

_BY_NAME = {s.name: s for s in SETTINGS}

#: settings of earlier releases that are gone, and why (a node given one says so)
RETIRED_SETTINGS = dict.fromkeys(
    ("aiding_kp", "aiding_ki", "aiding_accel_tol", "aiding_rate_max", "aiding_accel_lowpass_s"),
    "the gravity filter is retired (aiding gravity runs the AHRS filter: its settings are "
    "ahrs_*)")


def setting(name: str) -> Setting:
    """The row called ``name``."""
    return _BY_NAME[name]


class _StreamConfigMethods:
    """Methods of :class:`StreamConfig` (its fields come from :data:`SETTINGS`)."""

    def __post_init__(self):
        for s in SETTINGS:
            object.__setattr__(self, s.name, s.check(getattr(self, s.name)))
        self.check()

    def check(self) -> None:
        """Rules that involve several settings (``ValueError`` naming them).  (The rest
        thresholds need none: rest_gyro_std_max's range starts above the noise floor the bias
        estimator asks a rest window to show.)"""
        if not any(self.initial_attitude):
            raise SettingError("initial_attitude", "initial_attitude must be a quaternion "
                               "x, y, z, w, not all zero")
        if self.heading_source is HeadingSource.GYROCOMPASS:
            if self.initial_attitude_source is not InitialAttitudeSource.LEVEL:
                raise SettingError("heading_source", "heading_source 'gyrocompass' needs "
                                   "initial_attitude_source 'level'")
            if self.gyro_bias is not GyroBiasMode.PARAMETER or not self.gyro_bias_sigma_rad_s > 0:
                raise SettingError("heading_source", "gyrocompass needs gyro_bias 'parameter' with its 1σ "
                                 "gyro_bias_sigma_rad_s > 0 (a bias estimated at rest has "
                                 "absorbed the Earth rate and cannot find north)")
            check_gyrocompass_feasible(self.gyro_bias_sigma_rad_s, self.latitude_rad,
                                       self.heading_error_limit_deg)

    @property
    def max_gap_ns(self) -> int:
        return int(round(self.max_gap_s * 1e9))

    @property
    def time_jump_ns(self) -> int:
        return int(round(self.time_jump_threshold_s * 1e9))

    @property
    def levelling(self) -> bool:
        return self.initial_attitude_source is InitialAttitudeSource.LEVEL

    @property
    def aided(self) -> bool:
        """The aiding uses the accelerometer (when the Imu carries one)."""
        return self.aiding is not Aiding.NONE

    @property
    def uses_accelerometer(self) -> bool:
        """The estimator reads the accelerometer: its rest detector (auto gyro bias), the
        levelling, the aiding and the start from the first sample do."""
        return (self.gyro_bias is GyroBiasMode.AUTO or self.levelling or self.aided
                or self.start_source is InitialAttitudeSource.ACCELEROMETER)

    @property
    def start_source(self) -> InitialAttitudeSource:
        """``initial_attitude_source`` with ``auto`` resolved (:class:`InitialAttitudeSource`)."""
        src = self.initial_attitude_source
        if src is not InitialAttitudeSource.AUTO:
            return src
        if self.aided and _is_identity(self.initial_attitude):
            return InitialAttitudeSource.ACCELEROMETER
        return InitialAttitudeSource.PARAMETER

    def notes(self) -> list[str]:
        """What these settings resolve to that a user should be told once (a retired name)."""
        if self.aiding is Aiding.GRAVITY:
            return ["aiding gravity is retired: the AHRS tilt filter runs instead (aiding tilt; "
                    "it was better on every real recording)"]
        return []

    @property
    def latitude_known(self) -> bool:
        """The latitude describes where the IMU is: with frame enu, or for gyrocompassing
        (frame inertial otherwise leaves the Earth rate in the bias: see gyro_bias.py)."""
        return self.frame is Frame.ENU or self.heading_source is HeadingSource.GYROCOMPASS

    def nav_frame(self):
        """The constant :class:`NavFrame` of these settings (frame enu), else None."""
        if self.frame is not Frame.ENU:
            return None
        import numpy as np

        from gyro_attitude.core.attitude.nav_frame import NavFrame

        return NavFrame(latitude_rad=self.latitude_rad, longitude_rad=self.longitude_rad,
                        height_m=self.height_m, velocity_enu=np.asarray(self.velocity_enu))

    def replace(self, **changes):
        """A copy with ``changes`` (checked like the constructor)."""
        return replace(self, **changes)

    def values(self) -> dict:
        """``{name: value}`` with enum members as their words (for JSON and YAML)."""
        out = {}
        for s in SETTINGS:
            x = getattr(self, s.name)
            out[s.name] = x.value if isinstance(x, Enum) else (list(x) if isinstance(x, tuple)
                                                               else x)
        return out


StreamConfig = make_dataclass(
    "StreamConfig", [(s.name, object, field(default=s.default)) for s in SETTINGS],
    bases=(_StreamConfigMethods,), frozen=True)
StreamConfig.__module__ = __name__
StreamConfig.__doc__ = ("Settings of the attitude estimator: one field per row of "
                        ":data:`SETTINGS` (see there for names, units and ranges).")


def _is_identity(q) -> bool:
    """``q`` (x, y, z, w, any scale) is the identity rotation."""
    x, y, z, w = (float(c) for c in q)
    return x == 0.0 and y == 0.0 and z == 0.0 and w > 0.0


def _yaml_value(x) -> str:
    if isinstance(x, Enum):
        return x.value
    if isinstance(x, bool):
        return "true" if x else "false"
    if isinstance(x, str):
        return f'"{x}"'
    if isinstance(x, tuple):
        return "[" + ", ".join(repr(float(c)) for c in x) + "]"
    return repr(x)


def yaml_lines(indent: str = "    ", settings=SETTINGS) -> list[str]:
    """The estimator settings as commented YAML lines (``name: default  # help``)."""
    out = []
    group = None
    for s in settings:
        if s.group != group:
            group = s.group
            out.append(f"{indent}# -- {group}")
        out.append(f"{indent}{s.name}: {_yaml_value(s.default)}  # {s.describe()}")
    return out


def markdown_table(settings=SETTINGS) -> list[str]:
    """The estimator settings as a Markdown table (docs/settings.md)."""
    out = ["| setting (parameter, `replay` flag) | default | unit | meaning |",
           "|---|---|---|---|"]
    for s in settings:
        default = _yaml_value(s.default).strip('"')
        allowed = ""
        if s.choices is not None:
            allowed = " (" + " \\| ".join(f"`{m.value}`" for m in s.choices) + ")"
        elif s.low is not None and s.high is not None and s.kind != "vector":
            allowed = f" ({s.low:g} .. {s.high:g})"
        runtime = "; may change at runtime" if s.runtime else ""
        text = s.help.replace("|", "\\|")  # a bar in the help would end the cell
        out.append(f"| `{s.name}` `{s.flag}` | `{default}` | {s.unit} | {text}{allowed}"
                   f"{runtime} |")
    return out


def check_gyrocompass_feasible(gyro_bias_sigma_rad_s: float, latitude_rad: float | None,
                               heading_error_limit_deg: float) -> None:
    """Refuse gyrocompassing whose heading error from the bias uncertainty alone,
    ``σ_b / (ω_ie cos L)``, already exceeds the limit (:func:`.alignment.aligner_result`
    checks the full figure with the measured noise at the end of the rest)."""
    if latitude_rad is None:
        raise SettingError("heading_source", "gyrocompass needs the latitude (frame enu or "
                           "latitude_rad)")
    horizontal = OMEGA_IE * math.cos(latitude_rad)
    sigma = gyro_bias_sigma_rad_s / max(horizontal, 1e-300)
    if not math.degrees(sigma) <= heading_error_limit_deg:
        raise SettingError(
            "heading_source", "gyrocompass refused: gyro bias uncertainty "
            f"{math.degrees(gyro_bias_sigma_rad_s) * 3600:.3g}"
            f" °/h against a horizontal Earth rate of {math.degrees(horizontal) * 3600:.3g} °/h "
            f"gives a heading error of {min(math.degrees(sigma), 1e9):.3g}° > the limit "
            f"{heading_error_limit_deg:g}°; give initial_heading_deg instead")
