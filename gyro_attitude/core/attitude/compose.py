"""Composing increments into attitudes: blocked prefix product (batch), plain-float kernels."""

from __future__ import annotations

import math
import os
from collections import deque
from concurrent.futures import ThreadPoolExecutor
from typing import NamedTuple

import numpy as np

from gyro_attitude.core.jit import kernel
from gyro_attitude.core.rotation import _qmul

IDENTITY = np.array([0.0, 0.0, 0.0, 1.0])
CHUNK = 61440  # intervals per batch chunk
_CONJ = np.array([-1.0, -1.0, -1.0, 1.0])


def _cpus() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


#: Worker threads of :func:`compose_chunked` that prepare chunks ahead of the thread carrying
#: the attitude: two when this process may use several CPUs, else none (a pool worker sets 0:
#: its peers keep every core busy).  The arithmetic is the same either way.
_prepare_threads = 2 if _cpus() >= 2 else 0


def set_prepare_threads(n: int) -> int:
    """Set the chunk-preparing threads of this process; returns the previous number."""
    global _prepare_threads
    if isinstance(n, bool) or not isinstance(n, int) or not 0 <= n <= 64:
        raise ValueError(f"prepare threads must be an integer from 0 to 64, got {n!r}")
    previous, _prepare_threads = _prepare_threads, n
    return previous


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
        p = None
        for i, row in enumerate(d.tolist()):
            p = row if p is None else qmul_scalar(p, row)
            out[i] = p
        return out
    rows = _SCAN_ROWS
    nb = -(-m // rows)
    pad = nb * rows - m
    if pad:
        d = np.concatenate((d, np.tile(IDENTITY, (pad, 1))))
    # (4, rows, nb): component c of factor j of block b; each row slice is contiguous.
    x = np.ascontiguousarray(d.reshape(nb, rows, 4).transpose(2, 1, 0))
    for j in range(1, rows):
        x[:, j] = qmul_scalar(x[:, j - 1], x[:, j])
    totals = np.ascontiguousarray(x[:, rows - 1, :].T)  # (nb, 4)
    before = np.empty_like(totals)
    before[0] = IDENTITY
    if nb > 1:
        # Renormalize at block boundaries so the rounding of one block cannot scale the next.
        p = prefix_product(totals[:-1])
        before[1:] = p / np.sqrt(np.einsum("...i,...i->...", p, p))[..., None]
    res = _qmul(before[None, :, :], x.transpose(1, 2, 0))  # (rows, nb, 4)
    return res.transpose(1, 0, 2).reshape(nb * rows, 4)[:m]


def prefix_product_left(a: np.ndarray) -> np.ndarray:
    """``A_k = a_k ⊗ … ⊗ a_0`` as ``conj(prefix(conj(a)))`` (conjugation reverses order)."""
    return prefix_product(a * _CONJ) * _CONJ


def compose_chunked(n_samples: int, q0: np.ndarray, increments,
                    out: np.ndarray | None = None) -> np.ndarray:
    """``q_k = A_k ⊗ q0 ⊗ B_k`` over all intervals (the offline ``magnus6_quintic``'s batch)
    into ``out`` (n_samples, 4) or a new array, ``B_k``, ``A_k`` the prefix products of the
    body and nav increments: ``increments(k)`` gives ``(b, a)`` for the interval indices
    ``k`` (``a`` None without a nav frame, or a :class:`LeftPrefix`).  Chunk by chunk (memory
    bounded, the scans in cache; the carried attitude normalized at chunk boundaries); a
    chunk's increments and prefix products are prepared ahead by worker threads
    (:func:`_in_order`), so ``increments`` must be a pure function of ``k``.
    """
    q = np.empty((n_samples, 4)) if out is None else out
    q[0] = q0
    chunks = [(k0, min(k0 + CHUNK, n_samples)) for k0 in range(1, n_samples, CHUNK)]

    def prepare(bounds):
        b, a = increments(np.arange(*bounds))
        if a is not None:
            a = a.products if isinstance(a, LeftPrefix) else prefix_product_left(a)
        return prefix_product(b), a

    start = np.asarray(q0, dtype=np.float64)
    for (k0, k1), (b, a) in zip(chunks, _in_order(prepare, chunks), strict=True):
        # start ⊗ B_k is linear in B_k: one (m, 4) x (4, 4) product (then the nav frame's
        # A_k on the left, when there is one).  einsum's own loop, not matmul: OpenBLAS
        # would start threads that spin on the core the chunk workers need.
        out_k = q[k0:k1]
        np.einsum("ij,kj->ik", b, _left_product_matrix(start), out=out_k)
        if a is not None:
            out_k[:] = _qmul(a, out_k)
        out_k /= np.sqrt(np.einsum("ij,ij->i", out_k, out_k))[:, None]
        start = q[k1 - 1]
    return q


def _in_order(fn, items):
    """``fn(item)`` for each item, in order, computed ahead by the :data:`_prepare_threads`
    worker threads when there are any (numpy releases the GIL in its loops; at most one
    more submitted ahead than threads: memory stays a few chunks)."""
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


class LeftPrefix(NamedTuple):
    """The left products ``A_k = a_k ⊗ … ⊗ a_k0`` of a chunk, already known (in place of
    the increments ``a`` of :func:`compose_chunked`)."""

    products: np.ndarray


def _left_product_matrix(p: np.ndarray) -> np.ndarray:
    """The 4x4 matrix ``L`` with ``p ⊗ q = L q`` (x, y, z, w order; :func:`_qmul`)."""
    x, y, z, w = (float(c) for c in p)
    return np.array([[w, -z, y, x],
                     [z, w, -x, y],
                     [-y, x, w, z],
                     [-x, -y, -z, w]])


# plain floats (numpy's per-call overhead on 3-vectors would cost ~100 µs per update);
# kernels: the compiled per-sample chain calls these same functions

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
