"""The published orientation in the world frame the user picks (``world_frame``): ENU (REP-103,
the estimator's own frame), NED or NWU — one home for the conversion, used by the node and replay.
``q_world_b = q_world_enu ⊗ q_enu_b``: only the reference frame changes, the body stays the IMU's
frame (docs/architecture.md, "Notes: the integration library").
"""

from __future__ import annotations

import math

import numpy as np

from gyro_attitude.core.attitude.modes import WorldFrame
from gyro_attitude.core.rotation import quat_multiply

__all__ = ["WORLD_FROM_ENU", "frame_id_of", "from_enu", "from_enu_one"]

_H = math.sqrt(0.5)
#: q_world_enu (x, y, z, w) per world frame.
WORLD_FROM_ENU = {
    WorldFrame.ENU: (0.0, 0.0, 0.0, 1.0),
    WorldFrame.NED: (_H, _H, 0.0, 0.0),  # x north, y east, z down: half turn about (1, 1, 0)
    WorldFrame.NWU: (0.0, 0.0, -_H, _H),  # x north, y west, z up: -90° about z
}


def from_enu(q_enu_b, world: WorldFrame) -> np.ndarray:
    """Attitudes (..., 4) body→ENU as body→``world`` (a no-op copy-free return for ENU)."""
    q = np.asarray(q_enu_b, dtype=np.float64)
    if world is WorldFrame.ENU:
        return q
    return quat_multiply(np.asarray(WORLD_FROM_ENU[world]), q)


def from_enu_one(q_enu_b, world: WorldFrame) -> tuple[float, float, float, float]:
    """One attitude as 4 plain floats (the node's per-message path: no numpy call)."""
    x, y, z, w = q_enu_b
    if world is WorldFrame.ENU:
        return x, y, z, w
    a, b, c, d = WORLD_FROM_ENU[world]  # p ⊗ q, scalar last
    return (d * x + a * w + b * z - c * y, d * y + b * w + c * x - a * z,
            d * z + c * w + a * y - b * x, d * w - a * x - b * y - c * z)


def frame_id_of(frame, world: WorldFrame) -> str:
    """Default ``header.frame_id`` of the attitude: the world frame's name (``enu``, ``ned``,
    ``nwu``) when integrating in the nav frame; ``inertial`` (``inertial_ned`` ...) else."""
    if getattr(frame, "value", frame) == "enu":
        return world.value
    return "inertial" if world is WorldFrame.ENU else f"inertial_{world.value}"
