"""Coning algorithms and the quadratures that feed them: drift against docs/equations.md theory,
orders, increments against the analytic integral."""

from __future__ import annotations

import math

import numpy as np
import pytest
from attitude_truth import (
    Q0,
    angle_between,
    coning_increments,
    coning_truth,
    ode_truth,
    smooth_increments,
    smooth_rate,
    uniform_times,
)
from scipy.spatial.transform import Rotation

from gyro_attitude.core.attitude import (
    CONING_DRIFT_RHO,
    increments_from_rates,
    integrate_batch,
    integrate_increments_batch,
)


@pytest.fixture(scope="module")
def smooth_truth():
    return ode_truth(Q0, np.array([0.0, 2.0]))[-1]


@pytest.mark.parametrize("algorithm,n_code", [("coning1", 1), ("coning1_prev", 0),
                                              ("coning2", 2), ("coning3", 3),
                                              ("coning4", 4)])
def test_coning_drift_matches_theory(algorithm, n_code):
    """Drift rate ρ_N α² Ω (Ωh)^{2N} (1/60 (Ωh)⁴ for one-plus-previous), ratio 0.8–1.25."""
    alpha, h_ns = 1e-3, 1_000_000
    h = h_ns * 1e-9
    checked = 0
    for per in (12, 24, 48):
        omega_c = 2 * math.pi / (per * h)
        n = per * 20
        t_ns = np.arange(n + 1, dtype=np.int64) * h_ns
        t = t_ns * 1e-9
        q_true, _ = coning_truth(alpha, omega_c, t)
        q = integrate_increments_batch(t_ns, coning_increments(alpha, omega_c, t), q_true[0],
                                       algorithm)
        err = (Rotation.from_quat(q_true).inv() * Rotation.from_quat(q)).as_rotvec()
        idx = np.arange(0, n + 1, per)  # whole cone periods (multiples of N samples)
        drift = np.linalg.norm(np.polyfit(t[idx], err[idx], 1)[0])
        rho, power = (1 / 60, 4) if n_code == 0 else (CONING_DRIFT_RHO[n_code], 2 * n_code)
        theory = rho * alpha**2 * omega_c * (omega_c * h) ** power
        if theory * t[-1] < 1e-12:  # below the float64 floor of the attitude error
            continue
        checked += 1
        assert 0.8 < drift / theory < 1.25, (per, drift, theory)
    assert checked >= 2


@pytest.mark.parametrize("quadrature,order", [("trapezoid", 2), ("cubic", 4)])
def test_quadrature_sets_order_for_increment_algorithms_fed_with_rates(quadrature, order,
                                                                      smooth_truth):
    errors = []
    for n in (200, 400, 800):
        t_ns = uniform_times(n, 2.0)
        q = integrate_batch(t_ns, smooth_rate(t_ns * 1e-9), Q0, "coning2",
                            quadrature=quadrature)
        errors.append(angle_between(q[-1], smooth_truth)[0])
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    np.testing.assert_allclose(orders, order, atol=0.15)


def test_increments_from_rates_against_analytic_integral():
    t_ns = uniform_times(400, 2.0)
    t = t_ns * 1e-9
    exact = smooth_increments(t[:-1], t[1:])
    trap = increments_from_rates(t_ns, smooth_rate(t), "trapezoid")
    cubic = increments_from_rates(t_ns, smooth_rate(t), "cubic")
    h = 2.0 / 400
    assert np.abs(trap - exact).max() < 2 * h**3 * 20  # O(h³) per interval
    assert np.abs(cubic - exact)[3:].max() < 1e-3 * np.abs(trap - exact).max()
