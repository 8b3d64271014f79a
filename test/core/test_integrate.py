"""Attitude integrators against closed-form truth, scipy oracles and each other.

Truth sources: the closed-form coning motion of DESIGN.md, constant-rate exact solutions
(``Rotation.from_rotvec``), and ``scipy.integrate.solve_ivp`` (DOP853, rtol 1e-13) of
``q̇ = ½ q ⊗ ω`` for smooth analytic rates — never the code under test.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.linalg import polar
from scipy.spatial.transform import Rotation

from gyro_attitude.core.attitude import (
    ALGORITHMS,
    CONING_DRIFT_RHO,
    DEFAULT_ALGORITHM,
    GimbalLockError,
    NavFrame,
    StreamingIntegrator,
    increments_from_rates,
    integrate_batch,
    integrate_increments_batch,
)
from gyro_attitude.core.earth import earth_rate_enu, nav_rate_enu

RATE_ALGS = [a for a, i in ALGORITHMS.items() if i.consumes == "rate"]
INCR_ALGS = [a for a, i in ALGORITHMS.items() if i.consumes == "increment"]
QUAT_RATE_ALGS = [a for a in RATE_ALGS if not ALGORITHMS[a].sequential]


# ----------------------------------------------------------------------------- truth helpers
def angle_between(q1, q2):
    """Attitude error in rad, computed with scipy (independent of rotation.py)."""
    r = Rotation.from_quat(np.atleast_2d(q1)).inv() * Rotation.from_quat(np.atleast_2d(q2))
    return np.linalg.norm(r.as_rotvec(), axis=-1)


def coning_truth(alpha, omega_c, t):
    """DESIGN.md classical coning, converted to scalar-last: attitude and body rate."""
    s, c = math.sin(alpha / 2), math.cos(alpha / 2)
    q = np.stack([np.zeros_like(t), s * np.cos(omega_c * t), s * np.sin(omega_c * t),
                  np.full_like(t, c)], axis=-1)
    w = np.stack([np.full_like(t, -2 * omega_c * s * s),
                  -omega_c * math.sin(alpha) * np.sin(omega_c * t),
                  omega_c * math.sin(alpha) * np.cos(omega_c * t)], axis=-1)
    return q, w


def coning_increments(alpha, omega_c, t):
    """DESIGN.md exact coning angle increments over [t_k, t_{k+1}]."""
    h = np.diff(t)
    tm = t[:-1] + h / 2
    s2 = math.sin(alpha / 2) ** 2
    sa = math.sin(alpha)
    return np.stack([-2 * omega_c * h * s2,
                     -2 * sa * np.sin(omega_c * h / 2) * np.sin(omega_c * tm),
                     2 * sa * np.sin(omega_c * h / 2) * np.cos(omega_c * tm)], axis=-1)


# Smooth "random" motion: sums of sinusoids with analytic integrals.
_A = np.array([[1.1, 0.7, -0.4], [0.5, -0.9, 0.8], [-0.6, 0.4, 1.3]])
_F = np.array([[1.3, 2.1, 0.7], [1.7, 0.9, 2.6], [0.8, 1.9, 1.1]]) * 2 * np.pi / 4
_P = np.array([[0.3, 1.1, 2.0], [0.7, 0.2, 1.5], [1.9, 0.4, 0.9]])


def smooth_rate(t, scale=1.0):
    t = np.asarray(t)[..., None, None]
    return scale * (_A * np.sin(_F * t + _P)).sum(-1)


def smooth_increments(t0, t1, scale=1.0):
    a, b = t0[..., None, None], t1[..., None, None]
    return scale * (_A * (np.cos(_F * a + _P) - np.cos(_F * b + _P)) / _F).sum(-1)


def _qmul_ref(p, q):
    """Hamilton product written out here (not the package's) for the ODE right-hand side."""
    px, py, pz, pw = p
    qx, qy, qz, qw = q
    return np.array([pw * qx + px * qw + py * qz - pz * qy,
                     pw * qy - px * qz + py * qw + pz * qx,
                     pw * qz + px * qy - py * qx + pz * qw,
                     pw * qw - px * qx - py * qy - pz * qz])


def ode_truth(q0, t_eval, scale=1.0):
    def f(t, q):
        return 0.5 * _qmul_ref(q, np.append(smooth_rate(t, scale), 0.0))

    sol = solve_ivp(f, (t_eval[0], t_eval[-1]), q0, method="DOP853", rtol=1e-13,
                    atol=1e-14, t_eval=t_eval)
    q = sol.y.T
    return q / np.linalg.norm(q, axis=1, keepdims=True)


Q0 = np.array([0.2, 0.1, -0.3, 0.9]) / np.linalg.norm([0.2, 0.1, -0.3, 0.9])


@pytest.fixture(scope="module")
def smooth_truth():
    return ode_truth(Q0, np.array([0.0, 2.0]))[-1]


def uniform_times(n_steps, duration_s):
    step = int(round(duration_s * 1e9 / n_steps))
    return np.arange(n_steps + 1, dtype=np.int64) * step


# ----------------------------------------------------------------------------- orders
@pytest.mark.parametrize("algorithm", list(ALGORITHMS))
def test_order_of_convergence(algorithm, smooth_truth):
    """Halving h divides the final error by 2^order (smooth motion, scipy truth)."""
    info = ALGORITHMS[algorithm]
    errors = []
    for n in (200, 400, 800):
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


# ----------------------------------------------------------------------------- closed forms
@pytest.mark.parametrize("algorithm,angle_per_step", [
    ("quat_first_order", lambda th: 2 * np.arctan(th / 2)),
    ("dcm_first_order", np.arctan),
    ("exp_map", lambda th: th),
    ("rotvec_trapezoid", lambda th: th),
    ("rotvec_cubic", lambda th: th),
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
    for alg in ("exp_map", "rotvec_trapezoid", "rotvec_cubic"):
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


# ----------------------------------------------------------------------------- coning
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


# ----------------------------------------------------------------------------- interfaces
def _stream(algorithm, t_ns, w, q0, nav=None, quadrature="trapezoid"):
    s = StreamingIntegrator(algorithm, q0, nav=nav, quadrature=quadrature)
    return np.array([s.update(int(t), x) for t, x in zip(t_ns, w, strict=True)])


@pytest.mark.parametrize("algorithm", list(ALGORITHMS))
def test_batch_equals_streaming(algorithm):
    rng = np.random.default_rng(3)
    n = 400
    t_ns = np.cumsum(rng.integers(800_000, 1_200_000, n)).astype(np.int64)
    w = smooth_rate(t_ns * 1e-9, scale=2.0)
    q0 = Q0 if algorithm != "euler_zxz_rk4" else Rotation.from_euler("ZXZ", [0.3, 1.2, -0.4]
                                                                     ).as_quat()
    q_batch = integrate_batch(t_ns, w, q0, algorithm)
    assert angle_between(q_batch, _stream(algorithm, t_ns, w, q0)).max() < 1e-12
    if not ALGORITHMS[algorithm].sequential:
        lat = np.linspace(0.5, 0.52, n)
        vel = np.column_stack((np.linspace(0, 250, n), np.full(n, 30.0), np.zeros(n)))
        nav = NavFrame(lat, height_m=np.linspace(0, 1000, n), velocity_enu=vel)
        q_batch = integrate_batch(t_ns, w, q0, algorithm, nav=nav)
        assert angle_between(q_batch, _stream(algorithm, t_ns, w, q0, nav)).max() < 1e-12
    if ALGORITHMS[algorithm].consumes == "increment":
        q_batch = integrate_batch(t_ns, w, q0, algorithm, quadrature="cubic")
        q_stream = _stream(algorithm, t_ns, w, q0, quadrature="cubic")
        assert angle_between(q_batch, q_stream).max() < 1e-12
        d = increments_from_rates(t_ns, w)
        s = StreamingIntegrator(algorithm, q0, t0_ns=int(t_ns[0]))
        q_stream = np.array([q0] + [s.update_increment(int(t), x) for t, x in zip(t_ns[1:], d,
                                                                                   strict=True)])
        q_batch = integrate_increments_batch(t_ns, d, q0, algorithm)
        assert angle_between(q_batch, q_stream).max() < 1e-12


@pytest.mark.parametrize("algorithm", [DEFAULT_ALGORITHM, "exp_map", "quat_rk4"])
def test_batch_equals_streaming_over_1e5_samples(algorithm):
    """The blocked prefix product reorders roundings; agreement must hold at length."""
    n = 100_000
    t_ns = np.arange(n, dtype=np.int64) * 1_000_000
    w = smooth_rate(t_ns * 1e-9, scale=3.0)
    q_batch = integrate_batch(t_ns, w, Q0, algorithm)
    q_stream = _stream(algorithm, t_ns, w, Q0)
    assert angle_between(q_batch, q_stream).max() < 1e-12


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


# ----------------------------------------------------------------------------- nav frame
def test_earth_rate_only_one_hour_at_rest():
    lat = math.radians(47.0)
    q_nb = Rotation.from_euler("ZYX", [0.8, 0.1, -0.05]).as_quat()
    n = 360_000  # 1 h at 100 Hz
    t_ns = np.arange(n + 1, dtype=np.int64) * 10_000_000
    w_ib_b = Rotation.from_quat(q_nb).inv().apply(earth_rate_enu(lat))
    q = integrate_batch(t_ns, np.broadcast_to(w_ib_b, (n + 1, 3)), q_nb,
                        nav=NavFrame(lat))
    assert angle_between(q, q_nb).max() < 1e-10
    assert np.abs(np.linalg.norm(q, axis=1) - 1).max() < 1e-12
    # Without the nav frame the same samples show the Earth turning (sanity of the case).
    q_i = integrate_batch(t_ns, np.broadcast_to(w_ib_b, (n + 1, 3)), q_nb)
    assert angle_between(q_i[-1], q_nb)[0] == pytest.approx(7.292115e-5 * 3600, rel=1e-6)


def test_moving_base_and_turning_body_time_series():
    """Vehicle flying north-east (latitude series) while the body yaws at constant rate."""
    n, h = 20_000, 0.01
    t_ns = np.arange(n + 1, dtype=np.int64) * 10_000_000
    t = t_ns * 1e-9
    v = np.array([200.0, 150.0, 0.0])
    lat = 0.6 + 150.0 * t / 6.37e6
    rate_n = nav_rate_enu(lat, 0.0, np.broadcast_to(v, (n + 1, 3)))
    w_nb_b = np.array([0.0, 0.0, 0.2])
    q_true = (Rotation.from_quat(Q0) * Rotation.from_rotvec(np.outer(t, w_nb_b)))
    w_ib_b = q_true.inv().apply(rate_n) + w_nb_b
    nav = NavFrame(lat, height_m=0.0, velocity_enu=np.broadcast_to(v, (n + 1, 3)))
    q = integrate_batch(t_ns, w_ib_b, Q0, DEFAULT_ALGORITHM, nav=nav)
    assert angle_between(q, q_true.as_quat()).max() < 1e-9
    assert h > 0


# ----------------------------------------------------------------------------- singularities
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


# ----------------------------------------------------------------------------- bad input
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


def test_streaming_reset_and_state():
    s = StreamingIntegrator(DEFAULT_ALGORITHM, t0_ns=None)
    assert s.last_t_ns is None and s.samples == 0
    s.update(0, (0.0, 0.0, 1.0))
    q = s.update(1_000_000_000, (0.0, 0.0, 1.0))
    assert angle_between(q, Rotation.from_rotvec([0, 0, 1.0]).as_quat())[0] < 1e-14
    s.reset(Q0, t_ns=5)
    assert s.samples == 1 and s.last_t_ns == 5
    np.testing.assert_array_equal(s.quaternion, Q0)
    q = s.update(5 + 500_000_000, (2.0, 0.0, 0.0))
    truth = (Rotation.from_quat(Q0) * Rotation.from_rotvec([1.0, 0, 0])).as_quat()
    assert angle_between(q, truth)[0] < 1e-14


@pytest.mark.parametrize("algorithm", QUAT_RATE_ALGS + ["coning2"])
def test_streaming_with_start_time_holds_first_rate_back(algorithm):
    """t0_ns without a rate: the first rate is held back to t0 (as the node starts)."""
    t_ns = np.array([0, 4_000_000, 9_000_000, 15_000_000, 20_000_000], dtype=np.int64)
    w = smooth_rate(t_ns * 1e-9, scale=2.0)
    s = StreamingIntegrator(algorithm, Q0, t0_ns=0)
    q_stream = np.array([Q0] + [s.update(int(t), x) for t, x in zip(t_ns[1:], w[1:],
                                                                      strict=True)])
    w_held = w.copy()
    w_held[0] = w[1]
    q_batch = integrate_batch(t_ns, w_held, Q0, algorithm)
    assert angle_between(q_batch, q_stream).max() < 1e-14


# ----------------------------------------------------------------------------- streaming fast path
def _random_steps(n, seed=11):
    rng = np.random.default_rng(seed)
    return np.cumsum(rng.integers(700_000, 1_300_000, n)).astype(np.int64)


def _nav_cases(n):
    lat = np.linspace(0.5, 0.52, n)
    vel = np.column_stack((np.linspace(0, 250, n), np.full(n, 30.0), np.zeros(n)))
    return [None, NavFrame(0.7, velocity_enu=(40.0, -10.0, 0.0)),
            NavFrame(lat, height_m=np.linspace(0, 1000, n), velocity_enu=vel)]


@pytest.mark.parametrize("algorithm", INCR_ALGS)
@pytest.mark.parametrize("n", [1, 2, 3, 4, 5, 6, 9, 23])
def test_coning_streaming_first_samples_and_partial_blocks_equal_batch(algorithm, n):
    """Short runs end inside an N-block (and before/at the first-interval redo)."""
    t_ns = _random_steps(n)
    w = smooth_rate(t_ns * 1e-9, scale=3.0)
    for quadrature in ("trapezoid", "cubic"):
        for nav in _nav_cases(n):
            q_batch = integrate_batch(t_ns, w, Q0, algorithm, nav=nav, quadrature=quadrature)
            q_stream = _stream(algorithm, t_ns, w, Q0, nav, quadrature)
            assert angle_between(q_batch, q_stream).max() < 1e-13, (quadrature, nav)
    if n > 1:
        d = smooth_increments(t_ns[:-1] * 1e-9, t_ns[1:] * 1e-9, scale=3.0)
        for nav in _nav_cases(n):
            s = StreamingIntegrator(algorithm, Q0, nav=nav, t0_ns=int(t_ns[0]))
            q_stream = np.array([Q0] + [s.update_increment(int(t), x)
                                        for t, x in zip(t_ns[1:], d, strict=True)])
            q_batch = integrate_increments_batch(t_ns, d, Q0, algorithm, nav=nav)
            assert angle_between(q_batch, q_stream).max() < 1e-13, nav


def test_every_quaternion_algorithm_streams_on_the_scalar_path():
    """Only the Euler-angle baselines keep a numpy step per sample; the rest must have the
    scalar streaming path (the batch == streaming tests then cover all of it)."""
    from gyro_attitude.core import attitude as integrate

    quaternion_algs = {name for name, info in ALGORITHMS.items() if not info.sequential}
    assert set(integrate._FAST_STREAMING) == quaternion_algs
    for name in quaternion_algs:
        assert StreamingIntegrator(name, Q0)._fast


@pytest.mark.parametrize("algorithm", INCR_ALGS)
def test_coning_streaming_reset_mid_block(algorithm):
    """reset() inside an open N-block drops the block: the stream restarts like a batch."""
    t_ns = _random_steps(40, seed=2)
    w = smooth_rate(t_ns * 1e-9, scale=2.0)
    for quadrature in ("trapezoid", "cubic"):
        s = StreamingIntegrator(algorithm, Q0, quadrature=quadrature)
        for t, x in zip(t_ns[:7], w[:7], strict=True):
            s.update(int(t), x)
        # reset without a time: the next sample is the new origin
        s.reset(Q0)
        q_stream = np.array([s.update(int(t), x) for t, x in zip(t_ns[7:], w[7:], strict=True)])
        q_batch = integrate_batch(t_ns[7:], w[7:], Q0, algorithm, quadrature=quadrature)
        assert angle_between(q_batch, q_stream).max() < 1e-13
        # reset with a time: the first rate is held back to it (as for t0_ns)
        s.reset(Q0, t_ns=int(t_ns[-1]) + 1_000_000)
        t2 = int(t_ns[-1]) + 1_000_000 + np.cumsum(np.full(9, 900_000))
        w2 = smooth_rate(t2 * 1e-9, scale=2.0)
        q_stream = np.array([s.update(int(t), x) for t, x in zip(t2, w2, strict=True)])
        t_all = np.concatenate(([int(t_ns[-1]) + 1_000_000], t2))
        q_batch = integrate_batch(t_all, np.vstack((w2[:1], w2)), Q0, algorithm,
                                  quadrature=quadrature)
        assert angle_between(q_batch[1:], q_stream).max() < 1e-13


def test_update_increment_bad_input():
    s = StreamingIntegrator("coning2")
    with pytest.raises(ValueError, match="start time"):
        s.update_increment(10, (0.0, 0.0, 0.0))
    s.reset(Q0, t_ns=0)
    with pytest.raises(ValueError, match="non-finite"):
        s.update_increment(10, (0.0, np.nan, 0.0))
    with pytest.raises(ValueError, match="shape"):
        s.update_increment(10, (0.0, 0.0))
    with pytest.raises(ValueError, match="not positive"):
        s.update_increment(0, (0.0, 0.0, 0.0))
    assert s.samples == 1 and s.last_t_ns == 0
    with pytest.raises(ValueError, match="consumes rate samples"):
        StreamingIntegrator("rotvec_cubic", t0_ns=0).update_increment(10, (0.0, 0.0, 0.0))


def test_streaming_nav_series_checked_and_bounded():
    nav = NavFrame(np.array([0.5, 0.51, 0.52]))
    s = StreamingIntegrator("coning2", nav=nav)
    for k in range(3):
        s.update(k * 1_000_000, (0.1, 0.0, 0.0))
    with pytest.raises(ValueError, match="sample 3 is beyond"):
        s.update(3_000_000, (0.1, 0.0, 0.0))
    with pytest.raises(ValueError, match="latitude"):
        StreamingIntegrator("coning2", nav=NavFrame(np.array([0.5, 2.0])))


# ----------------------------------------------------------------------------- update_nav
_LAT, _H = 0.87, 3000.0
_VELS = [(120.0, 0.0, 0.0), (84.9, 84.9, 1.0), (0.0, 120.0, -2.0)]


def _piecewise_velocity(n, switches):
    """(n, 3) ENU velocity: _VELS[j] from sample switches[j-1] on (switches ascending)."""
    vel = np.empty((n, 3))
    edges = [0, *switches, n]
    for j in range(len(edges) - 1):
        vel[edges[j]:edges[j + 1]] = _VELS[j]
    return vel


def _stream_switching(algorithm, t_ns, w, switches):
    s = StreamingIntegrator(algorithm, Q0, nav=NavFrame(_LAT, height_m=_H,
                                                        velocity_enu=_VELS[0]))
    out = []
    for k, (t, x) in enumerate(zip(t_ns, w, strict=True)):
        if k in switches:
            s.update_nav(NavFrame(_LAT, height_m=_H, velocity_enu=_VELS[switches.index(k) + 1]))
        out.append(s.update(int(t), x))
    return np.array(out)


@pytest.mark.parametrize("algorithm", [DEFAULT_ALGORITHM, "exp_map", "quat_rk4", "coning1_prev",
                                       "coning2", "coning3"])
def test_update_nav_mid_stream_equals_batch_with_piecewise_constant_series(algorithm):
    """update_nav before sample s == a NavFrame series holding the new values from s on."""
    n, switches = 300, [101, 218]
    t_ns = _random_steps(n, seed=5)
    w = smooth_rate(t_ns * 1e-9, scale=2.0)
    nav = NavFrame(_LAT, height_m=_H, velocity_enu=_piecewise_velocity(n, switches))
    q_batch = integrate_batch(t_ns, w, Q0, algorithm, nav=nav)
    q_stream = _stream_switching(algorithm, t_ns, w, switches)
    assert angle_between(q_batch, q_stream).max() < 1e-12
    # and the switch matters: the stale velocity differs by ~5e-6 rad at the end
    q_stale = integrate_batch(t_ns, w, Q0, algorithm,
                              nav=NavFrame(_LAT, height_m=_H, velocity_enu=_VELS[0]))
    assert angle_between(q_stale[-1], q_stream[-1])[0] > 1e-6


@pytest.mark.parametrize("algorithm", ["exp_map", "coning1"])
def test_update_nav_body_at_rest_in_n_stays_put(algorithm):
    """Closed form: a body at rest in a nav frame whose velocity steps measures
    ω_ib^b = C_bn ω_in^n(t); with the rate switched at the same samples the exponential map
    of the trapezoid increment cancels ζ exactly, so q_nb stays q0.  A stale velocity drifts
    by |Δω_en|·T."""
    n, switches = 400, [150, 290]
    t_ns = np.arange(n, dtype=np.int64) * 5_000_000  # 200 Hz, 2 s
    vel = _piecewise_velocity(n, switches)
    rate_n = nav_rate_enu(np.full(n, _LAT), np.full(n, _H), vel)
    w = Rotation.from_quat(Q0).inv().apply(rate_n)  # C_bn ω_in^n
    q = _stream_switching(algorithm, t_ns, w, switches)
    assert angle_between(q, np.broadcast_to(Q0, q.shape)).max() < 1e-13
    s = StreamingIntegrator(algorithm, Q0, nav=NavFrame(_LAT, height_m=_H,
                                                        velocity_enu=_VELS[0]))
    q_stale = [s.update(int(t), x) for t, x in zip(t_ns, w, strict=True)][-1]
    # trapezoid of the rate error over the two later segments (closed form)
    err = rate_n - rate_n[0]
    dt = 5e-3
    expected = np.linalg.norm(0.5 * (err[1:] + err[:-1]).sum(axis=0) * dt)
    assert angle_between(q_stale, Q0)[0] == pytest.approx(expected, rel=1e-6)
    assert expected > 5e-6


def test_update_nav_refuses_bad_values_and_keeps_its_frame():
    nav0 = NavFrame(_LAT, height_m=_H, velocity_enu=_VELS[0])
    s = StreamingIntegrator(DEFAULT_ALGORITHM, Q0, nav=nav0)
    for bad in (NavFrame(2.0), NavFrame(_LAT, velocity_enu=(np.nan, 0.0, 0.0)),
                NavFrame(np.array([0.5, 0.6])), (0.5, 0.0, 0.0)):
        with pytest.raises(ValueError):
            s.update_nav(bad)
        assert s.nav is nav0
    np.testing.assert_array_equal(s._nav_const, nav0.rate_enu())
    with pytest.raises(ValueError, match="NavFrame"):
        StreamingIntegrator(DEFAULT_ALGORITHM, Q0).update_nav(nav0)
