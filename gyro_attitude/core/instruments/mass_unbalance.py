"""g-sensitive drift of a gyro from mass unbalance along its spin axis (book §5-3): closed-form
drift rate and a small free-gyro model on a carrier.

With the rotor's centre of mass displaced by ``l`` along the spin axis ``s`` (``m l`` > 0: toward
the +s end), the specific force ``f`` acts on it in the case frame as ``−m f``, so the torque is
``M = l s × (−m f) = m l (f × s)`` and the axis precesses at ``ṡ = M/H = ω_d × s`` with the drift
rate vector ::

    ω_d = (m l / H) f_⊥,   f_⊥ = f − (f·s) s

— about the axis perpendicular to ``s`` along the specific force, magnitude ``m l |f| sin∠(f, s)
/ H``, proportional to the specific force ('g-sensitive').  A level north-pointing rotor at rest
(``f = g e_U``) drifts about the vertical at ``m l g / H``: its north end moves west.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from gyro_attitude.core.earth import check_latitude
from gyro_attitude.core.instruments.common import (
    carrier_point,
    check_times,
    finite,
    integrate_chunked,
    positive,
)
from gyro_attitude.core.motion import Motion

__all__ = ["g_sensitive_drift_rate", "MassUnbalanceParams", "UnbalancedGyro"]


def g_sensitive_drift_rate(unbalance: float, angular_momentum: float, specific_force,
                           spin_axis) -> np.ndarray:
    """Drift rate vector ``ω_d = (m l / H) (f − (f·ŝ) ŝ)`` (rad/s, same frame as the inputs).

    ``unbalance`` m·l (kg·m, signed), ``angular_momentum`` H (N·m·s), ``specific_force`` f (m/s²)
    and ``spin_axis`` s, shapes ``(..., 3)`` broadcast.
    """
    ml = finite(unbalance, "unbalance")
    h = positive(angular_momentum, "angular_momentum")
    f = np.asarray(specific_force, dtype=np.float64)
    s = np.asarray(spin_axis, dtype=np.float64)
    if f.shape[-1:] != (3,) or s.shape[-1:] != (3,):
        raise ValueError("specific_force and spin_axis must have a last axis of length 3")
    if not (np.all(np.isfinite(f)) and np.all(np.isfinite(s))):
        raise ValueError("specific_force and spin_axis must be finite")
    norm = np.linalg.norm(s, axis=-1, keepdims=True)
    if np.any(norm == 0.0):
        raise ValueError("spin_axis must be nonzero")
    s = s / norm
    return (ml / h) * (f - np.sum(f * s, axis=-1, keepdims=True) * s)


@dataclass(frozen=True)
class MassUnbalanceParams:
    """``unbalance`` m·l (kg·m, signed), ``angular_momentum`` H (N·m·s)."""

    unbalance: float
    angular_momentum: float

    def __post_init__(self):
        finite(self.unbalance, "unbalance")
        positive(self.angular_momentum, "angular_momentum")


class UnbalancedGyro:
    """Free gyro with mass unbalance on a carrier: ``ṡ = ω_d × s − ω_in^n × s`` (DOP853, chunked).

    :meth:`iter_chunks` yields ``(t, s_n)`` pieces; the spin axis in ENU, shape ``(m, 3)``."""

    def __init__(self, params: MassUnbalanceParams):
        if not isinstance(params, MassUnbalanceParams):
            raise ValueError(f"params must be MassUnbalanceParams, got {type(params).__name__}")
        self.params = params

    def iter_chunks(self, t_grid, carrier: Motion, latitude: float, spin_axis0=(0.0, 1.0, 0.0),
                    height: float = 0.0, chunk: int = 4096, rtol: float = 1e-11, atol: float = 1e-13,
                    max_step: float = 10.0) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        t = check_times(t_grid)
        if not isinstance(carrier, Motion):
            raise ValueError(f"carrier must be a core.motion.Motion, got {type(carrier).__name__}")
        lat0 = float(check_latitude(finite(latitude, "latitude")))
        height = finite(height, "height")
        s0 = np.asarray(spin_axis0, dtype=np.float64)
        if s0.shape != (3,) or not np.all(np.isfinite(s0)) or np.linalg.norm(s0) == 0.0:
            raise ValueError(f"spin_axis0 must be a finite nonzero 3-vector, got {spin_axis0!r}")
        s0 = s0 / np.linalg.norm(s0)
        k = self.params.unbalance / self.params.angular_momentum

        def rhs(tt, y):
            s = y[:3] / math.sqrt(y[0] * y[0] + y[1] * y[1] + y[2] * y[2])
            f, w, _, lat_rate = carrier_point(carrier, tt, y[3], height)
            ds = np.cross(k * (f - (f @ s) * s) - w, s)
            return np.array([ds[0], ds[1], ds[2], lat_rate])

        for tc, yc in integrate_chunked(rhs, [*s0, lat0], t, chunk, rtol, atol, max_step):
            yield tc, yc[:, :3] / np.linalg.norm(yc[:, :3], axis=1, keepdims=True)

    def simulate(self, t_grid, carrier: Motion, latitude: float, **kwargs) -> tuple[np.ndarray, np.ndarray]:
        """``(t, s_n)`` for the whole run (see :meth:`iter_chunks`)."""
        parts = list(self.iter_chunks(t_grid, carrier, latitude, **kwargs))
        return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])
