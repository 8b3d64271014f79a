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
    """The polynomial through ``(x_nodes, y_nodes)`` at ``x_eval``: (M, n) s, (M, n, 3), (M, p)
    → (M, p, 3), each row its own nodes (Lagrange form, n ≤ 6).  For rows gathered one by one
    (the ends of a record); runs of rows use :func:`sliding_fit_rates`."""
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
    """Rates (len(fractions), k1-k0, 3) at ``t_{k-1} + f h_k`` for the intervals ``k0 ≤ k <
    k1`` from the polynomial through the ``n`` samples ``k-offset … k-offset+n-1`` (all inside
    the record): :func:`lagrange_eval`'s fit on slices, the nodes in units of ``h_k`` from int64
    differences; on equally spaced samples every row has the same weights, computed once."""
    m = k1 - k0
    s0 = k0 - offset  # window start of the first row
    fr = [float(f) for f in fractions]
    out = np.empty((len(fr), m, 3))
    if m <= 0:
        return out
    # u_j: node j relative to t_{k-1} in units of h_k; a plain float where it is the same on
    # every row (the interval's ends 0 and 1, or every node on equally spaced samples)
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
    samples ``k-offset … k-offset+n_nodes-1``: :func:`sliding_fit_rates` where ``k`` is a run
    and the window lies inside the record; the other rows (the ends of the record, where a
    method fits fewer or shifted samples, or scattered ``k``) from ``gathered(k_rows)``."""
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
# A rate fit is trusted only where its samples resolve the motion (docs/equations.md "When a rate
# fit cannot be trusted"; the thresholds measured by ``bench --suite nyquist``): not where the
# rate's change turns by more than FIT_TURN_MAX_RAD from one sample to the next (aliasing near
# Nyquist) while that change is an angle that matters (h·|Δω| >= FIT_CHANGE_MIN_RAD), nor where
# the fitted rate leaves its samples' range by more than FIT_OVERSHOOT_MAX times their spread
# (tested on uneven stamps only: on even ones the Lagrange weights keep it below 1).  Such an
# interval's step moves toward the exponential map of the endpoint mean, counted.  The tests
# below work on floats and arrays alike: the causal step runs them compiled, one interval at a
# time (:func:`untrusted_fit_scalar`), the offline quintic as numpy over a record
# (:func:`untrusted_fits`: an offline replay imports no compiler).
FIT_OVERSHOOT_MAX = 2.0
FIT_TURN_MAX_RAD = 2.6
FIT_CHANGE_MIN_RAD = 1e-2
_TURN_COS = math.cos(FIT_TURN_MAX_RAD)
_TURN_COS2 = _TURN_COS * _TURN_COS
_CHANGE_MIN2 = FIT_CHANGE_MIN_RAD * FIT_CHANGE_MIN_RAD
_EVEN_TOL = 1e-3  # relative spread of the steps under which the stamps count as even


@kernel(inline=True)
def _turned(dot, na, nb, h):
    """Whether the rate's change ``b`` (squared norm ``nb``, over a step ``h`` s) matters and
    turned from the one before, ``a`` (``na``; ``dot = a·b``), by more than FIT_TURN_MAX_RAD."""
    return (nb * (h * h) >= _CHANGE_MIN2) & (dot < 0.0) & (dot * dot > _TURN_COS2 * na * nb)


@kernel(inline=True)
def _turn_weight(turn):
    """The exponential map's weight of a change turned by ``turn`` rad: from 0 at
    FIT_TURN_MAX_RAD to 1 at π.  The callers take the arc cosine, ``math.acos`` on a float and
    ``np.arccos`` on an array: numpy's arc cosine of a float differs from libm's, which the
    compiled step calls, in the last bit."""
    return np.minimum(np.maximum((turn - FIT_TURN_MAX_RAD) / (math.pi - FIT_TURN_MAX_RAD),
                                 1e-300), 1.0)


@kernel(inline=True)
def _overshoots(f, lo, hi):
    """Whether the fitted rate ``f`` leaves its samples' range ``[lo, hi]`` by more than
    FIT_OVERSHOOT_MAX times its spread."""
    slack = FIT_OVERSHOOT_MAX * (hi - lo) + 1e-12 * (np.abs(lo) + np.abs(hi))
    return (f > hi + slack) | (f < lo - slack)


def untrusted_fits(t_ns: np.ndarray, omega: np.ndarray, k: np.ndarray, fitted: np.ndarray,
                   window) -> np.ndarray | None:
    """The exponential map's weight for each of the intervals ``k`` (sample k-1 to k), fitted
    at the rates ``fitted`` (len(k), p, 3), or None when every fit can be trusted (the usual
    case: a few array operations).  ``window(k)`` → (first, last) sample of each row's fit
    (inclusive), needed on uneven stamps only.  Runs of consecutive intervals (what the
    integrators pass) are judged on slices, each run of scattered ``k`` on its own."""
    k = np.asarray(k)
    starts = np.flatnonzero(np.diff(k) != 1) + 1
    if starts.size == 0:
        return _untrusted_run(t_ns, omega, k, fitted, window)
    bad = None
    for rows in np.split(np.arange(k.size), starts):
        run = _untrusted_run(t_ns, omega, k[rows], fitted[rows], window)
        if run is not None:
            bad = np.zeros(k.size) if bad is None else bad
            bad[rows] = run
    return bad


def _untrusted_run(t_ns, omega, k, fitted, window) -> np.ndarray | None:
    """:func:`untrusted_fits` for a run of consecutive intervals ``k``."""
    m = k.size
    if m == 0:
        return None
    k0 = int(k[0])
    steps = np.diff(t_ns[max(k0 - 6, 0):min(k0 + m + 5, t_ns.size)])
    s_min, s_max = (int(steps.min()), int(steps.max())) if steps.size else (1, 1)
    h_max = s_max * 1e-9
    bad = None
    if t_ns.size > 2:
        # the changes into samples j - 1 and j, j = max(k, 2) (interval 1 takes change 2, as
        # interval 2 does).  A first pass with the longest step keeps the rows whose change
        # may matter (few: noise at rest and resolved motion change by far less).
        j0 = max(k0, 2)
        db = omega[j0:k0 + m] - omega[j0 - 1:k0 + m - 1]
        if k0 == 1:
            db = np.concatenate((omega[2:3] - omega[1:2], db))
        nb = np.einsum("ij,ij->i", db, db)
        cand = np.flatnonzero(nb >= _CHANGE_MIN2 / (h_max * h_max))
        if cand.size:
            j = np.maximum(k0 + cand, 2)
            nb, db = nb[cand], db[cand]
            da = omega[j - 1] - omega[j - 2]
            dot = np.einsum("ij,ij->i", da, db)
            na = np.einsum("ij,ij->i", da, da)
            hit = _turned(dot, na, nb, (t_ns[j] - t_ns[j - 1]) * 1e-9)
            if hit.any():
                bad = np.zeros(m)
                cos = dot[hit] / np.sqrt(na[hit] * nb[hit])
                bad[cand[hit]] = _turn_weight(np.arccos(np.clip(cos, -1.0, 1.0)))
    if s_max - s_min > _EVEN_TOL * s_min:  # overshoot: on uneven stamps only
        first, last = window(k)
        lo = hi = omega[first]
        for jj in range(1, int((last - first).max()) + 1):
            wj = omega[np.minimum(first + jj, last)]
            lo, hi = np.minimum(lo, wj), np.maximum(hi, wj)
        over = _overshoots(fitted, lo[:, None], hi[:, None]).any(axis=(1, 2))
        if over.any():
            bad = over.astype(np.float64) if bad is None else np.where(over, 1.0, bad)
    return bad


@kernel(inline=True)
def untrusted_fit_scalar(ts, ws, k, n, f0, f1) -> float:
    """The rule above for one interval ``k`` of the causal step's histories ``ts, ws`` (their
    first ``n`` entries, the fit's nodes) fitted at two points (the rates ``f0``, ``f1``): the
    exponential map's weight, 0.0 when the fit can be trusted.  Indexing only, nothing
    allocated."""
    weight = 0.0
    j = max(k, 2)
    if j < n:
        b, m, a = ws[j], ws[j - 1], ws[j - 2]
        db0, db1, db2 = b[0] - m[0], b[1] - m[1], b[2] - m[2]
        da0, da1, da2 = m[0] - a[0], m[1] - a[1], m[2] - a[2]
        nb = db0 * db0 + db1 * db1 + db2 * db2
        dot = da0 * db0 + da1 * db1 + da2 * db2
        na = da0 * da0 + da1 * da1 + da2 * da2
        if _turned(dot, na, nb, (ts[j] - ts[j - 1]) * 1e-9):
            weight = _turn_weight(math.acos(max(-1.0, min(1.0, dot / math.sqrt(na * nb)))))
    if n > 2 and _uneven(ts, n):
        for c in range(3):
            lo, hi = math.inf, -math.inf
            for i in range(n):
                v = ws[i][c]
                if v < lo:
                    lo = v
                if v > hi:
                    hi = v
            if _overshoots(f0[c], lo, hi) or _overshoots(f1[c], lo, hi):
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
    if lam is None:
        return
    bad = np.flatnonzero(lam)
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
