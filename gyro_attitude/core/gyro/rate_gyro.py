"""Single-gimbal rate gyro and integrating gyro (§4-2): models, exact discretization, closed forms.

Section numbers (§) refer to the gyroscope-mechanics textbook (``docs/equations.md``).
SI units: rad, rad/s, N·m, kg·m², seconds as floats (the scene layer converts its
integer-nanosecond clock); ``scipy.linalg.expm`` is used once per set-up.

Geometry.  One gimbal carries the rotor (spin momentum ``H`` along the spin axis S) and turns
by the angle β about the output axis O = S × I, where I is the input axis.  A triad has
input axes e_x, e_y, e_z; the gyro with input axis e_i spins along S = e_{(i+1) mod 3}, so
its output axis is O = −e_{(i+2) mod 3} (x gyro: −z, y gyro: −x, z gyro: −y).

Deflected by β, the gimbal turns the spin axis to S' = S cos β + I sin β and the input axis
to I' = I cos β − S sin β.  The gyroscopic torque about O is ``H ω·I'``, the base turning
about O accelerates the gimbal with it (its inertial angle is β plus the case's), and a rotor
whose centre of mass sits ``l`` along the spin axis (unbalance ``m l``) feels the torque
``m l (f × S')·O = −m l f·I'`` of the specific force f.  Newton about O::

    J (β̈ + ω̇_O) + D β̇ + K β = H u,
    u = (ω_I − (m l/H) f_I) cos β − c (ω_S − (m l/H) f_S) sin β

(``c`` = ``cross_coupling``: 1 is the full geometry, 0 removes the ω_S leak; the cos β of
the input axis is part of the model whatever c).  Two instruments:

* **Rate gyro** (spring K > 0).  Indicated rate ``x = K β / H``; with ω_n² = K/J, 2ζω_n = D/J::

      ẍ + 2ζω_n ẋ + ω_n² x = ω_n² (u − (J/H) ω̇_O),   β = (H/K) x,   J/H = 1/(ω_n² H/K).

  Steady output for a constant rate: the root of x = u(β = (H/K) x) — ω_I for small β.  A
  step α of base angular acceleration about O alone deflects the gimbal by −J α / K in the
  steady state (the second-order step response scaled by that).  The −3 dB bandwidth is
  ω_n (1 − 2ζ² + (4ζ⁴ − 4ζ² + 2)^½)^½.
* **Integrating gyro** (no spring, K = 0).  Indicated angle ``θ = D β / H``; with τ = J/D::

      τ θ̈ + θ̇ = u − (J/H) ω̇_O,   β = (H/D) θ,   J/H = τ/(H/D),

  so ``θ → ∫u dt`` after the time constant τ: the gimbal angle is (H/D)·∫ω_I dt.  For a
  ramp ω_I = a t from rest, θ = a (t²/2 − τ t + τ² (1 − e^{−t/τ})) (small β).

g-sensitive drift (§5-3): the unbalance acts as a false rate −(m l/H) f_I along the input
axis, proportional to the specific force.

Numerics.  The linear part (2×2 system) is discretized exactly by a matrix exponential with
the input linear ("foh") or held ("zoh") between samples; a step or ramp of u gives the
analytic response to round-off.  The base angular acceleration over an interval is the slope
of the sampled rate, (ω_O,k − ω_O,k−1)/dt — exact for the foh interpretation of the samples
(a base rate linear in time); with zoh it places the rate jump's impulse over the interval
instead of at its start, an O(dt) shift.  The nonlinear factor u(β): zoh holds u(β_{k−1})
(explicit); foh needs u(β_k) at the end of the interval and takes it by one predictor (β_k
from u(β_{k−1})) and one corrector pass — second order in the small change of β per step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gyro_attitude.core.validators import check_finite, check_positive

__all__ = [
    "RateGyroParams",
    "IntegratingGyroParams",
    "RateGyroTriad",
    "rate_gyro_step_response",
    "integrating_gyro_ramp_response",
]


def _check_common(p) -> None:
    check_finite(p.cross_coupling, "cross_coupling")
    if p.hold not in ("foh", "zoh"):
        raise ValueError(f"hold must be 'foh' or 'zoh', got {p.hold!r}")
    if not isinstance(p.output_axis_acceleration, bool):
        raise ValueError("output_axis_acceleration must be true or false, got "
                         f"{p.output_axis_acceleration!r}")
    check_finite(p.mass_unbalance, "mass_unbalance")
    if p.spin_momentum is not None:
        check_positive(p.spin_momentum, "spin_momentum")
    elif p.mass_unbalance != 0.0:
        raise ValueError("mass_unbalance needs spin_momentum (H, N·m·s): the drift is m·l·f/H")


@dataclass(frozen=True)
class RateGyroParams:
    """Second-order rate-gyro model, identical for the three axes of a triad.

    natural_frequency_hz: undamped natural frequency f_n = ω_n/2π = (K/J)^½ / 2π.
    damping_ratio: ζ = D / (2 (K J)^½), > 0.
    cross_coupling: c in ``u = ω_I cos β − c ω_S sin β`` (0: no ω_S leak, 1: full geometry).
    gimbal_gain_s: H/K, the gimbal deflection per unit input rate (rad per rad/s).
    hold: "foh" (input linear between samples, default) or "zoh" (held constant).
    output_axis_acceleration: the base's angular acceleration about the output axis drives
        the gimbal (physics; False drops it, for the textbook transfer function alone).
    mass_unbalance: m·l (kg·m, signed, + toward the +S end) of the rotor along its spin axis:
        a false rate −(m l/H) f_I (g-sensitive drift); needs ``spin_momentum``.
    spin_momentum: H (N·m·s), only used by the mass unbalance.
    """

    natural_frequency_hz: float
    damping_ratio: float
    cross_coupling: float = 0.0
    gimbal_gain_s: float = 0.01
    hold: str = "foh"
    output_axis_acceleration: bool = True
    mass_unbalance: float = 0.0
    spin_momentum: float | None = None

    def __post_init__(self):
        check_positive(self.natural_frequency_hz, "natural_frequency_hz")
        check_positive(self.damping_ratio, "damping_ratio")
        check_positive(self.gimbal_gain_s, "gimbal_gain_s")
        _check_common(self)

    @classmethod
    def from_physical(cls, spin_momentum: float, gimbal_inertia: float, damping: float,
                      spring: float, **kwargs) -> RateGyroParams:
        """From H (N·m·s), J (kg·m²), D (N·m·s/rad) and K (N·m/rad)."""
        h = check_positive(spin_momentum, "spin_momentum")
        j = check_positive(gimbal_inertia, "gimbal_inertia")
        d = check_positive(damping, "damping")
        k = check_positive(spring, "spring")
        wn = math.sqrt(k / j)
        return cls(natural_frequency_hz=wn / (2 * math.pi), damping_ratio=d / (2 * math.sqrt(k * j)),
                   gimbal_gain_s=h / k, spin_momentum=h, **kwargs)

    @property
    def natural_frequency_rad_s(self) -> float:
        return 2.0 * math.pi * self.natural_frequency_hz

    @property
    def bandwidth_hz(self) -> float:
        """−3 dB bandwidth of ``ω_n²/(s² + 2ζω_n s + ω_n²)`` in Hz."""
        z2 = self.damping_ratio ** 2
        return self.natural_frequency_hz * math.sqrt(1 - 2 * z2 + math.sqrt(4 * z2 * z2 - 4 * z2 + 2))

    @property
    def inertia_over_momentum_s2(self) -> float:
        """J/H = 1/(ω_n² · H/K) (s²): the gain of the base angular acceleration."""
        return 1.0 / (self.natural_frequency_rad_s ** 2 * self.gimbal_gain_s)

    def system(self) -> tuple[np.ndarray, np.ndarray, float]:
        """``(A, B, β per unit state)`` of ``ṡ = A s + B u`` with s = (x, ẋ)."""
        wn, z = self.natural_frequency_rad_s, self.damping_ratio
        return (np.array([[0.0, 1.0], [-wn * wn, -2 * z * wn]]), np.array([0.0, wn * wn]),
                self.gimbal_gain_s)


@dataclass(frozen=True)
class IntegratingGyroParams:
    """Integrating (rate-integrating) gyro: no spring, viscous damping D, identical per axis.

    time_constant_s: τ = J/D (s).
    gimbal_gain: H/D, the gimbal angle per unit input angle (rad/rad).
    Other fields as in :class:`RateGyroParams`.  The indication is the angle θ = D β / H.
    """

    time_constant_s: float
    gimbal_gain: float = 1.0
    cross_coupling: float = 0.0
    hold: str = "foh"
    output_axis_acceleration: bool = True
    mass_unbalance: float = 0.0
    spin_momentum: float | None = None

    def __post_init__(self):
        check_positive(self.time_constant_s, "time_constant_s")
        check_positive(self.gimbal_gain, "gimbal_gain")
        _check_common(self)

    @classmethod
    def from_physical(cls, spin_momentum: float, gimbal_inertia: float, damping: float,
                      **kwargs) -> IntegratingGyroParams:
        """From H (N·m·s), J (kg·m²) and D (N·m·s/rad)."""
        h = check_positive(spin_momentum, "spin_momentum")
        j = check_positive(gimbal_inertia, "gimbal_inertia")
        d = check_positive(damping, "damping")
        return cls(time_constant_s=j / d, gimbal_gain=h / d, spin_momentum=h, **kwargs)

    @property
    def inertia_over_momentum_s2(self) -> float:
        """J/H = τ / (H/D) (s²)."""
        return self.time_constant_s / self.gimbal_gain

    def system(self) -> tuple[np.ndarray, np.ndarray, float]:
        """``(A, B, β per unit state)`` of ``ṡ = A s + B u`` with s = (θ, θ̇)."""
        r = 1.0 / self.time_constant_s
        return np.array([[0.0, 1.0], [0.0, -r]]), np.array([0.0, r]), self.gimbal_gain


def rate_gyro_step_response(t, natural_frequency_hz: float, damping_ratio: float) -> np.ndarray:
    """Closed-form unit-step response of ``ω_n²/(s² + 2ζω_n s + ω_n²)`` from rest at t = 0."""
    t = np.asarray(t, dtype=np.float64)
    wn = 2 * math.pi * check_positive(natural_frequency_hz, "natural_frequency_hz")
    z = check_positive(damping_ratio, "damping_ratio")
    if z < 1.0:
        wd = wn * math.sqrt(1 - z * z)
        return 1 - np.exp(-z * wn * t) * (np.cos(wd * t) + z / math.sqrt(1 - z * z) * np.sin(wd * t))
    if z == 1.0:
        return 1 - np.exp(-wn * t) * (1 + wn * t)
    r = math.sqrt(z * z - 1)
    s1, s2 = -wn * (z - r), -wn * (z + r)
    return 1 + (s2 * np.exp(s1 * t) - s1 * np.exp(s2 * t)) / (s1 - s2)


def integrating_gyro_ramp_response(t, time_constant_s: float, rate_slope: float) -> np.ndarray:
    """Indicated angle θ(t) = a (t²/2 − τ t + τ² (1 − e^{−t/τ})) of ``τ θ̈ + θ̇ = a t`` from rest."""
    t = np.asarray(t, dtype=np.float64)
    tau = check_positive(time_constant_s, "time_constant_s")
    a = check_finite(rate_slope, "rate_slope")
    return a * (0.5 * t * t - tau * t - tau * tau * np.expm1(-t / tau))


class RateGyroTriad:
    """Three single-gimbal gyros (rate or integrating) on the body axes x, y, z.

    ``step_block(omega_in, specific_force=None)`` takes the true inertial rates (and, with a
    mass unbalance, the specific force in body axes, m/s²) at consecutive samples ``dt``
    apart and returns the indications at the same samples — rates (rad/s) for
    :class:`RateGyroParams`, angles θ (rad) for :class:`IntegratingGyroParams`; the state
    carries over between calls, and ``gimbal_angles`` holds β at the last sample.  The first
    sample of the first block is the initial state: at rest (``initial="rest"``: zero state)
    or steady with the first input (``initial="steady"``, default: the rate gyro at its
    steady deflection, the integrating gyro at θ = 0 turning at θ̇ = u).
    """

    def __init__(self, params: RateGyroParams | IntegratingGyroParams, dt: float,
                 initial: str = "steady"):
        if not isinstance(params, RateGyroParams | IntegratingGyroParams):
            raise ValueError("params must be a RateGyroParams or IntegratingGyroParams")
        self.params = params
        self.integrating = isinstance(params, IntegratingGyroParams)
        self.dt = check_positive(dt, "dt")
        if initial not in ("steady", "rest"):
            raise ValueError(f"initial must be 'steady' or 'rest', got {initial!r}")
        self.initial = initial
        a, b, self._beta_per_state = params.system()
        # Van Loan: expm([[A, B, 0], [0, 0, 1/dt], [0, 0, 0]] dt) holds Φ = e^{A dt},
        # Γ0 = ∫0^dt e^{Aτ}dτ B (held input) and Γ1 = ∫0^dt e^{A(dt−τ)} (τ/dt) dτ B (ramp).
        m = np.zeros((4, 4))
        m[:2, :2] = a * self.dt
        m[:2, 2] = b * self.dt
        m[2, 3] = 1.0
        from scipy.linalg import expm  # (imported where used: see sensor_errors)

        e = expm(m)
        self._phi = e[:2, :2].copy()
        self._gamma0 = e[:2, 2].copy()
        self._gamma1 = e[:2, 3].copy()
        self._state: np.ndarray | None = None  # (3, 2): indication and its derivative per axis
        self._last_u: np.ndarray | None = None  # u at the last sample, per axis
        self._last_w: np.ndarray | None = None  # rate at the last sample (base acceleration)
        self.samples = 0

    def reset(self) -> None:
        self._state = None
        self._last_u = None
        self._last_w = None
        self.samples = 0

    @property
    def state(self) -> np.ndarray | None:
        """``(3, 2)`` indication and its derivative at the last sample (None before)."""
        return None if self._state is None else self._state.copy()

    @property
    def gimbal_angles(self) -> np.ndarray | None:
        """``(3,)`` gimbal angles β (rad) at the last sample (None before)."""
        return None if self._state is None else self._beta_per_state * self._state[:, 0]

    def _input(self, w_eff: np.ndarray, x: np.ndarray) -> np.ndarray:
        """u = w_I cos β − c w_S sin β per axis (w_eff: rates with the unbalance's false rate)."""
        beta = self._beta_per_state * x
        spin = np.roll(w_eff, -1, axis=-1)  # ω_S for input axes x, y, z is ω_y, ω_z, ω_x
        return w_eff * np.cos(beta) - self.params.cross_coupling * spin * np.sin(beta)

    def _checked(self, a, name: str, n: int | None = None) -> np.ndarray:
        a = np.asarray(a, dtype=np.float64)
        if a.ndim != 2 or a.shape[1] != 3 or (n is not None and a.shape[0] != n):
            want = "(n, 3)" if n is None else f"({n}, 3)"
            raise ValueError(f"{name} must have shape {want}, got {a.shape}")
        if not np.all(np.isfinite(a)):
            raise ValueError(f"{name} contains non-finite values")
        return a

    def step_block(self, omega_in, specific_force=None) -> np.ndarray:
        """Indications ``(n, 3)`` for true rates ``omega_in`` ``(n, 3)`` in rad/s."""
        w = self._checked(omega_in, "omega_in")
        n = w.shape[0]
        p = self.params
        w_eff = w
        if p.mass_unbalance != 0.0:
            if specific_force is None:
                raise ValueError("specific_force (n, 3) is needed: the gyro has a mass unbalance")
            f = self._checked(specific_force, "specific_force", n)
            w_eff = w - (p.mass_unbalance / p.spin_momentum) * f
        out = np.empty((n, 3))
        if n == 0:
            return out
        k0 = 0
        if self._state is None:
            s = np.zeros((3, 2))
            if self.initial == "steady":
                if self.integrating:
                    s[:, 1] = self._input(w_eff[0], s[:, 0])
                else:  # fixed point of x = u(x): a contraction for |β| ≪ 1, a few passes
                    s[:, 0] = w_eff[0]
                    for _ in range(50):
                        s[:, 0] = self._input(w_eff[0], s[:, 0])
            self._state = s
            self._last_u = self._input(w_eff[0], s[:, 0])
            self._last_w = w[0].copy()
            out[0] = s[:, 0]
            k0 = 1
        out[k0:] = self._recursion(w[k0:], w_eff[k0:])
        self.samples += n
        return out

    def _recursion(self, w: np.ndarray, w_eff: np.ndarray) -> np.ndarray:
        """s_k = Φ s_{k−1} + Γ0 (u_{k−1} + a_k) + Γ1 (u_k − u_{k−1}) (Γ1 = 0: zoh), per axis.

        ``a_k = −(J/H)(ω_O,k − ω_O,k−1)/dt`` is the base angular acceleration term.  A plain
        loop over samples on Python floats: the recursion is sequential, and the 2×2 update
        with the cos/sin of u costs ~2 µs per axis and sample this way (numpy's per-call
        overhead on 2-vectors would cost ten times that).
        """
        n = w.shape[0]
        out = np.empty((n, 3))
        if n == 0:
            return out
        p = self.params
        p00, p01, p10, p11 = self._phi.ravel().tolist()
        g0a, g0b = self._gamma0.tolist()
        foh = p.hold == "foh"
        g1a, g1b = self._gamma1.tolist() if foh else (0.0, 0.0)
        acc = np.zeros((n, 3))
        if p.output_axis_acceleration:
            prev = np.concatenate((self._last_w[None, :], w[:-1]), axis=0)
            # output axis of input axis i is −e_{i+2}: ω_O = −ω_{i+2}
            acc = (p.inertia_over_momentum_s2 / self.dt) * np.roll(w - prev, -2, axis=1)
        kb, c = self._beta_per_state, p.cross_coupling
        spin = np.roll(w_eff, -1, axis=1)
        s = self._state
        for ax in range(3):
            x, v = float(s[ax, 0]), float(s[ax, 1])
            u_prev = float(self._last_u[ax])
            wi, ws, ak = w_eff[:, ax].tolist(), spin[:, ax].tolist(), acc[:, ax].tolist()
            col = [0.0] * n
            for k in range(n):
                # part of the update known before u_k: Φ s + Γ0 (u_{k−1} + a_k) − Γ1 u_{k−1}
                ba = p00 * x + p01 * v + g0a * (u_prev + ak[k]) - g1a * u_prev
                bb = p10 * x + p11 * v + g0b * (u_prev + ak[k]) - g1b * u_prev
                if foh:  # u_k at the end: predictor from β_{k−1}, one corrector at β_k
                    beta = kb * x
                    u = wi[k] * math.cos(beta) - c * ws[k] * math.sin(beta)
                    beta = kb * (ba + g1a * u)
                    u = wi[k] * math.cos(beta) - c * ws[k] * math.sin(beta)
                    x, v = ba + g1a * u, bb + g1b * u
                else:
                    x, v = ba, bb
                    beta = kb * x
                    u = wi[k] * math.cos(beta) - c * ws[k] * math.sin(beta)
                u_prev = u
                col[k] = x
            out[:, ax] = col
            s[ax, 0], s[ax, 1] = x, v
            self._last_u[ax] = u_prev
        self._last_w = w[-1].copy()
        return out
