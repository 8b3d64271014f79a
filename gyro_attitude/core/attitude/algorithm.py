"""The Algorithm protocol, and the causal rate algorithms: each one's step a kernel,
:func:`body_increment` dispatching on its code."""

from __future__ import annotations

import math

import numpy as np

from gyro_attitude.core.attitude.compose import exp_scalar, qmul_scalar
from gyro_attitude.core.attitude.interpolation import GAUSS2, causal_fit_two
from gyro_attitude.core.jit import kernel

_SQRT3_12 = math.sqrt(3.0) / 12.0
_GA, _GB = GAUSS2
# the rate algorithms' codes (RateAlgorithm.code): plain ints, constants of the compiled code
QUAT1, DCM1, EXP, TRAP, CUBIC, RK4 = range(6)


class Algorithm:
    """One attitude update algorithm.

    Facts: ``name``; ``consumes`` ("rate": ω samples, "increment": angle increments Δθ);
    ``order`` (global order in the sample period on smooth motion with exact input);
    ``description``; ``cost``; ``causal`` (False: needs samples after the interval, batch
    only); ``samples_per_update`` (N of the N-sample coning algorithms); ``sequential``
    (True: a Python step per sample on a nonlinear state, :meth:`stepper`);
    ``supports_nav`` (False: q_ib only).  Batch behaviour: :meth:`integrate`, unless the
    step is a kernel (rate and increment algorithms: :mod:`.streaming`).
    """

    consumes = "rate"
    causal = True
    samples_per_update = 1
    sequential = False
    supports_nav = True
    #: True when the step checks its rate fit (and counts the intervals it could not trust)
    checks_rate_fit = False
    #: True when :meth:`integrate` takes ``out=`` (writes the attitudes into a given array)
    integrates_into = False

    def __init__(self, name: str, order: int, description: str, cost: str):
        self.name = name
        self.order = order
        self.description = description
        self.cost = cost

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.name}: {self.consumes}, order {self.order}>"

    def integrate(self, t, w, q0, rate_n, quadrature, singular_tol) -> np.ndarray:
        """Attitudes (N, 4) from checked rate samples ``w`` at times ``t`` (``rate_n``:
        ``ω_in^n``, (3,) or (N, 3), or None; ``quadrature``: a :class:`.coning.Quadrature`)."""
        raise NotImplementedError


class RateAlgorithm(Algorithm):
    """A causal quaternion algorithm on rate samples: interval k (sample k-1 to k) becomes a
    body increment ``b_k``, and ``q_k = normalize(exp(−ζ_k) ⊗ q_{k-1} ⊗ b_k)``.  Its step,
    ``increment(ts, ws, k, n)`` → ``(b_k, fell_back)`` on the first ``n`` ≤ 4 samples held,
    is the branch ``code`` of :func:`body_increment`.  ``checks_rate_fit``: the rate is
    fitted by a polynomial; the first interval's linear fit is redone with the quadratic
    through samples 0..2 once sample 2 is in, and the step falls back toward the exponential
    map where the fit cannot be trusted (:func:`.interpolation.untrusted_fit_scalar`).
    """

    integrates_into = True

    def __init__(self, name, order, description, cost, code: int, checks_rate_fit=False):
        super().__init__(name, order, description, cost)
        self.code = code
        self.checks_rate_fit = checks_rate_fit


@kernel
def quat_first_order_increment(ts, ws, k, n):
    """``q_k = normalize(q_{k-1} ⊗ [θ/2, 1])``, ``θ = ω_{k-1} h``: ``normalize([θ/2, 1])`` is
    the rotation by ``2·atan(|θ|/2)`` about θ."""
    h = (ts[k] - ts[k - 1]) * 1e-9
    x, y, z = 0.5 * ws[k - 1, 0] * h, 0.5 * ws[k - 1, 1] * h, 0.5 * ws[k - 1, 2] * h
    m = math.sqrt(x * x + y * y + z * z + 1.0)
    return (x / m, y / m, z / m, 1.0 / m), False


