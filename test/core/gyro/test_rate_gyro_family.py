"""Rate-gyro family (§4-2, §5-3): the cos β factor at zero cross-coupling, base angular
acceleration about the output axis, the integrating gyro, g-sensitive drift — each against a
closed form written here or an independent solver (scipy brentq / solve_ivp)."""

import math

import numpy as np
import pytest
from scipy import optimize
from scipy.integrate import solve_ivp

from gyro_attitude.core.gyro.rate_gyro import IntegratingGyroParams, RateGyroParams, RateGyroTriad


def _unit_step(t, wn, zeta):
    """Unit-step response of ω_n²/(s² + 2ζω_n s + ω_n²), ζ < 1, written out here."""
    wd = wn * math.sqrt(1 - zeta**2)
    return 1 - np.exp(-zeta * wn * t) * (np.cos(wd * t) + zeta / math.sqrt(1 - zeta**2) * np.sin(wd * t))


def test_cos_beta_factor_is_kept_at_zero_cross_coupling():
    """c = 0 removes only the ω_S leak: the steady output solves x = ω_I cos(k x) (module
    equation), solved by Brent's method; differs from ω_I by ~ω_I (kω_I)²/2 (up to 1 %)."""
    k = 0.1
    p = RateGyroParams(40.0, 0.7, cross_coupling=0.0, gimbal_gain_s=k)
    w = np.array([1.5, -0.8, 0.4])
    out = RateGyroTriad(p, 1e-3, initial="rest").step_block(np.tile(w, (3000, 1)))
    for ax in range(3):
        x = optimize.brentq(lambda x, ax=ax: x - w[ax] * np.cos(k * x), -10, 10, xtol=1e-15)
        # 3 s = 84 time constants 1/(ζω_n): transient gone; the foh predictor-corrector is
        # exact at a steady state
        assert out[-1, ax] == pytest.approx(x, rel=1e-12, abs=0)
        assert abs(x - w[ax]) > 5e-4 * abs(w[ax])


def test_base_angular_acceleration_about_the_output_axis_deflects_the_gimbal():
    """A step α of angular acceleration about z (the x gyro's output axis is −z) from rest:
    J(β̈ + ω̇_O) + Dβ̇ + Kβ = 0 with ω̇_O = −α gives β = (J α / K)·(unit step response); the
    indicated rate is K β / H.  foh samples a linear base rate exactly: round-off agreement."""
    h, j, d, kk = 0.02, 2e-5, 4e-3, 2.0
    p = RateGyroParams.from_physical(h, j, d, kk)
    alpha, dt = 3.0, 1e-4
    t = np.arange(3000) * dt
    w = np.zeros((t.size, 3))
    w[:, 2] = alpha * t
    gyro = RateGyroTriad(p, dt, initial="rest")
    out = gyro.step_block(w)
    wn, zeta = math.sqrt(kk / j), d / (2 * math.sqrt(kk * j))
    beta = j * alpha / kk * _unit_step(t, wn, zeta)
    np.testing.assert_allclose(out[:, 0], kk * beta / h, rtol=0, atol=1e-12 * np.max(kk * beta / h))
    assert gyro.gimbal_angles[0] == pytest.approx(beta[-1], rel=1e-10)
    # without the term the x gyro sees nothing (u = 0)
    p0 = RateGyroParams.from_physical(h, j, d, kk, output_axis_acceleration=False)
    assert np.all(RateGyroTriad(p0, dt, initial="rest").step_block(w)[:, 0] == 0.0)


