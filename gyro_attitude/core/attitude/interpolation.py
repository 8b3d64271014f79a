"""Polynomial fits of rate samples in time (any spacing) and whether one can be trusted: the
causal step's kernels (the cubic through the last samples held, one interval at a time) and the
offline ``magnus6_quintic``'s vectorized fits over a whole record (numpy only: an offline replay
imports no compiler)."""

from __future__ import annotations

import math

import numpy as np

from gyro_attitude.core.jit import kernel

GAUSS2 = (0.5 - 0.5 / math.sqrt(3.0), 0.5 + 0.5 / math.sqrt(3.0))  # 2-point Gauss nodes in [0, 1]


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
                xj = x_nodes[:, j:j + 1]
                w = w * (x_eval - xj) / (x_nodes[:, i:i + 1] - xj)
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


# --------------------------------------------------------------------------- trusting a fit
# A rate fit is a polynomial through samples; it can be trusted only where the samples resolve
# the motion.  Two signs that they do not (docs/equations.md "When a rate fit cannot be trusted";
# the thresholds are measured by ``bench --suite nyquist``):
#
# * the fitted rate leaves the range of the samples it was fitted to by more than
#   FIT_OVERSHOOT_MAX times their spread.  On equally spaced samples it cannot: the Lagrange
#   weights bound the overshoot by (Σ|w| − 1)/2 of the spread — 0.232 for the causal cubic's
#   Gauss points, 0.195 for the centered quintic's, 0.996 for the quintic's one-sided windows at
#   the ends of a record — so this fires only on uneven stamps (after missing samples the
#   cubic extrapolates over the hole), and is not evaluated on (nearly) even ones;
# * the rate's change turns by more than FIT_TURN_MAX_RAD from one sample to the next: a rate
#   vector turning at Ω rad/s sampled every h turns its sample-to-sample change by Ωh, which
#   reaches π at the Nyquist rate, where a cone turning one way at Ω and the other way at
#   2π/h − Ω give the same samples (the transverse ones), so no fit can know the sign of the
#   commutation term that the higher-order step adds; the exponential map of the held rate
#   adds none.  Only where that change is an angle that matters (h·|Δω| ≥
#   FIT_CHANGE_MIN_RAD): white noise turns its differences by ~120° on average (often past
#   the bound), but its change per step is h·|Δω| ≈ 2.4·N·√h for a noise density N — 1e-2 rad
#   needs N ≥ 4e-3/√h (0.03 rad/√s at 50 Hz, ~100× a poor MEMS gyro), while the aliased cones
#   this is for (half-angle ≥ 0.1° at 100 Hz) exceed it;
# The step of such an interval falls back to the exponential map of the endpoint mean
# (``exp_map``), counted.  The rule is evaluated by the causal step, one interval at a time
# (:func:`untrusted_fit_scalar`), and over a whole record by the offline quintic
# (:func:`untrusted_fits`, vectorized: the offline estimator runs no compiled code).
FIT_OVERSHOOT_MAX = 2.0
FIT_TURN_MAX_RAD = 2.6
FIT_CHANGE_MIN_RAD = 1e-2
_TURN_COS = math.cos(FIT_TURN_MAX_RAD)
_TURN_COS2 = _TURN_COS * _TURN_COS
_CHANGE_MIN2 = FIT_CHANGE_MIN_RAD * FIT_CHANGE_MIN_RAD
_EVEN_TOL = 1e-3  # relative spread of the steps under which the stamps count as even


