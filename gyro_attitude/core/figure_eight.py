"""A figure-eight walked with a hand-held IMU, in closed form: poses, body rate, acceleration.

The shipped trajectory example (``config/trajectories/figure_eight.tum``, written by
``python -m gyro_attitude.io.make_figure_eight``) samples it, and the trajectory tests
check the simulated IMU against it. In the tangent frame (m, s)::

    p(t) = (A sin ωt, B sin 2ωt, h0 + c sin Ωt),    ω = 2π / period,  Ω = 2π f_step

heading along the horizontal velocity, ψ = atan2(ṗ_y, ṗ_x), the hand swaying in roll at the
step frequency, φ = φ0 sin Ωt, and pitching once per loop, θ = θ0 sin(ωt + 0.3);
``q_tb = Rz(ψ) Ry(θ) Rx(φ)``. The horizontal speed never vanishes (ṗ_x = 0 needs cos ωt = 0,
where ṗ_y = 2Bω cos 2ωt = −2Bω), so ψ is smooth: ψ̇ = (ṗ_x p̈_y − ṗ_y p̈_x)/(ṗ_x² + ṗ_y²).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gyro_attitude.core.motion import body_rate_from_ypr_rates, quat_from_ypr
from gyro_attitude.core.rotation import quat_conjugate, quat_rotate

__all__ = ["FigureEight"]


@dataclass(frozen=True)
class FigureEight:
    """Closed-form figure-eight (module docstring); lengths in m, angles in rad."""

    a: float = 3.0
    b: float = 1.5
    period_s: float = 10.0
    h0: float = 1.2
    bob_m: float = 0.015
    step_hz: float = 1.8
    roll_rad: float = math.radians(8.0)
    pitch_rad: float = math.radians(5.0)

    def _parts(self, t):
        t = np.asarray(t, dtype=np.float64)
        w = 2.0 * math.pi / self.period_s
        s = 2.0 * math.pi * self.step_hz
        sw, cw, s2, c2 = np.sin(w * t), np.cos(w * t), np.sin(2 * w * t), np.cos(2 * w * t)
        ss, cs = np.sin(s * t), np.cos(s * t)
        p = np.stack((self.a * sw, self.b * s2, self.h0 + self.bob_m * ss), axis=-1)
        v = np.stack((self.a * w * cw, 2 * self.b * w * c2, self.bob_m * s * cs), axis=-1)
        acc = np.stack((-self.a * w * w * sw, -4 * self.b * w * w * s2,
                        -self.bob_m * s * s * ss), axis=-1)
        yaw = np.arctan2(v[:, 1], v[:, 0])
        yaw_rate = (v[:, 0] * acc[:, 1] - v[:, 1] * acc[:, 0]) / (v[:, 0] ** 2 + v[:, 1] ** 2)
        roll = self.roll_rad * ss
        roll_rate = self.roll_rad * s * cs
        pitch = self.pitch_rad * np.sin(w * t + 0.3)
        pitch_rate = self.pitch_rad * w * np.cos(w * t + 0.3)
        q = quat_from_ypr(yaw, pitch, roll)
        omega = body_rate_from_ypr_rates(pitch, roll, yaw_rate, pitch_rate, roll_rate)
        return p, v, acc, q, omega

    def poses(self, t) -> tuple[np.ndarray, np.ndarray]:
        """``(p (n,3), q_tb (n,4))`` at times ``t`` (s)."""
        p, _, _, q, _ = self._parts(t)
        return p, q

    def body_rate(self, t) -> np.ndarray:
        """``ω_tb^b (n,3)`` rad/s."""
        return self._parts(t)[4]

    def velocity(self, t) -> np.ndarray:
        return self._parts(t)[1]

    def acceleration(self, t) -> np.ndarray:
        """``a^t = p̈ (n,3)`` m/s² in the tangent frame."""
        return self._parts(t)[2]

    def kinematic_force(self, t) -> np.ndarray:
        """``C_bt a^t (n,3)``: the specific force without gravity and Earth terms."""
        _, _, acc, q, _ = self._parts(t)
        return quat_rotate(quat_conjugate(q), acc)
