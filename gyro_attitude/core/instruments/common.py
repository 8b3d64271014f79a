"""Shared by the instruments: parameter checks, the carrier's truth (specific force, nav-frame rate,
heading, roll/pitch), the chunked ``solve_ivp`` driver and the resumable block stepper.

Every instrument here is a gyro whose spin axis ``s`` (a unit vector in the ENU frame n) is
held in inertial space and torqued by its correction system.  With ``H`` the spin angular
momentum and ``M`` the applied torque, ``d(H s)/dt`` in inertial space is ``M``; seen from the
rotating navigation frame (rate ``ω_in^n = ω_ie^n + ω_en^n``)::

    ṡ = M_⊥ / H − ω_in^n × s        (M_⊥: the part of M perpendicular to s)

(precession model: the rotor's nutation is left out; the torque component along s only changes
the spin speed, which the rotor motor holds).  The latitude ``L`` is integrated with the
state, ``L̇ = v_N / (R_M + h)``, so long runs on a moving carrier see the latitude they reach.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass, fields

import numpy as np

from gyro_attitude.core.angles import wrap_2pi, wrap_pi
from gyro_attitude.core.earth import (
    OMEGA_IE,
    check_latitude,
    earth_rate_enu,
    gravity_enu,
    radii_of_curvature,
    transport_rate_enu,
)
from gyro_attitude.core.motion import Motion
from gyro_attitude.core.rotation import quat_rotate

# the shared parameter checks, under the short names the instrument modules use
from gyro_attitude.core.validators import check_finite as finite
from gyro_attitude.core.validators import check_nonnegative as nonnegative
from gyro_attitude.core.validators import check_positive as positive

__all__ = [
    "positive",
    "nonnegative",
    "finite",
    "CarrierTruth",
    "carrier_truth",
    "carrier_point",
    "heading_from_quat",
    "roll_pitch_from_up",
    "wrap_2pi",
    "wrap_pi",
    "check_times",
    "integrate_chunked",
    "InstrumentStepper",
    "JOINT_RATE_STEP_S",
]

#: Half-width (s) of the central difference that turns joint angles into joint rates (see
#: :class:`InstrumentStepper`): instrument states move at ≲ 1 rad/s, so the truncation error
#: (∝ step²) and the round-off (∝ 1e-16/step) both stay below 1e-9 rad/s.
JOINT_RATE_STEP_S = 1e-4


def heading_from_quat(q_nb) -> np.ndarray:
    """True heading (rad, clockwise from north, [0, 2π)) of the body x axis: ``atan2(x_E, x_N)``."""
    x_n = quat_rotate(q_nb, [1.0, 0.0, 0.0])
    return wrap_2pi(np.arctan2(x_n[..., 0], x_n[..., 1]))


def roll_pitch_from_up(up_b) -> tuple[np.ndarray, np.ndarray]:
    """Roll and pitch (rad, REP-103: roll + = right wing down, pitch + = nose down) of a body whose
    reference 'up' direction, in body axes, is ``up_b``.

    With ``q_nb = Rz(ψ) Ry(θ) Rx(φ)`` the up vector in body axes is
    ``[−sin θ, sin φ cos θ, cos φ cos θ]``, so ``φ = atan2(u_y, u_z)`` and
    ``θ = atan2(−u_x, √(u_y² + u_z²))`` (valid for any length of ``up_b``).
    """
    u = np.asarray(up_b, dtype=np.float64)
    roll = np.arctan2(u[..., 1], u[..., 2])
    pitch = np.arctan2(-u[..., 0], np.hypot(u[..., 1], u[..., 2]))
    return roll, pitch


@dataclass(frozen=True)
class CarrierTruth:
    """The carrier at ``n`` times: ``q_nb (n,4)``, ``velocity_enu (n,3)``, specific force
    ``f_n (n,3)`` (m/s²), nav-frame rate ``omega_in_n (n,3)`` (rad/s) and true ``heading (n,)``."""

    q_nb: np.ndarray
    velocity_enu: np.ndarray
    f_n: np.ndarray
    omega_in_n: np.ndarray
    heading: np.ndarray


def carrier_truth(carrier: Motion, t, latitude, height: float = 0.0) -> CarrierTruth:
    """Truth of ``carrier`` at times ``t`` (s) and latitudes ``latitude`` (rad, scalar or per time).

    Specific force ``f^n = dv^n/dt + (2ω_ie^n + ω_en^n) × v^n − g^n`` (docs/equations.md), with the
    WGS-84 normal gravity of :mod:`gyro_attitude.core.earth`.
    """
    if not isinstance(carrier, Motion):
        raise ValueError(f"carrier must be a core.motion.Motion, got {type(carrier).__name__}")
    m = carrier.evaluate(t, need_accel=True)
    lat = check_latitude(np.broadcast_to(np.asarray(latitude, dtype=np.float64), m.q_nb.shape[:1]))
    v = m.velocity_enu
    w_ie = earth_rate_enu(lat)
    w_en = transport_rate_enu(lat, height, v)
    f = m.accel_enu + np.cross(2.0 * w_ie + w_en, v) - gravity_enu(lat, height)
    return CarrierTruth(m.q_nb, v, f, w_ie + w_en, heading_from_quat(m.q_nb))


def carrier_point(carrier: Motion, t: float, lat: float,
                  height: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Scalar fast path of :func:`carrier_truth` for an ODE right-hand side: ``(f^n, ω_in^n, v^n,
    L̇)`` at one time ``t`` and latitude ``lat`` (the Earth terms in plain floats: numpy's
    per-call overhead on 3-vectors would cost four times the arithmetic)."""
    m = carrier.evaluate(np.array([t]), need_accel=True)
    v = m.velocity_enu[0]
    ve, vn, vu = float(v[0]), float(v[1]), float(v[2])
    r_m, r_n = radii_of_curvature(lat)
    r_m, r_n = float(r_m) + height, float(r_n) + height
    sl, cl = math.sin(lat), math.cos(lat)
    w_ie = (0.0, OMEGA_IE * cl, OMEGA_IE * sl)
    w_en = (-vn / r_m, ve / r_n, ve * sl / (cl * r_n))
    c = (2.0 * w_ie[0] + w_en[0], 2.0 * w_ie[1] + w_en[1], 2.0 * w_ie[2] + w_en[2])
    g = -float(gravity_enu(lat, height)[2])
    a = m.accel_enu[0]
    f = np.array([a[0] + c[1] * vu - c[2] * vn,
                  a[1] + c[2] * ve - c[0] * vu,
                  a[2] + c[0] * vn - c[1] * ve + g])
    w_in = np.array([w_ie[0] + w_en[0], w_ie[1] + w_en[1], w_ie[2] + w_en[2]])
    return f, w_in, v, vn / r_m