def untrusted_fits(t_ns: np.ndarray, omega: np.ndarray, k: np.ndarray, fitted: np.ndarray,
                   window) -> np.ndarray | None:
    """Which intervals ``k`` (sample k-1 to k) have a rate fit that cannot be trusted (the
    rule above): a bool mask (len(k),), or None when none has (the usual case, found with a
    few array operations over the rows).

    ``fitted`` (len(k), p, 3) the fitted rates; ``window(k)`` → (first, last) sample of each
    row's fit (inclusive), needed only on uneven stamps.
    """
    m = k.size
    if m == 0:
        return None
    k0 = int(k[0])
    kmin, kmax = (k0, int(k[-1])) if k[-1] - k0 == m - 1 else (int(k.min()), int(k.max()))
    steps = np.diff(t_ns[max(kmin - 6, 0):min(kmax + 6, t_ns.size)])
    s_min = int(steps.min()) if steps.size else 1
    s_max = int(steps.max()) if steps.size else 1
    h_max = s_max * 1e-9
    bad = None
    # the turn of the rate's change, where the change is an angle that matters: changes
    # j-1 and j, j = k (interval 1: the next change, where sample 2 exists).  A first pass
    # with the longest step keeps the rows that may pass the angle test (few: noise at rest
    # and resolved motion change by far less); the exact tests run on those rows only.
    run = k[-1] - k0 == m - 1 and (k0 >= 2 or (k0 == 1 and t_ns.size > 2 and m >= 2))
    if run:  # a run of intervals: slices (interval 1 takes change 2, as interval 2 does)
        j0 = max(k0, 2)
        db = omega[j0:k0 + m] - omega[j0 - 1:k0 + m - 1]
        if k0 == 1:
            db = np.concatenate((db[:1], db))
        rows_ = None
    else:
        rows_ = np.flatnonzero((k >= 2) | (t_ns.size > 2))
        kk = np.maximum(k[rows_], 2)
        db = omega[kk] - omega[kk - 1]
    nb = np.einsum("ij,ij->i", db, db)
    cand = np.flatnonzero(nb >= _CHANGE_MIN2 / (h_max * h_max))
    if cand.size:
        j = np.maximum(k0 + cand if run else k[rows_[cand]], 2)
        h = (t_ns[j] - t_ns[j - 1]) * 1e-9
        nb, db = nb[cand], db[cand]
        keep = nb * (h * h) >= _CHANGE_MIN2
        cand, j, nb, db = cand[keep], j[keep], nb[keep], db[keep]
        da = omega[j - 1] - omega[j - 2]
        dot = np.einsum("ij,ij->i", da, db)
        na = np.einsum("ij,ij->i", da, da)
        turned = (dot < 0.0) & (dot * dot > _TURN_COS2 * na * nb)
        if turned.any():
            bad = np.zeros(m)
            hit = cand[turned]
            turn = np.arccos(np.clip(dot[turned] / np.sqrt(na[turned] * nb[turned]), -1.0, 1.0))
            bad[hit if rows_ is None else rows_[hit]] = np.clip(
                (turn - FIT_TURN_MAX_RAD) / (math.pi - FIT_TURN_MAX_RAD), 1e-300, 1.0)
    # overshoot beyond the samples' range: only on uneven stamps
    if s_max - s_min > _EVEN_TOL * s_min:
        first, last = window(k)
        lo = hi = omega[first]
        for jj in range(1, int((last - first).max()) + 1):
            wj = omega[np.minimum(first + jj, last)]
            lo, hi = np.minimum(lo, wj), np.maximum(hi, wj)
        slack = FIT_OVERSHOOT_MAX * (hi - lo) + 1e-12 * (np.abs(lo) + np.abs(hi))
        over = ((fitted > (hi + slack)[:, None])
                | (fitted < (lo - slack)[:, None])).any(axis=(1, 2))
        if over.any():
            bad = over.astype(np.float64) if bad is None else np.where(over, 1.0, bad)
    return bad


@kernel(inline=True)
def untrusted_fit_scalar(ts, ws, k, n, f0, f1) -> float:
    """The rule above (:func:`untrusted_fits` for the offline quintic) for one interval ``k`` of
    the causal step's histories ``ts, ws`` (their first ``n`` entries, the fit's nodes) fitted
    at two points (the rates ``f0``, ``f1``): the weight of the exponential map's step, 0.0
    when the fit can be trusted.  A kernel (:mod:`gyro_attitude.core.jit`): indexing only,
    nothing allocated."""
    weight = 0.0
    j = max(k, 2)
    if j < n:
        b, m, a = ws[j], ws[j - 1], ws[j - 2]
        db0, db1, db2 = b[0] - m[0], b[1] - m[1], b[2] - m[2]
        da0, da1, da2 = m[0] - a[0], m[1] - a[1], m[2] - a[2]
        h = (ts[j] - ts[j - 1]) * 1e-9
        nb = db0 * db0 + db1 * db1 + db2 * db2
        if nb * (h * h) >= _CHANGE_MIN2:
            dot = da0 * db0 + da1 * db1 + da2 * db2
            na = da0 * da0 + da1 * da1 + da2 * da2
            if dot < 0.0 and dot * dot > _TURN_COS2 * na * nb:
                turn = math.acos(max(-1.0, min(1.0, dot / math.sqrt(na * nb))))
                weight = min(max((turn - FIT_TURN_MAX_RAD) / (math.pi - FIT_TURN_MAX_RAD),
                                 1e-300), 1.0)
    if n > 2 and _uneven(ts, n):
        for c in range(3):
            lo, hi = math.inf, -math.inf
            for i in range(n):
                v = ws[i][c]
                if v < lo:
                    lo = v
                if v > hi:
                    hi = v
            slack = FIT_OVERSHOOT_MAX * (hi - lo) + 1e-12 * (abs(lo) + abs(hi))
            if f0[c] > hi + slack or f0[c] < lo - slack or f1[c] > hi + slack \
                    or f1[c] < lo - slack:
                return 1.0
    return weight


@kernel(inline=True)
def _uneven(ts, n) -> bool:
    """Whether the steps of the first ``n`` stamps ``ts`` spread by more than _EVEN_TOL of the
    shortest."""
    prev = ts[1]
    s_min = s_max = prev - ts[0]
    for i in range(2, n):
        step = ts[i] - prev
        prev = ts[i]
        if step < s_min:
            s_min = step
        elif step > s_max:
            s_max = step
    return s_max - s_min > _EVEN_TOL * s_min


