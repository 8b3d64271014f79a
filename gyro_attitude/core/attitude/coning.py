"""Coning algorithms on angle increments: one-sample-plus-previous and compressed N-sample."""

from __future__ import annotations

import numpy as np

from gyro_attitude.core.attitude.algorithm import Algorithm
from gyro_attitude.core.attitude.compose import compose_scalar, exp_scalar
from gyro_attitude.core.jit import kernel

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

# The coning state beside the rate state's slots (streaming.RateState, which is longer for
# it): the block's count and whether an increment came before (int), the attitude at the
# block's start and the nav rotation summed over the block (float), the block's increments
# and the one before in ``blk`` (5, 3): rows 0..3 the block, row 4 the previous.
C_BLOCK, C_HAS_PREV = 9, 10
F_Q_BLOCK, F_ZETA_BLOCK = 14, 18
PREVIOUS = 0  # the code of one-sample-plus-previous; compressed N-sample: N


class IncrementAlgorithm(Algorithm):
    """Rotation vectors ``φ`` from angle increments, the attitude updated every N samples.

    Fed with rate samples, the increments come from a stated quadrature; the coning
    coefficients assume exact increments and do not carry over to rate samples.  The step
    is one kernel, :func:`coning_step` with ``code``; both interfaces step it
    (:mod:`.streaming`: ``integrate_batch`` a compiled loop, ``StreamingIntegrator`` one
    call per sample).
    """

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