def check_times(t_grid) -> np.ndarray:
    """A 1-D, finite, strictly increasing time grid (s) of at least one sample."""
    try:
        t = np.asarray(t_grid, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise ValueError(f"t_grid must be an array of times in s: {err}") from None
    if t.ndim != 1 or t.size == 0:
        raise ValueError(f"t_grid must be a non-empty 1-D array, got shape {t.shape}")
    if not np.all(np.isfinite(t)):
        raise ValueError("t_grid contains non-finite times")
    if np.any(np.diff(t) <= 0.0):
        raise ValueError("t_grid must be strictly increasing")
    return t


def integrate_chunked(rhs: Callable[[float, np.ndarray], np.ndarray], y0, t_grid: np.ndarray,
                      chunk: int, rtol: float, atol: float,
                      max_step: float) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """Yield ``(t_chunk, y_chunk)`` pieces of the solution of ``ẏ = rhs(t, y)`` on ``t_grid``.

    DOP853 (8th order, adaptive): every instrument state here is smooth between carrier events,
    not stiff (its fastest rate — erection gain, P/H — is far below 1/max_step), and the step
    limit ``max_step`` keeps the solver from stepping over a short manoeuvre.  Each chunk is a
    fresh ``solve_ivp`` call started from the previous chunk's last state, so memory stays
    bounded by ``chunk`` samples however long the run.
    """
    from scipy.integrate import solve_ivp  # (imported where used: see sensor_errors)

    chunk = int(chunk)
    if chunk < 1:
        raise ValueError(f"chunk must be >= 1, got {chunk}")
    positive(max_step, "max_step")
    y = np.asarray(y0, dtype=np.float64)
    first = True
    t_prev = float(t_grid[0])
    start = 0
    n = t_grid.shape[0]
    while start < n:
        stop = min(start + chunk, n)
        t_out = t_grid[start:stop]
        pieces = []
        if first:
            pieces.append(y[None, :])
            t_eval = t_out[1:]
            first = False
        else:
            t_eval = t_out
        if t_eval.size:
            sol = solve_ivp(rhs, (t_prev, t_eval[-1]), y, method="DOP853", t_eval=t_eval,
                            rtol=rtol, atol=atol, max_step=max_step)
            if not sol.success:
                raise ValueError(f"instrument integration failed at t = {sol.t[-1]:.6g} s: "
                                 f"{sol.message}")
            pieces.append(sol.y.T)
            y = sol.y[:, -1].copy()
        t_prev = t_out[-1]
        yield t_out, np.concatenate(pieces, axis=0)
        start = stop


class InstrumentStepper:
    """An instrument on a carrier advanced block after block: :meth:`advance` takes the next
    output times and returns ``(names, positions (n,k), velocities (n,k))`` of its joints.

    ``instrument`` provides ``initial_state(carrier, latitude, height, **initial)``,
    ``rhs(carrier, height)``, ``outputs(t, y, carrier, height)``, ``JOINTS`` (names) and
    ``joint_positions(outputs)``.  The solver state carries over between calls, so any split
    into blocks gives the run of one long call to within the solver tolerance (each block is a
    fresh ``solve_ivp`` start from the last state, as each chunk of a long run already is).

    Joint velocities are the time derivatives of the joint angles, taken by a central
    difference of the angle map along the exact state derivative:
    ``(P(t+δ, y+δ ẏ) − P(t−δ, y−δ ẏ)) / 2δ`` — second order in δ (the ``ÿ`` terms cancel),
    ``δ`` = :data:`JOINT_RATE_STEP_S`, differences wrapped to (−π, π] for heading-like angles.
    """

    def __init__(self, instrument, carrier: Motion, latitude: float, height: float = 0.0,
                 t0: float = 0.0, rtol: float = 1e-10, atol: float = 1e-12,
                 max_step: float = 10.0, chunk: int = 4096, **initial):
        self.instrument = instrument
        self.carrier = carrier
        self.height = finite(height, "height")
        self.names = tuple(instrument.JOINTS)
        self._rhs = instrument.rhs(carrier, self.height)
        self._y = np.asarray(instrument.initial_state(carrier, latitude, self.height, **initial),
                             dtype=np.float64)
        self.t = finite(t0, "t0")
        self._started = False
        self._tol = (positive(rtol, "rtol"), positive(atol, "atol"), positive(max_step, "max_step"))
        self._chunk = int(chunk)

    def _positions(self, t: np.ndarray, y: np.ndarray) -> np.ndarray:
        return np.asarray(self.instrument.joint_positions(
            self.instrument.outputs(t, y, self.carrier, self.height)), dtype=np.float64)

    def advance(self, t) -> tuple[tuple[str, ...], np.ndarray, np.ndarray]:
        """Joint angles and rates at the increasing times ``t`` (s, all after the last call's;
        the first call may start at ``t0``, which returns the initial state there)."""
        t = np.asarray(t, dtype=np.float64)
        k = len(self.names)
        if t.size == 0:
            return self.names, np.empty((0, k)), np.empty((0, k))
        t = check_times(t)
        if t[0] < self.t or (self._started and t[0] == self.t):
            raise ValueError(f"times must come after the instrument's current time {self.t!r} s")
        keep_first = not self._started and t[0] == self.t
        grid = t if keep_first else np.concatenate(([self.t], t))
        rtol, atol, max_step = self._tol
        parts = [yc for _, yc in integrate_chunked(self._rhs, self._y, grid, self._chunk,
                                                   rtol, atol, max_step)]
        y = np.concatenate(parts)
        if not keep_first:
            y = y[1:]
        self._y = y[-1].copy()
        self.t = float(t[-1])
        self._started = True
        positions = self._positions(t, y)
        ydot = np.array([self._rhs(float(ti), yi) for ti, yi in zip(t, y, strict=True)])
        d = JOINT_RATE_STEP_S
        ahead = self._positions(t + d, y + d * ydot)
        behind = self._positions(t - d, y - d * ydot)
        velocities = wrap_pi(ahead - behind) / (2.0 * d)
        return self.names, positions, velocities


class ChunkedOutput:
    """Mixin of an instrument's output dataclass (arrays over time): ``concatenate`` joins the
    chunks of :func:`integrate_chunked` field by field."""

    @classmethod
    def concatenate(cls, parts: list) -> ChunkedOutput:
        return cls(*(np.concatenate([getattr(p, f.name) for p in parts]) for f in fields(cls)))
