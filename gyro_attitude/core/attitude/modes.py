"""The estimator's modes as enums (their values the words users write, ``gyro_bias: auto``),
parsed once at the boundary by :func:`parse_mode`; inside the package they are compared as
members (``cfg.gyro_bias is GyroBiasMode.AUTO``), never as strings.  What each word means: the
help of its row in the settings table."""

from __future__ import annotations

from enum import Enum, StrEnum

__all__ = ["Aiding", "Estimator", "Frame", "GyroBiasMode", "HeadingSource", "InitialAttitudeSource",
           "Phase", "SettingError", "WorldFrame", "parse_mode"]


class SettingError(ValueError):
    """A setting's value (or a combination) is refused; ``setting`` names the one to change."""

    def __init__(self, setting: str, message: str):
        super().__init__(message)
        self.setting = setting


class Frame(StrEnum):
    """What the estimator integrates: ``q_ib`` (inertial) or ``q_nb`` (ENU nav frame)."""

    INERTIAL = "inertial"
    ENU = "enu"


class WorldFrame(StrEnum):
    """The frame the published orientation is expressed in (core/attitude/world_frame.py)."""

    ENU = "enu"
    NED = "ned"
    NWU = "nwu"


class InitialAttitudeSource(StrEnum):
    """Where the initial attitude comes from (``auto`` resolved by
    :attr:`StreamConfig.start_source`)."""

    AUTO = "auto"
    PARAMETER = "parameter"
    TRUTH = "truth"
    LEVEL = "level"
    ACCELEROMETER = "accelerometer"


class HeadingSource(StrEnum):
    """Heading of a levelled start: ``initial_heading_deg`` or gyrocompassing."""

    PARAMETER = "parameter"
    GYROCOMPASS = "gyrocompass"


class GyroBiasMode(StrEnum):
    """Gyro bias: estimated at rests (``auto``), none, or the fixed ``gyro_bias_rad_s``."""

    AUTO = "auto"
    NONE = "none"
    PARAMETER = "parameter"


class Aiding(StrEnum):
    """Aiding of the integrated attitude (the AHRS filter of ahrs.py; ``gravity``, the older
    complementary filter weaker than ``tilt`` on every real recording, is retired: accepted,
    runs ``tilt`` and says so)."""

    AUTO = "auto"
    NONE = "none"
    TILT = "tilt"
    MAGNETOMETER = "magnetometer"
    GRAVITY = "gravity"


class Estimator(StrEnum):
    """How replay estimates: ``offline`` over the whole recording (core/attitude/offline.py,
    non-causal), or ``causal`` sample by sample as the live node does (AttitudeStream)."""

    OFFLINE = "offline"
    CAUSAL = "causal"


class Phase(StrEnum):
    """Phase of an attitude stream: no attitude while ``aligning``; ``failed`` when the alignment
    was refused."""

    ALIGNING = "aligning"
    RUNNING = "running"
    FAILED = "failed"


def parse_mode(enum: type[Enum], value, setting: str):
    """``value`` (a member, or its word) as a member of ``enum``; ``ValueError`` naming
    ``setting`` and the allowed words otherwise."""
    if isinstance(value, enum):
        return value
    if isinstance(value, str):
        try:
            return enum(value.strip().lower())
        except ValueError:
            pass
    allowed = ", ".join(m.value for m in enum)
    raise SettingError(setting, f"{setting} must be one of {allowed}; got {value!r}")
