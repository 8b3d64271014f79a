"""Polynomial fits of rate samples in time (any spacing): batch and plain-float evaluation."""

from __future__ import annotations

import math

import numpy as np

GAUSS2 = (0.5 - 0.5 / math.sqrt(3.0), 0.5 + 0.5 / math.sqrt(3.0))  # 2-point Gauss nodes in [0, 1]
# Nodes of a streaming fit through the last n samples held (n = 2, 3, 4).
NODES = {n: tuple(range(n)) for n in range(1, 5)}


def lagrange_eval(x_nodes: np.ndarray, y_nodes: np.ndarray, x_eval: np.ndarray) -> np.ndarray:
    """Evaluate the interpolating polynomial through ``(x_nodes, y_nodes)``.

    ``x_nodes`` (M, n) in s, ``y_nodes`` (M, n, 3), ``x_eval`` (M, p) → (M, p, 3).  Each
    row has its own (non-uniform) nodes; Lagrange form, n ≤ 6 so the O(n²) weights are
    cheap and exact enough (nodes are distinct, spacing ≥ 1 ns).  For rows gathered one by
    one (ends of a record); runs of rows use :func:`sliding_fit_rates`.
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


def sliding_fit_rates(t_ns: np.ndarray, omega: np.ndarray, k0: int, k1: int, offset: int,
                      n: int, fractions) -> np.ndarray:
    """Rates at ``t_{k-1} + f h_k`` for the intervals ``k0 ≤ k < k1`` from the polynomial
    through the ``n`` samples ``k-offset … k-offset+n-1`` (all inside the record).

    Returns (len(fractions), k1-k0, 3).  Same fit as :func:`lagrange_eval` on gathered
    rows, computed on slices: node positions in units of ``h_k`` from int64 differences,
    the Lagrange denominators once for all fractions.  When the samples are equally
    spaced (equal int64 steps over the whole run), every row has the same weights:
    they are computed once and the fit is n scaled sums of slices.
    """
    m = k1 - k0
    s0 = k0 - offset  # window start of the first row
    fr = [float(f) for f in fractions]
    out = np.empty((len(fr), m, 3))
    if m <= 0:
        return out
    # u_j: node j relative to t_{k-1} in units of h_k.  Plain floats where it is the same on
    # every row (the interval's own ends, 0 and 1; every node when the samples are equally
    # spaced: (j - offset + 1)), so their terms cost no array operation and, when all are
    # floats, every row gets the same weights.
    steps = np.diff(t_ns[s0:s0 + m + n - 1])
    if (steps == steps[0]).all():
        u = [float(j - offset + 1) for j in range(n)]
    else:
        t_left = t_ns[k0 - 1:k1 - 1]
        h = (t_ns[k0:k1] - t_left).astype(np.float64)
        u = [float(j - offset + 1) if offset - 1 <= j <= offset
             else (t_ns[s0 + j:s0 + j + m] - t_left) / h for j in range(n)]
    inv_den = []
    for j in range(n):
        d = None
        for i in range(n):
            if i != j:
                d = u[j] - u[i] if d is None else d * (u[j] - u[i])
        inv_den.append(1.0 / d)
    weights = []
    for e in fr:
        diff = [e - ui for ui in u]
        # numerator of weight j: ∏_{i≠j} (e − u_i) from prefix and suffix products
        pre = [None] * n
        acc = None
        for j in range(n):
            pre[j] = acc
            acc = diff[j] if acc is None else acc * diff[j]
        row, acc = [None] * n, None
        for j in range(n - 1, -1, -1):
            num = pre[j] if acc is None else (acc if pre[j] is None else pre[j] * acc)
            wj = num * inv_den[j]
            row[j] = wj[:, None] if np.ndim(wj) else wj  # per row, or one for all rows
            acc = diff[j] if acc is None else acc * diff[j]
        weights.append(row)
    tmp = np.empty((m, 3))
    for f, row in enumerate(weights):
        o = out[f]
        np.multiply(omega[s0:s0 + m], row[0], out=o)
        for j in range(1, n):
            np.multiply(omega[s0 + j:s0 + j + m], row[j], out=tmp)
            o += tmp
    return out


def fitted_rates(t_ns: np.ndarray, omega: np.ndarray, k: np.ndarray, fractions,
                 offset: int, n_nodes: int, gathered) -> np.ndarray:
    """Rates (len(k), len(fractions), 3) at ``t_{k-1} + f h_k`` from the polynomial through
    samples ``k-offset … k-offset+n_nodes-1``.

    The rows whose window lies inside the record take :func:`sliding_fit_rates` when ``k``
    is a run of consecutive intervals (what the batch integrators pass); the others (the
    ends of the record, where a method fits fewer or shifted samples, or scattered ``k``)
    come from ``gathered(k_rows)`` → (len(k_rows), len(fractions), 3).
    """
    k = np.asarray(k)
    m = k.size
    lo, hi = offset, t_ns.size - n_nodes + offset  # intervals with the whole window inside
    if m == 0 or not (k[-1] - k[0] == m - 1 and (m == 1 or (np.diff(k) == 1).all())):
        return gathered(k)
    i0 = min(max(lo - int(k[0]), 0), m)
    i1 = max(min(hi - int(k[0]) + 1, m), i0)
    if i1 == i0:
        return gathered(k)
    out = np.empty((len(fractions), m, 3))
    out[:, i0:i1] = sliding_fit_rates(t_ns, omega, int(k[i0]), int(k[i1 - 1]) + 1, offset,
                                      n_nodes, fractions)
    for r0, r1 in ((0, i0), (i1, m)):
        if r1 > r0:
            out[:, r0:r1] = gathered(k[r0:r1]).transpose(1, 0, 2)
    return out.transpose(1, 0, 2)


def causal_rates_at(t_ns: np.ndarray, omega: np.ndarray, k: np.ndarray,
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
    fit before going on.
    """
    return fitted_rates(t_ns, omega, k, fractions, 3, 4,
                        lambda kk: _gathered_causal_rates(t_ns, omega, kk, fractions,
                                                          lookahead))


def _gathered_causal_rates(t_ns, omega, k, fractions, lookahead):
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
        out[sel] = lagrange_eval(x, omega[idx], h[:, None] * fr[None, :])
    return out


def lagrange_scalar(xs, ys, e):
    """Plain-float twin of :func:`lagrange_eval` at one point ``e`` (ys: 3-tuples)."""
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


def causal_rates_scalar(ts, ws, k, nodes, fractions):
    """Plain-float twin of :func:`causal_rates_at` for one interval ``k`` (fit on ``nodes``)."""
    t_prev = ts[k - 1]
    h = (ts[k] - t_prev) * 1e-9
    xs = [(ts[i] - t_prev) * 1e-9 for i in nodes]
    ys = [ws[i] for i in nodes]
    return [lagrange_scalar(xs, ys, h * f) for f in fractions]
