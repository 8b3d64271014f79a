"""Two-gimbal free gyro (three degrees of freedom): precession and full equations, torques, friction.

Section numbers (§) refer to the gyroscope-mechanics textbook (§2-1, §2-2, §3-7, §5-1…§5-3;
``docs/equations.md``).  SI units: rad, rad/s, N·m, kg·m², seconds as floats.

Frames (all right-handed): case ``c`` (fixed to the carrier), outer gimbal ``o``, inner
gimbal ``g``.  The outer gimbal turns by α (``outer_gimbal``) about ``z_c = z_o``; the
inner gimbal turns by β (``inner_gimbal``) about ``y_o = y_g``; the rotor spins about
``x_g``::

    C_co = Rz(α),  C_og = Ry(β)   (active: v_c = C_co v_o),
    spin axis in the case frame  s_c = [cos α cos β, sin α cos β, −sin β].

With α = β = 0 the spin axis lies along the case x axis and the outer axis along case z
(a directional gyro: α measures azimuth, β tilt).  |β| < 90° reaches every spin
direction; β = ±90° is gimbal lock: the spin axis lies along the outer axis.  The precession
model divides by cos β there and has no solution, so it raises ``ValueError`` saying so.  The
full model stays regular through the lock as long as the outer axis keeps an inertia
(``M_11 = I_oz + I_gx sin²β + (J_t + I_gz) cos²β > 0``, i.e. I_oz or I_gx nonzero): the
inner gimbal goes over the top (|β| passes 90°, the flip — the spin axis crosses the outer
axis and its azimuth turns by 180°), and :meth:`FreeGyroSimulator.kinetic_energy` and the
outer-axis component of :meth:`FreeGyroSimulator.angular_momentum` keep the bookkeeping of
the free motion.
The rotor is symmetric and no torque acts about its spin axis, so its axial angular
momentum ``H = J_s (ω_gx + φ̇)`` is constant (``H = spin_inertia · spin_rate``).

Inertial angular velocities (ω_c from ``omega_base_fn``, in case axes)::

    ω_o = C_oc ω_c + α̇ e_z,      ω_g = C_go ω_o + β̇ e_y.

Full equations (``model="full"``; Newton-Euler for the inner assembly = rotor + inner
gimbal, and for the outer gimbal; rotor transverse inertia J_t, inner gimbal principal
inertias (I_gx, I_gy, I_gz), outer gimbal (I_ox, I_oy, I_oz))::

    h_g = [H + I_gx ω_gx, A_y ω_gy, A_z ω_gz],  A_y = J_t + I_gy,  A_z = J_t + I_gz
    inner axis:  e_yᵀ (A ω̇_g + ω_g × h_g) = M_β
    outer axis:  I_oz ω̇_oz + (ω_o × I_o ω_o)_z + e_zᵀ C_og (A ω̇_g + ω_g × h_g) = M_α

with A = diag(I_gx, A_y, A_z).  Expanding ω̇_o and ω̇_g (they contain the base angular
acceleration ω̇_c) gives a diagonal mass matrix::

    (I_oz + I_gx sin²β + A_z cos²β) α̈ = M_α − (known terms),   A_y β̈ = M_β − (known terms).

Linearized about a fast rotor these show nutation at ω_nut = H / (A_y M_11)^½ — for a
24 000 rpm rotor on light gimbals thousands of rad/s, far above any output rate.

Precession (technical) equations (``model="precession"``, §3-7): drop the gimbal and
transverse inertia, keep the gyroscopic torques ``ω_g × H e_x``::

    H (ω_gz) = M_β,   −H cos β (ω_gy) = M_α
    ⇒  α̇ = (M_β/H − w_z) / cos β,    β̇ = −M_α / (H cos β) − w_y,    w = C_gc ω_c.

With no torque the spin axis keeps its inertial direction and the gimbal angles show
the apparent drift of the base (Earth rate ω_ie sin L about the vertical, plus the
transport rate v_E tan L/(R_N+h) when moving east; §2-3, §2-4).

Torques on the gimbal axes (outer, inner): constant, harmonic ``A sin(2πf t + φ)``
(§4-6), rectangular impact pulses of given angular impulse (§5-2: a fast gyro answers an
impulse S with a jump S/H of the *other* gimbal, plus a small nutation), viscous friction
``−c_v q̇`` and Coulomb friction ``−M_c tanh(q̇/ε)`` on the relative gimbal rate q̇.
Coulomb friction is smoothed rather than handled by stick/slip events because in a free
gyro the gimbal rates are driven by the base and the gyroscopic coupling, not by the
friction: in the precession model the rate equations with friction reduce to one scalar
equation g(β̇) = 0 with g′ ≥ 1 (friction is dissipative), so the smoothed problem has a
unique solution for every ε and tends to the Filippov (set-valued friction) solution as
ε → 0; ε = ``coulomb_smoothing_rate`` (default 1e-9 rad/s) is far below any rate of
interest.  Result of §5-2 reproduced: outer-axis friction M_c makes the inner gimbal drift
at M_c/(H cos β).

g-sensitive drift (§5-3, ``mass_unbalance`` m·l, kg·m, + toward the +spin end): the rotor's
centre of mass sits ``l`` along the spin axis s, and the specific force f (case axes, from
``specific_force_fn``) acts on it as ``−m f``: the torque ``M = m l (f × s)``, i.e. on the
gimbal axes ::

    M_α = m l cos β (f_x sin α − f_y cos α),   M_β = m l (sin β (f_x cos α + f_y sin α) + f_z cos β)

so the spin axis precesses at ``ω_d = (m l / H) (f − (f·s) s)`` (a level rotor at rest turns
about the vertical at ``m l g / H``).  f is taken at the midpoint of each integration step.

Gimbal stops (full model only): ``inner_gimbal_stops`` / ``outer_gimbal_stops`` = (low, high)
angles (rad) of hard stops on the relative gimbal angle.  A gimbal reaching a stop impacts it:
Newton's restitution on the joint rate, ``q̇⁺ = −e q̇⁻`` (``stop_restitution`` e ∈ [0, 1]).  The
mass matrix is diagonal in (α̈, β̈), so the stop's impulse changes that joint's rate alone; the
kinetic energy drops by ``½ M_qq (q̇⁻² − q̇⁺²)`` on a base at rest (``M_11`` or ``A_y``), and
an inner-stop impulse is internal to the outer gimbal, so it leaves the angular momentum about
the outer axis unchanged.  The impact time is located inside the step (regula falsi on the
step length, to 1e-12 s) and the step is finished from there.  A rebound slower than
``stop_rest_rate`` (and every impact with e = 0) leaves the gimbal resting on the stop: its rate
and acceleration are held at zero while the free acceleration pushes into the stop, and it
lifts off when that acceleration turns away (decided at the start of each step).
``stop_impacts`` lists ``(t, axis, rate before, rate after)`` of every impact.

Numerics.  Precession model: classical RK4 on (α, β) with fixed sub-steps
(≤ ``max_step``, ≤ 1/16 of a harmonic-torque period), pulse edges and output times on
the step grid; the rates solve the algebraic friction equation by safeguarded Newton.
Full model: the nutation mode is a weakly damped oscillation far faster than the
motion of interest.  ``integrator="midpoint"`` (default) uses the implicit midpoint
rule, solved by Newton with a finite-difference Jacobian: it is A-stable and its
amplification factor has modulus exactly 1 on the imaginary axis, so a nutation that
is not resolved by the step is neither amplified (explicit methods blow up) nor
artificially damped (BDF/Radau would damp it); the slow precession is second-order
accurate in the step.  Coulomb friction (stiff and dissipative for small ε, where the
midpoint rule would make the rates chatter instead of stick) enters that step
backward-Euler (L-stable), with a backtracked Newton iteration; when the nutation decay by
friction matters, resolve the nutation (``max_step`` well below 2π/ω_nut).
``integrator="rk4"`` resolves the nutation explicitly (step ≤
nutation period / ``steps_per_nutation``) — exact nutation, cost ∝ H.  The benchmark
``gyro_attitude.benchmarks.gyro_fidelity`` measures both against the precession model.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from enum import StrEnum

import numpy as np

from gyro_attitude.core.validators import check_finite, check_nonnegative, check_positive, pair, triple

__all__ = [
    "HarmonicTorque",
    "ImpactTorque",
    "FreeGyroParams",
    "FreeGyroSimulator",
    "free_gyro_angles_from_spin_axis",
    "spin_axis_from_free_gyro_angles",
]


class FreeGyroModel(StrEnum):
    """Equations of the free gyro (module docstring): ``precession`` (state α, β; the
    rates solve the algebraic precession equations) or ``full`` (state α, β, α̇, β̇;
    Newton-Euler with gimbal inertia and nutation)."""

    PRECESSION = "precession"
    FULL = "full"


class FreeGyroIntegrator(StrEnum):
    """Stepper of the full model: ``midpoint`` (implicit, one stage at the step's middle)
    or ``rk4`` (explicit, stages at start, middle and end). The precession model always
    steps RK4."""

    MIDPOINT = "midpoint"
    RK4 = "rk4"


def _parse_enum(cls, value, name):
    try:
        return cls(value)
    except ValueError:
        allowed = " or ".join(repr(m.value) for m in cls)
        raise ValueError(f"{name} must be {allowed}, got {value!r}") from None



@dataclass(frozen=True)
class HarmonicTorque:
    """Torque ``amplitude · sin(2π frequency_hz · t + phase_rad)`` on (outer, inner) axes."""

    amplitude: tuple[float, float]
    frequency_hz: float
    phase_rad: float = 0.0

    def __post_init__(self):
        object.__setattr__(self, "amplitude", pair(self.amplitude, "harmonic amplitude"))
        check_positive(self.frequency_hz, "harmonic frequency_hz")
        check_finite(self.phase_rad, "harmonic phase_rad")


@dataclass(frozen=True)
class ImpactTorque:
    """Rectangular torque pulse carrying the angular impulse ``impulse`` (N·m·s) on
    (outer, inner) axes, applied on ``[t_start, t_start + duration)``."""

    t_start: float
    duration: float
    impulse: tuple[float, float]

    def __post_init__(self):
        check_finite(self.t_start, "impact t_start")
        check_positive(self.duration, "impact duration")
        object.__setattr__(self, "impulse", pair(self.impulse, "impact impulse"))


@dataclass(frozen=True)
class FreeGyroParams:
    """Two-gimbal free gyro (see the module docstring for frames and equations).

    Inertias in kg·m², rates in rad/s, torques in N·m; pairs are (outer, inner) axis.
    ``initial_rates`` (full model only): relative gimbal rates at t0; None starts on the
    precession solution (no nutation excited by the start itself).
    """

    spin_inertia: float
    transverse_inertia: float
    spin_rate: float
    model: str = "precession"
    inner_gimbal_inertia: tuple[float, float, float] = (0.0, 0.0, 0.0)
    outer_gimbal_inertia: tuple[float, float, float] = (0.0, 0.0, 0.0)
    initial_angles: tuple[float, float] = (0.0, 0.0)
    initial_rates: tuple[float, float] | None = None
    constant_torque: tuple[float, float] = (0.0, 0.0)
    harmonic_torques: tuple[HarmonicTorque, ...] = ()
    impacts: tuple[ImpactTorque, ...] = ()
    viscous_friction: tuple[float, float] = (0.0, 0.0)
    coulomb_friction: tuple[float, float] = (0.0, 0.0)
    coulomb_smoothing_rate: float = 1e-9
    integrator: str = "midpoint"
    max_step: float = 0.01
    steps_per_nutation: float = 20.0
    base_rate_derivative_step: float = 1e-5
    mass_unbalance: float = 0.0
    outer_gimbal_stops: tuple[float, float] | None = None
    inner_gimbal_stops: tuple[float, float] | None = None
    stop_restitution: float = 0.5
    stop_rest_rate: float = 1e-6

    def __post_init__(self):
        check_positive(self.spin_inertia, "spin_inertia")
        check_positive(self.transverse_inertia, "transverse_inertia")
        s = check_finite(self.spin_rate, "spin_rate")
        if s == 0.0:
            raise ValueError("spin_rate must be non-zero (a free gyro needs angular momentum)")
        # parsed once here: the simulator chooses its equations and stepper from the enums
        object.__setattr__(self, "model", _parse_enum(FreeGyroModel, self.model, "model"))
        object.__setattr__(self, "integrator",
                           _parse_enum(FreeGyroIntegrator, self.integrator, "integrator"))
        object.__setattr__(self, "inner_gimbal_inertia",
                           triple(self.inner_gimbal_inertia, "inner_gimbal_inertia"))
        object.__setattr__(self, "outer_gimbal_inertia",
                           triple(self.outer_gimbal_inertia, "outer_gimbal_inertia"))
        object.__setattr__(self, "initial_angles", pair(self.initial_angles, "initial_angles"))
        if self.initial_rates is not None:
            object.__setattr__(self, "initial_rates", pair(self.initial_rates, "initial_rates"))
        object.__setattr__(self, "constant_torque", pair(self.constant_torque, "constant_torque"))
        object.__setattr__(self, "viscous_friction",
                           pair(self.viscous_friction, "viscous_friction", check_nonnegative))
        object.__setattr__(self, "coulomb_friction",
                           pair(self.coulomb_friction, "coulomb_friction", check_nonnegative))
        check_positive(self.coulomb_smoothing_rate, "coulomb_smoothing_rate")
        check_positive(self.max_step, "max_step")
        check_positive(self.steps_per_nutation, "steps_per_nutation")
        check_positive(self.base_rate_derivative_step, "base_rate_derivative_step")
        check_finite(self.mass_unbalance, "mass_unbalance")
        e = check_finite(self.stop_restitution, "stop_restitution")
        if not 0.0 <= e <= 1.0:
            raise ValueError(f"stop_restitution must lie in [0, 1], got {e!r}")
        check_positive(self.stop_rest_rate, "stop_rest_rate")
        for axis, name in enumerate(("outer_gimbal_stops", "inner_gimbal_stops")):
            stops = getattr(self, name)
            if stops is None:
                continue
            lo, hi = pair(stops, name)
            if not lo < hi:
                raise ValueError(f"{name} must be (low, high) with low < high, got {stops!r}")
            if self.model is not FreeGyroModel.FULL:
                raise ValueError(f"{name} need model='full' (an impact needs gimbal inertia)")
            if not lo < self.initial_angles[axis] < hi:
                raise ValueError(f"{name}: the initial angle {self.initial_angles[axis]!r} must "
                                 "lie strictly between the stops")
            object.__setattr__(self, name, (lo, hi))
        harm = tuple(self.harmonic_torques)
        if not all(isinstance(h, HarmonicTorque) for h in harm):
            raise ValueError("harmonic_torques must be HarmonicTorque instances")
        object.__setattr__(self, "harmonic_torques", harm)
        imp = tuple(self.impacts)
        if not all(isinstance(i, ImpactTorque) for i in imp):
            raise ValueError("impacts must be ImpactTorque instances")
        object.__setattr__(self, "impacts", imp)
        if (abs(math.cos(self.initial_angles[1])) < 1e-6
                and (self.model is FreeGyroModel.PRECESSION or self.initial_rates is None)):
            raise ValueError("initial inner gimbal angle is at ±90° (gimbal lock): the "
                             "precession rates divide by cos β; start the full model there "
                             "with initial_rates")

    @property
    def spin_momentum(self) -> float:
        """H = J_s · spin_rate (N·m·s)."""
        return self.spin_inertia * self.spin_rate

    def nutation_frequency_rad_s(self, beta: float = 0.0) -> float:
        """Linearized nutation frequency H / (A_y M_11(β))^½ of the full model."""
        jt = self.transverse_inertia
        igx, igy, igz = self.inner_gimbal_inertia
        sb, cb = math.sin(beta), math.cos(beta)
        m11 = self.outer_gimbal_inertia[2] + igx * sb * sb + (jt + igz) * cb * cb
        return abs(self.spin_momentum) / math.sqrt((jt + igy) * m11)


def spin_axis_from_free_gyro_angles(angles) -> np.ndarray:
    """Spin axis in case axes ``[cos α cos β, sin α cos β, −sin β]`` for angles (..., 2)."""
    a = np.asarray(angles, dtype=np.float64)
    al, be = a[..., 0], a[..., 1]
    return np.stack((np.cos(al) * np.cos(be), np.sin(al) * np.cos(be), -np.sin(be)), axis=-1)


def free_gyro_angles_from_spin_axis(s_c) -> np.ndarray:
    """Gimbal angles (α, β) of a spin-axis direction in case axes (inverse of the above)."""
    s = np.asarray(s_c, dtype=np.float64)
    al = np.arctan2(s[..., 1], s[..., 0])
    be = np.arctan2(-s[..., 2], np.hypot(s[..., 0], s[..., 1]))
    return np.stack((al, be), axis=-1)


def _rot_to_gimbal(al, be, wx, wy, wz):
    """w = C_gc ω = Ry(β)ᵀ Rz(α)ᵀ ω, plus the intermediate C_oc ω (Python floats)."""
    ca, sa, cb, sb = math.cos(al), math.sin(al), math.cos(be), math.sin(be)
    v0 = ca * wx + sa * wy
    v1 = -sa * wx + ca * wy
    v2 = wz
    return (v0, v1, v2), (cb * v0 - sb * v2, v1, sb * v0 + cb * v2), (ca, sa, cb, sb)


class FreeGyroSimulator:
    """Two-gimbal free gyro on a moving base; resumable (see module docstring).

    ``omega_base_fn(t)`` maps times ``(m,)`` in s to the inertial angular velocity of the
    case in case axes ``(m, 3)`` in rad/s.  The full model also needs the base angular
    acceleration: pass ``omega_base_dot_fn`` (same signature) or it is taken by central
    differences of ``omega_base_fn`` with step ``params.base_rate_derivative_step``.

    ``run_until(t_out)`` integrates on one step grid containing every requested time and
    impact-pulse edge (sub-steps ≤ ``step_size()``) and returns angles and relative gimbal
    rates (rad, rad/s; columns ``names``).  ``state()`` gives the current pair,
    ``kinetic_energy()`` (full model) the energy of rotor and gimbals, ``t`` the current
    time, ``steps`` / ``rhs_evaluations`` the work done so far (for benchmarks).
    Numerical failure (non-finite state, gimbal lock, Newton not converging) raises
    ``ValueError`` naming the time.
    """

    names: tuple[str, ...] = ("outer_gimbal", "inner_gimbal")

    def __init__(self, params: FreeGyroParams,
                 omega_base_fn: Callable[[np.ndarray], np.ndarray], t0: float = 0.0,
                 omega_base_dot_fn: Callable[[np.ndarray], np.ndarray] | None = None,
                 specific_force_fn: Callable[[np.ndarray], np.ndarray] | None = None):
        if not isinstance(params, FreeGyroParams):
            raise ValueError("params must be a FreeGyroParams")
        if not callable(omega_base_fn):
            raise ValueError("omega_base_fn must be callable: t (m,) -> (m, 3) rad/s")
        self.params = params
        self._omega_fn = omega_base_fn
        self._omega_dot_fn = omega_base_dot_fn
        if params.mass_unbalance != 0.0 and not callable(specific_force_fn):
            raise ValueError("mass_unbalance needs specific_force_fn: t (m,) -> (m, 3) m/s² "
                             "in case axes")
        self._force_fn = specific_force_fn if params.mass_unbalance != 0.0 else None
        self._force_step: tuple[float, float, float] | None = None  # f held over a step
        self._stops = (params.outer_gimbal_stops, params.inner_gimbal_stops)
        self._held = [False, False]  # joint resting on a stop
        self.stop_impacts: list[tuple[float, int, float, float]] = []
        self.t = check_finite(t0, "t0")
        p = params
        self._h = p.spin_momentum
        self._jt = p.transverse_inertia
        self._ig = p.inner_gimbal_inertia
        self._io = p.outer_gimbal_inertia
        self._ay = self._jt + self._ig[1]
        self._az = self._jt + self._ig[2]
        self._fric = any(v != 0.0 for v in p.viscous_friction + p.coulomb_friction)
        self._breaks = sorted({b for imp in p.impacts for b in (imp.t_start, imp.t_start + imp.duration)})
        self._pulse_clock: float | None = None
        self.steps = 0  # sub-steps taken so far (cost figure for benchmarks)
        self.rhs_evaluations = 0
        # Model and stepper chosen once: the state carries the gimbal rates only in the
        # full model (which alone needs the base angular acceleration); the implicit
        # midpoint takes its base inputs at the step's middle, RK4 at start, middle, end.
        self._full = p.model is FreeGyroModel.FULL
        self._rhs = self._full_rhs if self._full else self._prec_rhs
        midpoint = self._full and p.integrator is FreeGyroIntegrator.MIDPOINT
        self._raw_step = self._step_midpoint if midpoint else self._step_rk4
        self._stages = 1 if midpoint else 3
        self._resolve_nutation = self._full and p.integrator is FreeGyroIntegrator.RK4
        al, be = p.initial_angles
        w0 = self._base_rates(np.array([self.t]))[0]
        if not self._full:
            self._y = np.array([al, be])
        else:
            if p.initial_rates is None:
                ad, bd = self._precession_rates(self.t, al, be, *w0)
            else:
                ad, bd = p.initial_rates
            self._y = np.array([al, be, ad, bd])

    # -- inputs ---------------------------------------------------------------------
    def _base_rates(self, t: np.ndarray) -> np.ndarray:
        w = np.asarray(self._omega_fn(np.asarray(t, dtype=np.float64)), dtype=np.float64)
        if w.shape != (t.shape[0], 3):
            raise ValueError(f"omega_base_fn must return shape ({t.shape[0]}, 3), got {w.shape}")
        if not np.all(np.isfinite(w)):
            raise ValueError("omega_base_fn returned non-finite rates")
        return w

    def _base_accel(self, t: np.ndarray) -> np.ndarray:
        if self._omega_dot_fn is not None:
            wd = np.asarray(self._omega_dot_fn(t), dtype=np.float64)
            if wd.shape != (t.shape[0], 3) or not np.all(np.isfinite(wd)):
                raise ValueError("omega_base_dot_fn must return finite (m, 3) values")
            return wd
        d = self.params.base_rate_derivative_step
        return (self._base_rates(t + d) - self._base_rates(t - d)) / (2 * d)

    def _torques(self, t: float) -> tuple[float, float]:
        """External (non-friction) torques about the outer and inner axes at time t.

        Impact pulses are switched by ``self._pulse_clock`` when a step is under way (the
        midpoint of the current sub-step; pulse edges lie on the step grid), so that a
        stage evaluated exactly on an edge counts for the step it belongs to.
        """
        tp = t if self._pulse_clock is None else self._pulse_clock
        p = self.params
        ma, mb = p.constant_torque
        for h in p.harmonic_torques:
            s = math.sin(2 * math.pi * h.frequency_hz * t + h.phase_rad)
            ma += h.amplitude[0] * s
            mb += h.amplitude[1] * s
        for imp in p.impacts:
            if imp.t_start <= tp < imp.t_start + imp.duration:
                ma += imp.impulse[0] / imp.duration
                mb += imp.impulse[1] / imp.duration
        return ma, mb

    def _specific_force(self, t: float) -> tuple[float, float, float]:
        """f in case axes: the value held over the current step, or evaluated at ``t``."""
        if self._force_step is not None:
            return self._force_step
        f = np.asarray(self._force_fn(np.array([t], dtype=np.float64)), dtype=np.float64)
        if f.shape != (1, 3) or not np.all(np.isfinite(f)):
            raise ValueError("specific_force_fn must return finite (m, 3) values")
        return tuple(f[0].tolist())

    def _unbalance_torque(self, t: float, al: float, be: float) -> tuple[float, float]:
        """(M_α, M_β) of the mass unbalance m l (f × s) (module docstring)."""
        fx, fy, fz = self._specific_force(t)
        ml = self.params.mass_unbalance
        ca, sa, cb, sb = math.cos(al), math.sin(al), math.cos(be), math.sin(be)
        return (ml * cb * (fx * sa - fy * ca),
                ml * (sb * (fx * ca + fy * sa) + fz * cb))

    def _friction(self, axis: int, rate: float) -> tuple[float, float]:
        """Friction torque on one axis and its derivative d/d(rate) (both ≤ 0 slope)."""
        p = self.params
        cv, mc, eps = p.viscous_friction[axis], p.coulomb_friction[axis], p.coulomb_smoothing_rate
        if mc == 0.0:
            return -cv * rate, -cv
        x = rate / eps
        th = math.tanh(x) if abs(x) < 40.0 else math.copysign(1.0, x)
        return -cv * rate - mc * th, -cv - mc * (1.0 - th * th) / eps

    # -- precession model -------------------------------------------------------------
    def _precession_rates(self, t, al, be, wx, wy, wz) -> tuple[float, float]:
        h = self._h
        _, w, (_, _, cb, _) = _rot_to_gimbal(al, be, wx, wy, wz)
        if abs(cb) < 1e-9:
            raise ValueError(f"inner gimbal reached ±90° at t = {t:.6g} s (gimbal lock)")
        ma, mb = self._torques(t)
        if self._force_fn is not None:
            ua, ub = self._unbalance_torque(t, al, be)
            ma, mb = ma + ua, mb + ub
        if not self._fric:
            return (mb / h - w[2]) / cb, -ma / (h * cb) - w[1]
        # g(b) = b + M_α(a(b))/(H c) + w_y with a(b) = (M_β(b)/H − w_z)/c; g' ≥ 1, so the
        # root lies within |g(b0)| of any b0: safeguarded Newton inside that bracket.

        def g_of(b):
            fb, dfb = self._friction(1, b)
            a = ((mb + fb) / h - w[2]) / cb
            fa, dfa = self._friction(0, a)
            val = b + (ma + fa) / (h * cb) + w[1]
            der = 1.0 + dfa * (dfb / (h * cb)) / (h * cb)
            return val, der, a

        b = -ma / (h * cb) - w[1]
        val, der, a = g_of(b)
        lo, hi = b - abs(val), b + abs(val)
        for _ in range(200):
            if val == 0.0 or hi - lo <= 1e-15 * max(1.0, abs(b)):
                break
            if val > 0:
                hi = min(hi, b)
            else:
                lo = max(lo, b)
            b_new = b - val / der
            if not (lo < b_new < hi):
                b_new = 0.5 * (lo + hi)
            if abs(b_new - b) <= 1e-16 * max(1.0, abs(b)):
                b = b_new
                break
            b = b_new
            val, der, a = g_of(b)
        _, _, a = g_of(b)
        return a, b

    # -- full model -------------------------------------------------------------------
    def _full_rhs(self, t, y, wc, wcd, with_coulomb: bool = True) -> tuple[float, float, float, float]:
        al, be, ad, bd = y
        h = self._h
        igx, igy, igz = self._ig
        iox, ioy, ioz = self._io
        ay, az = self._ay, self._az
        v, _, (ca, sa, cb, sb) = _rot_to_gimbal(al, be, *wc)
        # ω_o = C_oc ω_c + α̇ e_z ;  a_o = −α̇ e_z × (C_oc ω_c) + C_oc ω̇_c
        wo0, wo1, wo2 = v[0], v[1], v[2] + ad
        wd0, wd1, wd2 = wcd
        ao0 = ad * v[1] + (ca * wd0 + sa * wd1)
        ao1 = -ad * v[0] + (-sa * wd0 + ca * wd1)
        ao2 = wd2
        # ω_g = C_go ω_o + β̇ e_y ;  a_g = −β̇ e_y × (C_go ω_o) + C_go a_o
        u0 = cb * wo0 - sb * wo2
        u1 = wo1
        u2 = sb * wo0 + cb * wo2
        wg0, wg1, wg2 = u0, u1 + bd, u2
        ag0 = -bd * u2 + (cb * ao0 - sb * ao2)
        ag1 = ao1
        ag2 = bd * u0 + (sb * ao0 + cb * ao2)
        # T_g = A a_g + ω_g × h_g, h_g = [H + I_gx ω_gx, A_y ω_gy, A_z ω_gz]
        hx, hy, hz = h + igx * wg0, ay * wg1, az * wg2
        tg0 = igx * ag0 + (wg1 * hz - wg2 * hy)
        tg1 = ay * ag1 + (wg2 * hx - wg0 * hz)
        tg2 = az * ag2 + (wg0 * hy - wg1 * hx)
        ma, mb = self._torques(t)
        if self._force_fn is not None:
            ua, ub = self._unbalance_torque(t, al, be)
            ma, mb = ma + ua, mb + ub
        if self._fric:
            if with_coulomb:
                ma += self._friction(0, ad)[0]
                mb += self._friction(1, bd)[0]
            else:  # viscous part only (the midpoint solver adds Coulomb's slope itself)
                ma -= self.params.viscous_friction[0] * ad
                mb -= self.params.viscous_friction[1] * bd
        gyro_o = (ioy - iox) * wo0 * wo1  # (ω_o × I_o ω_o)_z
        m11 = ioz + igx * sb * sb + az * cb * cb
        if m11 <= 0.0:
            raise ValueError(f"outer-axis inertia vanished at t = {t:.6g} s (gimbal lock at "
                             "β = ±90° with no outer-gimbal inertia): give outer_gimbal_inertia "
                             "z or inner_gimbal_inertia x > 0 to pass through the lock")
        add = (ma - ioz * ao2 - gyro_o - (-sb * tg0 + cb * tg2)) / m11
        bdd = (mb - tg1) / ay
        self.rhs_evaluations += 1
        if self._held[0]:  # resting on an outer stop: the stop takes the torque
            ad = add = 0.0
        if self._held[1]:
            bd = bdd = 0.0
        return ad, bd, add, bdd

    def _step_midpoint(self, t, hstep, y0, wc, wcd):
        """One implicit-midpoint step, y1 = y0 + h f(t + h/2, (y0 + y1)/2), by Newton.

        The Jacobian of the smooth part is taken by finite differences at y0 and reused
        (chord Newton).  Coulomb friction ``−M_c tanh(q̇/ε)`` is a stiff *dissipative*
        term for small ε, and the midpoint rule's amplification tends to −1 for such
        modes (the rates would chatter instead of sticking).  So Coulomb friction is taken
        at the end of the step (backward Euler, L-stable: a gimbal that should stick does;
        first order in the friction term only), i.e. the step solves
        ``y1 = y0 + h [f_smooth(t_m, (y0 + y1)/2) + f_coulomb(y1)]``.  Its exact slope is
        added to the Jacobian at every iterate, and each Newton step is backtracked until
        the residual drops (plain Newton overshoots on tanh).  The friction term is
        monotone, so the step equation keeps a unique solution however small ε is.
        """
        tm = t + 0.5 * hstep
        self._pulse_clock = tm
        coulomb = any(v != 0.0 for v in self.params.coulomb_friction)
        f0 = np.array(self._full_rhs(tm, y0, wc, wcd, with_coulomb=not coulomb))
        jac = np.empty((4, 4))
        for j in range(4):
            d = 1e-7 * max(1.0, abs(y0[j]))
            yp = y0.copy()
            yp[j] += d
            jac[:, j] = (np.array(self._full_rhs(tm, yp, wc, wcd, with_coulomb=not coulomb))
                         - f0) / d
        mat = np.eye(4) - 0.5 * hstep * jac
        # predictor: the midpoint step of the linearized (smooth) system
        y1 = y0 + hstep * np.linalg.solve(mat, f0)
        scale = 1.0 + np.abs(y0)

        def residual(y):
            if not coulomb:
                return y - y0 - hstep * np.array(self._full_rhs(tm, 0.5 * (y0 + y), wc, wcd))
            ym = 0.5 * (y0 + y)
            f = np.array(self._full_rhs(tm, ym, wc, wcd, with_coulomb=False))
            sb, cb = math.sin(ym[1]), math.cos(ym[1])
            m11 = self._io[2] + self._ig[0] * sb * sb + self._az * cb * cb
            f[2] += self._friction_coulomb(0, y[2]) / m11
            f[3] += self._friction_coulomb(1, y[3]) / self._ay
            return y - y0 - hstep * f

        res = residual(y1)
        for _ in range(60):
            if coulomb:
                ym = 0.5 * (y0 + y1)
                m = mat.copy()
                sb, cb = math.sin(ym[1]), math.cos(ym[1])
                m11 = self._io[2] + self._ig[0] * sb * sb + self._az * cb * cb
                m[2, 2] -= hstep * self._coulomb_slope(0, y1[2]) / m11
                m[3, 3] -= hstep * self._coulomb_slope(1, y1[3]) / self._ay
                dy = np.linalg.solve(m, res)
                # backtracking on the scaled residual norm
                norm0 = np.max(np.abs(res) / scale)
                lam = 1.0
                while True:
                    y_try = y1 - lam * dy
                    res_try = residual(y_try)
                    if np.max(np.abs(res_try) / scale) <= (1 - 1e-4 * lam) * norm0 or lam < 1e-8:
                        break
                    lam *= 0.5
                y1, res = y_try, res_try
                step = lam * dy
            else:
                dy = np.linalg.solve(mat, res)
                y1 = y1 - dy
                res = residual(y1)
                step = dy
            if np.all(np.abs(step) <= 1e-13 * scale) or np.all(np.abs(res) <= 1e-15 * scale):
                break
        else:
            raise ValueError(f"implicit midpoint did not converge at t = {t:.6g} s; "
                             "reduce max_step")
        self._pulse_clock = None
        return y1

    def _friction_coulomb(self, axis: int, rate: float) -> float:
        """Smoothed Coulomb torque −M_c tanh(rate/ε) alone."""
        p = self.params
        mc, eps = p.coulomb_friction[axis], p.coulomb_smoothing_rate
        if mc == 0.0:
            return 0.0
        x = rate / eps
        return -mc * (math.tanh(x) if abs(x) < 40.0 else math.copysign(1.0, x))

    def _coulomb_slope(self, axis: int, rate: float) -> float:
        """d/d(rate) of the smoothed Coulomb torque −M_c tanh(rate/ε) (≤ 0)."""
        p = self.params
        mc, eps = p.coulomb_friction[axis], p.coulomb_smoothing_rate
        if mc == 0.0:
            return 0.0
        x = rate / eps
        if abs(x) > 40.0:
            return 0.0
        th = math.tanh(x)
        return -mc * (1.0 - th * th) / eps

    def _step_rk4(self, t, hstep, y0, w3, wd3):
        """Classical RK4; w3/wd3 hold base rates/accelerations at t, t+h/2, t+h
        (wd3 entries are None for the precession model, which does not use them)."""
        f = self._rhs
        self._pulse_clock = t + 0.5 * hstep
        k1 = np.array(f(t, y0, w3[0], wd3[0]))
        k2 = np.array(f(t + 0.5 * hstep, y0 + 0.5 * hstep * k1, w3[1], wd3[1]))
        k3 = np.array(f(t + 0.5 * hstep, y0 + 0.5 * hstep * k2, w3[1], wd3[1]))
        k4 = np.array(f(t + hstep, y0 + hstep * k3, w3[2], wd3[2]))
        self._pulse_clock = None
        return y0 + (hstep / 6.0) * (k1 + 2 * k2 + 2 * k3 + k4)

    def _prec_rhs(self, t, y, wc, _wcd):
        self.rhs_evaluations += 1
        return self._precession_rates(t, y[0], y[1], *wc)

    # -- stepping ---------------------------------------------------------------------
    def step_size(self) -> float:
        """The largest sub-step this simulator takes (s)."""
        p = self.params
        hmax = p.max_step
        for hm in p.harmonic_torques:
            hmax = min(hmax, 1.0 / (16.0 * hm.frequency_hz))
        if self._resolve_nutation:
            beta = float(self._y[1])
            hmax = min(hmax, 2 * math.pi / (p.nutation_frequency_rad_s(beta) * p.steps_per_nutation))
        return hmax

    def _advance(self, t_marks: np.ndarray) -> np.ndarray:
        """Integrate from self.t through the increasing times ``t_marks`` (all > self.t);
        return the state at each mark.

        One step grid covers all marks and impact-pulse edges (each interval between them
        split into equal sub-steps ≤ step_size()); the base rates for every stage of a
        chunk of the grid come from one vectorized ``omega_base_fn`` call.
        """
        out = np.empty((t_marks.shape[0], self._y.shape[0]))
        if t_marks.size == 0:
            return out
        t_end = float(t_marks[-1])
        brk = np.array([b for b in self._breaks if self.t < b < t_end])
        edges = np.unique(np.concatenate(([self.t], t_marks, brk)))
        a, b = edges[:-1], edges[1:]
        hmax = self.step_size()
        n = np.maximum(1, np.ceil((b - a) / hmax - 1e-9).astype(np.int64))
        ends = np.cumsum(n)  # grid index (1-based step count) at which each edge is reached
        total = int(ends[-1])
        mark_step = ends[np.searchsorted(b, t_marks)] - 1  # step after which each mark is hit
        y = self._y
        # chunk the grid so memory stays bounded on long runs
        for c0 in range(0, total, 20000):
            c1 = min(total, c0 + 20000)
            k = np.arange(c0, c1)
            iv = np.searchsorted(ends, k, side="right")  # interval of each step
            j = k - (ends[iv] - n[iv])
            left = a[iv] + (b[iv] - a[iv]) * j / n[iv]
            right = np.where(j + 1 == n[iv], b[iv], a[iv] + (b[iv] - a[iv]) * (j + 1) / n[iv])
            hs = right - left
            tm = left + 0.5 * hs
            rec_all: dict[int, list[int]] = {}
            for i, s in enumerate(mark_step):
                if c0 <= s < c1:
                    rec_all.setdefault(int(s) - c0, []).append(i)
            w, wd = self._inputs(left, tm, right)
            f = self._forces(tm)
            for i in range(hs.shape[0]):
                self._force_step = f[i]
                y = self._step(float(left[i]), float(hs[i]), y, w[i], wd[i])
                self._check_lock(y, right[i])
                for m_i in rec_all.get(i, ()):
                    out[m_i] = y
            self._force_step = None
            self._y = y
            self.steps += hs.shape[0]
        self.t = t_end
        return out

    def _forces(self, tm: np.ndarray) -> list:
        """Specific force at the step midpoints ``tm`` (None entries without unbalance)."""
        if self._force_fn is None:
            return [None] * tm.shape[0]
        f = np.asarray(self._force_fn(tm), dtype=np.float64)
        if f.shape != (tm.shape[0], 3) or not np.all(np.isfinite(f)):
            raise ValueError(f"specific_force_fn must return finite ({tm.shape[0]}, 3) values")
        return [tuple(r) for r in f.tolist()]

    def _inputs(self, left: np.ndarray, tm: np.ndarray, right: np.ndarray):
        """Base rates and accelerations of the stepper's stages for steps [left, right]:
        per step a 3-list (midpoint: at tm) or three of them (RK4: left, tm, right);
        accelerations are None where the model does not use them (precession)."""
        m = tm.shape[0]
        if self._stages == 1:
            w = self._base_rates(tm).tolist()
            return w, (self._base_accel(tm).tolist() if self._full else [None] * m)
        tt = np.stack((left, tm, right), axis=1).reshape(-1)
        w = self._base_rates(tt).reshape(-1, 3, 3).tolist()
        wd = (self._base_accel(tt).reshape(-1, 3, 3).tolist() if self._full
              else [[None, None, None]] * m)
        return w, wd

    def _stage_inputs(self, t: float, h: float):
        """Base rates/accelerations of a step of length h from t (for a re-taken sub-step)."""
        w, wd = self._inputs(np.array([t]), np.array([t + 0.5 * h]), np.array([t + h]))
        return w[0], wd[0]

    def _step(self, t, h, y, w, wd):
        """One step from t to t + h, with impacts on the gimbal stops located inside it."""
        if self._stops == (None, None):
            return self._raw_step(t, h, y, w, wd)
        t_end = t + h
        for _ in range(1000):  # impacts within one step; more means a chattering stop
            self._update_held(t, y, w, wd)
            y1 = self._raw_step(t, h, y, w, wd)
            hit = self._first_crossing(y, y1)
            if hit is None:
                return y1
            axis, stop = hit
            # regula falsi (Illinois) on the step length for the crossing of the stop
            lo, hi, g_lo, g_hi = 0.0, h, y[axis] - stop, y1[axis] - stop
            y_hit, side = y, 0
            while hi - lo > 1e-12:
                hh = (lo * g_hi - hi * g_lo) / (g_hi - g_lo)
                if not lo < hh < hi:
                    hh = 0.5 * (lo + hi)
                wh, wdh = self._stage_inputs(t, hh)
                yh = self._raw_step(t, hh, y, wh, wdh)
                g = yh[axis] - stop
                if (g > 0) == (g_lo > 0):
                    lo, g_lo, y_hit = hh, g, yh
                    if side == -1:
                        g_hi *= 0.5
                    side = -1
                else:
                    hi, g_hi = hh, g
                    if side == 1:
                        g_lo *= 0.5
                    side = 1
            if lo == 0.0:
                wh, wdh = self._stage_inputs(t, hi)
                y_hit = self._raw_step(t, hi, y, wh, wdh)
            y = np.array(y_hit, dtype=np.float64)
            t = t + hi
            y[axis] = stop
            before = float(y[axis + 2])
            after = -self.params.stop_restitution * before
            if abs(after) < self.params.stop_rest_rate:
                after = 0.0
            y[axis + 2] = after
            self.stop_impacts.append((t, axis, before, after))
            h = t_end - t
            if h <= 1e-12:
                return y
            w, wd = self._stage_inputs(t, h)
        raise ValueError(f"gimbal stop chattering at t = {t:.6g} s (over 1000 impacts in one "
                         "step); reduce max_step or raise stop_rest_rate")

    def _first_crossing(self, y0, y1):
        """(axis, stop angle) of a stop crossed during the step y0 → y1, or None."""
        for axis, stops in enumerate(self._stops):
            if stops is None or self._held[axis]:
                continue
            lo, hi = stops
            if y1[axis] <= lo and y0[axis] > lo:
                return axis, lo
            if y1[axis] >= hi and y0[axis] < hi:
                return axis, hi
        return None

    def _update_held(self, t, y, w, wd) -> None:
        """Rest a joint on its stop (zero rate, pushed into it) or lift it off, at step start."""
        if not self._full:
            return
        wc, wcd = (w, wd) if self._stages == 1 else (w[0], wd[0])
        for axis, stops in enumerate(self._stops):
            if stops is None:
                continue
            lo, hi = stops
            at = lo if abs(y[axis] - lo) <= abs(y[axis] - hi) else hi
            if y[axis] != at or y[axis + 2] != 0.0:
                self._held[axis] = False
                continue
            self._held[axis] = False  # the free acceleration decides
            acc = self._full_rhs(t, y, wc, wcd)[axis + 2]
            self._held[axis] = (acc < 0.0) if at == lo else (acc > 0.0)

    def _check_lock(self, y, t) -> None:
        if not (math.isfinite(y[0]) and math.isfinite(y[1])):
            raise ValueError(f"free-gyro state became non-finite at t = {float(t):.6g} s")
        # Reaching (or stepping across) β = ±90° means the spin axis met the outer axis:
        # gimbal lock, where the precession equations divide by cos β = 0.  The full model's
        # mass matrix stays regular there (its own check is on M_11), so it goes through.
        # A step may jump across the lock, so |β| beyond 90° counts as reaching it (the
        # precession model's β lives in (−90°, 90°); without I_oz and I_gx neither can the
        # full model's, M_11 → 0 there).
        if abs(y[1]) > 0.5 * math.pi - 1e-6:
            if not self._full:
                raise ValueError(
                    f"inner gimbal reached ±90° at t = {float(t):.6g} s (gimbal lock): the "
                    "precession model divides by cos β and has no solution there; use model "
                    "'full' with gimbal inertia to pass through the lock")
            if self._io[2] + self._ig[0] <= 0.0 and abs(y[1]) < 0.5 * math.pi + 1e-3:
                raise ValueError(
                    f"outer-axis inertia vanished at t = {float(t):.6g} s (gimbal lock at β = "
                    "±90° with no outer-gimbal inertia): give outer_gimbal_inertia z or "
                    "inner_gimbal_inertia x > 0 to pass through the lock")

    def state(self) -> tuple[np.ndarray, np.ndarray]:
        """Current (angles (2,), relative gimbal rates (2,))."""
        if self._full:
            return self._y[:2].copy(), self._y[2:].copy()
        w = self._base_rates(np.array([self.t]))[0]
        return self._y.copy(), np.array(self._precession_rates(self.t, *self._y, *w))

    def run_until(self, t_out) -> tuple[np.ndarray, np.ndarray]:
        """Gimbal angles and relative rates ``(m, 2)`` (outer, inner) at times ``t_out``.

        ``t_out`` must be finite, non-decreasing and not earlier than the current time.
        """
        t_out = np.atleast_1d(np.asarray(t_out, dtype=np.float64))
        if t_out.ndim != 1:
            raise ValueError("t_out must be a 1-D array of times")
        if not np.all(np.isfinite(t_out)):
            raise ValueError("t_out contains non-finite times")
        if t_out.size and (t_out[0] < self.t - 1e-12 or np.any(np.diff(t_out) < 0)):
            raise ValueError(f"t_out must be non-decreasing and start at or after the "
                             f"current time {self.t!r}")
        m = t_out.shape[0]
        dim = self._y.shape[0]
        states = np.empty((m, dim))
        now = t_out <= self.t  # requested at the current time (within 1e-12 s)
        states[now] = self._y
        later = t_out[~now]
        if later.size:
            uniq, inverse = np.unique(later, return_inverse=True)
            states[~now] = self._advance(uniq)[inverse]
        angles = states[:, :2].copy()
        if self._full:
            rates = states[:, 2:].copy()
        else:
            w = self._base_rates(t_out).tolist()
            rates = np.array([self._precession_rates(float(t_out[i]), *states[i], *w[i])
                              for i in range(m)]).reshape(m, 2)
        return angles, rates

    def _body_rates(self):
        """Inertial angular velocities of the outer gimbal (o axes) and inner assembly (g axes)."""
        al, be, ad, bd = self._y
        wc = self._base_rates(np.array([self.t]))[0]
        v, _, (ca, sa, cb, sb) = _rot_to_gimbal(al, be, *wc)
        wo = np.array([v[0], v[1], v[2] + ad])
        wg = np.array([cb * wo[0] - sb * wo[2], wo[1] + bd, sb * wo[0] + cb * wo[2]])
        return wo, wg, (ca, sa, cb, sb)

    def angular_momentum(self) -> np.ndarray:
        """Total angular momentum of rotor + gimbals about the pivot (full model), in case
        axes (N·m·s): ``C_co (I_o ω_o + C_og h_g)``, ``h_g = [H + I_gx ω_gx, A_y ω_gy, A_z ω_gz]``.
        The case holds the outer axis (its bearings take torques about x_c and y_c), so on a
        base at rest with no outer-axis torque the z component (about the outer axis) is the
        conserved one, and it changes by the outer-axis torque's impulse otherwise."""
        if not self._full:
            raise ValueError("angular_momentum needs model='full'")
        wo, wg, (ca, sa, cb, sb) = self._body_rates()
        ig = self._ig
        hg = np.array([self._h + ig[0] * wg[0], self._ay * wg[1], self._az * wg[2]])
        lo = np.array(self._io) * wo + np.array([cb * hg[0] + sb * hg[2], hg[1],
                                                 -sb * hg[0] + cb * hg[2]])
        return np.array([ca * lo[0] - sa * lo[1], sa * lo[0] + ca * lo[1], lo[2]])

    def kinetic_energy(self) -> float:
        """Kinetic energy of rotor + gimbals (full model) at the current state, in J."""
        if not self._full:
            raise ValueError("kinetic_energy needs model='full'")
        al, be, ad, bd = self._y
        wc = self._base_rates(np.array([self.t]))[0]
        v, _, (_, _, cb, sb) = _rot_to_gimbal(al, be, *wc)
        wo = np.array([v[0], v[1], v[2] + ad])
        wg = np.array([cb * wo[0] - sb * wo[2], wo[1] + bd, sb * wo[0] + cb * wo[2]])
        io, ig = np.array(self._io), np.array(self._ig)
        e_rot = 0.5 * self._h ** 2 / self.params.spin_inertia
        return float(0.5 * wo @ (io * wo) + 0.5 * wg @ (ig * wg)
                     + 0.5 * self._jt * (wg[1] ** 2 + wg[2] ** 2) + e_rot)
