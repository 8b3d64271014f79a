"""Scenes: the YAML schema (``schema``) and the simulator of only the effects named (``simulator``)."""

from gyro_attitude.core.scene.schema import (
    MAX_DURATION_S,
    MAX_LIST_ITEMS,
    MAX_RATE_HZ,
    MAX_START_TIME_NS,
    MOTION_TYPES,
    EarthSpec,
    SceneSpec,
)
from gyro_attitude.core.scene.simulator import (
    BLOCK_SAMPLES,
    MAX_SAMPLES_PER_CALL,
    GimbalBlock,
    SceneSimulator,
    SimBlock,
    integrate_position,
)

__all__ = [
    "SceneSpec",
    "EarthSpec",
    "MOTION_TYPES",
    "MAX_RATE_HZ",
    "MAX_DURATION_S",
    "MAX_START_TIME_NS",
    "MAX_LIST_ITEMS",
    "SceneSimulator",
    "SimBlock",
    "GimbalBlock",
    "integrate_position",
    "BLOCK_SAMPLES",
    "MAX_SAMPLES_PER_CALL",
]
