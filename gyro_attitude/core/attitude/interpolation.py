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
