"""Composing increments into attitudes: blocked prefix product (batch), plain-float helpers."""

from __future__ import annotations

import math
import os
from collections import deque
from concurrent.futures import ThreadPoolExecutor
from typing import NamedTuple

import numpy as np

from gyro_attitude.core.attitude.nav_frame import nav_zeta
from gyro_attitude.core.jit import kernel
from gyro_attitude.core.rotation import _exp_rotvec, _qmul

IDENTITY = np.array([0.0, 0.0, 0.0, 1.0])
CHUNK = 61440  # intervals per batch chunk: a multiple of 1..4 (N-sample blocks align)
_CONJ = np.array([-1.0, -1.0, -1.0, 1.0])


def _cpus() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


#: Worker threads of :func:`compose_chunked` that prepare chunks ahead of the thread carrying
#: the attitude: two when this process may use several CPUs, else none.  A process that is one
#: of several workers sharing the cores (the Monte Carlo and fleet pools, a Dask task) sets 0
#: once with :func:`set_prepare_threads`: its peers already keep every core busy, and two more
#: threads per process only add switching.  The arithmetic is the same either way.
_prepare_threads = 2 if _cpus() >= 2 else 0


def set_prepare_threads(n: int) -> int:
    """Set the chunk-preparing threads of this process (0: every chunk in the caller's
    thread); returns the previous number."""
    global _prepare_threads
    if isinstance(n, bool) or not isinstance(n, int) or not 0 <= n <= 64:
        raise ValueError(f"prepare threads must be an integer from 0 to 64, got {n!r}")
    previous, _prepare_threads = _prepare_threads, n
    return previous


def normalize_rows(q: np.ndarray) -> np.ndarray:
    return q / np.sqrt(np.einsum("...i,...i->...", q, q))[..., None]


#: Rows of the blocked scan in :func:`prefix_product` (up to 3·this many factors, the
#: plain loop).
_SCAN_ROWS = 16


