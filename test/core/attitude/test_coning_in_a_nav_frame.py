"""Increment (coning) algorithms in a navigation frame."""

import math

import numpy as np
import pytest
from attitude_truth import (
    Q0,
    angle_between,
    coning_increments,
    coning_truth,
    nav_rate_written_out,
)
from scipy.spatial.transform import Rotation

from gyro_attitude.core.attitude import (
    ALGORITHMS,
    NavFrame,
    StreamingIntegrator,
    integrate_batch,
    integrate_increments_batch,
)

INCR_ALGS = [a for a, i in ALGORITHMS.items() if i.consumes == "increment"]


@pytest.mark.parametrize("quadrature", ["trapezoid", "cubic"])
@pytest.mark.parametrize("algorithm", INCR_ALGS)
def test_body_at_rest_in_nav_stays_put(algorithm, quadrature):
    # Closed form: at rest in ENU the gyro measures C_bn ω_ie^n, constant, so every
    # increment and every ζ are exact and q_nb stays q0.  Ignoring (or adding) the nav rate
    # would turn it by ω_ie·T ≈ 7e-4 rad over these 10 s.
    lat = math.radians(35.0)
    n = 1001
    t_ns = np.arange(n, dtype=np.int64) * 10_000_000
    w = Rotation.from_quat(Q0).inv().apply(nav_rate_written_out(lat, 0.0, (0.0, 0.0, 0.0)))
    q = integrate_batch(t_ns, np.broadcast_to(w, (n, 3)), Q0, algorithm,
                        nav=NavFrame(lat), quadrature=quadrature)
    # round-off of 1000 quaternion products
    assert angle_between(q, np.broadcast_to(Q0, q.shape)).max() < 1e-12


# --------------------------------------------------------------------------------------------
# The first interval, the chunk boundary and one-sample-plus-previous, written out against the
# closed forms of docs/equations.md.

# Non-uniform steps [ns] so no rule can lean on equal spacing.
_STEPS_NS = np.array([10, 13, 8, 11, 9, 12, 10, 14, 7, 11, 10, 12], dtype=np.int64) * 1_000_000
# ω(t) = A + B t + C t² [rad/s]: a quadratic the cubic quadrature (and the quadratic through
# samples 0, 1, 2 that redoes interval 1) integrates exactly, the causal linear fit does not
# (its error over interval 1 is ~|C| h³/6 ≈ 1e-5 rad here).
_A = np.array([0.8, -0.5, 0.3])
_B = np.array([-4.0, 6.0, 3.0])
_C = np.array([50.0, 30.0, -60.0])


def _times(n):
    return np.concatenate(([0], np.cumsum(_STEPS_NS[: n - 1])))


def _poly_rate(t, axis=None):
    if axis is not None:  # a fixed axis: the same scalar profile along it
        return np.outer(1.0 + 6.0 * t - 50.0 * t**2, axis)
    return _A + np.outer(t, _B) + np.outer(t**2, _C)


def _poly_increments(t, axis=None):
    """Exact ∫ω dt over each interval (polynomial integral)."""
    t0, t1 = t[:-1], t[1:]
    if axis is not None:
        return np.outer((t1 - t0) + 3.0 * (t1**2 - t0**2) - 50.0 / 3.0 * (t1**3 - t0**3), axis)
    return (np.outer(t1 - t0, _A) + np.outer(t1**2 - t0**2, _B) / 2
            + np.outer(t1**3 - t0**3, _C) / 3)


def _stream(algorithm, t_ns, w, **kw):
    s = StreamingIntegrator(algorithm, Q0, quadrature="cubic", **kw)
    return np.array([s.update(int(tk), wk) for tk, wk in zip(t_ns, w, strict=True)])


_AXIS = np.array([2.0, -1.0, 2.0]) / 3.0


@pytest.mark.parametrize("path", ["batch", "stream"])
@pytest.mark.parametrize("n", [3, 4, 13])
@pytest.mark.parametrize("algorithm", INCR_ALGS)
def test_first_interval_emitted_causal_then_redone_fixed_axis(algorithm, n, path):
    # About a fixed axis every coning term vanishes and q_k = q0 ⊗ exp(θ(t_k) u) exactly.
    # q[1] is emitted from the causal linear fit (the trapezoid); once sample 2 is in,
    # interval 1 is redone with the quadratic through samples 0, 1, 2 (exact here), so every
    # later attitude is exact.  Without the redo q[2:] carry the ~1e-5 rad trapezoid error;
    # with the redo leaking into q[1] it would be exact instead of the trapezoid.
    t_ns = _times(n)
    t = t_ns * 1e-9
    w = _poly_rate(t, _AXIS)
    if path == "batch":
        q = integrate_batch(t_ns, w, Q0, algorithm, quadrature="cubic")
    else:
        q = _stream(algorithm, t_ns, w)
    r0 = Rotation.from_quat(Q0)
    theta = np.concatenate(([0.0], np.cumsum(_poly_increments(t, _AXIS) @ _AXIS)))
    exact = (r0 * Rotation.from_rotvec(np.outer(theta, _AXIS))).as_quat()
    trap1 = 0.5 * (w[0] + w[1]) * (t[1] - t[0])
    q1 = (r0 * Rotation.from_rotvec(trap1)).as_quat()
    assert angle_between(q[1], q1)[0] < 1e-14  # a few roundings of one product
    assert angle_between(q1, exact[1])[0] > 1e-6  # the two differ: the check can tell
    assert angle_between(q[2:], exact[2:]).max() < 1e-13  # rounding of ≤ 12 products


