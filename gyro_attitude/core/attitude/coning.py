"""Coning algorithms on angle increments: one-sample-plus-previous and compressed N-sample."""

from __future__ import annotations

import numpy as np

from gyro_attitude.core.attitude.algorithm import Algorithm
from gyro_attitude.core.attitude.compose import (
    compose_chunked,
    compose_scalar,
    exp_scalar,
    first_interval_output,
)
from gyro_attitude.core.attitude.interpolation import NODES
from gyro_attitude.core.attitude.nav_frame import nav_zeta
from gyro_attitude.core.rotation import _exp_rotvec

#: Compressed N-sample coning coefficients k_1..k_{N-1} (docs/equations.md).
CONING_COEFFICIENTS: dict[int, tuple[float, ...]] = {
    1: (),
    2: (2.0 / 3.0,),
    3: (9.0 / 20.0, 27.0 / 20.0),
    4: (54.0 / 105.0, 92.0 / 105.0, 214.0 / 105.0),
}
#: Coning drift coefficient ρ_N: drift ≈ ρ_N α² Ω (Ωh)^{2N} (h = sample period).
CONING_DRIFT_RHO: dict[int, float] = {1: 1 / 12, 2: 1 / 60, 3: 1 / 280, 4: 1 / 1260}


class IncrementAlgorithm(Algorithm):
    """Rotation vectors ``φ`` from angle increments, the attitude updated every N samples.

    Fed with rate samples, the increments come from a stated quadrature; the coning
    coefficients assume exact increments and do not carry over to rate samples.
    Subclasses give :meth:`rotation_vectors` (batch) and :meth:`rotation_vector_scalar`
    (its plain-float twin for streaming).
    """

    consumes = "increment"

    def rotation_vectors(self, dtheta: np.ndarray, prev: np.ndarray | None) -> np.ndarray:
        """``φ`` (M, 3) for increments (M, 3) that start on an N-block edge; ``prev`` is the
        increment before the first (None at the start)."""
        raise NotImplementedError

    def rotation_vector_scalar(self, block: list, prev):
        """``φ`` after the increments ``block`` of the open N-block (plain floats)."""
        raise NotImplementedError

    def integrate(self, t, w, q0, rate_n, quadrature, singular_tol):
        q = self.integrate_increments(
            t, lambda k: quadrature.increments(t, w, k, lookahead=True), q0, rate_n)
        if t.size >= 3 and quadrature.fits_polynomial:
            # Emitted q[1] is causal (linear fit); the chain used the redone interval 1.
            d1 = quadrature.increments(t[:2], w[:2], np.array([1]))
            q[1] = first_interval_output(q0, _exp_rotvec(self.rotation_vectors(d1, None))[0],
                                         t, rate_n)
        return q

    def integrate_increments(self, t, get_dtheta, q0, rate_n):
        """Attitudes (N, 4) from increments ``get_dtheta(k)`` of intervals ``k``."""
        n = self.samples_per_update

        def increments(k):
            d = get_dtheta(k)
            prev = get_dtheta(k[:1] - 1)[0] if k[0] > 1 else None
            b = _exp_rotvec(self.rotation_vectors(d, prev))  # chunks start on block edges
            a = None
            if rate_n is not None:
                a = _exp_rotvec(-_block_partial_sums(nav_zeta(t, rate_n, k), n))
            return b, a

        return compose_chunked(t.size, q0, n, increments)

    def _new_stepper(self, q0, quadrature, singular_tol):
        return ConingStepper(self, q0, quadrature)


class PreviousConing(IncrementAlgorithm):
    """One-sample-plus-previous: ``φ = Δθ_k + 1/12 Δθ_{k-1}×Δθ_k`` (drift α²Ω(Ωh)⁴/60)."""

    def rotation_vectors(self, dtheta, prev):
        before = np.empty_like(dtheta)
        before[0] = prev if prev is not None else 0.0
        before[1:] = dtheta[:-1]
        return dtheta + np.cross(before, dtheta) / 12.0

    def rotation_vector_scalar(self, block, prev):
        d = block[-1]
        if prev is None:
            return d
        (px, py, pz), (dx, dy, dz) = prev, d
        return (dx + (py * dz - pz * dy) / 12.0, dy + (pz * dx - px * dz) / 12.0,
                dz + (px * dy - py * dx) / 12.0)