def prefix_product(d: np.ndarray) -> np.ndarray:
    """Inclusive right prefix product ``P_k = d_0 ⊗ d_1 ⊗ … ⊗ d_k`` of unit quaternions.

    Blocked scan (a hand-written scan because numpy has no associative scan for a
    non-commutative product): the M factors are laid out as ``L`` rows of ``B = M/L``
    blocks; one vectorized quaternion product per row scans all blocks at once (L numpy
    calls on length-B arrays), the B block totals are scanned recursively, and each block
    is multiplied by the normalized product of the blocks before it.  Work O(M), numpy
    calls O(L log_L M).  ``L`` = :data:`_SCAN_ROWS`: few long rows, so that the fixed cost
    of each ufunc call is spread over M/L elements (with ``L = √M`` it dominated at the
    chunk size).  The result differs from the left-to-right sequential product only by
    rounding reassociation (~1e-16 per factor and level, random-walk).
    """
    m = d.shape[0]
    if m <= 3 * _SCAN_ROWS:
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
    rows = _SCAN_ROWS
    nb = -(-m // rows)
    pad = nb * rows - m
    if pad:
        d = np.concatenate((d, np.tile(IDENTITY, (pad, 1))))
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
    before[0] = IDENTITY
    if nb > 1:
        # Renormalize at block boundaries so the rounding of one block cannot scale the next.
        before[1:] = normalize_rows(prefix_product(totals[:-1]))
    res = _qmul(before[None, :, :], x.transpose(1, 2, 0))  # (rows, nb, 4)
    return res.transpose(1, 0, 2).reshape(nb * rows, 4)[:m]


def prefix_product_left(a: np.ndarray) -> np.ndarray:
    """``A_k = a_k ⊗ … ⊗ a_0`` as ``conj(prefix(conj(a)))`` (conjugation reverses order)."""
    return prefix_product(a * _CONJ) * _CONJ


def compose_chunked(n_samples: int, q0: np.ndarray, n_per_update: int, increments,
                    out: np.ndarray | None = None) -> np.ndarray:
    """Run ``q_k = a'_k ⊗ Q ⊗ b'_k`` over all intervals, chunk by chunk.

    ``increments(k)`` returns ``(b', a' or None)`` for the interval indices ``k`` (with one
    sample per update ``a'`` may be a :class:`LeftPrefix`, its products already); with N
    samples per update, ``Q`` is the attitude at the last completed N-block and the
    primed increments are the partial ones since that block.  Chunks bound memory and
    keep the scans in cache; the carried attitude is normalized at chunk boundaries.

    Everything of a chunk but the attitude carried into it (its increments and their
    prefix products: most of the work) is independent of the other chunks, so on a
    multi-core machine two chunks are prepared at once by worker threads (numpy releases
    the GIL in its loops) while this thread carries the attitude through the chunks in
    order.  ``increments`` must therefore be a pure function of ``k``.  The arithmetic is
    the same in either case.  ``out``: an (n_samples, 4) float64 array to write the
    attitudes into (and return) instead of a new one.
    """
    q = np.empty((n_samples, 4)) if out is None else out
    q[0] = q0
    chunks = [(k0, min(k0 + CHUNK, n_samples)) for k0 in range(1, n_samples, CHUNK)]

    def prepare(bounds):
        k = np.arange(*bounds)
        return _chunk_local(k, n_per_update, *increments(k))

    start = np.asarray(q0, dtype=np.float64)
    for (k0, k1), local in zip(chunks, _in_order(prepare, chunks), strict=True):
        _chunk_attitudes(local, start, q[k0:k1])
        start = q[k1 - 1]
    return q


def _in_order(fn, items):
    """``fn(item)`` for each item, in order; with several chunks, computed ahead by the
    :data:`_prepare_threads` worker threads when there are any (at most one more submitted
    ahead than threads: memory stays a few chunks)."""
    threads = _prepare_threads
    if len(items) < 2 or threads == 0:
        yield from map(fn, items)
        return
    ahead = threads + 1
    with ThreadPoolExecutor(max_workers=threads, thread_name_prefix="attitude_chunk") as pool:
        pending = deque(pool.submit(fn, it) for it in items[:ahead])
        for it in items[ahead:]:
            yield pending.popleft().result()
            pending.append(pool.submit(fn, it))
        while pending:
            yield pending.popleft().result()


class _ChunkLocal(NamedTuple):
    """The part of a chunk that does not depend on the attitude carried into it.

    One sample per update: ``b``, ``a`` are the prefix products of the increments (``a``
    None without a nav frame).  N per update: ``b``, ``a`` the partial increments since
    each block and ``b_blocks``, ``a_blocks`` the prefix products over whole blocks."""

    n_per_update: int
    b: np.ndarray
    a: np.ndarray | None
    b_blocks: np.ndarray | None = None
    a_blocks: np.ndarray | None = None


class LeftPrefix(NamedTuple):
    """What an ``increments`` function of :func:`compose_chunked` may return in place of the
    left increments ``a`` (one sample per update only): their products
    ``A_k = a_k ⊗ … ⊗ a_k0`` from the chunk's first interval on, already known."""

    products: np.ndarray


def _chunk_local(k, n_per_update, b, a) -> _ChunkLocal:
    if n_per_update == 1:
        if isinstance(a, LeftPrefix):
            return _ChunkLocal(1, prefix_product(b), a.products)
        return _ChunkLocal(1, prefix_product(b), None if a is None else prefix_product_left(a))
    if isinstance(a, LeftPrefix):
        raise ValueError("LeftPrefix needs one sample per update")
    nfull = k.size // n_per_update
    major = slice(n_per_update - 1, nfull * n_per_update, n_per_update)
    nblk = -(-k.size // n_per_update)
    bm = am = None
    if nblk > 1:
        bm = prefix_product(b[major][: nblk - 1])
        if a is not None:
            am = prefix_product_left(a[major][: nblk - 1])
    return _ChunkLocal(n_per_update, b, a, bm, am)


def _chunk_attitudes(local: _ChunkLocal, start, out) -> None:
    """Normalized attitudes of one chunk into ``out`` from its local part and the attitude
    ``start`` carried into it."""
    n, b, a = local.n_per_update, local.b, local.a
    if n == 1:
        # start ⊗ B_k is linear in B_k: one (m, 4) x (4, 4) product (then the nav frame's
        # A_k on the left, when there is one).  einsum's own loop, not matmul: OpenBLAS
        # would start threads that spin on the core the chunk workers need.
        np.einsum("ij,kj->ik", b, _left_product_matrix(start), out=out)
        if a is not None:
            out[:] = _qmul(a, out)
        out /= np.sqrt(np.einsum("ij,ij->i", out, out))[:, None]
        return
    m = b.shape[0]
    nblk = -(-m // n)
    # Attitude before each block: Q_{m-1} = A_{m-1} ⊗ start ⊗ B_{m-1}.
    q_before = np.empty((nblk, 4))
    q_before[0] = start
    if nblk > 1:
        qb = _qmul(start, local.b_blocks)
        if local.a_blocks is not None:
            qb = _qmul(local.a_blocks, qb)
        q_before[1:] = normalize_rows(qb)
    qrep = np.repeat(q_before, n, axis=0)[:m]
    res = _qmul(qrep, b)
    if a is not None:
        res = _qmul(a, res)
    out[:] = normalize_rows(res)


def _left_product_matrix(p: np.ndarray) -> np.ndarray:
    """The 4x4 matrix ``L`` with ``p ⊗ q = L q`` (x, y, z, w order; :func:`_qmul`)."""
    x, y, z, w = (float(c) for c in p)
    return np.array([[w, -z, y, x],
                     [z, w, -x, y],
                     [-y, x, w, z],
                     [-x, -y, -z, w]])


def first_interval_output(q0, b1, t, rate_n):
    """``q[1]`` as the causal stream emits it: ``a_1 ⊗ q0 ⊗ b_1`` from the linear fit."""
    out = _qmul(q0, b1)
    if rate_n is not None:
        out = _qmul(_exp_rotvec(-nav_zeta(t, rate_n, np.array([1]))[0]), out)
    return out / math.sqrt(float(np.dot(out, out)))


# --------------------------------------------------------------------------- plain floats
# The streaming steps work on tuples of floats: numpy's per-call overhead on 3-vectors
# (~1 µs per operation) would cost ~100 µs per update.  Kernels (core/jit.py): the compiled
# per-sample chain calls these same functions.

@kernel(inline=True)
def exp_scalar(x, y, z):
    """Scalar twin of :func:`gyro_attitude.core.rotation._exp_rotvec` (same series)."""
    th2 = x * x + y * y + z * z
    th = math.sqrt(th2)
    if th < 1e-4:
        k = 0.5 - th2 / 48.0 + th2 * th2 / 3840.0
    else:
        k = math.sin(0.5 * th) / th
    return (x * k, y * k, z * k, math.cos(0.5 * th))


@kernel(inline=True)
def qmul_scalar(a, b):
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz)


@kernel(inline=True)
def compose_scalar(q, b, zeta):
    """``normalize(exp(−ζ) ⊗ q ⊗ b)`` in plain floats (``zeta`` None: no nav frame)."""
    out = qmul_scalar(q, b)
    if zeta is not None:
        out = qmul_scalar(exp_scalar(-zeta[0], -zeta[1], -zeta[2]), out)
    n = math.sqrt(out[0] * out[0] + out[1] * out[1] + out[2] * out[2] + out[3] * out[3])
    return (out[0] / n, out[1] / n, out[2] / n, out[3] / n)
