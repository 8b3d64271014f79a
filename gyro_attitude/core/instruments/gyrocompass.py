"""Pendulous gyrocompass (book §2-5, §5-3, §5-4): meridian seeking, Schuler tuning, speed error,
ballistic deflection, damping with latitude correction; closed forms for the checks.

Model (precession equations of :mod:`.common`).  The sensitive element is a two-degree-of-
freedom gyro, free in azimuth about the true vertical and in tilt, spin axis ``s`` (unit, ENU),
``α`` its azimuth east of north and ``β`` its elevation.  A pendulous mass (moment ``m·l``) hangs
below the pivot along the element's 'up' axis ``u`` (perpendicular to ``s`` in the vertical
plane through ``s``).  In the carrier-accelerated frame the mass feels ``−m f`` (``f`` the
specific force), so the torque is ``M_p = m l (u × f)``; at rest ``|M_p| = m l g sin β``: the
pendulosity is ``P = m l g`` per radian of tilt.  The rotor spins so that ``H`` points to the
north-seeking end.  Damping (Anschütz style): a torque about the vertical proportional to the
tilt, ``M_d = −D (β − β_ref(L)) e_U``, where the latitude corrector ``β_ref(L)`` is the
equilibrium tilt at rest at the current latitude; without that corrector the damping would
leave the classical damping error ``α ≈ (D/P) tan L``.

Small-angle form (docs/equations.md), with ``ω_in = (ω_E, ω_N, ω_U)`` and horizontal specific force
``(f_E, f_N)``::

    α̇ = ω_U − ω_N β − (P/H)(β + f_N/g)
    β̇ = ω_N α − ω_E − (D/H)(β − β_ref)

so ``α̈ + (D/H) α̇ + (P/H + ω_N) ω_N α = …``: undamped period ``T = 2π √(H / (P ω_ie cos L))``
(the ``ω_N`` beside ``P/H`` is < 0.2 % at Schuler tuning), equilibrium
``β_eq = (ω_U − (P/H) f_N/g) / (P/H + ω_N)``, ``α_eq = (ω_E + (D/H)(β_eq − β_ref)) / ω_N``.
On a ship ``ω_E = −v_N/(R_M+h)``: the axis settles west of north on a northerly course, the
speed error ``δ = atan(v_N / (R Ω cos L + v_E))``, and the compass reads ``+δ`` high.

Ballistic deflection: a change ``Δv_N`` of northerly speed over a short time throws the axis by
``∫α̇ dt = −(P/(g H)) Δv_N`` while the equilibrium moves by ``Δα_eq = −Δv_N/(R_M Ω cos L)``.
They are equal — no deflection, the compass goes straight to its new settle point — when
``P/(g H) = 1/(R Ω cos L)``, i.e. ``m l = H/(R Ω cos L)``, i.e. ``T = 2π √(R/g)`` = 84.4 min
(Schuler tuning).  Otherwise the first throw is ``Δv_N (1/(R Ω cos L) − P/(g H))`` from the new
equilibrium (sign: axis minus its new settle point).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from gyro_attitude.core.earth import (
    OMEGA_IE,
    STANDARD_GRAVITY,
    check_latitude,
    gravity_enu,
    radii_of_curvature,
)
from gyro_attitude.core.instruments.common import (
    ChunkedOutput,
    carrier_point,
    carrier_truth,
    check_times,
    finite,
    integrate_chunked,
    nonnegative,
    positive,
    wrap_2pi,
    wrap_pi,
)
from gyro_attitude.core.motion import Motion

__all__ = [
    "SCHULER_RADIUS",
    "SCHULER_GRAVITY",
    "GyrocompassParams",
    "GyrocompassOutput",
    "Gyrocompass",
    "gyrocompass_period",
    "schuler_period",
    "speed_error",
    "gyrocompass_equilibrium",
    "gyrocompass_settle_point",
    "ballistic_throw",
]

SCHULER_RADIUS = 6.371e6  # m, mean Earth radius of the Schuler period in docs/equations.md
SCHULER_GRAVITY = STANDARD_GRAVITY  # m/s²


def _g(lat: float, h: float = 0.0) -> float:
    return float(-gravity_enu(lat, h)[2])


def _lat(latitude, name: str = "latitude") -> float:
    lat = float(check_latitude(finite(latitude, name), name))
    if abs(lat) >= math.radians(89.0):
        # the compass's directive moment vanishes with cos L: no meridian to seek at the poles
        raise ValueError(f"{name} must lie within ±89° for a gyrocompass, got {math.degrees(lat):.6g}°")
    return lat


def gyrocompass_period(angular_momentum: float, pendulosity: float, latitude: float) -> float:
    """Undamped period ``T = 2π √(H / (P ω_ie cos L))`` (s); ``P`` in N·m/rad."""
    h = positive(angular_momentum, "angular_momentum")
    p = positive(pendulosity, "pendulosity")
    return 2.0 * math.pi * math.sqrt(h / (p * OMEGA_IE * math.cos(_lat(latitude))))


def schuler_period(radius: float = SCHULER_RADIUS, gravity: float = SCHULER_GRAVITY) -> float:
    """``2π √(R/g)`` (s): 5064 s = 84.4 min for the docs/equations.md constants."""
    return 2.0 * math.pi * math.sqrt(positive(radius, "radius") / positive(gravity, "gravity"))


def speed_error(v_north: float, v_east: float, latitude: float, height: float = 0.0) -> float:
    """Speed error ``δ`` (rad): the settled axis lies ``δ`` west of north, the compass reads ``+δ``.

    ``δ = atan2(v_N/(R_M+h), Ω cos L + v_E/(R_N+h))`` — the azimuth of the horizontal part of
    ``ω_ie + ω_en`` (WGS-84 radii; docs/equations.md's ``atan(v_N / (R Ω cos L + v_E))`` with R_M ≈ R_N).
    """
    lat = _lat(latitude)
    r_m, r_n = (float(r) for r in radii_of_curvature(lat))
    h = finite(height, "height")
    return math.atan2(finite(v_north, "v_north") / (r_m + h),
                      OMEGA_IE * math.cos(lat) + finite(v_east, "v_east") / (r_n + h))


@dataclass(frozen=True)
class GyrocompassParams:
    """``angular_momentum`` H (N·m·s), ``pendulous_moment`` m·l (kg·m, so P = m l g),
    ``damping`` D (N·m/rad of tilt, 0 = undamped), ``latitude_correction`` (the damping
    torque acts on β − β_ref(L), removing the damping error)."""

    angular_momentum: float
    pendulous_moment: float
    damping: float = 0.0
    latitude_correction: bool = True

    def __post_init__(self):
        positive(self.angular_momentum, "angular_momentum")
        positive(self.pendulous_moment, "pendulous_moment")
        nonnegative(self.damping, "damping")
        if not isinstance(self.latitude_correction, bool):
            raise ValueError(f"latitude_correction must be a bool, got {self.latitude_correction!r}")

    def pendulosity(self, latitude: float, height: float = 0.0) -> float:
        """``P = m l g(L, h)`` (N·m/rad) with WGS-84 normal gravity."""
        return self.pendulous_moment * _g(_lat(latitude), finite(height, "height"))

    def period(self, latitude: float) -> float:
        """Undamped period (s) at ``latitude`` (:func:`gyrocompass_period`)."""
        return gyrocompass_period(self.angular_momentum, self.pendulosity(latitude), latitude)

    def damping_ratio(self, latitude: float) -> float:
        """``ζ = (D/H) / (2 ω_n)``, ``ω_n = 2π/T``."""
        return self.damping / self.angular_momentum * self.period(latitude) / (4.0 * math.pi)

    @classmethod
    def schuler_tuned(cls, angular_momentum: float, latitude: float, damping_ratio: float = 0.0,
                      latitude_correction: bool = True) -> GyrocompassParams:
        """Schuler tuning at ``latitude``: ``m l = H / (R_M Ω cos L)`` (no ballistic deflection)."""
        lat = _lat(latitude)
        r_m, _ = radii_of_curvature(lat)
        ml = positive(angular_momentum, "angular_momentum") / (float(r_m) * OMEGA_IE * math.cos(lat))
        return cls._with_damping(angular_momentum, ml, lat, damping_ratio, latitude_correction)

    @classmethod
    def with_period(cls, angular_momentum: float, period: float, latitude: float,
                    damping_ratio: float = 0.0, latitude_correction: bool = True) -> GyrocompassParams:
        """Pendulosity chosen for an undamped period ``period`` (s) at ``latitude``."""
        lat = _lat(latitude)
        h = positive(angular_momentum, "angular_momentum")
        p = 4.0 * math.pi ** 2 * h / (positive(period, "period") ** 2 * OMEGA_IE * math.cos(lat))
        return cls._with_damping(h, p / _g(lat), lat, damping_ratio, latitude_correction)

    @classmethod
    def with_damping_ratio(cls, angular_momentum: float, pendulous_moment: float, latitude: float,
                           damping_ratio: float = 0.0,
                           latitude_correction: bool = True) -> GyrocompassParams:
        """Given ``m l``, the damping D for a damping ratio ``damping_ratio`` at ``latitude``."""
        return cls._with_damping(positive(angular_momentum, "angular_momentum"),
                                 positive(pendulous_moment, "pendulous_moment"), _lat(latitude),
                                 damping_ratio, latitude_correction)

    @classmethod
    def _with_damping(cls, h, ml, lat, damping_ratio, latitude_correction):
        zeta = nonnegative(damping_ratio, "damping_ratio")
        undamped = cls(h, ml, 0.0, latitude_correction)
        omega_n = 2.0 * math.pi / undamped.period(lat)
        return cls(h, ml, 2.0 * zeta * omega_n * h, latitude_correction)


def _static_tilt(p_over_h: float, lat: float) -> float:
    """Equilibrium tilt at rest ``β = Ω sin L / (P/H + Ω cos L)`` (the latitude corrector's value)."""
    return OMEGA_IE * math.sin(lat) / (p_over_h + OMEGA_IE * math.cos(lat))


def gyrocompass_equilibrium(params: GyrocompassParams, latitude: float, v_enu=(0.0, 0.0, 0.0),
                            f_horizontal=(0.0, 0.0), height: float = 0.0) -> tuple[float, float]:
    """Settle point ``(α_eq, β_eq)`` (rad) of the small-angle model (module docstring) for a
    constant velocity ``v_enu`` and constant horizontal specific force ``(f_E, f_N)``."""
    lat = _lat(latitude)
    h = finite(height, "height")
    v = np.asarray(v_enu, dtype=np.float64)
    fh = np.asarray(f_horizontal, dtype=np.float64)
    if v.shape != (3,) or fh.shape != (2,) or not (np.all(np.isfinite(v)) and np.all(np.isfinite(fh))):
        raise ValueError("v_enu must be 3 finite numbers and f_horizontal 2 finite numbers")
    r_m, r_n = (float(r) for r in radii_of_curvature(lat))
    w_e = -v[1] / (r_m + h)
    w_n = OMEGA_IE * math.cos(lat) + v[0] / (r_n + h)
    w_u = OMEGA_IE * math.sin(lat) + v[0] * math.tan(lat) / (r_n + h)
    g = _g(lat, h)
    p_over_h = params.pendulous_moment * g / params.angular_momentum
    beta = (w_u - p_over_h * fh[1] / g) / (p_over_h + w_n)
    beta_ref = _static_tilt(p_over_h, lat) if params.latitude_correction else 0.0
    alpha = (w_e + params.damping / params.angular_momentum * (beta - beta_ref)) / w_n
    return alpha, beta


def gyrocompass_settle_point(params: GyrocompassParams, latitude: float,
                             v_enu=(0.0, 0.0, 0.0)) -> tuple[float, float]:
    """Settle point ``(α_eq, β_eq)`` (rad) on a steady horizontal course ``v_enu``: the
    equilibrium of :func:`gyrocompass_equilibrium` with the Coriolis part of the specific force
    that the pendulum feels at that velocity."""
    lat = _lat(latitude)
    v = np.asarray(v_enu, dtype=np.float64)
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise ValueError("v_enu must be 3 finite numbers")
    return gyrocompass_equilibrium(params, lat, v, _coriolis_horizontal(lat, v))


def ballistic_throw(params: GyrocompassParams, latitude: float, v_before, v_after) -> dict[str, float]:
    """First throw after a short change of velocity from ``v_before`` to ``v_after`` (ENU, m/s).

    The manoeuvre is short against the period, so during it only the impulse of the
    acceleration acts: ``Δα = −(P/(g H)) Δv_N`` (the ``m l/H`` of the pendulous torque times the
    north velocity change) and β does not move.  Returns ``throw`` = axis azimuth minus its new
    equilibrium just after the manoeuvre (rad), ``tilt_offset`` = β minus its new equilibrium,
    and ``amplitude`` of the undamped azimuth swing that follows about the new equilibrium,
    ``√(throw² + (k·tilt_offset/ω)²)`` with ``k = P/H + ω_N``, ``ω² = k ω_N``.
    """
    lat = _lat(latitude)
    vb = np.asarray(v_before, dtype=np.float64)
    va = np.asarray(v_after, dtype=np.float64)
    a0, b0 = gyrocompass_equilibrium(params, lat, vb, _coriolis_horizontal(lat, vb))
    a1, b1 = gyrocompass_equilibrium(params, lat, va, _coriolis_horizontal(lat, va))
    throw = a0 - params.pendulous_moment / params.angular_momentum * (va[1] - vb[1]) - a1
    tilt = b0 - b1
    r_m, r_n = (float(r) for r in radii_of_curvature(lat))
    w_n = OMEGA_IE * math.cos(lat) + va[0] / r_n
    k = params.pendulous_moment * _g(lat) / params.angular_momentum + w_n
    omega = math.sqrt(k * w_n)
    return {"throw": throw, "tilt_offset": tilt, "amplitude": math.hypot(throw, k * tilt / omega)}


def _coriolis_horizontal(lat: float, v: np.ndarray) -> tuple[float, float]:
    """Horizontal part of ``(2ω_ie + ω_en) × v`` for a horizontal velocity: ``c (−v_N, v_E)``,
    ``c = 2Ω sin L + v_E tan L / R_N``."""
    _, r_n = radii_of_curvature(lat)
    c = 2.0 * OMEGA_IE * math.sin(lat) + v[0] * math.tan(lat) / float(r_n)
    return (-c * v[1], c * v[0])


@dataclass(frozen=True)
class GyrocompassOutput(ChunkedOutput):
    """Per sample: ``t`` (s), ``heading_true``/``heading_indicated`` (rad clockwise from north,
    [0, 2π)), ``spin_axis_azimuth`` α (rad east of north), ``spin_axis_elevation`` β (rad),
    ``gimbal_azimuth`` (the element's azimuth from the bow, clockwise, = −(indicated heading)),
    ``latitude`` (rad)."""

    t: np.ndarray
    heading_true: np.ndarray
    heading_indicated: np.ndarray
    spin_axis_azimuth: np.ndarray
    spin_axis_elevation: np.ndarray
    gimbal_azimuth: np.ndarray
    latitude: np.ndarray



class Gyrocompass:
    """A gyrocompass on a carrier: :meth:`simulate` (whole run) or :meth:`iter_chunks` (bounded
    memory).  Integrated by DOP853 (:func:`.common.integrate_chunked`): the state is smooth and
    slow (periods of ~1 h) and a high-order adaptive method takes long steps between the
    carrier's manoeuvres; ``max_step`` must be shorter than the shortest manoeuvre."""

    def __init__(self, params: GyrocompassParams):
        if not isinstance(params, GyrocompassParams):
            raise ValueError(f"params must be GyrocompassParams, got {type(params).__name__}")
        self.params = params

    def rhs(self, carrier: Motion, height: float):
        """Right-hand side ``ẏ(t, y)`` of the solver state ``(s_E, s_N, s_U, L)``."""
        H = self.params.angular_momentum
        ml = self.params.pendulous_moment
        d_over_h = self.params.damping / H
        corr = self.params.latitude_correction and self.params.damping > 0.0

        def rhs(t, y):
            s = y[:3] / math.sqrt(y[0] * y[0] + y[1] * y[1] + y[2] * y[2])
            lat = y[3]
            f, w, _, lat_rate = carrier_point(carrier, t, lat, height)
            # element 'up' axis: e_U minus its component along s, normalized (s never vertical here)
            u = np.array([-s[2] * s[0], -s[2] * s[1], 1.0 - s[2] * s[2]])
            u /= math.sqrt(u @ u)
            torque = ml * np.cross(u, f)
            if d_over_h:
                beta = math.asin(max(-1.0, min(1.0, s[2])))
                beta_ref = _static_tilt(ml * _g(lat, height) / H, lat) if corr else 0.0
                torque[2] -= self.params.damping * (beta - beta_ref)
            torque -= (torque @ s) * s
            ds = torque / H - np.cross(w, s)
            return np.array([ds[0], ds[1], ds[2], lat_rate])

        return rhs

    #: Joints published for a scene (rad): the indication, the spin axis and the azimuth gimbal.
    JOINTS = ("heading_indicated", "spin_axis_azimuth", "spin_axis_elevation", "gimbal_azimuth")

    def initial_state(self, carrier: Motion, latitude: float, height: float = 0.0,
                      azimuth0: float = 0.0, elevation0: float | None = None) -> np.ndarray:
        """Solver state ``(s_E, s_N, s_U, L)`` from the initial spin axis (rad; elevation
        default: the static equilibrium tilt at ``latitude``)."""
        if not isinstance(carrier, Motion):
            raise ValueError(f"carrier must be a core.motion.Motion, got {type(carrier).__name__}")
        lat0 = _lat(latitude)
        height = finite(height, "height")
        a0 = finite(azimuth0, "azimuth0")
        p_over_h = self.params.pendulous_moment * _g(lat0, height) / self.params.angular_momentum
        b0 = _static_tilt(p_over_h, lat0) if elevation0 is None else finite(elevation0, "elevation0")
        if abs(b0) > math.radians(80.0):
            raise ValueError(f"elevation0 must be within ±80°, got {math.degrees(b0):.6g}°")
        return np.array([math.cos(b0) * math.sin(a0), math.cos(b0) * math.cos(a0), math.sin(b0), lat0])

    def outputs(self, tc: np.ndarray, yc: np.ndarray, carrier: Motion,
                height: float = 0.0) -> GyrocompassOutput:
        """The indication and gimbal angles of solver states ``yc`` at times ``tc``."""
        s = yc[:, :3] / np.linalg.norm(yc[:, :3], axis=1, keepdims=True)
        lat = yc[:, 3]
        if np.any(np.abs(lat) >= math.radians(89.0)):
            raise ValueError("the carrier reached ±89° latitude: the gyrocompass model ends there")
        alpha = np.arctan2(s[:, 0], s[:, 1])
        beta = np.arcsin(np.clip(s[:, 2], -1.0, 1.0))
        heading = carrier_truth(carrier, tc, lat, height).heading
        gimbal = wrap_pi(alpha - heading)
        return GyrocompassOutput(tc, heading, wrap_2pi(-gimbal), alpha, beta, gimbal, lat)

    @staticmethod
    def joint_positions(out: GyrocompassOutput) -> np.ndarray:
        """``(n, 4)`` angles in the order of :attr:`JOINTS`."""
        return np.stack((out.heading_indicated, out.spin_axis_azimuth, out.spin_axis_elevation,
                         out.gimbal_azimuth), axis=1)

    def iter_chunks(self, t_grid, carrier: Motion, latitude: float, height: float = 0.0,
                    azimuth0: float = 0.0, elevation0: float | None = None, chunk: int = 4096,
                    rtol: float = 1e-10, atol: float = 1e-12,
                    max_step: float = 10.0) -> Iterator[GyrocompassOutput]:
        """Yield :class:`GyrocompassOutput` pieces of at most ``chunk`` samples.

        ``azimuth0``/``elevation0``: the initial spin axis (rad; elevation default: the static
        equilibrium tilt at ``latitude``).  ``t_grid[0]`` is the initial time.
        """
        t = check_times(t_grid)
        height = finite(height, "height")
        y0 = self.initial_state(carrier, latitude, height, azimuth0, elevation0)
        positive(rtol, "rtol")
        positive(atol, "atol")
        for tc, yc in integrate_chunked(self.rhs(carrier, height), y0, t, chunk, rtol, atol, max_step):
            yield self.outputs(tc, yc, carrier, height)

    def simulate(self, t_grid, carrier: Motion, latitude: float, **kwargs) -> GyrocompassOutput:
        """The whole run at once (see :meth:`iter_chunks` for the arguments)."""
        return GyrocompassOutput.concatenate(list(self.iter_chunks(t_grid, carrier, latitude, **kwargs)))
