"""Attitude integration from gyro output: batch (vectorized) and streaming, same results.

Conventions (docs/conventions.md):

* Input samples are rate-gyro outputs ``ω_ib^b`` (rad/s, body frame, as
  ``sensor_msgs/Imu.angular_velocity`` carries them) at strictly increasing times
  ``t_ns`` (int64 nanoseconds, non-uniform steps allowed), or angle increments
  ``Δθ_k = ∫ ω_ib^b dt`` over ``(t_{k-1}, t_k]`` (rad) for the coning algorithms.
* Quaternions are scalar-last ``(x, y, z, w)``.  Without a navigation frame the result
  is ``q_ib`` (body to inertial, ``q_ib[0] = q0``); with ``nav=NavFrame(...)`` it is
  ``q_nb`` (body to local ENU) and each interval T is updated as
  ``q_nb(t+T) = exp(−ζ) ⊗ q_nb(t) ⊗ exp(φ)``, with ``φ`` the body rotation vector and
  ``ζ = ∫ ω_in^n dt`` (Earth rate plus transport rate, trapezoid over the endpoints).
* ``q[k]`` is the attitude at ``t_ns[k]``.

Every quaternion algorithm turns each interval ``k`` (from sample ``k-1`` to ``k``) into
a body increment ``b_k`` and a nav increment ``a_k = exp(−ζ_k)``, so that
``q_k = a_k ⊗ q_{k-1} ⊗ b_k``.  The batch interface computes all increments at once and
forms the products as a blocked prefix product (see :func:`_prefix_product`); the
streaming interface multiplies one increment per call.  Both normalize every output, so
they agree to rounding (~1e-16·√N; measured in the tests at 1e5 samples).  The Euler-angle
baselines are nonlinear in their state and run a Python loop in both interfaces.

Algorithms (name: consumes, global order in the step h, cost):

``euler_zxz_rk4``, ``euler_krylov_rk4`` (rate, 4)
    Seed (1-10) / (1-15) angle kinematics, classical RK4; the mid-step rate comes from
    the causal cubic through the last four samples.  Divides by sin θ / cos γ: raises
    :class:`~gyro_attitude.core.euler_kinematics.GimbalLockError` near the singularity.
    Sequential Python loop: tens of µs per sample.  Inertial frame only.
``dcm_first_order`` (rate, 1)
    ``C_k = orth(C_{k-1} (I + [θ×]))`` with ``θ = ω_{k-1} h`` (forward Euler) and exact
    (polar / SVD) re-orthonormalization; see :func:`_dcm_first_order_increment`.
``quat_first_order`` (rate, 1)
    ``q_k = normalize(q_{k-1} ⊗ [θ/2, 1])``, ``θ = ω_{k-1} h``.
``quat_rk4`` (rate, 4)
    RK4 of ``q̇ = ½ q ⊗ [ω, 0]`` with ``ω(t_{k-1})``, cubic mid-step ``ω``, ``ω(t_k)``;
    normalized each step.  Truncates the spin angle: error ~θ⁵/… per step for
    ``θ = |ω|h`` — fast spin punishes it.
``exp_map`` (rate, 2)
    Exact finite rotation of the rate held at the mean of the two endpoint samples
    (zero-order hold of the trapezoid increment): ``b_k = exp(½(ω_{k-1}+ω_k) h)``.
    Exact for a constant rate of any magnitude; ignores non-commutativity (coning).
``rotvec_trapezoid`` (rate, 2)
    Rotation vector of the linear rate model: ``φ = ½(ω_{k-1}+ω_k)h + h²/12 ω_{k-1}×ω_k``
    (trapezoid increment plus its exact commutation term).  The trapezoid limits it to
    order 2 for general motion; the coning drift falls as h⁴.
``rotvec_cubic`` (rate, 4)
    Fourth-order Magnus step on the causal cubic through samples k-3..k (Lagrange, any
    spacing): rates ``ω_a, ω_b`` at the two Gauss points,
    ``φ = h/2 (ω_a+ω_b) + √3/12 h² ω_a×ω_b`` (Gauss quadrature is exact for the cubic's
    increment; the cross term is its commutation correction).  First two intervals fall
    back to the linear/quadratic fit.
``coning1``, ``coning1_prev``, ``coning2``, ``coning3``, ``coning4`` (increment)
    Rotation vector from angle increments.  ``coning1``: ``φ = Δθ`` (drift
    α²Ω(Ωh)²/12); ``coning1_prev``: ``φ = Δθ_k + 1/12 Δθ_{k-1}×Δθ_k`` (α²Ω(Ωh)⁴/60);
    ``coningN``: compressed N-sample ``φ = ΣΔθ_i + (Σ_{i<N} k_i Δθ_i) × Δθ_N``, the
    attitude updated every N samples (drift ρ_N α²Ω(Ωh)^{2N}).  On general (non-coning)
    motion with exact increments the measured orders are 2, 3, 4, 3, 3: the N = 3, 4
    coefficients are tuned to pure coning and do not cancel the general h⁴ term.  The outputs between two
    N-sample updates use the j-sample formula on the j increments so far (j < N) and are
    not fed back.  Fed with rate samples, increments come from a stated quadrature
    (``"trapezoid"``: order 2; ``"cubic"``: the causal cubic integrated exactly,
    order 4); the coning coefficients assume exact increments and do not carry over.

The default (:data:`DEFAULT_ALGORITHM`) is ``rotvec_cubic``: the most accurate rate
algorithm in ``gyro-attitude bench`` at 1 kHz and above (order 4 on smooth motion, exact
for constant spin of any magnitude, coning drift ∝ h⁴), at ~0.4 µs per sample in batch
(2.3-2.6 M samples/s) and 6-9 µs per streaming call (scalar fast path) on the 2-core
development machine.  Its limit: a rate signal near the Nyquist frequency (e.g. 300 rad/s
spin sampled at 100 Hz, 3 rad per step) defeats the cubic fit, and the plain exponential
map of the trapezoid increment can then be more accurate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from gyro_attitude.core.earth import check_latitude, nav_rate_enu
from gyro_attitude.core.euler_kinematics import (
    GimbalLockError,
    euler_zxz_rates_from_body_rates,
    krylov_rates_from_body_rates,
    quat_as_euler_zxz,
    quat_as_krylov,
    quat_from_euler_zxz,
    quat_from_krylov,
)
from gyro_attitude.core.rotation import _exp_rotvec, _qmul, as_quat_array, as_vector_array

__all__ = [
    "AlgorithmInfo",
    "ALGORITHMS",
    "DEFAULT_ALGORITHM",
    "CONING_COEFFICIENTS",
    "CONING_DRIFT_RHO",
    "NavFrame",
    "GimbalLockError",
    "integrate_batch",
    "integrate_increments_batch",
    "increments_from_rates",
    "StreamingIntegrator",
]


@dataclass(frozen=True)
class AlgorithmInfo:
    """What an algorithm consumes, its order, and what it costs."""

    name: str
    consumes: str  # "rate" (ω samples) or "increment" (angle increments Δθ)
    order: int  # global order in the sample period for smooth motion with exact input
    description: str
    cost: str
    samples_per_update: int = 1  # N of the compressed N-sample coning algorithms
    sequential: bool = False  # True: Python loop per sample (nonlinear state update)


#: Compressed N-sample coning coefficients k_1..k_{N-1} (docs/equations.md).
CONING_COEFFICIENTS: dict[int, tuple[float, ...]] = {
    1: (),
    2: (2.0 / 3.0,),
    3: (9.0 / 20.0, 27.0 / 20.0),
    4: (54.0 / 105.0, 92.0 / 105.0, 214.0 / 105.0),
}
#: Coning drift coefficient ρ_N: drift ≈ ρ_N α² Ω (Ωh)^{2N} (h = sample period).
CONING_DRIFT_RHO: dict[int, float] = {1: 1 / 12, 2: 1 / 60, 3: 1 / 280, 4: 1 / 1260}

ALGORITHMS: dict[str, AlgorithmInfo] = {
    a.name: a
    for a in (
        AlgorithmInfo("euler_zxz_rk4", "rate", 4,
                      "z-x-z Euler angles (seed 1-10) integrated by RK4; singular at "
                      "theta = 0, pi", "Python loop, ~50-100 us/sample", sequential=True),
        AlgorithmInfo("euler_krylov_rk4", "rate", 4,
                      "Krylov angles (seed 1-15) integrated by RK4; singular at "
                      "gamma = +-90 deg", "Python loop, ~50-100 us/sample", sequential=True),
        AlgorithmInfo("dcm_first_order", "rate", 1,
                      "DCM C(I + [w h x]) (forward Euler) with exact re-orthonormalization",
                      "1 exp map + product per sample"),
        AlgorithmInfo("quat_first_order", "rate", 1,
                      "quaternion q (x) [w h/2, 1], normalized (forward Euler)",
                      "1 normalization + product per sample"),
        AlgorithmInfo("quat_rk4", "rate", 4,
                      "quaternion RK4, cubic-interpolated mid-step rate, normalized",
                      "cubic weights + 4 quaternion products per sample"),
        AlgorithmInfo("exp_map", "rate", 2,
                      "exact exponential map of the trapezoid increment (rate held at "
                      "the endpoint mean)", "1 exp map + product per sample"),
        AlgorithmInfo("rotvec_trapezoid", "rate", 2,
                      "rotation vector: trapezoid increment + h^2/12 w0 x w1 commutation",
                      "1 cross + exp map + product per sample"),
        AlgorithmInfo("rotvec_cubic", "rate", 4,
                      "4th-order Magnus on the causal cubic (2 Gauss points + commutation)",
                      "cubic weights + cross + exp map + product per sample"),
        AlgorithmInfo("coning1", "increment", 2,
                      "rotation vector = angle increment (no coning correction)",
                      "1 exp map + product per sample"),
        AlgorithmInfo("coning1_prev", "increment", 3,
                      "one-sample-plus-previous: dth_k + 1/12 dth_{k-1} x dth_k",
                      "1 cross + exp map + product per sample"),
        AlgorithmInfo("coning2", "increment", 4,
                      "compressed 2-sample coning (k = 2/3), update every 2 samples",
                      "cross + exp map per sample", samples_per_update=2),
        AlgorithmInfo("coning3", "increment", 3,
                      "compressed 3-sample coning (9/20, 27/20), update every 3 samples",
                      "cross + exp map per sample", samples_per_update=3),
        AlgorithmInfo("coning4", "increment", 3,
                      "compressed 4-sample coning (54, 92, 214)/105, update every 4 samples",
                      "cross + exp map per sample", samples_per_update=4),
    )
}
DEFAULT_ALGORITHM = "rotvec_cubic"
QUADRATURES = ("trapezoid", "cubic")

_IDENTITY = np.array([0.0, 0.0, 0.0, 1.0])
_CHUNK = 61440  # intervals per batch chunk: a multiple of 1..4 (N-sample blocks align)
_GAUSS_OFFSET = 0.5 / math.sqrt(3.0)  # Gauss-Legendre nodes at h(1/2 ∓ 1/(2√3))


def _check_algorithm(name: str) -> AlgorithmInfo:
    if name not in ALGORITHMS:
        raise ValueError(f"unknown algorithm {name!r}; choose one of {sorted(ALGORITHMS)}")
    return ALGORITHMS[name]


def _check_quadrature(name: str) -> str:
    if name not in QUADRATURES:
        raise ValueError(f"unknown quadrature {name!r}; choose one of {QUADRATURES}")
    return name


# --------------------------------------------------------------------------- nav frame
@dataclass(frozen=True)
class NavFrame:
    """Local ENU navigation frame whose rate ``ω_in^n = ω_ie^n + ω_en^n`` is removed.

    ``latitude_rad``, ``longitude_rad``, ``height_m`` (m above WGS-84) and
    ``velocity_enu`` (m/s, (3,)) are constants, or time series aligned with the samples
    (``(N,)`` and ``(N, 3)``).  Only latitude, height and velocity enter ``ω_in^n``.
    """

    latitude_rad: float | np.ndarray
    longitude_rad: float | np.ndarray = 0.0
    height_m: float | np.ndarray = 0.0
    velocity_enu: np.ndarray | tuple = field(default=(0.0, 0.0, 0.0))

    def rate_enu(self, n_samples: int | None = None) -> np.ndarray:
        """``ω_in^n`` in rad/s: shape (3,) for constants or (n_samples, 3) for series."""
        lat = check_latitude(self.latitude_rad)
        h = np.asarray(self.height_m, dtype=np.float64)
        v = np.asarray(self.velocity_enu, dtype=np.float64)
        if v.shape[-1:] != (3,):
            raise ValueError(f"velocity_enu must have shape (3,) or (N, 3), got {v.shape}")
        if not (np.all(np.isfinite(h)) and np.all(np.isfinite(v))):
            raise ValueError("NavFrame height_m / velocity_enu contain non-finite values")
        series = lat.ndim > 0 or h.ndim > 0 or v.ndim > 1
        if series:
            if n_samples is None:
                raise ValueError("NavFrame holds time series; the sample count is needed")
            for name, arr, nd in (("latitude_rad", lat, 0), ("height_m", h, 0),
                                  ("velocity_enu", v, 1)):
                if arr.ndim > nd and arr.shape[0] != n_samples:
                    raise ValueError(f"NavFrame.{name} has {arr.shape[0]} samples, "
                                     f"expected {n_samples} (one per gyro sample)")
            lat = np.broadcast_to(lat, (n_samples,))
            h = np.broadcast_to(h, (n_samples,))
            v = np.broadcast_to(v, (n_samples, 3))
        return nav_rate_enu(lat, h, v)


# --------------------------------------------------------------------------- validation
def _check_times(t_ns) -> np.ndarray:
    t = np.asarray(t_ns)
    if t.ndim != 1:
        raise ValueError(f"t_ns must be a 1-D array of int nanoseconds, got shape {t.shape}")
    if t.size and not np.issubdtype(t.dtype, np.integer):
        raise ValueError(f"t_ns must hold integer nanoseconds, got dtype {t.dtype}")
    t = t.astype(np.int64, copy=False)
    if t.size < 1:
        raise ValueError("t_ns is empty: at least one sample is needed")
    dt = np.diff(t)
    bad = np.flatnonzero(dt <= 0)
    if bad.size:
        k = int(bad[0]) + 1
        raise ValueError(f"time step t_ns[{k}] - t_ns[{k - 1}] = {int(dt[k - 1])} ns is not "
                         "positive: samples must be strictly increasing in time")
    return t


def _check_q0(q0) -> np.ndarray:
    q = as_quat_array(q0, "q0")
    if q.shape != (4,):
        raise ValueError(f"q0 must have shape (4,), got {q.shape}")
    n = float(np.linalg.norm(q))
    if n < 1e-12:
        raise ValueError("q0 has zero norm")
    return q / n


# --------------------------------------------------------------------------- prefix product
def _normalize_rows(q: np.ndarray) -> np.ndarray:
    return q / np.sqrt(np.einsum("...i,...i->...", q, q))[..., None]


def _prefix_product(d: np.ndarray) -> np.ndarray:
    """Inclusive right prefix product ``P_k = d_0 ⊗ d_1 ⊗ … ⊗ d_k`` of unit quaternions.

    Blocked scan (a hand-written scan because numpy has no associative scan for a
    non-commutative product): the M factors are laid out as ``L ≈ √M`` rows of ``B``
    blocks; one vectorized quaternion product per row scans all blocks at once (L numpy
    calls on length-B arrays), the B block totals are scanned recursively, and each block
    is multiplied by the normalized product of the blocks before it.  Work O(M), numpy
    calls O(√M).  The result differs from the left-to-right sequential product only by
    rounding reassociation (~1e-16 per factor, random-walk).
    """
    m = d.shape[0]
    if m <= 48:
        out = np.empty_like(d)
        if m == 0:
            return out
        ax, ay, az, aw = (float(c) for c in d[0])
        out[0] = d[0]
        for i in range(1, m):
            bx, by, bz, bw = (float(c) for c in d[i])
            ax, ay, az, aw = (aw * bx + ax * bw + ay * bz - az * by,
                              aw * by - ax * bz + ay * bw + az * bx,
                              aw * bz + ax * by - ay * bx + az * bw,
                              aw * bw - ax * bx - ay * by - az * bz)
            out[i] = (ax, ay, az, aw)
        return out
    rows = max(8, int(math.sqrt(m)))
    nb = -(-m // rows)
    pad = nb * rows - m
    if pad:
        d = np.concatenate((d, np.tile(_IDENTITY, (pad, 1))))
    # (4, rows, nb): component c of factor j of block b; each row slice is contiguous.
    x = np.ascontiguousarray(d.reshape(nb, rows, 4).transpose(2, 1, 0))
    X, Y, Z, W = x[0], x[1], x[2], x[3]
    for j in range(1, rows):
        ax, ay, az, aw = X[j - 1], Y[j - 1], Z[j - 1], W[j - 1]
        bx, by, bz, bw = X[j], Y[j], Z[j], W[j]
        nx = aw * bx + ax * bw + ay * bz - az * by
        ny = aw * by - ax * bz + ay * bw + az * bx
        nz = aw * bz + ax * by - ay * bx + az * bw
        W[j] = aw * bw - ax * bx - ay * by - az * bz
        X[j], Y[j], Z[j] = nx, ny, nz
    totals = np.ascontiguousarray(x[:, rows - 1, :].T)  # (nb, 4)
    before = np.empty_like(totals)
    before[0] = _IDENTITY
    if nb > 1:
        # Renormalize at block boundaries so the rounding of one block cannot scale the next.
        before[1:] = _normalize_rows(_prefix_product(totals[:-1]))
    res = _qmul(before[None, :, :], x.transpose(1, 2, 0))  # (rows, nb, 4)
    return res.transpose(1, 0, 2).reshape(nb * rows, 4)[:m]


def _prefix_product_left(a: np.ndarray) -> np.ndarray:
    """``A_k = a_k ⊗ … ⊗ a_0`` as ``conj(prefix(conj(a)))`` (conjugation reverses order)."""
    conj = a * np.array([-1.0, -1.0, -1.0, 1.0])
    return _prefix_product(conj) * np.array([-1.0, -1.0, -1.0, 1.0])


# --------------------------------------------------------------------------- interpolation
def _lagrange_eval(x_nodes: np.ndarray, y_nodes: np.ndarray, x_eval: np.ndarray) -> np.ndarray:
    """Evaluate the interpolating polynomial through ``(x_nodes, y_nodes)``.

    ``x_nodes`` (M, n) in s, ``y_nodes`` (M, n, 3), ``x_eval`` (M, p) → (M, p, 3).  Each
    row has its own (non-uniform) nodes; Lagrange form, n ≤ 4 so the O(n²) weights are
    cheap and exact enough (nodes are distinct, spacing ≥ 1 ns).
    """
    n = x_nodes.shape[1]
    out = np.zeros(x_eval.shape + (3,))
    for i in range(n):
        w = np.ones(x_eval.shape)
        for j in range(n):
            if j != i:
                w = w * (x_eval - x_nodes[:, j:j + 1]) / (x_nodes[:, i:i + 1] - x_nodes[:, j:j + 1])
        out += w[..., None] * y_nodes[:, None, i, :]
    return out


def _rate_at_fractions(t_ns: np.ndarray, omega: np.ndarray, k: np.ndarray,
                       fractions: tuple[float, ...], lookahead: bool = False) -> np.ndarray:
    """Causal cubic (samples k-3..k) rates at ``t_{k-1} + f h_k`` for intervals ``k``.

    ``k`` holds interval indices ≥ 1 (interval k runs from sample k-1 to k).  Intervals
    with fewer than four samples behind them use the quadratic (k = 2) or linear (k = 1)
    fit.  Times are taken relative to ``t_{k-1}`` from int64 differences, so long
    recordings lose no precision.  Returns (len(k), len(fractions), 3).

    ``lookahead=True`` fits the first interval (k = 1) with the quadratic through
    samples 0, 1, 2 when they exist.  The linear fit there leaves a one-off O(h³) error
    that would cap every fourth-order method at order 3; both interfaces emit ``q[1]``
    from the causal linear fit and then, once sample 2 is in, redo interval 1 with this
    fit before going on (see ``_uses_rate_fit``).
    """
    out = np.empty((k.size, len(fractions), 3))
    fr = np.asarray(fractions, dtype=np.float64)
    first_fix = lookahead and t_ns.size >= 3
    for n_nodes in (2, 3, 4):
        sel = (np.minimum(k, 3) + 1) == n_nodes
        if first_fix:
            sel = (sel & (k != 1)) | ((k == 1) & (n_nodes == 3))
        if not np.any(sel):
            continue
        kk = k[sel]
        idx = kk[:, None] + np.arange(1 - n_nodes, 1)[None, :]  # (m, n_nodes)
        if first_fix and n_nodes == 3:
            idx = np.where((kk == 1)[:, None], np.arange(3)[None, :], idx)
        x = (t_ns[idx] - t_ns[kk - 1][:, None]) * 1e-9
        h = (t_ns[kk] - t_ns[kk - 1]) * 1e-9
        out[sel] = _lagrange_eval(x, omega[idx], h[:, None] * fr[None, :])
    return out


# --------------------------------------------------------------------------- increments
def _exp_scaled_first_order(theta: np.ndarray, kind: str) -> np.ndarray:
    """Body increments of the first-order methods as exact rotations.

    ``quat``: ``normalize([θ/2, 1])`` is the rotation by ``2·atan(|θ|/2)`` about θ.
    ``dcm``: the polar factor of ``I + [θ×]`` is the rotation by ``atan(|θ|)`` about θ —
    in the plane ⊥ θ, ``I + [θ×]`` acts as ``√(1+|θ|²)`` times a rotation by atan|θ| and
    along θ as 1.  Because ``C_{k-1}`` is orthogonal, ``polar(C_{k-1}(I+[θ×])) =
    C_{k-1} polar(I+[θ×])``, so the classical "multiply, then re-orthonormalize by
    SVD/polar decomposition" update equals composing these rotations (the tests check
    this against a literal matrix loop with ``scipy.linalg.polar``).
    """
    if kind == "quat":
        half = 0.5 * theta
        q = np.concatenate((half, np.ones(theta.shape[:-1] + (1,))), axis=-1)
        return _normalize_rows(q)
    mag = np.sqrt(np.einsum("...i,...i->...", theta, theta))
    small = mag < 1e-4
    safe = np.where(small, 1.0, mag)
    # atan(x)/x = 1 - x²/3 + x⁴/5 - … ; series below 1e-4 avoids 0/0.
    scale = np.where(small, 1.0 - mag * mag / 3.0, np.arctan(safe) / safe)
    return _exp_rotvec(theta * scale[..., None])


def _rate_body_increments(algorithm: str, t_ns: np.ndarray, omega: np.ndarray,
                          k: np.ndarray, lookahead: bool = False) -> np.ndarray:
    """Body quaternion increments ``b_k`` of a rate algorithm for intervals ``k`` (M, 4)."""
    h = ((t_ns[k] - t_ns[k - 1]) * 1e-9)[:, None]
    w0 = omega[k - 1]
    w1 = omega[k]
    if algorithm == "quat_first_order":
        return _exp_scaled_first_order(w0 * h, "quat")
    if algorithm == "dcm_first_order":
        return _exp_scaled_first_order(w0 * h, "dcm")
    if algorithm == "exp_map":
        return _exp_rotvec(0.5 * (w0 + w1) * h)
    if algorithm == "rotvec_trapezoid":
        return _exp_rotvec(0.5 * (w0 + w1) * h + (h * h / 12.0) * np.cross(w0, w1))
    if algorithm == "rotvec_cubic":
        g = _rate_at_fractions(t_ns, omega, k, (0.5 - _GAUSS_OFFSET, 0.5 + _GAUSS_OFFSET),
                               lookahead)
        wa, wb = g[:, 0], g[:, 1]
        phi = 0.5 * h * (wa + wb) + (math.sqrt(3.0) / 12.0) * (h * h) * np.cross(wa, wb)
        return _exp_rotvec(phi)
    if algorithm == "quat_rk4":
        wm = _rate_at_fractions(t_ns, omega, k, (0.5,), lookahead)[:, 0]
        return _normalize_rows(_rk4_quat_increment(w0, wm, w1, h))
    raise AssertionError(algorithm)


def _pure(w: np.ndarray) -> np.ndarray:
    return np.concatenate((w, np.zeros(w.shape[:-1] + (1,))), axis=-1)


def _rk4_quat_increment(w0, wm, w1, h):
    """RK4 for ``q̇ = ½ q ⊗ ω`` from ``q = 1``; since the right-hand side is linear under
    right multiplication, the step from any ``q`` is ``q ⊗ p`` with this ``p``."""
    one = np.zeros(w0.shape[:-1] + (4,))
    one[..., 3] = 1.0
    p0, pm, p1 = _pure(w0), _pure(wm), _pure(w1)
    k1 = 0.5 * p0
    k2 = 0.5 * _qmul(one + 0.5 * h * k1, pm)
    k3 = 0.5 * _qmul(one + 0.5 * h * k2, pm)
    k4 = 0.5 * _qmul(one + h * k3, p1)
    return one + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)


def increments_from_rates(t_ns, omega_ib_b, quadrature: str = "trapezoid") -> np.ndarray:
    """Angle increments ``Δθ_k ≈ ∫_{t_{k-1}}^{t_k} ω dt`` from rate samples, (N-1, 3).

    ``"trapezoid"``: ``½(ω_{k-1}+ω_k) h`` (error O(h³) per interval → order 2).
    ``"cubic"``: the causal cubic through samples k-3..k integrated exactly (two-point
    Gauss), error O(h⁵) per interval → order 4 (first two intervals: linear/quadratic).
    """
    t = _check_times(t_ns)
    w = as_vector_array(omega_ib_b, "omega_ib_b")
    if w.shape != (t.size, 3):
        raise ValueError(f"omega_ib_b must have shape ({t.size}, 3), got {w.shape}")
    _check_quadrature(quadrature)
    k = np.arange(1, t.size)
    return _increments_from_rates(t, w, k, quadrature, lookahead=True)


def _uses_rate_fit(info: AlgorithmInfo, quadrature: str) -> bool:
    """Whether the algorithm fits a polynomial to the rate samples (first-interval redo)."""
    if info.consumes == "increment":
        return quadrature == "cubic"
    return info.sequential or info.name in ("rotvec_cubic", "quat_rk4")


def _increments_from_rates(t, w, k, quadrature, lookahead=False):
    h = ((t[k] - t[k - 1]) * 1e-9)[:, None]
    if quadrature == "trapezoid":
        return 0.5 * (w[k - 1] + w[k]) * h
    g = _rate_at_fractions(t, w, k, (0.5 - _GAUSS_OFFSET, 0.5 + _GAUSS_OFFSET), lookahead)
    return 0.5 * h * (g[:, 0] + g[:, 1])


def _coning_partials(dtheta: np.ndarray, first_pos: int, n: int,
                     prev: np.ndarray | None, block_start: np.ndarray | None) -> np.ndarray:
    """Rotation vectors ``φ`` (M, 3) for increments ``dtheta`` (M, 3).

    ``n == 0`` stands for ``coning1_prev`` (``prev`` is the increment before the first);
    otherwise the j-sample compressed formula is applied with j the position of each
    increment in its N-block.  ``first_pos`` is the 0-based position of ``dtheta[0]``
    within its block and ``block_start`` the increments of that block already consumed.
    """
    if n == 0:
        before = np.empty_like(dtheta)
        before[0] = prev if prev is not None else 0.0
        before[1:] = dtheta[:-1]
        return dtheta + np.cross(before, dtheta) / 12.0
    if n == 1:
        return dtheta.copy()
    head = block_start if block_start is not None else np.zeros((0, 3))
    if head.shape[0] != first_pos:
        raise AssertionError("block bookkeeping")
    full = np.concatenate((head, dtheta)) if first_pos else dtheta
    m = full.shape[0]
    nb = -(-m // n)
    padded = np.zeros((nb * n, 3))
    padded[:m] = full
    blk = padded.reshape(nb, n, 3)
    csum = np.cumsum(blk, axis=1)
    phi = np.empty_like(blk)
    for j in range(1, n + 1):  # j increments so far: j-sample formula
        coef = CONING_COEFFICIENTS[j]
        phi_j = csum[:, j - 1].copy()
        if coef:
            weighted = sum(c * blk[:, i] for i, c in enumerate(coef))
            phi_j += np.cross(weighted, blk[:, j - 1])
        phi[:, j - 1] = phi_j
    return phi.reshape(nb * n, 3)[first_pos:m]


def _nav_zeta(t_ns: np.ndarray, rate_n: np.ndarray, k: np.ndarray) -> np.ndarray:
    """``ζ_k = ∫ ω_in^n dt`` over interval k by the trapezoid (exact for constants)."""
    h = ((t_ns[k] - t_ns[k - 1]) * 1e-9)[:, None]
    if rate_n.ndim == 1:
        return rate_n[None, :] * h
    return 0.5 * (rate_n[k - 1] + rate_n[k]) * h


def _block_partial_sums(z: np.ndarray, n: int) -> np.ndarray:
    """Running sums of ``z`` (M, 3) restarting every n rows (chunk starts on a block)."""
    if n == 1:
        return z
    m = z.shape[0]
    nb = -(-m // n)
    padded = np.zeros((nb * n, 3))
    padded[:m] = z
    return np.cumsum(padded.reshape(nb, n, 3), axis=1).reshape(nb * n, 3)[:m]


# --------------------------------------------------------------------------- batch
def _compose_chunked(n_samples: int, q0: np.ndarray, n_per_update: int, increments) -> np.ndarray:
    """Run ``q_k = a'_k ⊗ Q ⊗ b'_k`` over all intervals, chunk by chunk.

    ``increments(k)`` returns ``(b', a' or None)`` for the interval indices ``k``; with N
    samples per update, ``Q`` is the attitude at the last completed N-block and the
    primed increments are the partial ones since that block.  Chunks bound memory and
    keep the scans in cache; the carried attitude is normalized at chunk boundaries.
    """
    q = np.empty((n_samples, 4))
    q[0] = q0
    start = q0
    for k0 in range(1, n_samples, _CHUNK):
        k = np.arange(k0, min(k0 + _CHUNK, n_samples))
        b, a = increments(k)
        if n_per_update == 1:
            out = _qmul(start, _prefix_product(b))
            if a is not None:
                out = _qmul(_prefix_product_left(a), out)
        else:
            nfull = k.size // n_per_update
            major = slice(n_per_update - 1, nfull * n_per_update, n_per_update)
            nblk = -(-k.size // n_per_update)
            # Attitude before each block: Q_{m-1} = A_{m-1} ⊗ start ⊗ B_{m-1}.
            q_before = np.empty((nblk, 4))
            q_before[0] = start
            if nblk > 1:
                qb = _qmul(start, _prefix_product(b[major][: nblk - 1]))
                if a is not None:
                    qb = _qmul(_prefix_product_left(a[major][: nblk - 1]), qb)
                q_before[1:] = _normalize_rows(qb)
            qrep = np.repeat(q_before, n_per_update, axis=0)[: k.size]
            out = _qmul(qrep, b)
            if a is not None:
                out = _qmul(a, out)
        out = _normalize_rows(out)
        q[k] = out
        start = out[-1]
    return q


def _nav_rate_for(nav: NavFrame | None, n_samples: int) -> np.ndarray | None:
    if nav is None:
        return None
    if not isinstance(nav, NavFrame):
        raise ValueError(f"nav must be a NavFrame or None, got {type(nav).__name__}")
    return nav.rate_enu(n_samples)


def integrate_batch(t_ns, omega_ib_b, q0=(0.0, 0.0, 0.0, 1.0),
                    algorithm: str = DEFAULT_ALGORITHM, nav: NavFrame | None = None,
                    quadrature: str = "trapezoid", singular_tol: float = 1e-3) -> np.ndarray:
    """Attitudes ``q[k]`` (N, 4) at ``t_ns[k]`` from rate samples ``ω_ib^b`` (N, 3).

    ``q[0] = q0``; ``q_ib`` when ``nav`` is None, else ``q_nb`` with the nav-frame rate
    removed.  Increment algorithms (``coning*``) get their increments from ``quadrature``
    (see :func:`increments_from_rates`).  ``singular_tol`` applies to the Euler-angle
    baselines only.  Raises ``ValueError`` for non-increasing times, wrong shapes,
    non-finite input, unknown names.
    """
    info = _check_algorithm(algorithm)
    t = _check_times(t_ns)
    w = as_vector_array(omega_ib_b, "omega_ib_b")
    if w.shape != (t.size, 3):
        raise ValueError(f"omega_ib_b must have shape ({t.size}, 3), got {w.shape}")
    q0 = _check_q0(q0)
    _check_quadrature(quadrature)
    rate_n = _nav_rate_for(nav, t.size)
    if info.sequential:
        if rate_n is not None:
            raise ValueError(f"{algorithm} integrates q_ib only; nav frames need a "
                             "quaternion algorithm")
        return _euler_batch(info.name, t, w, q0, singular_tol)
    if info.consumes == "increment":
        q = _increments_batch(
            info, t, lambda k: _increments_from_rates(t, w, k, quadrature, lookahead=True),
            q0, rate_n)
        if t.size >= 3 and _uses_rate_fit(info, quadrature):
            # Emitted q[1] is causal (linear fit); the chain used the redone interval 1.
            d1 = _increments_from_rates(t[:2], w[:2], np.array([1]), quadrature)
            q[1] = _first_interval_output(q0, _exp_rotvec(d1)[0], t, rate_n)
        return q
    n = info.samples_per_update

    def increments(k):
        b = _rate_body_increments(algorithm, t, w, k, lookahead=True)
        a = None if rate_n is None else _exp_rotvec(-_nav_zeta(t, rate_n, k))
        return b, a

    q = _compose_chunked(t.size, q0, n, increments)
    if t.size >= 3 and _uses_rate_fit(info, quadrature):
        b1 = _rate_body_increments(algorithm, t[:2], w[:2], np.array([1]))[0]
        q[1] = _first_interval_output(q0, b1, t, rate_n)
    return q


def _first_interval_output(q0, b1, t, rate_n):
    """``q[1]`` as the causal stream emits it: ``a_1 ⊗ q0 ⊗ b_1`` from the linear fit."""
    out = _qmul(q0, b1)
    if rate_n is not None:
        out = _qmul(_exp_rotvec(-_nav_zeta(t, rate_n, np.array([1]))[0]), out)
    return out / math.sqrt(float(np.dot(out, out)))


def integrate_increments_batch(t_ns, delta_theta, q0=(0.0, 0.0, 0.0, 1.0),
                               algorithm: str = "coning4",
                               nav: NavFrame | None = None) -> np.ndarray:
    """Attitudes (N, 4) from angle increments ``delta_theta`` (N-1, 3) of an increment
    algorithm; ``delta_theta[k-1] = ∫ ω_ib^b dt`` over ``(t_ns[k-1], t_ns[k]]``."""
    info = _check_algorithm(algorithm)
    if info.consumes != "increment":
        raise ValueError(f"{algorithm} consumes rate samples; use integrate_batch")
    t = _check_times(t_ns)
    d = as_vector_array(delta_theta, "delta_theta")
    if d.shape != (t.size - 1, 3):
        raise ValueError(f"delta_theta must have shape ({t.size - 1}, 3) (one per interval), "
                         f"got {d.shape}")
    q0 = _check_q0(q0)
    rate_n = _nav_rate_for(nav, t.size)
    return _increments_batch(info, t, lambda k: d[k - 1], q0, rate_n)


def _coning_n(info: AlgorithmInfo) -> int:
    return 0 if info.name == "coning1_prev" else info.samples_per_update


def _increments_batch(info, t, get_dtheta, q0, rate_n):
    n_code = _coning_n(info)
    n = info.samples_per_update

    def increments(k):
        d = get_dtheta(k)
        prev = get_dtheta(k[:1] - 1)[0] if (n_code == 0 and k[0] > 1) else None
        phi = _coning_partials(d, 0, n_code, prev, None)  # chunks start on block edges
        b = _exp_rotvec(phi)
        a = None
        if rate_n is not None:
            a = _exp_rotvec(-_block_partial_sums(_nav_zeta(t, rate_n, k), n))
        return b, a

    return _compose_chunked(t.size, q0, n, increments)


# --------------------------------------------------------------------------- Euler baselines
def _euler_setup(algorithm: str):
    if algorithm == "euler_zxz_rk4":
        return quat_as_euler_zxz, quat_from_euler_zxz, euler_zxz_rates_from_body_rates, \
            "sin(theta)", lambda a: math.sin(a[1])
    return quat_as_krylov, quat_from_krylov, krylov_rates_from_body_rates, \
        "cos(gamma)", lambda a: math.cos(a[1])


def _euler_step(rates_fn, div_fn, div_name, angles, w0, wm, w1, h, tol, k, t_ns):
    """One RK4 step of the angle kinematics; raises GimbalLockError near the singularity.

    Two flags: the divisor (|sin θ| or |cos γ|) below ``tol`` at any stage, or a step
    whose angle change exceeds what the body rotated by more than 1/tol — the
    discrete steps jump over the exact singularity, so the second catches the blow-up.
    """
    def f(a, w):
        if abs(div_fn(a)) < tol:
            raise GimbalLockError(
                f"Euler-angle integration reached its singularity at sample {k} "
                f"(t = {t_ns} ns): |{div_name}| = {abs(div_fn(a)):.3g} < {tol:g}; "
                "use a quaternion algorithm")
        return rates_fn(a, w, tol=0.0)

    k1 = f(angles, w0)
    k2 = f(angles + 0.5 * h * k1, wm)
    k3 = f(angles + 0.5 * h * k2, wm)
    k4 = f(angles + h * k3, w1)
    step = (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    turned = h * max(float(np.abs(w0).max()), float(np.abs(w1).max()), 1e-300)
    if not np.all(np.isfinite(step)) or float(np.abs(step).max()) > 3.0 * turned / tol:
        raise GimbalLockError(
            f"Euler-angle integration blew up near its singularity at sample {k} "
            f"(t = {t_ns} ns): the angles moved {float(np.abs(step).max()):.3g} rad while "
            f"the body turned {turned:.3g} rad; use a quaternion algorithm")
    return angles + step


def _euler_batch(algorithm, t, w, q0, tol):
    to_angles, from_angles, rates_fn, div_name, div_fn = _euler_setup(algorithm)
    angles = _initial_angles(to_angles, q0, tol, div_fn, div_name)
    out = np.empty((t.size, 3))
    out[0] = angles
    if t.size > 1:
        k = np.arange(1, t.size)
        wm_all = _rate_at_fractions(t, w, k, (0.5,), lookahead=True)[:, 0]
        h_all = np.diff(t) * 1e-9
        for i in range(1, t.size):
            angles = _euler_step(rates_fn, div_fn, div_name, angles, w[i - 1], wm_all[i - 1],
                                 w[i], h_all[i - 1], tol, i, int(t[i]))
            out[i] = angles
        if t.size >= 3:
            # Emitted sample 1 is causal (linear fit); the chain used the redone interval.
            wm1 = _rate_at_fractions(t[:2], w[:2], k[:1], (0.5,))[0, 0]
            out[1] = _euler_step(rates_fn, div_fn, div_name, out[0], w[0], wm1, w[1],
                                 h_all[0], tol, 1, int(t[1]))
    q = from_angles(out)
    # Same sign convention as q0 at the start (both q and -q are valid outputs).
    return q * (1.0 if float(np.dot(q[0], q0)) >= 0 else -1.0)


def _initial_angles(to_angles, q0, tol, div_fn, div_name):
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # lock is reported below instead
        angles = to_angles(q0)
    if abs(div_fn(angles)) < tol:
        raise GimbalLockError(f"the initial attitude is at the Euler-angle singularity: "
                              f"|{div_name}| = {abs(div_fn(angles)):.3g} < {tol:g}")
    return angles


# --------------------------------------------------------------------------- streaming
_FAST_STREAMING = ("rotvec_cubic", "rotvec_trapezoid", "exp_map", "quat_rk4",
                   "quat_first_order", "dcm_first_order",
                   "coning1", "coning1_prev", "coning2", "coning3", "coning4")
_SQRT3_12 = math.sqrt(3.0) / 12.0


def _increment_scalar(algorithm, ts, ws, k, nodes):
    """Scalar twin of :func:`_rate_body_increments`: body increment quaternion of interval k.

    Plain-float arithmetic because numpy's per-call overhead on 3-vectors (~1 µs per
    operation) would cost ~100 µs per streaming update; the tests hold it to the batch.
    """
    t_prev = ts[k - 1]
    h = (ts[k] - t_prev) * 1e-9
    ax, ay, az = ws[k - 1]
    if algorithm == "quat_first_order":
        x, y, z = 0.5 * ax * h, 0.5 * ay * h, 0.5 * az * h
        n = math.sqrt(x * x + y * y + z * z + 1.0)
        return (x / n, y / n, z / n, 1.0 / n)
    if algorithm == "dcm_first_order":
        x, y, z = ax * h, ay * h, az * h
        mag = math.sqrt(x * x + y * y + z * z)
        scale = 1.0 - mag * mag / 3.0 if mag < 1e-4 else math.atan(mag) / mag
        return _exp_scalar(x * scale, y * scale, z * scale)
    if algorithm == "quat_rk4":
        xs = [(ts[i] - t_prev) * 1e-9 for i in nodes]
        wm = _lagrange_scalar(xs, [ws[i] for i in nodes], 0.5 * h)
        return _rk4_scalar(ws[k - 1], wm, ws[k], h)
    return _exp_scalar(*_phi_scalar(algorithm, h, ts, ws, k, nodes))


def _rk4_scalar(w0, wm, w1, h):
    """Scalar twin of :func:`_rk4_quat_increment`, normalized."""
    one = (0.0, 0.0, 0.0, 1.0)

    def stage(p, scale, w):  # ½ (1 + scale·p) ⊗ [w, 0]
        q = (scale * p[0], scale * p[1], scale * p[2], 1.0 + scale * p[3])
        r = _qmul_scalar(q, (w[0], w[1], w[2], 0.0))
        return (0.5 * r[0], 0.5 * r[1], 0.5 * r[2], 0.5 * r[3])

    k1 = (0.5 * w0[0], 0.5 * w0[1], 0.5 * w0[2], 0.0)
    k2 = stage(k1, 0.5 * h, wm)
    k3 = stage(k2, 0.5 * h, wm)
    k4 = stage(k3, h, w1)
    c = h / 6.0
    p = tuple(one[i] + c * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]) for i in range(4))
    n = math.sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2] + p[3] * p[3])
    return (p[0] / n, p[1] / n, p[2] / n, p[3] / n)


def _phi_scalar(algorithm, h, ts, ws, k, nodes):
    """Rotation vector of interval k for the rotation-vector algorithms (plain floats)."""
    t_prev = ts[k - 1]
    (ax, ay, az), (bx, by, bz) = ws[k - 1], ws[k]
    if algorithm == "exp_map":
        return (0.5 * (ax + bx) * h, 0.5 * (ay + by) * h, 0.5 * (az + bz) * h)
    if algorithm == "rotvec_cubic":
        xs = [(ts[i] - t_prev) * 1e-9 for i in nodes]
        ys = [ws[i] for i in nodes]
        ax, ay, az = _lagrange_scalar(xs, ys, h * (0.5 - _GAUSS_OFFSET))
        bx, by, bz = _lagrange_scalar(xs, ys, h * (0.5 + _GAUSS_OFFSET))
        c = _SQRT3_12 * (h * h)
        half = 0.5 * h
    else:  # rotvec_trapezoid
        c = h * h / 12.0
        half = 0.5 * h
    return (half * (ax + bx) + c * (ay * bz - az * by),
            half * (ay + by) + c * (az * bx - ax * bz),
            half * (az + bz) + c * (ax * by - ay * bx))


def _lagrange_scalar(xs, ys, e):
    ox = oy = oz = 0.0
    for i, xi in enumerate(xs):
        wgt = 1.0
        for j, xj in enumerate(xs):
            if j != i:
                wgt = wgt * (e - xj) / (xi - xj)
        ox += wgt * ys[i][0]
        oy += wgt * ys[i][1]
        oz += wgt * ys[i][2]
    return ox, oy, oz


def _quadrature_scalar(quadrature, ts, ws, k, nodes):
    """Scalar twin of :func:`_increments_from_rates`: angle increment of interval k."""
    h = (ts[k] - ts[k - 1]) * 1e-9
    if quadrature == "trapezoid":
        (ax, ay, az), (bx, by, bz) = ws[k - 1], ws[k]
        return (0.5 * (ax + bx) * h, 0.5 * (ay + by) * h, 0.5 * (az + bz) * h)
    t_prev = ts[k - 1]
    xs = [(ts[i] - t_prev) * 1e-9 for i in nodes]
    ys = [ws[i] for i in nodes]
    ax, ay, az = _lagrange_scalar(xs, ys, h * (0.5 - _GAUSS_OFFSET))
    bx, by, bz = _lagrange_scalar(xs, ys, h * (0.5 + _GAUSS_OFFSET))
    half = 0.5 * h
    return (half * (ax + bx), half * (ay + by), half * (az + bz))


def _exp_scalar(x, y, z):
    th2 = x * x + y * y + z * z
    th = math.sqrt(th2)
    if th < 1e-4:  # same series as rotation._exp_rotvec
        k = 0.5 - th2 / 48.0 + th2 * th2 / 3840.0
    else:
        k = math.sin(0.5 * th) / th
    return (x * k, y * k, z * k, math.cos(0.5 * th))


def _qmul_scalar(a, b):
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz)


def _nav_zeta_scalar(rates, h):
    """``ζ = ∫ ω_in^n dt`` over one interval of length ``h``: trapezoid of the nav rates at
    its two ends (``rates = [r0, r1]``), as the batch interface forms it.  For a constant
    rate ``0.5·(r + r)·h`` is ``r·h`` to the last bit."""
    r0, r1 = rates
    return (0.5 * (r0[0] + r1[0]) * h, 0.5 * (r0[1] + r1[1]) * h, 0.5 * (r0[2] + r1[2]) * h)


def _compose_scalar(q, b, zeta):
    """``normalize(exp(−ζ) ⊗ q ⊗ b)`` in plain floats."""
    out = _qmul_scalar(q, b)
    if zeta is not None:
        out = _qmul_scalar(_exp_scalar(-zeta[0], -zeta[1], -zeta[2]), out)
    n = math.sqrt(out[0] * out[0] + out[1] * out[1] + out[2] * out[2] + out[3] * out[3])
    return (out[0] / n, out[1] / n, out[2] / n, out[3] / n)


class StreamingIntegrator:
    """Per-sample attitude update with the same results as :func:`integrate_batch`.

    The quaternion rate and the coning algorithms run a plain-float path (~3-10 µs per
    call on the 2-core development machine); the Euler baselines use the numpy path
    (tens of µs per call).

    ``update(t_ns, omega_ib_b)`` takes one rate sample and returns the attitude at
    ``t_ns`` (the first call, or the first after ``reset`` without ``t_ns``, only sets
    the time origin and returns ``q0``).  Increment algorithms get their increments from
    ``quadrature`` exactly as the batch interface does, or directly through
    ``update_increment(t_ns, delta_theta)``.  A NavFrame with time series is indexed by
    the sample count.  Raises ``ValueError`` on a zero/negative step or non-finite input.

    ``update_nav(nav)`` replaces the navigation frame by a constant one from the next
    sample on (a moving carrier whose velocity is measured while integrating): its rate
    ``ω_in^n`` is evaluated once, at the call, and is the nav rate *at the next sample*;
    the interval ending at that sample uses the trapezoid of the previous sample's rate
    and the new one, later intervals the new rate.  A stream whose nav frame is switched
    this way equals :func:`integrate_batch` with the NavFrame time series that holds the
    old values up to the sample before and the new values from that sample on.
    """

    def __init__(self, algorithm: str = DEFAULT_ALGORITHM, q0=(0.0, 0.0, 0.0, 1.0),
                 nav: NavFrame | None = None, t0_ns: int | None = None,
                 quadrature: str = "trapezoid", singular_tol: float = 1e-3):
        self.info = _check_algorithm(algorithm)
        self.algorithm = algorithm
        self.quadrature = _check_quadrature(quadrature)
        self.singular_tol = float(singular_tol)
        if nav is not None and self.info.sequential:
            raise ValueError(f"{algorithm} integrates q_ib only; nav frames need a "
                             "quaternion algorithm")
        self.nav = nav
        self._nav_const = None
        if nav is not None:
            if not isinstance(nav, NavFrame):
                raise ValueError(f"nav must be a NavFrame or None, got {type(nav).__name__}")
            try:
                self._nav_const = nav.rate_enu(None)
                self._nav_series = None
            except ValueError as err:
                if "time series" not in str(err):
                    raise
                self._nav_series = nav
                n = None
                for arr in (nav.latitude_rad, nav.height_m):
                    a = np.asarray(arr)
                    if a.ndim:
                        n = a.shape[0]
                v = np.asarray(nav.velocity_enu)
                if v.ndim > 1:
                    n = v.shape[0]
                # Evaluated once for the whole series (as the batch does): per-sample numpy
                # calls would cost ~30 µs per update.
                self._nav_rates = nav.rate_enu(n)
        self.reset(q0, t0_ns)

    def reset(self, q0, t_ns: int | None = None) -> None:
        """Restart from attitude ``q0`` (at ``t_ns`` if given), dropping all history."""
        self._q = _check_q0(q0)
        self._t_hist: list[int] = []
        self._w_hist: list[np.ndarray] = []
        self.samples = 0
        self.last_t_ns: int | None = None
        self._angles = None
        self._redo_first = _uses_rate_fit(self.info, self.quadrature)
        if self.info.sequential:
            to_angles, _, _, div_name, div_fn = _euler_setup(self.algorithm)
            self._angles = _initial_angles(to_angles, self._q, self.singular_tol, div_fn,
                                           div_name)
        self._angles_start = self._angles
        # Scalar fast path (plain floats, no numpy per call) for the quaternion algorithms;
        # the Euler-angle baselines run their numpy RK4 step per sample.
        self._fast = self.algorithm in _FAST_STREAMING
        self._fincr = self.info.consumes == "increment"
        self._fblock: list[tuple[float, float, float]] = []  # increments of the open N-block
        self._fzeta_block = None
        self._fprev = None  # previous increment (coning1_prev)
        self._ft: list[int] = []
        self._fw: list[tuple[float, float, float]] = []
        self._fq = tuple(float(c) for c in self._q)
        self._fq_start = self._fq_block = self._fq
        self._fnav: list[tuple[float, float, float]] = []
        self._fzeta_first = None
        if t_ns is not None:
            self._start(int(t_ns), None)
            if self._fast:
                self._ft = [int(t_ns)]
                self._fw = []
                rate = self._nav_rate_at(0)
                self._fnav = [] if rate is None else [tuple(float(c) for c in rate)]

    @property
    def quaternion(self) -> np.ndarray:
        return self._q.copy()

    def update_nav(self, nav: NavFrame) -> None:
        """Use the constant navigation frame ``nav`` from the next sample on.

        ``ω_in^n`` of ``nav`` (Earth rate plus transport rate) is computed here, once, and
        becomes the nav rate at the next sample: the interval from the last sample to the
        next one integrates the trapezoid of the previous rate and this one, every later
        interval this one (until the next call).  Called before any sample (or between
        ``reset`` and the first sample), it is the rate from the first sample on.  The
        attitude and the history are kept; ``reset`` keeps the new frame.

        Raises ``ValueError`` (and changes nothing) when the integrator was built without a
        nav frame, ``nav`` is not a NavFrame, holds time series, or has an invalid
        latitude (beyond ±π/2) or non-finite values.
        """
        if self.nav is None:
            raise ValueError("update_nav needs an integrator built with a NavFrame (q_nb); "
                             "this one integrates q_ib")
        if not isinstance(nav, NavFrame):
            raise ValueError(f"nav must be a NavFrame, got {type(nav).__name__}")
        rate = nav.rate_enu(None)  # raises on series and on invalid values
        if rate.shape != (3,):
            raise ValueError(f"update_nav needs a constant NavFrame, got rate shape {rate.shape}")
        self.nav = nav
        self._nav_const = rate
        self._nav_series = None

    def _nav_rate_at(self, index: int) -> np.ndarray | None:
        if self.nav is None:
            return None
        if self._nav_const is not None:
            return self._nav_const
        n = self._nav_rates.shape[0]
        if index >= n:
            raise ValueError(f"NavFrame time series has {n} samples; sample {index} is beyond")
        return self._nav_rates[index]

    def _check_time(self, t_ns) -> int:
        if isinstance(t_ns, float | np.floating) or not isinstance(t_ns, int | np.integer):
            raise ValueError(f"t_ns must be an int number of nanoseconds, got {t_ns!r}")
        t = int(t_ns)
        if self.last_t_ns is not None and t <= self.last_t_ns:
            raise ValueError(f"time step {t - self.last_t_ns} ns is not positive "
                             f"(t_ns={t} after {self.last_t_ns}): samples must be strictly "
                             "increasing in time")
        return t

    def _start(self, t: int, w: np.ndarray | None) -> None:
        self.last_t_ns = t
        self._t_hist = [t]
        self._w_hist = [w if w is not None else np.zeros(3)]
        self._have_w0 = w is not None
        self.samples += 1

    def update(self, t_ns: int, omega_ib_b) -> np.ndarray:
        """Consume one rate sample; return the attitude at ``t_ns`` (shape (4,))."""
        if self._fast:
            return self._update_fast(t_ns, omega_ib_b)
        w = as_vector_array(omega_ib_b, "omega_ib_b")
        if w.shape != (3,):
            raise ValueError(f"omega_ib_b must have shape (3,), got {w.shape}")
        t = self._check_time(t_ns)
        if self.last_t_ns is None:
            self._start(t, w.copy())
            return self.quaternion
        if not self._have_w0:
            # reset(q0, t_ns) gave a start time but no rate there: hold this first rate
            # back to the start (zero-order hold) for the first interval.
            self._w_hist[0] = w.copy()
            self._have_w0 = True
        self._t_hist = (self._t_hist + [t])[-4:]
        self._w_hist = (self._w_hist + [w.copy()])[-4:]
        tt = np.array(self._t_hist, dtype=np.int64)
        ww = np.array(self._w_hist)
        k = np.array([tt.size - 1])
        if self.samples == 2 and self._redo_first:
            self._redo_first_interval(tt, ww)
        self._euler_update(tt, ww, k, t)
        self.last_t_ns = t
        self.samples += 1
        return self.quaternion

    def _update_fast(self, t_ns, omega_ib_b) -> np.ndarray:
        try:
            wx, wy, wz = (float(c) for c in omega_ib_b)
        except (TypeError, ValueError):
            raise ValueError(f"omega_ib_b must be 3 finite numbers, got {omega_ib_b!r}") from None
        if not (math.isfinite(wx) and math.isfinite(wy) and math.isfinite(wz)):
            raise ValueError("omega_ib_b contains non-finite values (NaN or inf)")
        t = self._check_time(t_ns)
        w = (wx, wy, wz)
        rate_n = self._nav_rate_at(self.samples)
        if rate_n is not None:
            rate_n = rate_n.tolist()
            self._fnav = (self._fnav + [rate_n])[-2:]
        self.samples += 1
        if self.last_t_ns is None:
            self.last_t_ns = t
            self._ft, self._fw = [t], [w]
            return self.quaternion
        if not self._fw:
            self._fw = [w]  # reset(q0, t_ns): hold the first rate back to the start time
        self._ft = (self._ft + [t])[-4:]
        self._fw = (self._fw + [w])[-4:]
        h = (t - self.last_t_ns) * 1e-9
        zeta = None
        if self.nav is not None:
            zeta = _nav_zeta_scalar(self._fnav, h)
        n = len(self._ft)
        if self.samples == 2:
            self._fzeta_first = zeta
        elif self.samples == 3 and self._redo_first:
            # Redo interval 1 with the quadratic through samples 0, 1, 2 (as the batch).
            if self._fincr:
                d1 = _quadrature_scalar(self.quadrature, self._ft, self._fw, 1, (0, 1, 2))
                if self.info.samples_per_update > 1:
                    self._fblock[0] = d1  # the N-block is still open: fix its first entry
                else:
                    self._fq = self._fq_block = _compose_scalar(
                        self._fq_start, _exp_scalar(*d1), self._fzeta_first)
                    self._fprev = d1
            else:
                b1 = _increment_scalar(self.algorithm, self._ft, self._fw, 1, (0, 1, 2))
                self._fq = _compose_scalar(self._fq_start, b1, self._fzeta_first)
        if self._fincr:
            d = _quadrature_scalar(self.quadrature, self._ft, self._fw, n - 1,
                                   tuple(range(n)))
            self._increment_fast(d, zeta)
        else:
            b = _increment_scalar(self.algorithm, self._ft, self._fw, n - 1, tuple(range(n)))
            self._fq = _compose_scalar(self._fq, b, zeta)
        self.last_t_ns = t
        self._q = np.array(self._fq)
        return self._q.copy()

    def _redo_first_interval(self, tt: np.ndarray, ww: np.ndarray) -> None:
        """Redo interval 1 with the quadratic through samples 0, 1, 2 (batch does the same)."""
        _, _, rates_fn, div_name, div_fn = _euler_setup(self.algorithm)
        wm = _rate_at_fractions(tt, ww, np.array([1]), (0.5,), lookahead=True)[0, 0]
        self._angles = _euler_step(rates_fn, div_fn, div_name, self._angles_start, ww[0],
                                   wm, ww[1], (tt[1] - tt[0]) * 1e-9, self.singular_tol,
                                   1, int(tt[1]))

    def update_increment(self, t_ns: int, delta_theta) -> np.ndarray:
        """Consume one angle increment over ``(last_t_ns, t_ns]`` (increment algorithms).

        The first call after construction/reset needs ``t0_ns`` (given to the
        constructor or to :meth:`reset`) so the interval is defined.
        """
        if self.info.consumes != "increment":
            raise ValueError(f"{self.algorithm} consumes rate samples; use update()")
        return self._update_increment_fast(t_ns, delta_theta)

    def _update_increment_fast(self, t_ns, delta_theta) -> np.ndarray:
        try:
            dx, dy, dz = (float(c) for c in delta_theta)
        except (TypeError, ValueError):
            raise ValueError("delta_theta must have shape (3,): 3 finite numbers, got "
                             f"{delta_theta!r}") from None
        if not (math.isfinite(dx) and math.isfinite(dy) and math.isfinite(dz)):
            raise ValueError("delta_theta contains non-finite values (NaN or inf)")
        t = self._check_time(t_ns)
        if self.last_t_ns is None:
            raise ValueError("update_increment needs a start time: pass t0_ns to the "
                             "constructor or reset(q0, t_ns)")
        zeta = None
        if self.nav is not None:
            rate_n = self._nav_rate_at(self.samples).tolist()
            self._fnav = (self._fnav + [rate_n])[-2:]
            zeta = _nav_zeta_scalar(self._fnav, (t - self.last_t_ns) * 1e-9)
        self._increment_fast((dx, dy, dz), zeta)
        self.last_t_ns = t
        self.samples += 1
        self._q = np.array(self._fq)
        return self._q.copy()

    def _increment_fast(self, d, zeta) -> None:
        """Scalar twin of :meth:`_increment_update` (same sums in the same order)."""
        dx, dy, dz = d
        if self.algorithm == "coning1_prev":
            p = self._fprev
            if p is not None:
                px, py, pz = p
                d = (dx + (py * dz - pz * dy) / 12.0, dy + (pz * dx - px * dz) / 12.0,
                     dz + (px * dy - py * dx) / 12.0)
            self._fprev = (dx, dy, dz)
            self._fq = self._fq_block = _compose_scalar(self._fq_block, _exp_scalar(*d), zeta)
            return
        block = self._fblock
        block.append(d)
        j = len(block)
        sx = sy = sz = 0.0
        for bx, by, bz in block:
            sx += bx
            sy += by
            sz += bz
        coef = CONING_COEFFICIENTS[j]
        if coef:
            wx = wy = wz = 0.0
            for c, (bx, by, bz) in zip(coef, block, strict=False):
                wx += c * bx
                wy += c * by
                wz += c * bz
            sx += wy * dz - wz * dy
            sy += wz * dx - wx * dz
            sz += wx * dy - wy * dx
        if zeta is not None:
            zb = self._fzeta_block
            if j > 1:
                zeta = (zb[0] + zeta[0], zb[1] + zeta[1], zb[2] + zeta[2])
            self._fzeta_block = zeta
        q = _compose_scalar(self._fq_block, _exp_scalar(sx, sy, sz), zeta)
        self._fq = q
        if j == self.info.samples_per_update:
            self._fq_block = q
            self._fblock = []
            self._fzeta_block = None

    def _euler_update(self, tt, ww, k, t):
        _, from_angles, rates_fn, div_name, div_fn = _euler_setup(self.algorithm)
        wm = _rate_at_fractions(tt, ww, k, (0.5,))[0, 0]
        h = (t - self.last_t_ns) * 1e-9
        self._angles = _euler_step(rates_fn, div_fn, div_name, self._angles, ww[-2], wm,
                                   ww[-1], h, self.singular_tol, self.samples, t)
        q = from_angles(self._angles)
        self._q = q if float(np.dot(q, self._q)) >= 0 else -q
