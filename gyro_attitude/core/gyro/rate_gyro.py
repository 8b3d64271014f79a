"""Single-gimbal rate gyro (two degrees of freedom, §4-2): model, exact discretization, step response.

Section numbers (§) refer to the gyroscope-mechanics textbook (``docs/equations.md``).
SI units: rad, rad/s, N·m, kg·m², seconds as floats (the scene layer converts its
integer-nanosecond clock); ``scipy.linalg.expm`` is used once per set-up.

One gimbal carries the rotor (spin momentum ``H`` along the spin axis S) and turns by the
angle β about the output axis O against a spring ``K`` and a damper ``D``. A rate ω_I
about the input axis I produces the gyroscopic torque ``H ω_I`` about O::

    J β̈ + D β̇ + K β = H (ω_I cos β − c ω_S sin β)

(``c`` = ``cross_coupling``: the deflected gimbal tilts the spin axis, so part of the rate
ω_S about the spin reference axis leaks in; c = 1 is the full geometric effect, 0 removes
it). The indicated rate is ``x = K β / H``; with ω_n² = K/J and 2ζω_n = D/J::

    ẍ + 2ζω_n ẋ + ω_n² x = ω_n² u,    u = ω_I cos β − c ω_S sin β,   β = (H/K) x.

The steady-state output for a constant rate is therefore ω_I (unit gain, when c = 0);
the −3 dB bandwidth is ω_n (1 − 2ζ² + (4ζ⁴ − 4ζ² + 2)^½)^½.  The linear part is
discretized exactly (matrix exponential of the 2×2 system, with the input held constant
("zoh") or linear ("foh") between samples), so a step response equals the analytic
second-order response to round-off.  With c ≠ 0 the coupling term u uses β at the start
of each sample interval (an O(dt) approximation of a small second-order effect).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gyro_attitude.core.validators import check_finite, check_positive

__all__ = ["RateGyroParams", "RateGyroTriad", "rate_gyro_step_response"]


@dataclass(frozen=True)
class RateGyroParams:
    """Second-order rate-gyro model, identical for the three axes of a triad.

    natural_frequency_hz: undamped natural frequency f_n = ω_n/2π = (K/J)^½ / 2π.
    damping_ratio: ζ = D / (2 (K J)^½), > 0.
    cross_coupling: c in ``u = ω_I cos β − c ω_S sin β`` (0 = ideal, 1 = full geometry).
    gimbal_gain_s: H/K, the gimbal deflection per unit input rate (rad per rad/s); only
        used by the cross-coupling term.
    hold: "foh" (input linear between samples, default) or "zoh" (held constant).
    """

    natural_frequency_hz: float
    damping_ratio: float
    cross_coupling: float = 0.0
    gimbal_gain_s: float = 0.01
    hold: str = "foh"

    def __post_init__(self):
        check_positive(self.natural_frequency_hz, "natural_frequency_hz")
        check_positive(self.damping_ratio, "damping_ratio")
        check_finite(self.cross_coupling, "cross_coupling")
        check_positive(self.gimbal_gain_s, "gimbal_gain_s")
        if self.hold not in ("foh", "zoh"):
            raise ValueError(f"hold must be 'foh' or 'zoh', got {self.hold!r}")

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
                   gimbal_gain_s=h / k, **kwargs)

    @property
    def natural_frequency_rad_s(self) -> float:
        return 2.0 * math.pi * self.natural_frequency_hz

    @property
    def bandwidth_hz(self) -> float:
        """−3 dB bandwidth of ``ω_n²/(s² + 2ζω_n s + ω_n²)`` in Hz."""
        z2 = self.damping_ratio ** 2
        return self.natural_frequency_hz * math.sqrt(1 - 2 * z2 + math.sqrt(4 * z2 * z2 - 4 * z2 + 2))


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


class RateGyroTriad:
    """Three single-gimbal rate gyros on the body axes x, y, z.

    The spin reference axis of the gyro with input axis e_i is e_{(i+1) mod 3} (for the
    cross-coupling term only).  ``step_block(omega_in)`` takes the true inertial rates at
    consecutive samples ``dt`` apart and returns the indicated rates at the same samples;
    the state carries over between calls.  The first sample of the first block is the
    initial state: at rest (``initial="rest"``: x = ẋ = 0) or in steady state with the
    first input (``initial="steady"``, default).
    """

    def __init__(self, params: RateGyroParams, dt: float, initial: str = "steady"):
        if not isinstance(params, RateGyroParams):
            raise ValueError("params must be a RateGyroParams")
        self.params = params
        self.dt = check_positive(dt, "dt")
        if initial not in ("steady", "rest"):
            raise ValueError(f"initial must be 'steady' or 'rest', got {initial!r}")
        self.initial = initial
        wn = params.natural_frequency_rad_s
        z = params.damping_ratio
        a = np.array([[0.0, 1.0], [-wn * wn, -2 * z * wn]])
        b = np.array([0.0, wn * wn])
        # Van Loan: expm([[A, B, 0], [0, 0, 1/dt], [0, 0, 0]] dt) holds Φ = e^{A dt},
        # Γ0 = ∫0^dt e^{Aτ}dτ B (held input) and Γ1 = ∫0^dt e^{A(dt−τ)} (τ/dt) dτ B (ramp).
        from scipy.linalg import expm  # one-off set-up cost; exact and well conditioned

        m = np.zeros((4, 4))
        m[:2, :2] = a * self.dt
        m[:2, 2] = b * self.dt
        m[2, 3] = 1.0
        e = expm(m)
        self._phi = e[:2, :2].copy()
        self._gamma0 = e[:2, 2].copy()
        self._gamma1 = e[:2, 3].copy()
        self._state: np.ndarray | None = None  # (3, 2): x, ẋ per axis
        self._last_u: np.ndarray | None = None
        self.samples = 0

    def reset(self) -> None:
        self._state = None
        self._last_u = None
        self.samples = 0

    @property
    def state(self) -> np.ndarray | None:
        """``(3, 2)`` indicated rate and its derivative at the last sample (None before)."""
        return None if self._state is None else self._state.copy()

    def _effective_input(self, omega: np.ndarray, x: np.ndarray) -> np.ndarray:
        c = self.params.cross_coupling
        if c == 0.0:
            return omega
        beta = self.params.gimbal_gain_s * x
        spin = np.roll(omega, -1, axis=-1)  # ω_S for input axes x, y, z is ω_y, ω_z, ω_x
        return omega * np.cos(beta) - c * spin * np.sin(beta)

    def step_block(self, omega_in) -> np.ndarray:
        """Indicated rates ``(n, 3)`` for true rates ``omega_in`` ``(n, 3)`` in rad/s."""
        w = np.asarray(omega_in, dtype=np.float64)
        if w.ndim != 2 or w.shape[1] != 3:
            raise ValueError(f"omega_in must have shape (n, 3), got {w.shape}")
        if not np.all(np.isfinite(w)):
            raise ValueError("omega_in contains non-finite values")
        n = w.shape[0]
        out = np.empty((n, 3))
        if n == 0:
            return out
        k0 = 0
        if self._state is None:
            s = np.zeros((3, 2))
            if self.initial == "steady":
                s[:, 0] = w[0]
                if self.params.cross_coupling != 0.0:  # fixed point of x = u(x), few passes
                    for _ in range(50):
                        s[:, 0] = self._effective_input(w[0], s[:, 0])
            self._state = s
            self._last_u = self._effective_input(w[0], s[:, 0])
            out[0] = s[:, 0]
            k0 = 1
        if self.params.cross_coupling == 0.0:
            out[k0:] = self._linear_block(w[k0:])
        else:
            out[k0:] = self._coupled_block(w[k0:])
        self.samples += n
        return out

    def _linear_block(self, u: np.ndarray) -> np.ndarray:
        """Exact recursion s_k = Φ s_{k−1} + Γ0 u_{k−1} + Γ1 (u_k − u_{k−1}) (Γ1 = 0: zoh).

        A plain loop over samples on Python floats: the recursion is sequential and the
        2×2 per-axis update costs ~1 µs per axis and sample this way.
        """
        n = u.shape[0]
        out = np.empty((n, 3))
        if n == 0:
            return out
        p00, p01, p10, p11 = self._phi.ravel().tolist()
        g0a, g0b = self._gamma0.tolist()
        if self.params.hold == "foh":
            g1a, g1b = self._gamma1.tolist()
        else:
            g1a = g1b = 0.0
        prev = np.concatenate((self._last_u[None, :], u[:-1]), axis=0)
        # input terms for both state components, vectorized; only the state recursion loops
        fa = (g0a - g1a) * prev + g1a * u
        fb = (g0b - g1b) * prev + g1b * u
        s = self._state
        for ax in range(3):
            x, v = float(s[ax, 0]), float(s[ax, 1])
            fa_ax = fa[:, ax].tolist()
            fb_ax = fb[:, ax].tolist()
            col = [0.0] * n
            for k in range(n):
                x, v = p00 * x + p01 * v + fa_ax[k], p10 * x + p11 * v + fb_ax[k]
                col[k] = x
            out[:, ax] = col
            s[ax, 0], s[ax, 1] = x, v
        self._last_u = u[-1].copy()
        return out

    def _coupled_block(self, w: np.ndarray) -> np.ndarray:
        n = w.shape[0]
        out = np.empty((n, 3))
        phi, g0, g1 = self._phi, self._gamma0, self._gamma1
        foh = self.params.hold == "foh"
        s = self._state
        for k in range(n):
            # coupling uses β at the start of the interval (see module docstring)
            u = self._effective_input(w[k], s[:, 0])
            if foh:
                s = s @ phi.T + np.outer(self._last_u, g0 - g1) + np.outer(u, g1)
            else:
                s = s @ phi.T + np.outer(self._last_u, g0)
            self._last_u = u
            out[k] = s[:, 0]
        self._state = s
        return out