def hold_untrusted(t_ns, omega, k, fitted, phi, h, window, fallbacks) -> None:
    """Where the fit of intervals ``k`` cannot be trusted (:func:`untrusted_fits`), blend the
    rotation vector ``phi`` (len(k), 3) of the step toward the exponential map's,
    ``½(ω_{k-1}+ω_k)h`` (``h`` (len(k), 1)), by the weight it gives each row; the intervals
    that fell back are appended to the list ``fallbacks`` (None: not collected)."""
    lam = untrusted_fits(t_ns, omega, k, fitted, window)
    bad = np.flatnonzero(lam > 0.0) if lam is not None else np.zeros(0, dtype=np.intp)
    if bad.size == 0:
        return
    kb = k[bad]
    lb = lam[bad][:, None]
    phi[bad] = (1.0 - lb) * phi[bad] + lb * (0.5 * (omega[kb - 1] + omega[kb]) * h[bad])
    if fallbacks is not None:
        fallbacks.append(kb)


@kernel(inline=True)
def _lagrange_at(n, x0, x1, x2, x3, y0, y1, y2, y3, e):
    """The polynomial through the first ``n`` (2, 3 or 4) of the nodes ``(x_i, y_i)`` at
    ``e`` (Lagrange form, written out per node count: nothing allocated)."""
    if n == 4:
        d01, d02, d03, d12, d13, d23 = x0 - x1, x0 - x2, x0 - x3, x1 - x2, x1 - x3, x2 - x3
        i0 = 1.0 / (d01 * d02 * d03)
        i1 = -1.0 / (d01 * d12 * d13)
        i2 = 1.0 / (d02 * d12 * d23)
        i3 = -1.0 / (d03 * d13 * d23)
        a0, a1, a2, a3 = e - x0, e - x1, e - x2, e - x3
        a01, a23 = a0 * a1, a2 * a3
        w0, w1, w2, w3 = a1 * a23 * i0, a0 * a23 * i1, a01 * a3 * i2, a01 * a2 * i3
        return (w0 * y0[0] + w1 * y1[0] + w2 * y2[0] + w3 * y3[0],
                w0 * y0[1] + w1 * y1[1] + w2 * y2[1] + w3 * y3[1],
                w0 * y0[2] + w1 * y1[2] + w2 * y2[2] + w3 * y3[2])
    if n == 3:
        w0 = 1.0 / (1.0 * (x0 - x1) * (x0 - x2)) * (e - x1) * (e - x2)
        w1 = 1.0 / (1.0 * (x1 - x0) * (x1 - x2)) * (e - x0) * (e - x2)
        w2 = 1.0 / (1.0 * (x2 - x0) * (x2 - x1)) * (e - x0) * (e - x1)
        return (0.0 + w0 * y0[0] + w1 * y1[0] + w2 * y2[0],
                0.0 + w0 * y0[1] + w1 * y1[1] + w2 * y2[1],
                0.0 + w0 * y0[2] + w1 * y1[2] + w2 * y2[2])
    w0 = 1.0 / (1.0 * (x0 - x1)) * (e - x1)
    w1 = 1.0 / (1.0 * (x1 - x0)) * (e - x0)
    return (0.0 + w0 * y0[0] + w1 * y1[0], 0.0 + w0 * y0[1] + w1 * y1[1],
            0.0 + w0 * y0[2] + w1 * y1[2])


@kernel(inline=True)
def causal_fit_two(ts, ws, k, n, fa, fb):
    """:func:`causal_fit_points` and whether the fit can be trusted
    (:func:`untrusted_fit_scalar`): (rate at ``fa``, at ``fb``, h, the exponential map's
    weight)."""
    f0, f1, h = causal_fit_points(ts, ws, k, n, fa, fb)
    return f0, f1, h, untrusted_fit_scalar(ts, ws, k, n, f0, f1)


@kernel(inline=True)
def causal_fit_points(ts, ws, k, n, fa, fb):
    """The causal fit through the first ``n`` samples of the histories at the fractions
    ``fa`` and ``fb`` of interval ``k``: (rate at the first point, at the second, h)."""
    t_prev = ts[k - 1]
    h = (ts[k] - t_prev) * 1e-9
    x0 = (ts[0] - t_prev) * 1e-9
    x1 = (ts[1] - t_prev) * 1e-9
    x2 = (ts[2] - t_prev) * 1e-9 if n > 2 else 0.0
    x3 = (ts[3] - t_prev) * 1e-9 if n > 3 else 0.0
    y0, y1 = ws[0], ws[1]
    y2 = ws[2] if n > 2 else ws[0]
    y3 = ws[3] if n > 3 else ws[0]
    f0 = _lagrange_at(n, x0, x1, x2, x3, y0, y1, y2, y3, h * fa)
    f1 = _lagrange_at(n, x0, x1, x2, x3, y0, y1, y2, y3, h * fb)
    return f0, f1, h
