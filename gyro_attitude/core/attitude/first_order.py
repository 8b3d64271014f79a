"""First-order (forward Euler) quaternion and DCM updates, as exact rotations."""

from __future__ import annotations

import math

import numpy as np

from gyro_attitude.core.attitude.algorithm import RateAlgorithm
from gyro_attitude.core.attitude.compose import exp_scalar, normalize_rows
from gyro_attitude.core.rotation import _exp_rotvec


class QuatFirstOrder(RateAlgorithm):
    """``q_k = normalize(q_{k-1} ⊗ [θ/2, 1])``, ``θ = ω_{k-1} h``: ``normalize([θ/2, 1])``
    is the rotation by ``2·atan(|θ|/2)`` about θ."""

    def body_increments(self, t_ns, omega, k, lookahead=False):
        h = ((t_ns[k] - t_ns[k - 1]) * 1e-9)[:, None]
        half = 0.5 * omega[k - 1] * h
        return normalize_rows(np.concatenate((half, np.ones((k.size, 1))), axis=-1))

    def body_increment_scalar(self, ts, ws, k, nodes):
        h = (ts[k] - ts[k - 1]) * 1e-9
        ax, ay, az = ws[k - 1]
        x, y, z = 0.5 * ax * h, 0.5 * ay * h, 0.5 * az * h
        n = math.sqrt(x * x + y * y + z * z + 1.0)
        return (x / n, y / n, z / n, 1.0 / n)


class DcmFirstOrder(RateAlgorithm):
    """``C_k = orth(C_{k-1} (I + [θ×]))``, ``θ = ω_{k-1} h``, exact (polar) re-orthonormalization.

    The polar factor of ``I + [θ×]`` is the rotation by ``atan(|θ|)`` about θ — in the
    plane ⊥ θ, ``I + [θ×]`` acts as ``√(1+|θ|²)`` times a rotation by atan|θ| and along θ
    as 1.  Because ``C_{k-1}`` is orthogonal, ``polar(C_{k-1}(I+[θ×])) = C_{k-1}
    polar(I+[θ×])``, so "multiply, then re-orthonormalize by SVD/polar decomposition"
    equals composing these rotations (the tests check this against a literal matrix loop
    with ``scipy.linalg.polar``).
    """

    def body_increments(self, t_ns, omega, k, lookahead=False):
        h = ((t_ns[k] - t_ns[k - 1]) * 1e-9)[:, None]
        theta = omega[k - 1] * h
        mag = np.sqrt(np.einsum("...i,...i->...", theta, theta))
        small = mag < 1e-4
        safe = np.where(small, 1.0, mag)
        # atan(x)/x = 1 - x²/3 + x⁴/5 - … ; series below 1e-4 avoids 0/0.
        scale = np.where(small, 1.0 - mag * mag / 3.0, np.arctan(safe) / safe)
        return _exp_rotvec(theta * scale[..., None])

    def body_increment_scalar(self, ts, ws, k, nodes):
        h = (ts[k] - ts[k - 1]) * 1e-9
        ax, ay, az = ws[k - 1]
        x, y, z = ax * h, ay * h, az * h
        mag = math.sqrt(x * x + y * y + z * z)
        scale = 1.0 - mag * mag / 3.0 if mag < 1e-4 else math.atan(mag) / mag
        return exp_scalar(x * scale, y * scale, z * scale)


QUAT_FIRST_ORDER = QuatFirstOrder(
    "quat_first_order", 1, "quaternion q (x) [w h/2, 1], normalized (forward Euler)",
    "1 normalization + product per sample")
DCM_FIRST_ORDER = DcmFirstOrder(
    "dcm_first_order", 1, "DCM C(I + [w h x]) (forward Euler) with exact re-orthonormalization",
    "1 exp map + product per sample")