@kernel
def dcm_first_order_increment(ts, ws, k, n):
    """``C_k = orth(C_{k-1} (I + [θ×]))``, ``θ = ω_{k-1} h``, exact (polar)
    re-orthonormalization.  The polar factor of ``I + [θ×]`` is the rotation by ``atan(|θ|)``
    about θ — in the plane ⊥ θ, ``I + [θ×]`` acts as ``√(1+|θ|²)`` times a rotation by atan|θ|
    and along θ as 1.  Because ``C_{k-1}`` is orthogonal, ``polar(C_{k-1}(I+[θ×])) = C_{k-1}
    polar(I+[θ×])``, so "multiply, then re-orthonormalize by SVD/polar decomposition" equals
    composing these rotations (the tests check this against a literal matrix loop with
    ``scipy.linalg.polar``).  atan(x)/x by its series below 1e-4 (no 0/0)."""
    h = (ts[k] - ts[k - 1]) * 1e-9
    x, y, z = ws[k - 1, 0] * h, ws[k - 1, 1] * h, ws[k - 1, 2] * h
    mag = math.sqrt(x * x + y * y + z * z)
    scale = 1.0 - mag * mag / 3.0 if mag < 1e-4 else math.atan(mag) / mag
    return exp_scalar(x * scale, y * scale, z * scale), False


@kernel
def exp_map_increment(ts, ws, k, n):
    """``b_k = exp(½(ω_{k-1}+ω_k) h)``: exact for a constant rate of any magnitude; ignores
    non-commutativity (coning)."""
    h = (ts[k] - ts[k - 1]) * 1e-9
    return exp_scalar(0.5 * (ws[k - 1, 0] + ws[k, 0]) * h, 0.5 * (ws[k - 1, 1] + ws[k, 1]) * h,
                      0.5 * (ws[k - 1, 2] + ws[k, 2]) * h), False


@kernel
def trapezoid_increment(ts, ws, k, n):
    """``φ = ½(ω_{k-1}+ω_k)h + h²/12 ω_{k-1}×ω_k``: the rotation vector of the linear rate
    model (trapezoid increment plus its exact commutation term).  The trapezoid limits it to
    order 2 on general motion; the coning drift falls as h⁴."""
    h = (ts[k] - ts[k - 1]) * 1e-9
    ax, ay, az = ws[k - 1, 0], ws[k - 1, 1], ws[k - 1, 2]
    bx, by, bz = ws[k, 0], ws[k, 1], ws[k, 2]
    half, c = 0.5 * h, h * h / 12.0
    return exp_scalar(half * (ax + bx) + c * (ay * bz - az * by),
                      half * (ay + by) + c * (az * bx - ax * bz),
                      half * (az + bz) + c * (ax * by - ay * bx)), False


@kernel(inline=True)
def cubic_increment(ts, ws, k, n):
    """4th-order Magnus step on the causal cubic through the ``n`` samples held (k-3..k;
    Lagrange, any spacing): rates ``ω_a, ω_b`` at the two Gauss points,
    ``φ = h/2 (ω_a+ω_b) + √3/12 h² ω_a×ω_b`` (Gauss quadrature is exact for the cubic's
    increment; the cross term is its commutation correction).  The first two intervals take
    the linear/quadratic fit.  An untrusted fit moves φ toward the exponential map of the
    endpoint mean."""
    a, b, h, held = causal_fit_two(ts, ws, k, n, _GA, _GB)
    ax, ay, az = a
    bx, by, bz = b
    half, c = 0.5 * h, _SQRT3_12 * (h * h)
    px = half * (ax + bx) + c * (ay * bz - az * by)
    py = half * (ay + by) + c * (az * bx - ax * bz)
    pz = half * (az + bz) + c * (ax * by - ay * bx)
    if held > 0.0:  # toward the exponential map of the endpoint mean (hold_untrusted)
        u, v = ws[k - 1], ws[k]
        keep = 1.0 - held
        px = keep * px + held * (0.5 * (u[0] + v[0]) * h)
        py = keep * py + held * (0.5 * (u[1] + v[1]) * h)
        pz = keep * pz + held * (0.5 * (u[2] + v[2]) * h)
    return exp_scalar(px, py, pz), held > 0.0


@kernel(inline=True)
def _rk4_stage(p, scale, w0, w1, w2):
    """``½ (1 + scale·p) ⊗ [w, 0]``."""
    r = qmul_scalar((scale * p[0], scale * p[1], scale * p[2], 1.0 + scale * p[3]),
                    (w0, w1, w2, 0.0))
    return (0.5 * r[0], 0.5 * r[1], 0.5 * r[2], 0.5 * r[3])


