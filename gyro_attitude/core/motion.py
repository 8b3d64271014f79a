"""Carrier motion profiles with closed-form truth (numpy only).

Every profile is a function of the time ``t`` in s since the start of the scene and returns,
vectorized over an array of times, the exact attitude ``q_nb`` (scalar-last, maps body vectors
into the ENU navigation frame: ``v_n = C_nb v_b``), the body angular rate ``ω_nb^b`` (rad/s),
the ENU velocity ``v^n = (v_E, v_N, v_U)`` (m/s) and, on request, its rate of change
``dv^n/dt`` (m/s², the components' time derivatives, as used in the specific-force equation
``f^n = dv^n/dt + (2ω_ie^n + ω_en^n) × v^n − g^n``).

Attitude angles follow ROS (REP-103, ``tf2`` ``setRPY``): ``q_nb = Rz(yaw) ⊗ Ry(pitch) ⊗
Rx(roll)`` with body x forward, y left, z up, ``yaw`` counter-clockwise from East about Up
(yaw = 90° points the nose North), positive ``pitch`` nose *down* (right-hand rule about the
left-pointing y axis) and positive ``roll`` left (y) side up, right side down (right-hand
rule about x forward).

The Earth does not appear here: profiles describe motion relative to the navigation frame.
:mod:`gyro_attitude.core.scene` adds Earth rate, transport rate, position and gravity.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gyro_attitude.core.earth import STANDARD_GRAVITY
from gyro_attitude.core.rotation import _exp_rotvec, _qmul, quat_rotate

__all__ = [
    "STANDARD_GRAVITY",
    "MotionSample",
    "Motion",
    "Stationary",
    "ConstantVelocity",
    "CoordinatedTurn",
    "ShipMotion",
    "ClassicalConing",
    "SpinningProjectile",
    "ProfileSegment",
    "SegmentProfile",
    "quat_from_ypr",
    "body_rate_from_ypr_rates",
]



@dataclass(frozen=True)
class MotionSample:
    """Motion truth at ``n`` times: ``q_nb (n,4)``, ``omega_nb_b (n,3)``, ``velocity_enu
    (n,3)``, ``accel_enu (n,3)`` (``None`` unless asked for)."""

    q_nb: np.ndarray
    omega_nb_b: np.ndarray
    velocity_enu: np.ndarray
    accel_enu: np.ndarray | None = None


def _times(t) -> np.ndarray:
    t = np.asarray(t, dtype=np.float64)
    if t.ndim != 1:
        raise ValueError(f"times must be a 1-D array, got shape {t.shape}")
    if not np.all(np.isfinite(t)):
        raise ValueError("times contain non-finite values")
    return t


def _axis_quat(angle: np.ndarray, axis: int) -> np.ndarray:
    """Quaternions of rotations by ``angle`` (rad, shape (n,)) about a coordinate axis."""
    q = np.zeros(np.shape(angle) + (4,))
    q[..., axis] = np.sin(0.5 * angle)
    q[..., 3] = np.cos(0.5 * angle)
    return q


def quat_from_ypr(yaw, pitch, roll) -> np.ndarray:
    """``q_nb = Rz(yaw) ⊗ Ry(pitch) ⊗ Rx(roll)`` (rad, broadcast), scalar-last ``(..., 4)``.

    Same as ``scipy.spatial.transform.Rotation.from_euler("ZYX", [yaw, pitch, roll])``.
    """
    yaw, pitch, roll = np.broadcast_arrays(
        np.asarray(yaw, float), np.asarray(pitch, float), np.asarray(roll, float)
    )
    return _qmul(_qmul(_axis_quat(yaw, 2), _axis_quat(pitch, 1)), _axis_quat(roll, 0))


def body_rate_from_ypr_rates(pitch, roll, yaw_rate, pitch_rate, roll_rate) -> np.ndarray:
    """``ω_nb^b`` of ``q_nb = Rz(ψ) Ry(θ) Rx(φ)`` from the angle rates, shape ``(..., 3)``.

    ``ω_nb^b = φ̇ e_x + Rx(φ)ᵀ θ̇ e_y + Rx(φ)ᵀ Ry(θ)ᵀ ψ̇ e_z`` =
    ``[φ̇ − ψ̇ sinθ, θ̇ cosφ + ψ̇ cosθ sinφ, −θ̇ sinφ + ψ̇ cosθ cosφ]``.
    """
    sp, cp = np.sin(pitch), np.cos(pitch)
    sr, cr = np.sin(roll), np.cos(roll)
    return np.stack(
        (
            roll_rate - yaw_rate * sp,
            pitch_rate * cr + yaw_rate * cp * sr,
            -pitch_rate * sr + yaw_rate * cp * cr,
        ),
        axis=-1,
    )


def _attitude_quat(attitude_rad) -> np.ndarray:
    """``(roll, pitch, yaw)`` in rad to ``q_nb`` (4,)."""
    roll, pitch, yaw = (float(a) for a in attitude_rad)
    return quat_from_ypr(yaw, pitch, roll)


class Motion:
    """Base class: a motion relative to the navigation frame, closed form in time.

    Subclasses set ``name`` and ``moves`` (False when the velocity is identically zero, so
    the scene can skip position and transport rate) and implement :meth:`evaluate`.
    """

    name = "motion"
    moves = True

    def evaluate(self, t, need_accel: bool = False) -> MotionSample:  # pragma: no cover
        raise NotImplementedError

    def velocity(self, t) -> np.ndarray:
        """ENU velocity (m/s), shape ``(n, 3)``; subclasses may override with a cheaper form."""
        return self.evaluate(t).velocity_enu


class Stationary(Motion):
    """At rest in the navigation frame with a fixed attitude ``(roll, pitch, yaw)`` in rad."""

    name = "stationary"
    moves = False

    def __init__(self, attitude_rad=(0.0, 0.0, 0.0)):
        self.q0 = _attitude_quat(attitude_rad)

    def evaluate(self, t, need_accel: bool = False) -> MotionSample:
        t = _times(t)
        n = t.shape[0]
        z = np.zeros((n, 3))
        return MotionSample(
            np.broadcast_to(self.q0, (n, 4)).copy(), z, z.copy(), z.copy() if need_accel else None
        )

    def velocity(self, t) -> np.ndarray:
        return np.zeros((_times(t).shape[0], 3))


class ConstantVelocity(Motion):
    """Straight line at ``speed`` m/s along the body x axis, fixed attitude (roll, pitch, yaw).

    ``v^n = speed · C_nb e_x`` (so a nonzero pitch climbs or descends).
    """

    name = "constant_velocity"

    def __init__(self, speed: float, attitude_rad=(0.0, 0.0, 0.0)):
        self.q0 = _attitude_quat(attitude_rad)
        self.v0 = quat_rotate(self.q0, [float(speed), 0.0, 0.0])
        self.moves = speed != 0.0

    def velocity(self, t) -> np.ndarray:
        return np.broadcast_to(self.v0, (_times(t).shape[0], 3)).copy()

    def evaluate(self, t, need_accel: bool = False) -> MotionSample:
        t = _times(t)
        n = t.shape[0]
        return MotionSample(
            np.broadcast_to(self.q0, (n, 4)).copy(),
            np.zeros((n, 3)),
            self.velocity(t),
            np.zeros((n, 3)) if need_accel else None,
        )


class CoordinatedTurn(Motion):
    """Level turn at constant ``speed`` (m/s) and ``turn_rate`` (rad/s, + = left/CCW).

    ``yaw(t) = yaw0 + turn_rate·t``, pitch 0, constant roll. Unless ``bank`` is given, the
    bank is coordinated against standard gravity: the flat-Earth specific force
    ``[0, 0, g] + a`` lies in the body x-z plane, ``roll = −atan(speed·turn_rate / g)``
    (a left turn lowers the left wing; with y left that is a negative roll).
    Velocity ``v^n = speed [cos yaw, sin yaw, 0]``, ``dv^n/dt = turn_rate · [−v_N, v_E, 0]``.
    """

    name = "coordinated_turn"

    def __init__(self, speed: float, turn_rate: float, yaw0: float = 0.0,
                 bank: float | None = None, gravity: float = STANDARD_GRAVITY):
        self.speed = float(speed)
        self.turn_rate = float(turn_rate)
        self.yaw0 = float(yaw0)
        self.roll = (-np.arctan(self.speed * self.turn_rate / gravity) if bank is None
                     else float(bank))
        self.moves = self.speed != 0.0

    def _yaw(self, t):
        return self.yaw0 + self.turn_rate * t

    def velocity(self, t) -> np.ndarray:
        yaw = self._yaw(_times(t))
        return self.speed * np.stack((np.cos(yaw), np.sin(yaw), np.zeros_like(yaw)), axis=-1)

    def evaluate(self, t, need_accel: bool = False) -> MotionSample:
        t = _times(t)
        yaw = self._yaw(t)
        roll = np.full_like(t, self.roll)
        zero = np.zeros_like(t)
        q = quat_from_ypr(yaw, zero, roll)
        w = body_rate_from_ypr_rates(zero, roll, np.full_like(t, self.turn_rate), zero, zero)
        v = self.velocity(t)
        a = None
        if need_accel:
            a = self.turn_rate * np.stack((-v[:, 1], v[:, 0], zero), axis=-1)
        return MotionSample(q, w, v, a)


def _sine(amplitude: float, period: float, phase: float, t: np.ndarray):
    """``A sin(2πt/T + φ)`` and its first two derivatives (zeros when A = 0 or T = 0)."""
    if amplitude == 0.0 or period == 0.0:
        z = np.zeros_like(t)
        return z, z, z
    w = 2.0 * np.pi / period
    arg = w * t + phase
    s, c = np.sin(arg), np.cos(arg)
    return amplitude * s, amplitude * w * c, -amplitude * w * w * s


class ShipMotion(Motion):
    """Ship on a straight course with roll/pitch/yaw oscillation and heave.

    ``roll(t) = A_r sin(2πt/T_r + φ_r)`` (likewise pitch, and yaw about ``yaw0``);
    heave ``z(t) = A_h sin(2πt/T_h + φ_h)``. The horizontal velocity is ``speed`` along the
    mean course ``yaw0`` (not along the oscillating heading), the vertical one is ``ż(t)``.
    ``oscillations`` maps ``"roll" | "pitch" | "yaw" | "heave"`` to ``(amplitude rad or m,
    period s, phase rad)``.
    """

    name = "ship"

    def __init__(self, speed: float, yaw0: float, oscillations: dict[str, tuple]):
        self.speed = float(speed)
        self.yaw0 = float(yaw0)
        self.osc = {k: tuple(float(x) for x in oscillations.get(k, (0.0, 0.0, 0.0)))
                    for k in ("roll", "pitch", "yaw", "heave")}
        self.moves = self.speed != 0.0 or self.osc["heave"][0] != 0.0
        self._v_course = self.speed * np.array([np.cos(self.yaw0), np.sin(self.yaw0), 0.0])

    def velocity(self, t) -> np.ndarray:
        t = _times(t)
        _, hdot, _ = _sine(*self.osc["heave"], t)
        v = np.broadcast_to(self._v_course, (t.shape[0], 3)).copy()
        v[:, 2] = hdot
        return v

    def evaluate(self, t, need_accel: bool = False) -> MotionSample:
        t = _times(t)
        roll, droll, _ = _sine(*self.osc["roll"], t)
        pitch, dpitch, _ = _sine(*self.osc["pitch"], t)
        yaw, dyaw, _ = _sine(*self.osc["yaw"], t)
        yaw = yaw + self.yaw0
        q = quat_from_ypr(yaw, pitch, roll)
        w = body_rate_from_ypr_rates(pitch, roll, dyaw, dpitch, droll)
        a = None
        if need_accel:
            _, _, hddot = _sine(*self.osc["heave"], t)
            a = np.zeros((t.shape[0], 3))
            a[:, 2] = hddot
        return MotionSample(q, w, self.velocity(t), a)


def coning_quat_and_rate(half_angle: float, omega: float, t: np.ndarray):
    """Classical coning (docs/equations.md): the body x axis sweeps a cone of half-angle α about the
    reference x axis at Ω rad/s.

    ``q(t) = [0, sin(α/2) cos Ωt, sin(α/2) sin Ωt, cos(α/2)]`` (scalar-last),
    ``ω_b(t) = [−2Ω sin²(α/2), −Ω sin α sin Ωt, Ω sin α cos Ωt]``.
    """
    s, c = np.sin(0.5 * half_angle), np.cos(0.5 * half_angle)
    wt = omega * t
    q = np.stack((np.zeros_like(t), s * np.cos(wt), s * np.sin(wt), np.full_like(t, c)), axis=-1)
    w = np.stack(
        (
            np.full_like(t, -2.0 * omega * s * s),
            -omega * np.sin(half_angle) * np.sin(wt),
            omega * np.sin(half_angle) * np.cos(wt),
        ),
        axis=-1,
    )
    return q, w


class ClassicalConing(Motion):
    """``q_nb(t) = q_base ⊗ q_cone(t)``, ``ω_nb^b = ω_cone(t)`` (see :func:`coning_quat_and_rate`).

    ``half_angle`` α in rad, ``omega`` Ω in rad/s; the base attitude is constant, so the body
    rates are exactly the closed form of docs/equations.md and the attitude is periodic (2π/Ω).
    """

    name = "coning"
    moves = False

    def __init__(self, half_angle: float, omega: float, attitude_rad=(0.0, 0.0, 0.0)):
        self.half_angle = float(half_angle)
        self.omega = float(omega)
        self.q_base = _attitude_quat(attitude_rad)

    def velocity(self, t) -> np.ndarray:
        return np.zeros((_times(t).shape[0], 3))

    def evaluate(self, t, need_accel: bool = False) -> MotionSample:
        t = _times(t)
        q, w = coning_quat_and_rate(self.half_angle, self.omega, t)
        z = np.zeros((t.shape[0], 3))
        return MotionSample(_qmul(self.q_base, q), w, z, z.copy() if need_accel else None)


class SpinningProjectile(Motion):
    """Spin ``p`` rad/s about the body x (symmetry) axis while that axis cones (α, Ω).

    ``q_nb(t) = q_base ⊗ q_cone(t) ⊗ [sin(pt/2), 0, 0, cos(pt/2)]``, hence
    ``ω_nb^b(t) = [p − 2Ω sin²(α/2), −Ω sin α sin((Ω−p)t), Ω sin α cos((Ω−p)t)]``
    (the coning rate of docs/equations.md seen from the spinning body). The projectile flies at
    ``speed`` m/s along the cone axis ``C_n,base e_x`` (constant velocity).
    """

    name = "spinning_projectile"

    def __init__(self, spin_rate: float, half_angle: float, omega: float, speed: float = 0.0,
                 attitude_rad=(0.0, 0.0, 0.0)):
        self.spin_rate = float(spin_rate)
        self.half_angle = float(half_angle)
        self.omega = float(omega)
        self.q_base = _attitude_quat(attitude_rad)
        self.v0 = quat_rotate(self.q_base, [float(speed), 0.0, 0.0])
        self.moves = speed != 0.0

    def velocity(self, t) -> np.ndarray:
        return np.broadcast_to(self.v0, (_times(t).shape[0], 3)).copy()

    def evaluate(self, t, need_accel: bool = False) -> MotionSample:
        t = _times(t)
        q_cone, _ = coning_quat_and_rate(self.half_angle, self.omega, t)
        q = _qmul(_qmul(self.q_base, q_cone), _axis_quat(self.spin_rate * t, 0))
        a, om, p = self.half_angle, self.omega, self.spin_rate
        rel = (om - p) * t
        w = np.stack(
            (
                np.full_like(t, p - 2.0 * om * np.sin(0.5 * a) ** 2),
                -om * np.sin(a) * np.sin(rel),
                om * np.sin(a) * np.cos(rel),
            ),
            axis=-1,
        )
        return MotionSample(q, w, self.velocity(t), np.zeros((t.shape[0], 3)) if need_accel
                            else None)


@dataclass(frozen=True)
class ProfileSegment:
    """One scripted segment: constant body rate ``ω_nb^b`` (rad/s) and ENU acceleration
    (m/s²) held for ``duration`` s."""

    duration: float
    angular_rate_b: tuple[float, float, float] = (0.0, 0.0, 0.0)
    acceleration_enu: tuple[float, float, float] = (0.0, 0.0, 0.0)


class SegmentProfile(Motion):
    """Scripted profile: segments of constant body rate and constant ENU acceleration.

    Within segment k starting at ``t_k`` with state ``(q_k, v_k)``:
    ``q_nb(t) = q_k ⊗ exp(ω_k (t − t_k))`` (exact for a constant body rate) and
    ``v(t) = v_k + a_k (t − t_k)``. Segment start states are chained once at construction.
    Before 0 and after the last segment the body holds its attitude at zero rate and keeps
    its velocity (zero acceleration).
    """

    name = "profile"

    def __init__(self, segments: list[ProfileSegment], attitude_rad=(0.0, 0.0, 0.0),
                 velocity_enu=(0.0, 0.0, 0.0)):
        if not segments:
            raise ValueError("profile needs at least one segment")
        n = len(segments)
        self.rates = np.array([s.angular_rate_b for s in segments] + [(0.0, 0.0, 0.0)], float)
        self.accels = np.array([s.acceleration_enu for s in segments] + [(0.0, 0.0, 0.0)], float)
        durations = np.array([s.duration for s in segments], float)
        if np.any(durations <= 0):
            raise ValueError("profile segment durations must be > 0")
        self.starts = np.concatenate(([0.0], np.cumsum(durations)))  # (n+1,)
        self.q_start = np.empty((n + 1, 4))
        self.v_start = np.empty((n + 1, 3))
        self.q_start[0] = _attitude_quat(attitude_rad)
        self.v_start[0] = np.asarray(velocity_enu, float)
        for k in range(n):
            q_end = _qmul(self.q_start[k], _exp_rotvec(self.rates[k] * durations[k]))
            self.q_start[k + 1] = q_end / np.linalg.norm(q_end)
            self.v_start[k + 1] = self.v_start[k] + self.accels[k] * durations[k]
        self.moves = bool(np.any(self.v_start != 0.0) or np.any(self.accels != 0.0))

    def _segment(self, t):
        k = np.searchsorted(self.starts, t, side="right") - 1
        before = k < 0
        k = np.clip(k, 0, len(self.starts) - 1)
        tau = np.where(before, 0.0, t - self.starts[k])
        return k, tau, before

    def velocity(self, t) -> np.ndarray:
        t = _times(t)
        k, tau, before = self._segment(t)
        a = np.where(before[:, None], 0.0, self.accels[k])
        return self.v_start[k] + a * tau[:, None]

    def evaluate(self, t, need_accel: bool = False) -> MotionSample:
        t = _times(t)
        k, tau, before = self._segment(t)
        w = np.where(before[:, None], 0.0, self.rates[k])
        q = _qmul(self.q_start[k], _exp_rotvec(w * tau[:, None]))
        a = np.where(before[:, None], 0.0, self.accels[k])
        v = self.v_start[k] + a * tau[:, None]
        return MotionSample(q, w, v, a if need_accel else None)
