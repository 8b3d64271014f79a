"""Sleeping top / spinning shell stability and g-sensitive drift against closed forms."""

import math

import numpy as np
import pytest

from gyro_attitude.core.earth import OMEGA_IE, gravity_enu
from gyro_attitude.core.instruments.mass_unbalance import (
    MassUnbalanceParams,
    UnbalancedGyro,
    g_sensitive_drift_rate,
)
from gyro_attitude.core.instruments.stability import (
    ShellParams,
    gyroscopic_stability_factor,
    shell_divergence_rate,
    shell_nutation_ratio,
    simulate_shell,
    sleeping_top_is_stable,
    sleeping_top_min_spin,
)
from gyro_attitude.core.motion import Stationary

C, A, N = 0.02, 0.2, 100.0  # kg·m², kg·m², rad/s: Cn = 2 N·m·s


def test_criteria_closed_forms():
    mgl = 3.0
    n_star = 2.0 * math.sqrt(A * mgl) / C
    assert sleeping_top_min_spin(C, A, mgl) == pytest.approx(n_star, rel=1e-15)
    assert sleeping_top_is_stable(C, 1.001 * n_star, A, mgl)
    assert not sleeping_top_is_stable(C, 0.999 * n_star, A, mgl)
    assert gyroscopic_stability_factor(C, N, A, 2.5) == pytest.approx(C * C * N * N / (4 * A * 2.5),
                                                                      rel=1e-15)
    assert gyroscopic_stability_factor(C, n_star, A, mgl) == pytest.approx(1.0, rel=1e-14)
    assert shell_nutation_ratio(4.0 / 3.0) == pytest.approx(2.0, rel=1e-15)
    assert shell_divergence_rate(C, N, A, 10.0) == pytest.approx(math.sqrt(8 - 4) / 0.4, rel=1e-15)
    assert shell_divergence_rate(C, N, A, 1.0) == 0.0


def test_shell_stays_up_for_s_above_one():
    """s = 1.2, released at 2°: θ nutates between θ₀ and θ₀/√(1 − 1/s) = 2.449 θ₀ (linear
    theory; 1 % covers the small-angle approximation at 5°), never beyond; invariants hold."""
    p = ShellParams.with_stability_factor(1.2, C, A, N)
    theta0 = math.radians(2.0)
    out = simulate_shell(p, theta0, duration=10.0, dt=5e-4)
    ratio = shell_nutation_ratio(1.2)
    assert ratio == pytest.approx(1.0 / math.sqrt(1.0 - 1.0 / 1.2), rel=1e-15)
    assert np.max(out.theta) == pytest.approx(ratio * theta0, rel=0.01)
    assert np.min(out.theta) == pytest.approx(theta0, rel=1e-3)
    for q in (out.energy, out.p_psi, out.p_phi):
        np.testing.assert_allclose(q, q[0], rtol=1e-12, atol=0)


def test_shell_tumbles_for_s_below_one():
    """s = 0.8: the angle of attack grows at σ = √(4AM_α − C²n²)/(2A) and passes 30°."""
    p = ShellParams.with_stability_factor(0.8, C, A, N)
    theta0 = math.radians(0.5)
    out = simulate_shell(p, theta0, duration=5.0, dt=5e-4)
    assert np.max(out.theta) > math.radians(30.0)
    # linear theory from rest: ξ = θ₀ e^{iβt} (cosh σt − i (β/σ) sinh σt), β = Cn/(2A), so
    # θ(t) = θ₀ √(cosh² σt + (β/σ)² sinh² σt); 2 % while θ < 3° (small-angle approximation)
    sigma = shell_divergence_rate(C, N, A, p.overturning_moment)
    beta = C * N / (2 * A)
    small = out.theta < math.radians(3.0)
    small[np.argmax(~small):] = False
    lin = theta0 * np.sqrt(np.cosh(sigma * out.t) ** 2 + (beta / sigma * np.sinh(sigma * out.t)) ** 2)
    assert np.count_nonzero(small) > 20
    np.testing.assert_allclose(out.theta[small], lin[small], rtol=0.02)


def test_sleeping_top_critical_spin_both_sides():
    """The same equations as the upright heavy top: 10 % above n* stays within a few θ₀,
    10 % below falls."""
    mgl = 2.0
    n_star = sleeping_top_min_spin(C, A, mgl)
    up = simulate_shell(ShellParams(C, A, mgl, 1.1 * n_star), math.radians(1.0), 10.0, dt=1e-3)
    down = simulate_shell(ShellParams(C, A, mgl, 0.9 * n_star), math.radians(1.0), 10.0, dt=1e-3)
    assert np.max(up.theta) < shell_nutation_ratio(1.21) * math.radians(1.0) * 1.02
    assert np.max(down.theta) > math.radians(30.0)


def test_g_sensitive_drift_rate_closed_form():
    ml, h = 2e-6, 0.5
    f = np.array([0.3, -0.2, 9.8])
    s = np.array([0.0, 2.0, 0.0])
    w = g_sensitive_drift_rate(ml, h, f, s)
    np.testing.assert_allclose(w, (ml / h) * np.array([0.3, 0.0, 9.8]), rtol=1e-15)
    # precession M/H with M = l s × (−m f)
    np.testing.assert_allclose(np.cross(w, [0.0, 1.0, 0.0]),
                               np.cross([0.0, 1.0, 0.0], -f) * ml / h, rtol=1e-15)


def test_unbalanced_gyro_drifts_about_vertical_at_mlg_over_h():
    """Level north-pointing rotor at rest at 30°N: azimuth rate = Ω sin L (apparent drift, east)
    − m l g / H (unbalance, north end toward the west)."""
    lat = math.radians(30.0)
    ml, h = 1e-6, 0.4
    g = float(-gravity_enu(lat)[2])
    t = np.arange(0.0, 60.0, 1.0)
    tt, s = UnbalancedGyro(MassUnbalanceParams(ml, h)).simulate(t, Stationary(), lat)
    az = np.unwrap(np.arctan2(s[:, 0], s[:, 1]))
    rate = np.polyfit(tt, az, 1)[0]
    # over 60 s the rotor stays level to 1e-7 rad: rate exact to ~1e-6
    assert rate == pytest.approx(OMEGA_IE * math.sin(lat) - ml * g / h, rel=1e-5)


def test_bad_inputs():
    with pytest.raises(ValueError, match="spin_rate"):
        ShellParams(C, A, 1.0, 0.0)
    with pytest.raises(ValueError, match="overturning_moment"):
        ShellParams(C, A, math.nan, 1.0)
    with pytest.raises(ValueError, match="theta0"):
        simulate_shell(ShellParams(C, A, 1.0, N), math.inf, 1.0)
    with pytest.raises(ValueError, match="dt"):
        simulate_shell(ShellParams(C, A, 1.0, N), 0.1, 1.0, dt=0.1)
    with pytest.raises(ValueError, match="stability_factor"):
        shell_nutation_ratio(0.9)
    with pytest.raises(ValueError, match="spin_axis"):
        g_sensitive_drift_rate(1e-6, 1.0, [0, 0, 9.8], [0, 0, 0])
    with pytest.raises(ValueError, match="angular_momentum"):
        MassUnbalanceParams(1e-6, 0.0)
