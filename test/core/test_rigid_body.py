"""Symmetric tops (textbook §4-1, §4-3, §4-4) against scipy's ODE solvers, closed forms and
conserved quantities."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.spatial.transform import Rotation

from gyro_attitude.core.rigid_body import (
    HeavyTop,
    free_symmetric_top,
    free_top_precession_rate,
    heavy_top_invariants,
    heavy_top_nutation_bounds,
    heavy_top_state_from_euler,
    integrate_heavy_top,
)


def _euler_rigid_body_oracle(q0, w0, inertia, t_eval):
    """Euler's equations + q̇ = ½ q ⊗ (ω, 0) integrated by scipy DOP853 (written here)."""
    inertia = np.asarray(inertia, dtype=float)

    def rhs(_, y):
        x, yq, z, w = y[:4]
        om = y[4:]
        p, q, r = om
        qdot = 0.5 * np.array([w * p + yq * r - z * q, w * q + z * p - x * r,
                               w * r + x * q - yq * p, -x * p - yq * q - z * r])
        hw = inertia * om
        wdot = -np.cross(om, hw) / inertia
        return np.concatenate((qdot, wdot))

    sol = solve_ivp(rhs, (0, t_eval[-1]), np.concatenate((q0, w0)), method="DOP853",
                    t_eval=t_eval, rtol=1e-12, atol=1e-13)
    assert sol.success
    return sol.y[:4].T, sol.y[4:].T


def test_free_symmetric_top_closed_form_matches_numerical_euler_equations():
    jt, js = 2.0, 3.5
    q0 = Rotation.from_euler("zyx", [0.3, -0.7, 1.1]).as_quat()
    w0 = np.array([0.4, -0.25, 3.0])
    t = np.linspace(0, 20, 401)
    q, w = free_symmetric_top(q0, w0, jt, js, t)
    q_ref, w_ref = _euler_rigid_body_oracle(q0, w0, [jt, jt, js], t)
    assert np.max(np.abs(w - w_ref)) < 1e-9
    ang = (Rotation.from_quat(q).inv() * Rotation.from_quat(q_ref)).magnitude()
    assert np.max(ang) < 1e-9