class CompressedConing(IncrementAlgorithm):
    """Compressed N-sample ``φ = ΣΔθ_i + (Σ_{i<N} k_i Δθ_i) × Δθ_N`` (drift
    ρ_N α²Ω(Ωh)^{2N}); between two N-sample updates the outputs use the j-sample formula on
    the j increments so far (j < N) and are not fed back."""

    def __init__(self, name, order, description, cost, samples_per_update: int):
        super().__init__(name, order, description, cost)
        self.samples_per_update = samples_per_update

    def rotation_vectors(self, dtheta, prev):
        n = self.samples_per_update
        if n == 1:
            return dtheta.copy()
        m = dtheta.shape[0]
        nb = -(-m // n)
        padded = np.zeros((nb * n, 3))
        padded[:m] = dtheta
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
        return phi.reshape(nb * n, 3)[:m]

    def rotation_vector_scalar(self, block, prev):
        sx = sy = sz = 0.0
        for bx, by, bz in block:
            sx += bx
            sy += by
            sz += bz
        coef = CONING_COEFFICIENTS[len(block)]
        if coef:
            dx, dy, dz = block[-1]
            wx = wy = wz = 0.0
            for c, (bx, by, bz) in zip(coef, block, strict=False):
                wx += c * bx
                wy += c * by
                wz += c * bz
            sx += wy * dz - wz * dy
            sy += wz * dx - wx * dz
            sz += wx * dy - wy * dx
        return (sx, sy, sz)


class ConingStepper:
    """Streaming state of an :class:`IncrementAlgorithm`: the open N-block of increments,
    the attitude at its start and the nav rotation summed over it."""

    def __init__(self, algorithm: IncrementAlgorithm, q0: tuple, quadrature):
        self._rotvec = algorithm.rotation_vector_scalar
        self._n = algorithm.samples_per_update
        self._quad = quadrature
        self.q = self._q_block = self._q_start = q0
        self._block: list = []
        self._zeta_block = None
        self._prev = None

    def interval(self, ts, ws, zeta):
        n = len(ts)
        return self.increment(self._quad.increment_scalar(ts, ws, n - 1, NODES[n]), zeta)

    def increment(self, d, zeta):
        block = self._block
        block.append(d)
        phi = self._rotvec(block, self._prev)
        self._prev = d
        if zeta is not None:
            zb = self._zeta_block
            if len(block) > 1:
                zeta = (zb[0] + zeta[0], zb[1] + zeta[1], zb[2] + zeta[2])
            self._zeta_block = zeta
        self.q = compose_scalar(self._q_block, exp_scalar(*phi), zeta)
        if len(block) == self._n:
            self._q_block = self.q
            self._block = []
            self._zeta_block = None
        return self.q

    def redo_first(self, ts, ws, zeta_first):
        if not self._quad.fits_polynomial:
            return
        d1 = self._quad.increment_scalar(ts, ws, 1, NODES[3])  # quadratic through 0, 1, 2
        self._prev = d1
        if self._n > 1:
            self._block[0] = d1  # the N-block is still open: fix its first entry
        else:
            self.q = self._q_block = compose_scalar(
                self._q_start, exp_scalar(*self._rotvec([d1], None)), zeta_first)


def _block_partial_sums(z: np.ndarray, n: int) -> np.ndarray:
    """Running sums of ``z`` (M, 3) restarting every n rows (chunk starts on a block)."""
    if n == 1:
        return z
    m = z.shape[0]
    nb = -(-m // n)
    padded = np.zeros((nb * n, 3))
    padded[:m] = z
    return np.cumsum(padded.reshape(nb, n, 3), axis=1).reshape(nb * n, 3)[:m]


CONING1 = CompressedConing("coning1", 2, "rotation vector = angle increment (no coning "
                           "correction)", "1 exp map + product per sample", 1)
CONING1_PREV = PreviousConing("coning1_prev", 3, "one-sample-plus-previous: dth_k + 1/12 "
                              "dth_{k-1} x dth_k", "1 cross + exp map + product per sample")
CONING2 = CompressedConing("coning2", 4, "compressed 2-sample coning (k = 2/3), update every 2 "
                           "samples", "cross + exp map per sample", 2)
CONING3 = CompressedConing("coning3", 3, "compressed 3-sample coning (9/20, 27/20), update every "
                           "3 samples", "cross + exp map per sample", 3)
CONING4 = CompressedConing("coning4", 3, "compressed 4-sample coning (54, 92, 214)/105, update "
                           "every 4 samples", "cross + exp map per sample", 4)
