"""The offline sixth-order Magnus algorithm (magnus6_quintic) against closed forms: constant
spin, polynomial rates about a fixed axis, coning, a spinning projectile, and its order."""

from __future__ import annotations

import math

import numpy as np
import pytest
from attitude_truth import (
    Q0,
    angle_between,
    coning_truth,
    ode_truth,
    smooth_rate,
    spinning_coning_truth,
    uniform_times,
)
from scipy.spatial.transform import Rotation

from gyro_attitude.core.attitude import ALGORITHMS, integrate_batch
from gyro_attitude.core.attitude.magnus6 import (
    GAUSS3,
    magnus6_rotation_vector,
    quintic_window_start,
)

ALG = "magnus6_quintic"
SPIN, ALPHA, CONE = 2 * math.pi * 50, math.radians(2.0), 2 * math.pi * 5  # the projectile


def _compose_exact(q0, rotvecs):
    """q0 ⊗ exp(φ_1) ⊗ exp(φ_2) ⊗ … with scipy (independent of the package's products)."""
    r = Rotation.from_quat(q0)
    out = [r.as_quat()]
    for step in Rotation.from_rotvec(rotvecs):
        r = r * step
        out.append(r.as_quat())
    return np.array(out)


def test_registered_as_offline_sixth_order():
    alg = ALGORITHMS[ALG]
    assert (alg.causal, alg.order, alg.consumes) == (False, 6, "rate")


def test_gauss_legendre_nodes_integrate_degree_five_exactly():
    """Closed form: ∫₀¹ x⁵ dx = 1/6 with weights 5/18, 8/18, 5/18 at the nodes."""
    w = np.array([5.0, 8.0, 5.0]) / 18.0
    for p in range(6):
        assert np.dot(w, np.asarray(GAUSS3) ** p) == pytest.approx(1.0 / (p + 1), rel=1e-14)


def test_window_is_centered_and_shifted_inward_at_the_ends():
    """Interval k (sample k-1 to k) fits samples k-3..k+2, i.e. two before its left end."""
    k = np.arange(1, 10)  # 10 samples
    np.testing.assert_array_equal(quintic_window_start(k, 10), [0, 0, 0, 1, 2, 3, 4, 4, 4])
    np.testing.assert_array_equal(quintic_window_start(np.arange(1, 4), 4), [0, 0, 0])


def test_constant_fast_spin_is_exact_on_irregular_stamps():
    """Constant rate of 50 rev/s (0.31 rad per step at 1 kHz): exact rotation, any spacing."""
    rng = np.random.default_rng(4)
    t_ns = np.cumsum(rng.integers(700_000, 1_300_000, 2001)).astype(np.int64)
    rate = SPIN * np.array([0.6, -0.48, 0.64])
    q = integrate_batch(t_ns, np.tile(rate, (t_ns.size, 1)), Q0, ALG)
    truth = _compose_exact(Q0, np.outer(np.diff(t_ns) * 1e-9, rate))
    # 2000 exact steps of up to 0.41 rad: only rounding remains (~1e-16 per step).
    assert angle_between(q, truth).max() < 1e-12


@pytest.mark.parametrize("n", [2, 3, 4, 5, 6, 7, 9])
def test_short_records_and_ends_exact_for_polynomial_rate_about_a_fixed_axis(n):
    """ω(t) = u·p(t) with p of degree ≤ min(n-1, 2) and a fixed axis u: the rotations
    commute, the truth is exp(u ∫p), and every fit of ≥ deg+1 samples reproduces p."""
    rng = np.random.default_rng(n)
    t_ns = np.cumsum(rng.integers(5_000_000, 15_000_000, n)).astype(np.int64)
    t = (t_ns - t_ns[0]) * 1e-9
    c = (1.5, -4.0, 30.0)[: min(n, 3)]
    p = sum(ci * t**i for i, ci in enumerate(c))
    integral = sum(ci * t ** (i + 1) / (i + 1) for i, ci in enumerate(c))
    u = np.array([2.0, -1.0, 2.0]) / 3.0
    q = integrate_batch(t_ns, np.outer(p, u), Q0, ALG)
    truth = (Rotation.from_quat(Q0) * Rotation.from_rotvec(np.outer(integral, u))).as_quat()
    assert angle_between(q, truth).max() < 1e-14


def test_magnus_step_with_exact_rates_on_spinning_projectile():
    """docs/equations.md check: exact rates at the Gauss points, 2 kHz, 10 s: ~2.6e-10 rad with the
    right-composition bracket [x, y] = −x × y (the + sign gives ~1.3e-3)."""
    rate_hz, dur = 2000, 10.0
    n = int(rate_hz * dur)
    h = 1.0 / rate_hz
    t = np.arange(n + 1) * h
    q_true, _ = spinning_coning_truth(ALPHA, CONE, SPIN, t)
    a = [spinning_coning_truth(ALPHA, CONE, SPIN, t[:-1] + c * h)[1] for c in GAUSS3]
    phi = magnus6_rotation_vector(*a, np.full((n, 1), h))
    q = _compose_exact(q_true[0], phi)
    err = angle_between(q[-1], q_true[-1])[0]
    assert err < 5e-10, err


@pytest.mark.parametrize("rate_hz,limit", [(1000, 1.5e-6), (2000, 2.5e-8)])
def test_spinning_projectile_final_error(rate_hz, limit):
    """Spin 50 rev/s + 2° coning at 5 Hz for 10 s.  Measured: 6.3e-7 rad at 1 kHz and
    9.9e-9 at 2 kHz (rotvec_cubic 5.8e-5 and 3.7e-6); limits ~2.5x above."""
    t_ns = np.arange(int(10 * rate_hz) + 1, dtype=np.int64) * (1_000_000_000 // rate_hz)
    q_true, w = spinning_coning_truth(ALPHA, CONE, SPIN, t_ns * 1e-9)
    err = angle_between(integrate_batch(t_ns, w, q_true[0], ALG)[-1], q_true[-1])[0]
    err_cubic = angle_between(integrate_batch(t_ns, w, q_true[0], "rotvec_cubic")[-1],
                              q_true[-1])[0]
    assert err < limit, err
    assert err < err_cubic / 50


def test_sixth_order_on_closed_form_coning():
    """Classical coning (closed form): halving h divides the max error by ~2⁶."""
    alpha, omega_c = 0.2, 2 * math.pi * 4
    errs = []
    for n in (500, 1000, 2000):
        t_ns = uniform_times(n, 5.0)
        q_true, w = coning_truth(alpha, omega_c, t_ns * 1e-9)
        errs.append(angle_between(integrate_batch(t_ns, w, q_true[0], ALG), q_true).max())
    orders = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert errs[-1] > 1e-12, errs  # above the float floor
    np.testing.assert_allclose(orders, 6.0, atol=0.2)


def test_sixth_order_on_irregular_stamps():
    """The fit is in time, not index: jittered stamps keep order ≈ 6 (scipy ODE truth)."""
    rng = np.random.default_rng(7)
    errors = []
    for n in (40, 80, 160):
        base = uniform_times(n, 2.0)
        jitter = rng.integers(-int(0.3e9 / n), int(0.3e9 / n), n + 1)
        jitter[[0, -1]] = 0
        t_ns = base + jitter
        t = t_ns * 1e-9
        q = integrate_batch(t_ns, smooth_rate(t), Q0, ALG)
        errors.append(angle_between(q, ode_truth(Q0, t)).max())
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(orders > 5.5), orders