def test_free_top_symmetry_axis_precesses_about_h_at_h_over_jt():
    jt, js = 1.0, 0.4  # prolate, like a rotor seen about its diameter... any J works
    q0 = Rotation.from_rotvec([0.2, 0.1, -0.3]).as_quat()
    w0 = np.array([0.6, 0.0, 8.0])
    t = np.linspace(0, 10, 2001)
    # the oracle trajectory, not the closed form, provides the measured precession
    q_ref, _ = _euler_rigid_body_oracle(q0, w0, [jt, jt, js], t)
    h_n = Rotation.from_quat(q0).apply([jt * w0[0], jt * w0[1], js * w0[2]])
    h_hat = h_n / np.linalg.norm(h_n)
    axis = Rotation.from_quat(q_ref).apply([0, 0, 1])
    e1 = np.cross(h_hat, [1.0, 0, 0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(h_hat, e1)
    phase = np.unwrap(np.arctan2(axis @ e2, axis @ e1))
    rate = np.polyfit(t, phase, 1)[0]
    expected = free_top_precession_rate(np.linalg.norm(h_n), jt)
    assert expected == pytest.approx(np.linalg.norm(h_n) / jt, rel=1e-15)
    assert rate == pytest.approx(expected, rel=1e-8)
    # nutation angle (cone half-angle between H and the symmetry axis) stays constant
    cone = np.arccos(np.clip(axis @ h_hat, -1, 1))
    assert np.ptp(cone) < 1e-9


@pytest.fixture(scope="module")
def heavy_top_run():
    top = HeavyTop(transverse_inertia=1.0, spin_inertia=0.5, mgl=1.0)
    h0, g0 = heavy_top_state_from_euler(top, theta=0.6, theta_dot=0.3, psi_dot=0.5, phi_dot=18.0)
    dt, n = 1e-3, 100_000
    h, g = integrate_heavy_top(top, h0, g0, dt, n, record_every=5)
    return top, h0, g0, dt, n, h, g


def test_heavy_top_conserves_energy_and_both_momenta_over_1e5_steps(heavy_top_run):
    top, h0, g0, dt, n, h, g = heavy_top_run
    inv = heavy_top_invariants(top, h, g)
    for key in ("energy", "p_psi", "p_phi", "gamma_norm"):
        rel = np.max(np.abs(inv[key] - inv[key][0])) / abs(inv[key][0])
        assert rel < 1e-9, (key, rel)
    # not a frozen state: the top really moved (nutation and precession)
    assert np.ptp(g[:, 2]) > 1e-3 and np.ptp(g[:, 0]) > 0.5


def test_heavy_top_nutation_between_roots_of_the_cubic(heavy_top_run):
    top, h0, g0, dt, n, h, g = heavy_top_run
    u_min, u_max = heavy_top_nutation_bounds(top, h0, g0)
    u = g[:, 2]
    assert u_min < g0[2] < u_max
    # sampled every 5 ms the extremes are reached to within the sampling resolution
    assert u.min() >= u_min - 1e-9 and u.max() <= u_max + 1e-9
    assert u.min() == pytest.approx(u_min, abs=2e-5)
    assert u.max() == pytest.approx(u_max, abs=2e-5)


def test_heavy_top_trajectory_matches_scipy_dop853():
    top = HeavyTop(transverse_inertia=0.8, spin_inertia=0.3, mgl=2.0)
    h0, g0 = heavy_top_state_from_euler(top, 1.0, -0.4, 0.7, 9.0)
    dt, n = 2e-4, 10_000  # 2 s
    h, g = integrate_heavy_top(top, h0, g0, dt, n, record_every=100)

    def rhs(_, y):
        hh, gg = y[:3], y[3:]
        w = hh / np.array([0.8, 0.8, 0.3])
        return np.concatenate((np.cross(hh, w) + 2.0 * np.cross(gg, [0, 0, 1.0]), np.cross(gg, w)))

    t = np.arange(0, n + 1, 100) * dt
    sol = solve_ivp(rhs, (0, t[-1]), np.concatenate((h0, g0)), method="DOP853", t_eval=t,
                    rtol=1e-12, atol=1e-12)
    # implicit midpoint is second order: error ~ (ω dt)² ω T / 12 ≈ 1e-5 here
    assert np.max(np.abs(h - sol.y[:3].T)) < 2e-5
    assert np.max(np.abs(g - sol.y[3:].T)) < 2e-5


def test_pseudo_regular_precession_scaling_with_spin():
    """§4-3: a fast top started with θ̇ = ψ̇ = 0 nutates by Δu ≈ 2 J_t mgl sin²θ₀ / H² and
    precesses on average at mgl / H."""
    top = HeavyTop(transverse_inertia=1.0, spin_inertia=0.6, mgl=1.5)
    theta0 = 0.8
    du = []
    for spin in (40.0, 80.0, 160.0):
        h0, g0 = heavy_top_state_from_euler(top, theta0, 0.0, 0.0, spin)
        hz = h0[2]
        u_min, u_max = heavy_top_nutation_bounds(top, h0, g0)
        assert u_max == pytest.approx(np.cos(theta0), abs=1e-11)  # starts at a turning point
        du.append(u_max - u_min)
        approx = 2 * top.transverse_inertia * top.mgl * np.sin(theta0) ** 2 / hz**2
        # leading order in 1/H²; the next term is relatively O(J_t mgl / H²)
        assert du[-1] == pytest.approx(approx, rel=4 * top.transverse_inertia * top.mgl / hz**2)
        # mean precession rate from the integrated motion: ψ̇ = (p_ψ − p_φ u)/(J_t (1 − u²))
        nut_period = 2 * np.pi * top.transverse_inertia / hz
        dt = nut_period / 60
        n = int(40 * nut_period / dt)
        h, g = integrate_heavy_top(top, h0, g0, dt, n)
        inv = heavy_top_invariants(top, h0, g0)
        u = g[:, 2]
        psi_dot = (inv["p_psi"] - inv["p_phi"] * u) / (top.transverse_inertia * (1 - u**2))
        mean_rate = np.trapezoid(psi_dot, dx=dt) / (n * dt)
        assert mean_rate == pytest.approx(top.mgl / hz, rel=0.03)
    # amplitude ∝ 1/H²: doubling the spin divides it by ≈ 4
    assert du[0] / du[1] == pytest.approx(4.0, rel=0.02)
    assert du[1] / du[2] == pytest.approx(4.0, rel=0.005)


def test_bad_inputs_raise():
    with pytest.raises(ValueError, match="transverse_inertia"):
        HeavyTop(0.0, 1.0, 1.0)
    top = HeavyTop(1.0, 1.0, 1.0)
    with pytest.raises(ValueError, match="dt"):
        integrate_heavy_top(top, [0, 0, 1], [0, 0, 1], -1.0, 10)
    with pytest.raises(ValueError, match="omega0_b"):
        free_symmetric_top([0, 0, 0, 1], [np.nan, 0, 0], 1.0, 1.0, [0.0])
    with pytest.raises(ValueError, match="converge"):
        integrate_heavy_top(top, [0, 0, 1000.0], [0, 0.5, 0.8], 1.0, 3)
