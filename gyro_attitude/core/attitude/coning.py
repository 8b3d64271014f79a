"""Coning algorithms on angle increments (one-sample-plus-previous and compressed N-sample),
and the stated quadratures that make increments from rate samples."""

from __future__ import annotations

import numpy as np

from gyro_attitude.core.attitude.algorithm import Algorithm
from gyro_attitude.core.attitude.compose import compose_scalar, exp_scalar
from gyro_attitude.core.attitude.inputs import check_rates, check_times
from gyro_attitude.core.attitude.interpolation import GAUSS2, causal_fit_points
from gyro_attitude.core.jit import compiled, kernel

#: Compressed N-sample coning coefficients k_1..k_{N-1} (docs/equations.md).
CONING_COEFFICIENTS: dict[int, tuple[float, ...]] = {
    1: (),
    2: (2.0 / 3.0,),
    3: (9.0 / 20.0, 27.0 / 20.0),
    4: (54.0 / 105.0, 92.0 / 105.0, 214.0 / 105.0),
}
#: Coning drift coefficient ρ_N: drift ≈ ρ_N α² Ω (Ωh)^{2N} (h = sample period).
CONING_DRIFT_RHO: dict[int, float] = {1: 1 / 12, 2: 1 / 60, 3: 1 / 280, 4: 1 / 1260}
# row j: the coefficients of the j-sample formula (compiled code reads an array, not a dict)
_K = np.array([CONING_COEFFICIENTS[j] + (0.0,) * (4 - j) for j in (1, 1, 2, 3, 4)])

# The coning state after the rate algorithm's slots of streaming.RateState: the block's count
# and whether an increment came before (int), the attitude at the block's start and the nav
# rotation summed over the block (float); ``blk`` (5, 3): rows 0..3 the block, 4 the previous.
C_BLOCK, C_HAS_PREV = 9, 10
F_Q_BLOCK, F_ZETA_BLOCK = 14, 18
PREVIOUS = 0  # the code of one-sample-plus-previous; compressed N-sample: N
RULE_TRAPEZOID, RULE_CUBIC = 0, 1  # the quadratures' codes
_GA, _GB = GAUSS2


class IncrementAlgorithm(Algorithm):
    """Rotation vectors ``φ`` from angle increments, the attitude updated every N samples
    (its step: :func:`coning_step` with ``code``).  Fed with rate samples, the increments come
    from a stated quadrature; the coning coefficients assume exact increments and do not
    carry over to rate samples."""

    consumes = "increment"
    integrates_into = True

    def __init__(self, name, order, description, cost, samples_per_update: int, code: int):
        super().__init__(name, order, description, cost)
        self.samples_per_update = samples_per_update
        self.code = code


@kernel(inline=True)
def _rotation_vector(alg, blk, j):
    """``φ`` after the ``j`` increments of the open block ``blk[:j]`` (``blk[4]`` the one
    before, when ``has_prev``): one-sample-plus-previous ``Δθ_k + 1/12 Δθ_{k-1}×Δθ_k``, or the
    compressed j-sample ``ΣΔθ_i + (Σ_{i<j} k_i Δθ_i) × Δθ_j``."""
    dx, dy, dz = blk[j - 1, 0], blk[j - 1, 1], blk[j - 1, 2]
    if alg == PREVIOUS:
        px, py, pz = blk[4, 0], blk[4, 1], blk[4, 2]
        return (dx + (py * dz - pz * dy) / 12.0, dy + (pz * dx - px * dz) / 12.0,
                dz + (px * dy - py * dx) / 12.0)
    sx = sy = sz = 0.0
    for i in range(j):
        sx += blk[i, 0]
        sy += blk[i, 1]
        sz += blk[i, 2]
    if j > 1:
        wx = wy = wz = 0.0
        for i in range(j - 1):
            wx += _K[j, i] * blk[i, 0]
            wy += _K[j, i] * blk[i, 1]
            wz += _K[j, i] * blk[i, 2]
        sx += wy * dz - wz * dy
        sy += wz * dx - wx * dz
        sz += wx * dy - wy * dx
    return (sx, sy, sz)


@kernel
def coning_step(alg, ci, cf, blk, d0, d1, d2, has_z, z0, z1, z2):
    """The increment ``d`` into the open block of the coning algorithm ``alg`` (its state in
    ``ci``, ``cf``, ``blk``), with the nav rotation ``z`` over its interval when ``has_z``:
    the attitude ``exp(−Σζ) ⊗ q_block ⊗ exp(φ)`` as 4 floats, stored; a full block (N
    increments) becomes the next block's start."""
    j = ci[C_BLOCK]
    blk[j, 0], blk[j, 1], blk[j, 2] = d0, d1, d2
    j += 1
    if alg == PREVIOUS and ci[C_HAS_PREV] == 0:
        px, py, pz = d0, d1, d2
    else:
        px, py, pz = _rotation_vector(alg, blk, j)
    blk[4, 0], blk[4, 1], blk[4, 2] = d0, d1, d2
    ci[C_HAS_PREV] = 1
    q_block = (cf[F_Q_BLOCK], cf[F_Q_BLOCK + 1], cf[F_Q_BLOCK + 2], cf[F_Q_BLOCK + 3])
    if has_z:
        if j > 1:
            z0, z1, z2 = (cf[F_ZETA_BLOCK] + z0, cf[F_ZETA_BLOCK + 1] + z1,
                          cf[F_ZETA_BLOCK + 2] + z2)
        cf[F_ZETA_BLOCK], cf[F_ZETA_BLOCK + 1], cf[F_ZETA_BLOCK + 2] = z0, z1, z2
        q = compose_scalar(q_block, exp_scalar(px, py, pz), (z0, z1, z2))
    else:
        q = compose_scalar(q_block, exp_scalar(px, py, pz), None)
    cf[0], cf[1], cf[2], cf[3] = q
    if j == (1 if alg == PREVIOUS else alg):
        cf[F_Q_BLOCK], cf[F_Q_BLOCK + 1], cf[F_Q_BLOCK + 2], cf[F_Q_BLOCK + 3] = q
        j = 0
    ci[C_BLOCK] = j
    return q