@pytest.mark.parametrize("path", ["batch", "stream"])
def test_one_plus_previous_written_out_with_redone_first_increment(path):
    # docs/equations.md: φ_k = Δθ_k + (1/12) Δθ_{k-1} × Δθ_k (φ_1 = Δθ_1), on a vector
    # quadratic rate whose cubic-quadrature increments are the exact integrals.  The emitted
    # q[1] uses the trapezoid; the chain (and the Δθ_1 in φ_2) the redone, exact increment.
    n = 13
    t_ns = _times(n)
    t = t_ns * 1e-9
    w = _poly_rate(t)
    if path == "batch":
        q = integrate_batch(t_ns, w, Q0, "coning1_prev", quadrature="cubic")
    else:
        q = _stream("coning1_prev", t_ns, w)
    d = _poly_increments(t)
    phi = d.copy()
    phi[1:] += np.cross(d[:-1], d[1:]) / 12.0
    chain = [Rotation.from_quat(Q0)]
    for p in phi:
        chain.append(chain[-1] * Rotation.from_rotvec(p))
    expected = Rotation.concatenate(chain).as_quat()
    expected[1] = (chain[0] * Rotation.from_rotvec(0.5 * (w[0] + w[1]) * (t[1] - t[0]))).as_quat()
    assert angle_between(q, expected).max() < 1e-13  # rounding of ≤ 12 products


@pytest.mark.parametrize("path", ["batch", "stream"])
@pytest.mark.parametrize("algorithm", INCR_ALGS)
def test_first_interval_in_nav_frame_takes_the_nav_rotation(algorithm, path):
    # A constant nav rate (fixed axis) and a fixed-axis body rate: the nav rotations multiply
    # on the left, the body ones on the right, each about one axis, so
    # q_k = exp(−ω_in^n (t_k − t_0)) ⊗ q0 ⊗ exp(θ(t_k) u) exactly; the emitted q[1] has the
    # trapezoid body increment and the same nav rotation ζ_1 = ω_in^n h_1 as the redone one.
    lat = math.radians(35.0)
    t_ns = _times(8)
    t = t_ns * 1e-9
    w = _poly_rate(t, _AXIS)
    nav = NavFrame(lat)
    if path == "batch":
        q = integrate_batch(t_ns, w, Q0, algorithm, nav=nav, quadrature="cubic")
    else:
        q = _stream(algorithm, t_ns, w, nav=nav)
    rate_n = nav_rate_written_out(lat, 0.0, (0.0, 0.0, 0.0))
    theta = np.concatenate(([0.0], np.cumsum(_poly_increments(t, _AXIS) @ _AXIS)))
    nav_turn = Rotation.from_rotvec(-np.outer((t_ns - t_ns[0]) * 1e-9, rate_n))
    exact = (nav_turn * Rotation.from_quat(Q0) * Rotation.from_rotvec(np.outer(theta, _AXIS)))
    h = (t_ns[1] - t_ns[0]) * 1e-9
    q1 = (nav_turn[1] * Rotation.from_quat(Q0)
          * Rotation.from_rotvec(0.5 * (w[0] + w[1]) * h)).as_quat()
    # ω_ie h ≈ 7e-7 rad per step: the checks resolve far below it (rounding of ≤ 8 products)
    assert angle_between(q[1], q1)[0] < 1e-14
    assert angle_between(q[2:], exact.as_quat()[2:]).max() < 1e-13


def _coning(n, alpha=0.05, per=48, h_ns=1_000_000):
    t_ns = np.arange(n, dtype=np.int64) * h_ns
    t = t_ns * 1e-9
    omega_c = 2 * math.pi / (per * h_ns * 1e-9)
    return t_ns, t, alpha, omega_c


@pytest.mark.parametrize("source", ["increments", "rates_trapezoid"])
def test_one_plus_previous_every_step_of_a_long_run(source):
    # Every step of a long run must rotate by docs/equations.md's
    # φ_k = Δθ_k + (1/12) Δθ_{k-1} × Δθ_k.  The coning term is ~(α Ωh)²/12 ≈ 3.6e-6 rad
    # here; a missing or misplaced Δθ_{k-1} changes a step by ≥ 4e-7 rad, against ~1e-16 of
    # rounding per step.
    n = 20_000
    t_ns, t, alpha, omega_c = _coning(n)
    if source == "increments":
        d = coning_increments(alpha, omega_c, t)
        q = integrate_increments_batch(t_ns, d, Q0, "coning1_prev")
    else:
        _, w = coning_truth(alpha, omega_c, t)
        d = 0.5 * (w[:-1] + w[1:]) * (np.diff(t_ns) * 1e-9)[:, None]  # h from int ns, as stated
        q = integrate_batch(t_ns, w, Q0, "coning1_prev", quadrature="trapezoid")
    phi = d.copy()
    phi[1:] += np.cross(d[:-1], d[1:]) / 12.0
    r = Rotation.from_quat(q)
    steps = (r[:-1].inv() * r[1:]).as_rotvec()
    np.testing.assert_allclose(steps, phi, rtol=0, atol=1e-14)  # rounding of two unit quats
    if source != "increments":
        return  # the drift law holds for exact increments only (docs/equations.md)
    # and the drift stays the closed form's: α²Ω(Ωh)⁴/60 over the run, sampled at whole
    # cone periods (per = 48 samples), ratio within the 0.8–1.25 of test_coning_drift
    q_true, _ = coning_truth(alpha, omega_c, t)
    err = (Rotation.from_quat(q_true).inv() * r).as_rotvec()
    idx = np.arange(0, n, 48)
    drift = np.linalg.norm(np.polyfit(t[idx], err[idx], 1)[0])
    theory = alpha**2 * omega_c * (omega_c * 1e-3) ** 4 / 60
    assert 0.8 < drift / theory < 1.25