@kernel
def quat_rk4_increment(ts, ws, k, n):
    """RK4 of ``q̇ = ½ q ⊗ [ω, 0]`` with ``ω(t_{k-1})``, the causal-cubic mid-step ``ω``,
    ``ω(t_k)``; normalized.

    Truncates the spin angle: error ~θ⁵/… per step for ``θ = |ω|h`` — fast spin punishes it.
    RK4 from ``q = 1``: since the right-hand side is linear under right multiplication, the
    step from any ``q`` is ``q ⊗ p`` with this ``p``.  Where the cubic cannot be trusted (near
    the Nyquist rate) all three rates move toward the endpoint mean (one constant rate: no
    commutation term)."""
    wm, _, h, held = causal_fit_two(ts, ws, k, n, 0.5, 0.5)
    a0, a1, a2 = ws[k - 1, 0], ws[k - 1, 1], ws[k - 1, 2]
    b0, b1, b2 = ws[k, 0], ws[k, 1], ws[k, 2]
    m0, m1, m2 = wm
    if held > 0.0:
        keep = 1.0 - held
        c0, c1, c2 = 0.5 * (a0 + b0), 0.5 * (a1 + b1), 0.5 * (a2 + b2)
        a0, a1, a2 = keep * a0 + held * c0, keep * a1 + held * c1, keep * a2 + held * c2
        m0, m1, m2 = keep * m0 + held * c0, keep * m1 + held * c1, keep * m2 + held * c2
        b0, b1, b2 = keep * b0 + held * c0, keep * b1 + held * c1, keep * b2 + held * c2
    k1 = (0.5 * a0, 0.5 * a1, 0.5 * a2, 0.0)
    k2 = _rk4_stage(k1, 0.5 * h, m0, m1, m2)
    k3 = _rk4_stage(k2, 0.5 * h, m0, m1, m2)
    k4 = _rk4_stage(k3, h, b0, b1, b2)
    c = h / 6.0
    p0 = c * (k1[0] + 2.0 * k2[0] + 2.0 * k3[0] + k4[0])
    p1 = c * (k1[1] + 2.0 * k2[1] + 2.0 * k3[1] + k4[1])
    p2 = c * (k1[2] + 2.0 * k2[2] + 2.0 * k3[2] + k4[2])
    p3 = c * (k1[3] + 2.0 * k2[3] + 2.0 * k3[3] + k4[3]) + 1.0
    m = math.sqrt(p0 * p0 + p1 * p1 + p2 * p2 + p3 * p3)
    return (p0 / m, p1 / m, p2 / m, p3 / m), held > 0.0


@kernel
def body_increment(alg, ts, ws, k, n):
    """The step of the rate algorithm ``alg`` over interval ``k`` of the first ``n`` samples
    held (``ts`` stamps, ``ws`` rates): (increment quaternion, whether its fit fell back)."""
    if alg == CUBIC:
        return cubic_increment(ts, ws, k, n)
    if alg == EXP:
        return exp_map_increment(ts, ws, k, n)
    if alg == RK4:
        return quat_rk4_increment(ts, ws, k, n)
    if alg == TRAP:
        return trapezoid_increment(ts, ws, k, n)
    if alg == QUAT1:
        return quat_first_order_increment(ts, ws, k, n)
    return dcm_first_order_increment(ts, ws, k, n)


QUAT_FIRST_ORDER = RateAlgorithm(
    "quat_first_order", 1, "quaternion q (x) [w h/2, 1], normalized (forward Euler)",
    "1 normalization + product per sample", QUAT1)
DCM_FIRST_ORDER = RateAlgorithm(
    "dcm_first_order", 1, "DCM C(I + [w h x]) (forward Euler) with exact re-orthonormalization",
    "1 exp map + product per sample", DCM1)
EXP_MAP = RateAlgorithm("exp_map", 2, "exact exponential map of the trapezoid increment (rate "
                        "held at the endpoint mean)", "1 exp map + product per sample", EXP)
ROTVEC_TRAPEZOID = RateAlgorithm(
    "rotvec_trapezoid", 2, "rotation vector: trapezoid increment + h^2/12 w0 x w1 commutation",
    "1 cross + exp map + product per sample", TRAP)
ROTVEC_CUBIC = RateAlgorithm(
    "rotvec_cubic", 4, "4th-order Magnus on the causal cubic (2 Gauss points + commutation)",
    "cubic weights + cross + exp map + product per sample", CUBIC, checks_rate_fit=True)
QUAT_RK4 = RateAlgorithm("quat_rk4", 4, "quaternion RK4, cubic-interpolated mid-step rate, "
                         "normalized", "cubic weights + 4 quaternion products per sample",
                         RK4, checks_rate_fit=True)
