"""Every attitude algorithm against closed-form truth and scipy oracles: orders of
convergence, constant-rate closed forms, singular Euler baselines, bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest
from attitude_truth import (
    INCR_ALGS,
    Q0,
    QUAT_RATE_ALGS,
    angle_between,
    coning_truth,
    ode_truth,
    smooth_increments,
    smooth_rate,
    uniform_times,
)
from scipy.linalg import polar
from scipy.spatial.transform import Rotation

from gyro_attitude.core.attitude import (
    ALGORITHMS,
    DEFAULT_ALGORITHM,
    GimbalLockError,
    NavFrame,
    StreamingIntegrator,
    integrate_batch,
    integrate_increments_batch,
)


@pytest.fixture(scope="module")
def smooth_truth():
    return ode_truth(Q0, np.array([0.0, 2.0]))[-1]


@pytest.mark.parametrize("algorithm", list(ALGORITHMS))
def test_order_of_convergence(algorithm, smooth_truth):
    """Halving h divides the final error by 2^order (smooth motion, scipy truth)."""
    info = ALGORITHMS[algorithm]
    errors = []
    # Sixth order reaches the truth's float floor at 800 steps: coarser steps for it.
    for n in ((200, 400, 800) if info.order <= 4 else (40, 80, 160)):
        t_ns = uniform_times(n, 2.0)
        t = t_ns * 1e-9
        if info.consumes == "rate":
            q = integrate_batch(t_ns, smooth_rate(t), Q0, algorithm)
        else:
            q = integrate_increments_batch(t_ns, smooth_increments(t[:-1], t[1:]), Q0,
                                           algorithm)
        errors.append(angle_between(q[-1], smooth_truth)[0])
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert errors[-1] > 1e-11  # still well above the truth's own error
    np.testing.assert_allclose(orders, info.order, atol=0.15)


def test_non_uniform_steps_keep_fourth_order():
    rng = np.random.default_rng(7)
    errors = []
    for n in (200, 400, 800):
        base = uniform_times(n, 2.0)
        jitter = rng.integers(-int(0.3e9 / n), int(0.3e9 / n), n + 1)
        jitter[[0, -1]] = 0
        t_ns = base + jitter
        t = t_ns * 1e-9
        truth = ode_truth(Q0, t)
        q = integrate_batch(t_ns, smooth_rate(t), Q0, "rotvec_cubic")
        # q[1] is emitted from the causal linear fit (one-off O(h³)); judge from sample 2 on
        errors.append(angle_between(q[2:], truth[2:]).max())
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(orders > 3.5), orders


@pytest.mark.parametrize("algorithm,angle_per_step", [
    ("quat_first_order", lambda th: 2 * np.arctan(th / 2)),
    ("dcm_first_order", np.arctan),
    ("exp_map", lambda th: th),
    ("rotvec_trapezoid", lambda th: th),
    ("rotvec_cubic", lambda th: th),
    ("magnus6_quintic", lambda th: th),
    # RK4 of exp(θ/2 u) keeps the series to 4th order: w = 1 − θ²/8 + θ⁴/384,
    # |v| = θ/2 − θ³/48; after normalization the angle is 2·atan2(|v|, w).
    ("quat_rk4", lambda th: 2 * np.arctan2(th / 2 - th**3 / 48, 1 - th**2 / 8 + th**4 / 384)),
])
def test_constant_rate_closed_form(algorithm, angle_per_step):
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    rate, n, h = 2.5, 1000, 0.01
    t_ns = uniform_times(n, n * h)
    q = integrate_batch(t_ns, np.tile(rate * axis, (n + 1, 1)), Q0, algorithm)
    steps = np.arange(n + 1)
    truth = (Rotation.from_quat(Q0) * Rotation.from_rotvec(
        np.outer(steps * angle_per_step(rate * h), axis))).as_quat()
    assert angle_between(q, truth).max() < 1e-12


def test_one_step_beyond_pi_is_exact():
    w = np.array([[0.0, 0.0, 0.0], [3.0, -2.0, 1.5], [3.0, -2.0, 1.5]])
    w[0] = w[1]
    t_ns = np.array([0, 1_000_000_000, 2_000_000_000])
    assert np.linalg.norm(w[1]) > math.pi
    truth = (Rotation.from_quat(Q0) * Rotation.from_rotvec(np.outer([0, 1, 2], w[1]))).as_quat()
    for alg in ("exp_map", "rotvec_trapezoid", "rotvec_cubic", "magnus6_quintic"):
        q = integrate_batch(t_ns, w, Q0, alg)
        assert angle_between(q, truth).max() < 1e-13, alg


@pytest.mark.parametrize("algorithm", QUAT_RATE_ALGS + INCR_ALGS)
def test_zero_and_tiny_rates(algorithm):
    n = 1000
    t_ns = uniform_times(n, 1.0)
    q = integrate_batch(t_ns, np.zeros((n + 1, 3)), Q0, algorithm)
    assert np.array_equal(q, np.tile(Q0, (n + 1, 1)))
    tiny = np.tile([1e-12, -2e-12, 0.5e-12], (n + 1, 1))
    q = integrate_batch(t_ns, tiny, (0, 0, 0, 1), algorithm)
    # the rotation vector of the result is the total angle: full relative accuracy
    rotvec = Rotation.from_quat(q[-1]).as_rotvec()
    np.testing.assert_allclose(rotvec, tiny[0] * 1.0, rtol=1e-9, atol=0)


def test_dcm_first_order_equals_literal_matrix_loop():
    """C ← C(I + [ω h ×]) then nearest rotation (scipy polar) each step, literally."""
    n = 300
    t_ns = uniform_times(n, 3.0)
    w = smooth_rate(t_ns * 1e-9, scale=3.0)
    h = 0.01
    c = Rotation.from_quat(Q0).as_matrix()
    mats = [c]
    for k in range(1, n + 1):
        x, y, z = w[k - 1] * h
        c = c @ (np.eye(3) + np.array([[0, -z, y], [z, 0, -x], [-y, x, 0]]))
        c = polar(c)[0]
        mats.append(c)
    q = integrate_batch(t_ns, w, Q0, "dcm_first_order")
    assert angle_between(q, Rotation.from_matrix(np.array(mats)).as_quat()).max() < 1e-12


def test_rate_algorithms_on_closed_form_coning():
    """Fourth-order rate algorithms converge on coning with the closed-form truth."""
    alpha, omega_c = 0.2, 2 * math.pi * 2
    errs = {}
    for n in (1000, 2000):
        t_ns = uniform_times(n, 5.0)
        t = t_ns * 1e-9
        q_true, w = coning_truth(alpha, omega_c, t)
        for alg in ("rotvec_cubic", "quat_rk4", "rotvec_trapezoid"):
            q = integrate_batch(t_ns, w, q_true[0], alg)
            errs.setdefault(alg, []).append(angle_between(q[2:], q_true[2:]).max())
    assert 14 < errs["rotvec_cubic"][0] / errs["rotvec_cubic"][1] < 18
    assert 14 < errs["quat_rk4"][0] / errs["quat_rk4"][1] < 18
    assert 3.5 < errs["rotvec_trapezoid"][0] / errs["rotvec_trapezoid"][1] < 4.5


@pytest.mark.slow
def test_norm_and_attitude_over_1e7_steps():
    n = 10_000_000
    t_ns = np.arange(n + 1, dtype=np.int64) * 100_000  # 10 kHz for 1000 s
    rate = np.array([0.7, -1.3, 2.1])
    q = integrate_batch(t_ns, np.broadcast_to(rate, (n + 1, 3)), Q0, "exp_map")
    assert np.abs(np.linalg.norm(q, axis=1) - 1.0).max() < 1e-13
    sel = np.arange(0, n + 1, 100_000)
    truth = (Rotation.from_quat(Q0) * Rotation.from_rotvec(np.outer(t_ns[sel] * 1e-9, rate))
             ).as_quat()
    # 1e7 exact steps: only rounding remains (~1e-16 per step, random walk).
    assert angle_between(q[sel], truth).max() < 1e-9


def test_euler_zxz_flagged_at_singularity_not_nan():
    """Coning passes the body z axis through the vertical: θ = 0 for z-x-z angles."""
    t_ns = uniform_times(2000, 2.0)
    q_true, w = coning_truth(0.3, 2 * math.pi, t_ns * 1e-9)
    with pytest.raises(GimbalLockError, match="singularity"):
        integrate_batch(t_ns, w, q_true[0], "euler_zxz_rk4")
    s = StreamingIntegrator("euler_zxz_rk4", q_true[0])
    with pytest.raises(GimbalLockError):
        for tk, wk in zip(t_ns, w, strict=True):
            assert np.all(np.isfinite(s.update(int(tk), wk)))
    # the quaternion methods sail through the same motion
    q = integrate_batch(t_ns, w, q_true[0], DEFAULT_ALGORITHM)
    assert angle_between(q, q_true).max() < 1e-8


def test_krylov_flagged_at_gamma_90():
    t_ns = uniform_times(1000, 1.0)
    w = np.tile([0.0, 2.0, 0.0], (1001, 1))  # pitch through +90°
    with pytest.raises(GimbalLockError):
        integrate_batch(t_ns, w, (0, 0, 0, 1), "euler_krylov_rk4")


def test_bad_input_raises_clear_errors():
    t_ns = np.array([0, 10, 10, 30], dtype=np.int64)
    w = np.zeros((4, 3))
    with pytest.raises(ValueError, match=r"t_ns\[2\] - t_ns\[1\] = 0 ns"):
        integrate_batch(t_ns, w)
    with pytest.raises(ValueError, match="not positive"):
        integrate_batch(np.array([0, 10, 5]), np.zeros((3, 3)))
    with pytest.raises(ValueError, match="integer nanoseconds"):
        integrate_batch(np.array([0.0, 1.0]), np.zeros((2, 3)))
    with pytest.raises(ValueError, match="shape"):
        integrate_batch(np.array([0, 10]), np.zeros((3, 3)))
    with pytest.raises(ValueError, match="non-finite"):
        integrate_batch(np.array([0, 10]), np.array([[0, 0, 0], [np.nan, 0, 0]]))
    with pytest.raises(ValueError, match="unknown algorithm"):
        integrate_batch(np.array([0, 10]), np.zeros((2, 3)), algorithm="magic")
    with pytest.raises(ValueError, match="zero norm"):
        integrate_batch(np.array([0, 10]), np.zeros((2, 3)), q0=(0, 0, 0, 0))
    with pytest.raises(ValueError, match="latitude"):
        integrate_batch(np.array([0, 10]), np.zeros((2, 3)), nav=NavFrame(2.0))
    for alg in (DEFAULT_ALGORITHM, "quat_rk4", "coning2"):
        s = StreamingIntegrator(alg)
        s.update(100, (0.0, 0.0, 0.0))
        with pytest.raises(ValueError, match="not positive"):
            s.update(100, (0.0, 0.0, 0.0))
        with pytest.raises(ValueError, match="not positive"):
            s.update(50, (0.0, 0.0, 0.0))
        with pytest.raises(ValueError, match="non-finite"):
            s.update(200, (0.0, np.inf, 0.0))
        assert s.samples == 1 and s.last_t_ns == 100


@pytest.mark.parametrize("algorithm", ["exp_map", "rotvec_cubic", "quat_rk4", "coning4",
                                       "magnus6_quintic", "quat_first_order"])
def test_rates_beyond_what_float64_integrates_are_one_error_not_nan_attitudes(algorithm):
    from gyro_attitude.core.attitude import integrate_batch

    t = np.arange(1, 101, dtype=np.int64) * 10**7
    w = np.full((100, 3), 0.1)
    w[50] = 1e300
    with np.errstate(all="ignore"), pytest.raises(ValueError, match="not finite from sample"):
        integrate_batch(t, w, algorithm=algorithm)
