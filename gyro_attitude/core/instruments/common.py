"""Shared by the instruments: parameter checks, the carrier's truth (specific force, nav-frame rate,
heading, roll/pitch) and the chunked ``solve_ivp`` driver for spin-axis states.

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
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

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
]


def positive(value, name: str) -> float:
    """``value`` as a float; ValueError naming ``name`` unless finite and > 0."""
    v = _float(value, name)
    if v <= 0.0:
        raise ValueError(f"{name} must be > 0, got {value!r}")
    return v


def nonnegative(value, name: str) -> float:
    """``value`` as a float; ValueError naming ``name`` unless finite and >= 0."""
    v = _float(value, name)
    if v < 0.0:
        raise ValueError(f"{name} must be >= 0, got {value!r}")
    return v


def finite(value, name: str) -> float:
    """``value`` as a float; ValueError naming ``name`` unless finite."""
    return _float(value, name)


def _float(value, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise ValueError(f"{name} must be a number, got {type(value).__name__} {value!r}")
    v = float(value)
    if not math.isfinite(v):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return v


def wrap_2pi(a):
    """Angles wrapped to [0, 2π) (compass headings)."""
    return np.mod(a, 2.0 * np.pi)


def wrap_pi(a):
    """Angles wrapped to [−π, π) (differences of headings)."""
    return np.mod(np.asarray(a) + np.pi, 2.0 * np.pi) - np.pi


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
