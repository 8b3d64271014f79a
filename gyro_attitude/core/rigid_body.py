"""Symmetric tops (§4-1 free top, §4-3 pseudo-regular precession, §4-4 heavy top).

Body frame b: principal axes, symmetry axis along body z.  ``J_t`` (``transverse_inertia``)
about x and y, ``J_s`` (``spin_inertia``) about z.  Quaternions are scalar-last ``q_nb``
(body → space), as everywhere in the package; ``H_b``, ``ω_b`` are angular momentum and
inertial angular velocity in body axes (Euler: ``Ḣ_b + ω_b × H_b = M_b``).

Free symmetric top, closed form (§4-1).  With ``H_b = J ω_b`` and ``H_n = C_nb H_b`` fixed
in space, ``ω_b = H_b / J_t + σ e_z`` with ``σ = ω_z (J_t − J_s)/J_t`` constant, so the
motion is two uniform rotations — about the fixed ``ĥ_n`` at the precession rate
``Ω_p = |H|/J_t`` (space cone) and about the body symmetry axis at ``σ`` (body cone)::

    q_nb(t) = exp(Ω_p t ĥ_n) ⊗ q_nb(0) ⊗ exp(σ t e_z).

Heavy symmetric top, Lagrange case (§4-4).  Fixed point on the symmetry axis, centre of
mass at distance l on +z, weight m g; Γ = the upward vertical in body axes.  In body axes::

    Ḣ = H × ω + m g l (Γ × e_z),   Γ̇ = Γ × ω,   ω = (H_x/J_t, H_y/J_t, H_z/J_s).

Integrals: energy ``E = ½ H·ω + m g l Γ_z``, momentum about the vertical ``p_ψ = H·Γ``,
about the symmetry axis ``p_φ = H_z``, and ``|Γ| = 1``.  All four are quadratic (or
linear) in the state (H, Γ), and the implicit midpoint rule conserves every quadratic
invariant exactly (``Q(x₁) − Q(x₀) = h ∇Q(x_m)·f(x_m) = 0`` for ``Q = xᵀCx + dᵀx``), so
:func:`integrate_heavy_top` conserves them to round-off and solver tolerance over any
number of steps, with no drift; it is second order for the trajectory itself.

With u = cos θ = Γ_z, eliminating H gives the classical cubic
``J_t² u̇² = f(u) = (1 − u²) 2J_t (E′ − m g l u) − (p_ψ − p_φ u)²``, ``E′ = E − p_φ²/(2J_s)``;
θ nutates between the two roots of f in [−1, 1] (:func:`heavy_top_nutation_bounds`).
A fast top started with θ̇ = ψ̇ = 0 nutates by ``Δu ≈ 2 J_t m g l sin²θ₀ / H²`` and
precesses on average at ``m g l / H`` (§4-3: torque M = m g l sin θ, rate ≈ M/(H sin θ)).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gyro_attitude.core.rotation import (
    _exp_rotvec,
    _qmul,
    as_quat_array,
    as_vector_array,
    quat_normalize,
    quat_rotate,
)
from gyro_attitude.core.validators import check_finite, check_positive

__all__ = [
    "free_symmetric_top",
    "free_top_precession_rate",
    "HeavyTop",
    "integrate_heavy_top",
    "heavy_top_invariants",
    "heavy_top_nutation_bounds",
    "heavy_top_state_from_euler",
]


def free_top_precession_rate(angular_momentum: float, transverse_inertia: float) -> float:
    """Regular precession rate ``|H| / J_t`` (rad/s) of a free symmetric top (§4-1)."""
    h = abs(check_finite(angular_momentum, "angular_momentum"))
    return h / check_positive(transverse_inertia, "transverse_inertia")


def free_symmetric_top(q0, omega0_b, transverse_inertia: float, spin_inertia: float,
                       t) -> tuple[np.ndarray, np.ndarray]:
    """Closed-form torque-free motion of a symmetric top (module docstring).

    q0: initial ``q_nb`` (4,); omega0_b: initial body rate (3,) rad/s; t: times (m,) s
    measured from the initial state.  Returns ``q_nb`` (m, 4) and ``ω_b`` (m, 3).
    """
    jt = check_positive(transverse_inertia, "transverse_inertia")
    js = check_positive(spin_inertia, "spin_inertia")
    q0 = quat_normalize(as_quat_array(q0, "q0"))
    w0 = as_vector_array(omega0_b, "omega0_b")
    if q0.shape != (4,) or w0.shape != (3,):
        raise ValueError("q0 must have shape (4,) and omega0_b shape (3,)")
    t = np.atleast_1d(np.asarray(t, dtype=np.float64))
    if t.ndim != 1 or not np.all(np.isfinite(t)):
        raise ValueError("t must be a 1-D array of finite times")
    h_b = np.array([jt * w0[0], jt * w0[1], js * w0[2]])
    h_n = quat_rotate(q0, h_b)
    sigma = w0[2] * (jt - js) / jt
    # Ω_p t ĥ_n = (t / J_t) H_n: no division by |H| (fine for H = 0 too)
    q_space = _exp_rotvec(np.outer(t, h_n) / jt)
    q_body = _exp_rotvec(np.outer(t, [0.0, 0.0, sigma]))
    q = _qmul(_qmul(q_space, np.broadcast_to(q0, q_space.shape)), q_body)
    # ω_b(t) = C_bn(t) H_n / J_t + σ e_z; C_bn(t) H_n = C(q_body)ᵀ H_b (the space rotation
    # is about H_n itself and leaves it unchanged)
    c, s = np.cos(sigma * t), np.sin(sigma * t)
    hx = c * h_b[0] + s * h_b[1]
    hy = -s * h_b[0] + c * h_b[1]
    omega = np.stack((hx / jt, hy / jt, np.full_like(t, h_b[2] / jt + sigma)), axis=-1)
    return q, omega


@dataclass(frozen=True)
class HeavyTop:
    """Heavy symmetric top: inertias about the fixed point and ``m g l`` (N·m)."""

    transverse_inertia: float
    spin_inertia: float
    mgl: float

    def __post_init__(self):
        check_positive(self.transverse_inertia, "transverse_inertia")
        check_positive(self.spin_inertia, "spin_inertia")
        check_finite(self.mgl, "mgl")


def heavy_top_state_from_euler(top: HeavyTop, theta: float, theta_dot: float, psi_dot: float,
                               phi_dot: float) -> tuple[np.ndarray, np.ndarray]:
    """``(H_b, Γ_b)`` from classical Euler angles (§1-1, φ = 0) and their rates.

    Body rates by (1-10) with φ = 0: p = θ̇, q = ψ̇ sin θ, r = ψ̇ cos θ + φ̇; the
    vertical in body axes is the third column of A = R1(θ): Γ = (0, sin θ, cos θ).
    """
    w = np.array([theta_dot, psi_dot * math.sin(theta), psi_dot * math.cos(theta) + phi_dot])
    h = np.array([top.transverse_inertia * w[0], top.transverse_inertia * w[1],
                  top.spin_inertia * w[2]])
    return h, np.array([0.0, math.sin(theta), math.cos(theta)])


def heavy_top_invariants(top: HeavyTop, h_b, gamma_b) -> dict[str, np.ndarray]:
    """Energy (J), ``p_psi = H·Γ``, ``p_phi = H_z`` (N·m·s) and ``gamma_norm = |Γ|``."""
    h = as_vector_array(h_b, "h_b")
    g = as_vector_array(gamma_b, "gamma_b")
    jt, js = top.transverse_inertia, top.spin_inertia
    energy = 0.5 * ((h[..., 0] ** 2 + h[..., 1] ** 2) / jt + h[..., 2] ** 2 / js) + top.mgl * g[..., 2]
    return {
        "energy": energy,
        "p_psi": np.sum(h * g, axis=-1),
        "p_phi": h[..., 2].copy(),
        "gamma_norm": np.linalg.norm(g, axis=-1),
    }


def heavy_top_nutation_bounds(top: HeavyTop, h_b, gamma_b) -> tuple[float, float]:
    """Turning points ``(u_min, u_max)`` of ``u = cos θ`` from the cubic f(u) (closed form).

    Returns the pair of real roots of f in [−1, 1] that brackets the current u.
    """
    inv = heavy_top_invariants(top, h_b, gamma_b)
    jt, js, mgl = top.transverse_inertia, top.spin_inertia, top.mgl
    a, b = float(inv["p_psi"]), float(inv["p_phi"])
    e1 = float(inv["energy"]) - b * b / (2 * js)
    u0 = float(np.asarray(gamma_b)[2])
    coeffs = [2 * jt * mgl, -(2 * jt * e1 + b * b), 2 * a * b - 2 * jt * mgl, 2 * jt * e1 - a * a]
    roots = np.roots(coeffs) if mgl != 0.0 else np.roots(coeffs[1:])
    real = np.sort(roots[np.abs(roots.imag) <= 1e-9 * max(1.0, np.max(np.abs(roots)))].real)
    # polish the companion-matrix roots with Newton steps (np.roots loses ~1e-11 here)
    dcoeffs = np.polyder(coeffs)
    for _ in range(3):
        d = np.polyval(dcoeffs, real)
        safe = np.abs(d) > 1e-300
        real = np.where(safe, real - np.polyval(coeffs, real) / np.where(safe, d, 1.0), real)
    # the motion lives where f(u) >= 0; u0 may itself be a root (a turning point), so pick
    # the pair of consecutive roots around u0 whose interior has f > 0
    tol = 1e-9
    for lo, hi in zip(real[:-1], real[1:], strict=True):
        if lo - tol <= u0 <= hi + tol and np.polyval(coeffs, 0.5 * (lo + hi)) > 0.0:
            return float(max(lo, -1.0)), float(min(hi, 1.0))
    # no interior with f > 0: a double root at u0 (regular precession, no nutation)
    return u0, u0


def integrate_heavy_top(top: HeavyTop, h0_b, gamma0_b, dt: float, n_steps: int,
                        record_every: int = 1, tol: float = 1e-15,
                        max_iter: int = 100) -> tuple[np.ndarray, np.ndarray]:
    """Implicit-midpoint integration of the heavy top (module docstring).

    Returns ``H_b`` and ``Γ_b`` of shape ``(n_steps // record_every + 1, 3)`` (the first
    row is the initial state).  Each step solves ``x_m = x₀ + (dt/2) f(x_m)`` by fixed-point
    iteration (contracting while ``dt·|ω| < 2``; raises ``ValueError`` if it does not
    converge) and sets ``x₁ = 2x_m − x₀``.  The loop runs on Python floats: the state is
    six numbers, for which numpy's per-call overhead would dominate.  The iteration stops at
    ``tol`` or when it stalls at the round-off floor (change < 1e-12 and not shrinking).
    """
    dt = check_positive(dt, "dt")
    n_steps = int(n_steps)
    record_every = int(record_every)
    if n_steps < 0 or record_every < 1:
        raise ValueError("n_steps must be >= 0 and record_every >= 1")
    h0 = as_vector_array(h0_b, "h0_b")
    g0 = as_vector_array(gamma0_b, "gamma0_b")
    if h0.shape != (3,) or g0.shape != (3,):
        raise ValueError("h0_b and gamma0_b must have shape (3,)")
    ijt, ijs, mgl = 1.0 / top.transverse_inertia, 1.0 / top.spin_inertia, top.mgl
    half = 0.5 * dt
    h1, h2, h3 = h0.tolist()
    g1, g2, g3 = g0.tolist()
    n_rec = n_steps // record_every + 1
    out_h = np.empty((n_rec, 3))
    out_g = np.empty((n_rec, 3))
    out_h[0] = h0
    out_g[0] = g0
    scale_h = max(abs(h1), abs(h2), abs(h3), 1e-300)
    rec = 1
    for k in range(1, n_steps + 1):
        m1, m2, m3, n1, n2, n3 = h1, h2, h3, g1, g2, g3
        err_prev = math.inf
        for _ in range(max_iter):
            w1, w2, w3 = m1 * ijt, m2 * ijt, m3 * ijs
            a1 = h1 + half * (m2 * w3 - m3 * w2 + mgl * n2)
            a2 = h2 + half * (m3 * w1 - m1 * w3 - mgl * n1)
            a3 = h3 + half * (m1 * w2 - m2 * w1)
            b1 = g1 + half * (n2 * w3 - n3 * w2)
            b2 = g2 + half * (n3 * w1 - n1 * w3)
            b3 = g3 + half * (n1 * w2 - n2 * w1)
            # change of the iterate, H relative to its initial size, Γ (a unit vector) absolute
            err = ((abs(a1 - m1) + abs(a2 - m2) + abs(a3 - m3)) / scale_h
                   + abs(b1 - n1) + abs(b2 - n2) + abs(b3 - n3))
            m1, m2, m3, n1, n2, n3 = a1, a2, a3, b1, b2, b3
            # converged, or stalled at the round-off floor (no further contraction)
            if err <= tol or (err < 1e-12 and err >= err_prev):
                break
            err_prev = err
        else:
            raise ValueError(f"heavy-top midpoint iteration did not converge at step {k}; "
                             "reduce dt")
        h1, h2, h3 = 2 * m1 - h1, 2 * m2 - h2, 2 * m3 - h3
        g1, g2, g3 = 2 * n1 - g1, 2 * n2 - g2, 2 * n3 - g3
        if k % record_every == 0:
            out_h[rec] = (h1, h2, h3)
            out_g[rec] = (g1, g2, g3)
            rec += 1
    return out_h, out_g
