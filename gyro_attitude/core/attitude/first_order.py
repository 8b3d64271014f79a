"""First-order (forward Euler) quaternion and DCM updates, as exact rotations."""

from __future__ import annotations

import math

from gyro_attitude.core.attitude.algorithm import RateAlgorithm
from gyro_attitude.core.attitude.compose import exp_scalar
from gyro_attitude.core.jit import kernel


@kernel
def quat_first_order_increment(ts, ws, k, n):
    """``q_k = normalize(q_{k-1} ⊗ [θ/2, 1])``, ``θ = ω_{k-1} h``: ``normalize([θ/2, 1])`` is
    the rotation by ``2·atan(|θ|/2)`` about θ.  (b_k, False): no fit to distrust."""
    h = (ts[k] - ts[k - 1]) * 1e-9
    x, y, z = 0.5 * ws[k - 1, 0] * h, 0.5 * ws[k - 1, 1] * h, 0.5 * ws[k - 1, 2] * h
    m = math.sqrt(x * x + y * y + z * z + 1.0)
    return (x / m, y / m, z / m, 1.0 / m), False


@kernel
def dcm_first_order_increment(ts, ws, k, n):
    """``C_k = orth(C_{k-1} (I + [θ×]))``, ``θ = ω_{k-1} h``, exact (polar)
    re-orthonormalization.  The polar factor of ``I + [θ×]`` is the rotation by ``atan(|θ|)``
    about θ — in the plane ⊥ θ, ``I + [θ×]`` acts as ``√(1+|θ|²)`` times a rotation by atan|θ|
    and along θ as 1.  Because ``C_{k-1}`` is orthogonal, ``polar(C_{k-1}(I+[θ×])) = C_{k-1}
    polar(I+[θ×])``, so "multiply, then re-orthonormalize by SVD/polar decomposition" equals
    composing these rotations (the tests check this against a literal matrix loop with
    ``scipy.linalg.polar``).  atan(x)/x by its series below 1e-4 (no 0/0)."""
    h = (ts[k] - ts[k - 1]) * 1e-9
    x, y, z = ws[k - 1, 0] * h, ws[k - 1, 1] * h, ws[k - 1, 2] * h
    mag = math.sqrt(x * x + y * y + z * z)
    scale = 1.0 - mag * mag / 3.0 if mag < 1e-4 else math.atan(mag) / mag
    return exp_scalar(x * scale, y * scale, z * scale), False


QUAT_FIRST_ORDER = RateAlgorithm(
    "quat_first_order", 1, "quaternion q (x) [w h/2, 1], normalized (forward Euler)",
    "1 normalization + product per sample", code=0)
DCM_FIRST_ORDER = RateAlgorithm(
    "dcm_first_order", 1, "DCM C(I + [w h x]) (forward Euler) with exact re-orthonormalization",
    "1 exp map + product per sample", code=1)
