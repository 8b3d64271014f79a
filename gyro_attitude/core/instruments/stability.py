"""Gyroscopic stability (book §4-5): the sleeping top C²n² > 4A·mgl, the spinning shell's stability
factor s = C²n² / (4A·M_α), and the shell's motion under its overturning moment (stays up for
s > 1, tumbles for s < 1).

The shell.  A spin-stabilized shell of axial inertia C and transverse inertia A (about its centre
of mass), spin n, flies with its axis at the angle of attack θ to the velocity; the centre of
pressure lies ahead of the centre of mass, so the aerodynamic moment ``M_α sin θ`` turns the axis
away from the velocity.  With the velocity direction ``Γ`` (unit, body axes) in place of the
upward vertical and ``M_α`` in place of ``m g l``, these are exactly the equations of the upright
heavy symmetric top (:mod:`gyro_attitude.core.rigid_body`: ``Ḣ = H × ω + m g l (Γ × e_z)``,
whose gravity moment also overturns — the centre of mass is above the pivot), so
:func:`gyro_attitude.core.rigid_body.integrate_heavy_top` is reused unchanged: implicit midpoint,
energy and both momenta conserved to round-off.  (The velocity direction is held fixed in space:
the trajectory's curvature and the damping moments are left out.)

Linear theory (small θ, ``ξ = θ e^{iψ}``): ``A ξ̈ − i C n ξ̇ − M_α ξ = 0``, roots
``λ = i (C n ± √(C²n² − 4 A M_α)) / (2A)``: oscillatory (bounded) iff ``s > 1``.  From rest
(``ξ̇(0) = 0``) the nutation swings θ between θ₀ and ``θ₀ / √(1 − 1/s)``
(:func:`shell_nutation_ratio`); for ``s < 1`` a root has a positive real part and θ grows as
``e^{σ t}``, ``σ = √(4 A M_α − C²n²) / (2A)``, until the shell tumbles.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gyro_attitude.core.instruments.common import finite, nonnegative, positive
from gyro_attitude.core.rigid_body import (
    HeavyTop,
    heavy_top_invariants,
    heavy_top_state_from_euler,
    integrate_heavy_top,
)

__all__ = [
    "sleeping_top_is_stable",
    "sleeping_top_min_spin",
    "gyroscopic_stability_factor",
    "shell_nutation_ratio",
    "shell_divergence_rate",
    "ShellParams",
    "ShellMotion",
    "simulate_shell",
    "SpinningShell",
]


def sleeping_top_is_stable(spin_inertia: float, spin_rate: float, transverse_inertia: float,
                           mgl: float) -> bool:
    """The upright (sleeping) top is stable iff ``C² n² > 4 A m g l`` (A about the pivot)."""
    c = positive(spin_inertia, "spin_inertia")
    n = finite(spin_rate, "spin_rate")
    a = positive(transverse_inertia, "transverse_inertia")
    return c * c * n * n > 4.0 * a * nonnegative(mgl, "mgl")


def sleeping_top_min_spin(spin_inertia: float, transverse_inertia: float, mgl: float) -> float:
    """Critical spin ``n* = 2 √(A m g l) / C`` (rad/s) of the sleeping top."""
    return (2.0 * math.sqrt(positive(transverse_inertia, "transverse_inertia") * nonnegative(mgl, "mgl"))
            / positive(spin_inertia, "spin_inertia"))


def gyroscopic_stability_factor(spin_inertia: float, spin_rate: float, transverse_inertia: float,
                                overturning_moment: float) -> float:
    """``s = C² n² / (4 A M_α)`` (moment ``M_α sin θ``, M_α in N·m); s > 1: stable."""
    c = positive(spin_inertia, "spin_inertia")
    n = finite(spin_rate, "spin_rate")
    return c * c * n * n / (4.0 * positive(transverse_inertia, "transverse_inertia")
                            * positive(overturning_moment, "overturning_moment"))


def shell_nutation_ratio(stability_factor: float) -> float:
    """``θ_max / θ₀ = 1 / √(1 − 1/s)`` of the linear theory from rest (s > 1)."""
    s = positive(stability_factor, "stability_factor")
    if s <= 1.0:
        raise ValueError(f"stability_factor must be > 1 for a bounded nutation, got {s!r}")
    return 1.0 / math.sqrt(1.0 - 1.0 / s)


def shell_divergence_rate(spin_inertia: float, spin_rate: float, transverse_inertia: float,
                          overturning_moment: float) -> float:
    """Growth rate ``σ = √(4 A M_α − C² n²) / (2A)`` (1/s) of θ for s < 1 (0 when s ≥ 1)."""
    c = positive(spin_inertia, "spin_inertia")
    n = finite(spin_rate, "spin_rate")
    a = positive(transverse_inertia, "transverse_inertia")
    d = 4.0 * a * positive(overturning_moment, "overturning_moment") - c * c * n * n
    return math.sqrt(d) / (2.0 * a) if d > 0.0 else 0.0


@dataclass(frozen=True)
class ShellParams:
    """``spin_inertia`` C, ``transverse_inertia`` A (kg·m², about the centre of mass),
    ``overturning_moment`` M_α (N·m at θ = 90°), ``spin_rate`` n (rad/s)."""

    spin_inertia: float
    transverse_inertia: float
    overturning_moment: float
    spin_rate: float

    def __post_init__(self):
        positive(self.spin_inertia, "spin_inertia")
        positive(self.transverse_inertia, "transverse_inertia")
        positive(self.overturning_moment, "overturning_moment")
        positive(self.spin_rate, "spin_rate")

    @property
    def stability_factor(self) -> float:
        return gyroscopic_stability_factor(self.spin_inertia, self.spin_rate, self.transverse_inertia,
                                           self.overturning_moment)

    @classmethod
    def with_stability_factor(cls, s: float, spin_inertia: float, transverse_inertia: float,
                              spin_rate: float) -> ShellParams:
        """The M_α that gives stability factor ``s``."""
        c, a, n = spin_inertia, transverse_inertia, spin_rate
        return cls(c, a, c * c * n * n / (4.0 * a * positive(s, "s")), n)


@dataclass(frozen=True)
class ShellMotion:
    """``t`` (s), angle of attack ``theta`` (rad), and the heavy-top invariants along the run
    (``energy``, ``p_psi``, ``p_phi``: conserved to round-off by the integrator)."""

    t: np.ndarray
    theta: np.ndarray
    energy: np.ndarray
    p_psi: np.ndarray
    p_phi: np.ndarray


def simulate_shell(params: ShellParams, theta0: float, duration: float, dt: float = 1e-3,
                   record_every: int = 10) -> ShellMotion:
    """Shell released at angle of attack ``theta0`` (rad) with no transverse rate.

    ``dt`` must resolve the spin for the midpoint iteration (``dt · n < 2``) and the nutation
    (tens of steps per nutation period, ``2π·2A/(C n)``) for accuracy.
    """
    if not isinstance(params, ShellParams):
        raise ValueError(f"params must be ShellParams, got {type(params).__name__}")
    th0 = finite(theta0, "theta0")
    if not 0.0 <= th0 < math.pi:
        raise ValueError(f"theta0 must lie in [0, π), got {theta0!r}")
    dt = positive(dt, "dt")
    duration = positive(duration, "duration")
    if dt * params.spin_rate >= 1.0:
        raise ValueError(f"dt must be < 1/spin_rate = {1.0 / params.spin_rate:.3g} s, got {dt!r}")
    n_steps = int(math.ceil(duration / dt))
    if n_steps > 50_000_000:
        raise ValueError(f"duration/dt = {n_steps} steps is too many; raise dt or shorten duration")
    top = HeavyTop(params.transverse_inertia, params.spin_inertia, params.overturning_moment)
    h0, g0 = heavy_top_state_from_euler(top, th0, 0.0, 0.0, params.spin_rate)
    h, g = integrate_heavy_top(top, h0, g0, dt, n_steps, record_every=int(record_every))
    inv = heavy_top_invariants(top, h, g)
    t = np.arange(h.shape[0]) * dt * int(record_every)
    theta = np.arccos(np.clip(g[:, 2] / inv["gamma_norm"], -1.0, 1.0))
    return ShellMotion(t, theta, inv["energy"], inv["p_psi"], inv["p_phi"])


class SpinningShell:
    """The shell as a scene instrument (:class:`.common.InstrumentStepper` interface).

    Solver state ``(H_b, Γ_b)`` (6,), body axes, with the heavy-top equations of the module
    docstring, ``Ḣ = H × ω + M_α (Γ × e_z)``, ``Γ̇ = Γ × ω``, integrated by DOP853 (the scene's
    generic instrument path); :func:`simulate_shell` is the conserving implicit-midpoint run of
    the same equations.  The carrier and the Earth do not enter: the flight lasts seconds and
    the velocity direction is held fixed in space.  Joint: ``angle_of_attack`` θ (rad)."""

    JOINTS = ("angle_of_attack",)

    def __init__(self, params: ShellParams):
        if not isinstance(params, ShellParams):
            raise ValueError(f"params must be ShellParams, got {type(params).__name__}")
        self.params = params
        self._top = HeavyTop(params.transverse_inertia, params.spin_inertia, params.overturning_moment)

    def initial_state(self, carrier, latitude, height=0.0, theta0: float = math.radians(2.0)):
        th0 = finite(theta0, "theta0")
        if not 0.0 <= th0 < math.pi:
            raise ValueError(f"theta0 must lie in [0, π), got {theta0!r}")
        h0, g0 = heavy_top_state_from_euler(self._top, th0, 0.0, 0.0, self.params.spin_rate)
        return np.concatenate((h0, g0))

    def rhs(self, carrier, height):
        a, c, m = self.params.transverse_inertia, self.params.spin_inertia, self.params.overturning_moment

        def rhs(t, y):
            hx, hy, hz, gx, gy, gz = y
            wx, wy, wz = hx / a, hy / a, hz / c
            return np.array([hy * wz - hz * wy + m * gy, hz * wx - hx * wz - m * gx,
                             hx * wy - hy * wx,
                             gy * wz - gz * wy, gz * wx - gx * wz, gx * wy - gy * wx])

        return rhs

    def outputs(self, t, y, carrier, height=0.0) -> np.ndarray:
        g = np.asarray(y)[:, 3:]
        return np.arccos(np.clip(g[:, 2] / np.linalg.norm(g, axis=1), -1.0, 1.0))

    @staticmethod
    def joint_positions(theta) -> np.ndarray:
        return np.asarray(theta)[:, None]