def test_integrating_gyro_ramp_gives_the_closed_form_angle():
    """No spring: τθ̈ + θ̇ = ω_I, θ = Dβ/H.  Ramp ω_I = a t from rest:
    θ = a(t²/2 − τt + τ²(1 − e^{−t/τ})), and the gimbal angle β = (H/D)θ → (H/D)∫ω dt.
    Small H/D (cos β = 1 to round-off): exact discretization, round-off agreement."""
    h, j, d = 1e-9, 2e-4, 1e-1  # τ = 2 ms, H/D = 1e-8
    p = IntegratingGyroParams.from_physical(h, j, d)
    tau = j / d
    a, dt = 0.5, 1e-4
    t = np.arange(5000) * dt
    w = np.zeros((t.size, 3))
    w[:, 0] = a * t
    gyro = RateGyroTriad(p, dt, initial="rest")
    theta = gyro.step_block(w)[:, 0]
    want = a * (0.5 * t**2 - tau * t + tau**2 * (1 - np.exp(-t / tau)))
    np.testing.assert_allclose(theta, want, rtol=0, atol=1e-12 * want[-1])
    # long after τ the gimbal angle is (H/D)(∫ω dt − τ ω): the rate-integrating output
    assert gyro.gimbal_angles[0] == pytest.approx(h / d * (a * t[-1] ** 2 / 2 - tau * a * t[-1]),
                                                  rel=1e-9)


def test_integrating_gyro_with_large_deflection_matches_solve_ivp():
    """H/D = 1: cos β matters (β reaches ~0.6 rad).  Oracle: solve_ivp (DOP853, rtol 1e-12) of
    τθ̈ + θ̇ = ω_I cos θ.  The foh predictor-corrector is second order in dt: measured 4e-8 rad
    at dt = 1 ms; bound 2e-7."""
    tau, a = 0.05, 0.3
    p = IntegratingGyroParams(tau, gimbal_gain=1.0)
    dt = 1e-3
    t = np.arange(2001) * dt
    w = np.zeros((t.size, 3))
    w[:, 1] = a * t
    theta = RateGyroTriad(p, dt, initial="rest").step_block(w)[:, 1]
    sol = solve_ivp(lambda tt, y: [y[1], (a * tt * math.cos(y[0]) - y[1]) / tau], (0, t[-1]),
                    [0.0, 0.0], t_eval=t, method="DOP853", rtol=1e-12, atol=1e-14)
    assert sol.y[0, -1] > 0.5
    np.testing.assert_allclose(theta, sol.y[0], rtol=0, atol=2e-7)


def test_rate_gyro_g_sensitive_drift_is_ml_f_over_h():
    """At rest under a specific force f, the unbalance m·l reads a false rate −(m l/H) f_I on
    each input axis (§5-3)."""
    h, ml = 0.02, 1e-6
    p = RateGyroParams(30.0, 0.7, mass_unbalance=ml, spin_momentum=h)
    f = np.array([0.5, -2.0, 9.81])
    out = RateGyroTriad(p, 1e-3, initial="rest").step_block(np.zeros((3000, 3)), np.tile(f, (3000, 1)))
    # β ~ 5e-6 rad: cos β − 1 ~ 1e-11 of the reading
    np.testing.assert_allclose(out[-1], -ml * f / h, rtol=1e-9, atol=0)
    with pytest.raises(ValueError, match="specific_force"):
        RateGyroTriad(p, 1e-3).step_block(np.zeros((2, 3)))
    with pytest.raises(ValueError, match="spin_momentum"):
        RateGyroParams(30.0, 0.7, mass_unbalance=ml)


def test_integrating_gyro_blocks_resume_exactly_and_bad_parameters_raise():
    p = IntegratingGyroParams(0.01, gimbal_gain=0.5, cross_coupling=1.0)
    u = np.random.default_rng(2).normal(size=(600, 3))
    whole = RateGyroTriad(p, 1e-3).step_block(u)
    g = RateGyroTriad(p, 1e-3)
    parts = np.concatenate([g.step_block(u[a:b]) for a, b in ((0, 1), (1, 300), (300, 600))])
    assert np.array_equal(parts, whole)
    for kw, word in ((dict(time_constant_s=0.0), "time_constant_s"),
                     (dict(time_constant_s=1.0, gimbal_gain=math.inf), "gimbal_gain"),
                     (dict(time_constant_s=1.0, output_axis_acceleration="yes"),
                      "output_axis_acceleration")):
        with pytest.raises(ValueError, match=word):
            IntegratingGyroParams(**kw)