class Quadrature:
    """One rule for ``Δθ_k ≈ ∫_{t_{k-1}}^{t_k} ω dt`` (its step: :func:`quadrature_increment`
    with ``code``)."""

    def __init__(self, name: str, code: int, description: str):
        self.name = name
        self.code = code
        self.description = description


@kernel(inline=True)
def quadrature_increment(rule, ts, ws, k, n):
    """The increment over interval ``k`` of the first ``n`` samples held (``ts`` stamps, ``ws``
    rates) by the rule ``rule``: the trapezoid ``½(ω_{k-1}+ω_k) h``, or the causal cubic
    through the samples held integrated exactly (two-point Gauss)."""
    if rule == RULE_CUBIC:
        (ax, ay, az), (bx, by, bz), h = causal_fit_points(ts, ws, k, n, _GA, _GB)
        half = 0.5 * h
        return (half * (ax + bx), half * (ay + by), half * (az + bz))
    h = (ts[k] - ts[k - 1]) * 1e-9
    return (0.5 * (ws[k - 1, 0] + ws[k, 0]) * h, 0.5 * (ws[k - 1, 1] + ws[k, 1]) * h,
            0.5 * (ws[k - 1, 2] + ws[k, 2]) * h)


@kernel
def quadrature_rows(rule, t, w, out):
    """:func:`quadrature_increment` of every interval k of ``t`` (N,), ``w`` (N, 3) into
    ``out[k-1]``, each from the samples k-3..k (fewer at the start; interval 1 from samples
    0..2 when they exist, the fit the streams redo it with)."""
    for k in range(1, t.shape[0]):
        lo = max(k - 3, 0)
        hi = k + 1 if k > 1 or rule != RULE_CUBIC else min(3, t.shape[0])
        out[k - 1, 0], out[k - 1, 1], out[k - 1, 2] = quadrature_increment(
            rule, t[lo:hi], w[lo:hi], k - lo, hi - lo)


QUADRATURES: dict[str, Quadrature] = {q.name: q for q in (
    Quadrature("trapezoid", RULE_TRAPEZOID,
               "½(ω_{k-1}+ω_k) h: error O(h³) per interval → order 2"),
    Quadrature("cubic", RULE_CUBIC,
               "the causal cubic through samples k-3..k integrated exactly (two-point Gauss): "
               "error O(h⁵) per interval → order 4 (first two intervals: linear/quadratic)"))}


def get_quadrature(name: str) -> Quadrature:
    if name not in QUADRATURES:
        raise ValueError(f"unknown quadrature {name!r}; choose one of {tuple(QUADRATURES)}")
    return QUADRATURES[name]


def increments_from_rates(t_ns, omega_ib_b, quadrature: str = "trapezoid") -> np.ndarray:
    """Angle increments ``Δθ_k ≈ ∫_{t_{k-1}}^{t_k} ω dt`` (N-1, 3) from rate samples by the
    rule ``quadrature`` (:data:`QUADRATURES`)."""
    t = check_times(t_ns)
    w = np.ascontiguousarray(check_rates(omega_ib_b, t.size), dtype=np.float64)
    out = np.empty((max(t.size - 1, 0), 3))
    compiled(quadrature_rows)(get_quadrature(quadrature).code, t, w, out)
    return out


CONING1 = IncrementAlgorithm("coning1", 2, "rotation vector = angle increment (no coning "
                             "correction)", "1 exp map + product per sample", 1, 1)
CONING1_PREV = IncrementAlgorithm(
    "coning1_prev", 3, "one-sample-plus-previous: dth_k + 1/12 dth_{k-1} x dth_k",
    "1 cross + exp map + product per sample", 1, PREVIOUS)
CONING2 = IncrementAlgorithm("coning2", 4, "compressed 2-sample coning (k = 2/3), update every 2 "
                             "samples", "cross + exp map per sample", 2, 2)
CONING3 = IncrementAlgorithm("coning3", 3, "compressed 3-sample coning (9/20, 27/20), update "
                             "every 3 samples", "cross + exp map per sample", 3, 3)
CONING4 = IncrementAlgorithm("coning4", 3, "compressed 4-sample coning (54, 92, 214)/105, "
                             "update every 4 samples", "cross + exp map per sample", 4, 4)
