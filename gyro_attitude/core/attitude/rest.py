"""Rest (zero-motion) detection from gyro and accelerometer statistics over a sliding time window.

The kernel :func:`rest_update` (one call per accepted sample, O(1) amortized) says whether the
window that ENDS at this sample (all samples with ``t >= t_ns - window``) is at rest; the index
of its oldest sample (counted from :func:`rest_start` / :func:`rest_reset`) is then
``ri[R_OLDEST]``.  The consumers (gyro bias, alignment) take the *oldest* sample of each rest
window, so a sample counts once a full window of rest follows it.  :func:`detect_rest` (the
offline estimator's) steps the same kernel over arrays in a compiled loop, :func:`rest_rows`.
A window is at rest when it spans a full ``rest_window_s`` since the first sample, the gyro's
deviation from the window mean (over 3 axes) lies in [``gyro_std_min``,
``rest_gyro_std_max``], the window-mean rate is within ``rest_gyro_mean_max`` on every axis
and, with an accelerometer, its deviation is within ``rest_accel_std_max`` and ``|‖mean f‖ −
g|`` within ``rest_accel_norm_tol``.  The thresholds are the settings table's rows; why these
tests and defaults: docs/architecture.md, "Notes: rest detection".

Numerics: window sums are differences of running (cumulative) sums of ``x − x_first`` and its
square.  Referencing the first sample keeps the squares small; the cumulative sums' rounding
grows like ε·N·max|x − x_first|², i.e. a variance error below 1e-8 (rad/s)² or (m/s²)² even after
10⁸ samples, far under the thresholds (1e-4 and 6e-2).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gyro_attitude.core.attitude.inputs import check_times
from gyro_attitude.core.attitude.settings import StreamConfig
from gyro_attitude.core.attitude.validation import all_within
from gyro_attitude.core.earth import STANDARD_GRAVITY
from gyro_attitude.core.jit import compiled, kernel, precompiled

__all__ = ["NOISE_FLOOR_RAD_S", "RestWindows", "detect_rest", "rest_rows", "rest_segments",
           "rest_start", "rest_update", "true_runs"]

# Every real gyro shows noise at rest (a navigation-grade one still ~1e-6 rad/s per sample at
# 100 Hz), so a window whose output is constant to rounding is a noise-free simulation or a stuck
# sensor, not evidence of rest.
NOISE_FLOOR_RAD_S = 1e-9


@dataclass
class RestWindows:
    """Batch result of :func:`detect_rest`, one entry per sample ``k`` for the window ending at k.

    ``at_rest`` (N,) bool; ``oldest`` (N,) int index of the window's oldest sample;
    ``gyro_std`` / ``accel_std`` (N,) deviation std over three axes (NaN before the window
    is full; ``accel_std`` all NaN without accelerometer); ``covered`` (N,) bool: the sample
    lies in at least one rest window.
    """

    at_rest: np.ndarray
    oldest: np.ndarray
    gyro_std: np.ndarray
    accel_std: np.ndarray
    covered: np.ndarray


# The streaming detector's state as two arrays (in the chain's state record). Float slots: the
# running sums (gyro x, gyro x², accel x, accel x²; 3 each), the reference samples, the last
# window's statistics, the thresholds.
F_C, F_REF_G, F_REF_A, F_GYRO_STD, F_ACCEL_STD = 0, 12, 15, 18, 19
F_GYRO_MEAN, F_ACCEL_MEAN = 20, 23
F_STD_MIN, F_STD_MAX, F_MEAN_MAX, F_ACCEL_STD_MAX, F_NORM_TOL, F_GRAVITY = 26, 27, 28, 29, 30, 31
_R_FLOATS = 32
# int slots: samples taken, whether a last stamp exists and its value, the window's oldest
# sample index, the decision, the accelerometer (-1 not yet known, 0 absent, 1 present), the
# first stamp, the window ring (first slot, entries), the window length in ns
R_SAMPLES, R_HAS_LAST, R_LAST_T, R_OLDEST, R_AT_REST, R_HAS_ACCEL, R_T_FIRST, R_HEAD, R_COUNT, \
    R_WINDOW_NS = range(10)
_R_INTS = 10
#: :func:`rest_update` codes besides a ring slot (≥ 0): the ring is full (nothing changed: grow
#: it, :func:`grown_ring`, and step again); the stamp does not increase, or the accelerometer
#: came or went (nothing changed: the caller resets the window)
RING_FULL, NOT_INCREASING, ACCEL_CHANGED = -2, -1, -4


def rest_start(cfg: StreamConfig, gyro_std_min: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """A rest detector's state arrays (``rf`` floats, ``ri`` ints) before its first sample,
    with the thresholds of ``cfg`` (windows less noisy than ``gyro_std_min`` refused)."""
    gyro_std_min = _checked_floor(cfg, gyro_std_min)
    rf = np.zeros(_R_FLOATS)
    ri = np.zeros(_R_INTS, dtype=np.int64)
    rf[F_STD_MIN:F_GRAVITY + 1] = (gyro_std_min, cfg.rest_gyro_std_max, cfg.rest_gyro_mean_max,
                                   cfg.rest_accel_std_max, cfg.rest_accel_norm_tol,
                                   STANDARD_GRAVITY)
    ri[R_WINDOW_NS] = int(round(cfg.rest_window_s * 1e9))
    rest_reset(rf, ri)  # the kernel's Python form: no compiler for a start
    return rf, ri


def _checked_floor(cfg, gyro_std_min) -> float:
    """``gyro_std_min`` as a float below ``cfg``'s ``rest_gyro_std_max`` (ValueError, or
    TypeError when ``cfg`` is not a :class:`StreamConfig`)."""
    if not isinstance(cfg, StreamConfig):
        raise TypeError(f"the rest thresholds come from a StreamConfig, got {cfg!r}")
    if isinstance(gyro_std_min, bool) or not isinstance(gyro_std_min, int | float) or not (
            0.0 <= gyro_std_min < cfg.rest_gyro_std_max):
        raise ValueError(f"gyro_std_min must be a number in [0, rest_gyro_std_max = "
                         f"{cfg.rest_gyro_std_max:g}), got {gyro_std_min!r}")
    return float(gyro_std_min)


@kernel
def rest_update(rf, ri, wt, wx, wc, t, g0, g1, g2, has_a, a0, a1, a2):
    """One sample (stamp ``t``, rate ``g``, specific force ``a`` when ``has_a``) into the
    window of the state arrays ``rf``, ``ri`` and its ring (``wt`` stamp, ``wx`` sample index,
    ``wc`` the running sums before each sample): the ring slot of this sample (the decision in
    ``ri[R_AT_REST]``), or a refusal code (:data:`RING_FULL`, :data:`NOT_INCREASING`,
    :data:`ACCEL_CHANGED`) with nothing changed."""
    cap = wt.shape[0]
    if ri[R_COUNT] == cap:
        return RING_FULL
    if ri[R_HAS_LAST] == 1 and t <= ri[R_LAST_T]:
        return NOT_INCREASING
    if ri[R_HAS_ACCEL] < 0:
        ri[R_HAS_ACCEL] = 1 if has_a else 0
        ri[R_T_FIRST] = t
        rf[F_REF_G], rf[F_REF_G + 1], rf[F_REF_G + 2] = g0, g1, g2
        if has_a:
            rf[F_REF_A], rf[F_REF_A + 1], rf[F_REF_A + 2] = a0, a1, a2
        else:
            rf[F_REF_A], rf[F_REF_A + 1], rf[F_REF_A + 2] = 0.0, 0.0, 0.0
    elif (ri[R_HAS_ACCEL] == 1) != has_a:
        return ACCEL_CHANGED
    slot = (ri[R_HEAD] + ri[R_COUNT]) % cap
    wt[slot] = t
    wx[slot] = ri[R_SAMPLES]
    for i in range(12):
        wc[slot, i] = rf[F_C + i]
    ri[R_COUNT] += 1
    for i, x in ((0, g0), (1, g1), (2, g2)):
        d = x - rf[F_REF_G + i]
        rf[F_C + i] = rf[F_C + i] + d
        rf[F_C + 3 + i] = rf[F_C + 3 + i] + d * d
    if has_a:
        for i, x in ((0, a0), (1, a1), (2, a2)):
            e = x - rf[F_REF_A + i]
            rf[F_C + 6 + i] = rf[F_C + 6 + i] + e
            rf[F_C + 9 + i] = rf[F_C + 9 + i] + e * e
    lo = t - ri[R_WINDOW_NS]
    while wt[ri[R_HEAD]] < lo:
        ri[R_HEAD] = (ri[R_HEAD] + 1) % cap
        ri[R_COUNT] -= 1
    ri[R_SAMPLES] += 1
    ri[R_HAS_LAST], ri[R_LAST_T] = 1, t
    head = ri[R_HEAD]
    ri[R_OLDEST] = wx[head]
    n = float(ri[R_SAMPLES] - wx[head])
    ri[R_AT_REST] = 1 if _decide(rf, ri, t, n, wc, head) else 0
    return slot


@kernel(inline=True)
def _decide(rf, ri, t, n, wc, head):
    m0 = (rf[F_C] - wc[head, 0]) / n
    m1 = (rf[F_C + 1] - wc[head, 1]) / n
    m2 = (rf[F_C + 2] - wc[head, 2]) / n
    v0 = (rf[F_C + 3] - wc[head, 3]) / n - m0 * m0
    v1 = (rf[F_C + 4] - wc[head, 4]) / n - m1 * m1
    v2 = (rf[F_C + 5] - wc[head, 5]) / n - m2 * m2
    gm0, gm1, gm2 = rf[F_REF_G] + m0, rf[F_REF_G + 1] + m1, rf[F_REF_G + 2] + m2
    rf[F_GYRO_MEAN], rf[F_GYRO_MEAN + 1], rf[F_GYRO_MEAN + 2] = gm0, gm1, gm2
    full = t - ri[R_T_FIRST] >= ri[R_WINDOW_NS]
    std = math.sqrt(max(v0 + v1 + v2, 0.0)) if full else math.nan
    rf[F_GYRO_STD] = std
    ok = full and rf[F_STD_MIN] <= std <= rf[F_STD_MAX] and max(
        abs(gm0), abs(gm1), abs(gm2)) <= rf[F_MEAN_MAX]
    if ri[R_HAS_ACCEL] == 1:
        m0 = (rf[F_C + 6] - wc[head, 6]) / n
        m1 = (rf[F_C + 7] - wc[head, 7]) / n
        m2 = (rf[F_C + 8] - wc[head, 8]) / n
        v0 = (rf[F_C + 9] - wc[head, 9]) / n - m0 * m0
        v1 = (rf[F_C + 10] - wc[head, 10]) / n - m1 * m1
        v2 = (rf[F_C + 11] - wc[head, 11]) / n - m2 * m2
        astd = math.sqrt(max(v0 + v1 + v2, 0.0)) if full else math.nan
        rf[F_ACCEL_STD] = astd
        f0, f1, f2 = rf[F_REF_A] + m0, rf[F_REF_A + 1] + m1, rf[F_REF_A + 2] + m2
        rf[F_ACCEL_MEAN], rf[F_ACCEL_MEAN + 1], rf[F_ACCEL_MEAN + 2] = f0, f1, f2
        norm = math.sqrt(f0 * f0 + f1 * f1 + f2 * f2)
        ok = ok and astd <= rf[F_ACCEL_STD_MAX] and abs(norm - rf[F_GRAVITY]) <= rf[F_NORM_TOL]
    return ok


@kernel
def rest_rows(rf, ri, ring, k0, t, g, has_a, a, at_rest, oldest, gyro_std, accel_std):
    """:func:`rest_update` over rows ``k0`` … of a recording (``a`` has a row per sample, which
    counts only when ``has_a``), each row's decision, window start and statistics into the last
    four arrays.  Returns the row it stopped at: ``len(t)`` when done, else the ring was full
    there (the caller grows it, :func:`grown_ring`, and calls again from that row)."""
    for k in range(k0, t.shape[0]):
        code = rest_update(rf, ri, ring.t, ring.x, ring.c, t[k], g[k, 0], g[k, 1], g[k, 2],
                           has_a, a[k, 0], a[k, 1], a[k, 2])
        if code < 0:  # RING_FULL (the stamps increase and the accelerometer is on every row)
            return k
        at_rest[k] = ri[R_AT_REST] == 1
        oldest[k] = ri[R_OLDEST]
        gyro_std[k] = rf[F_GYRO_STD]
        accel_std[k] = rf[F_ACCEL_STD]
    return t.shape[0]


#: the fields of a rest window's ring that :func:`rest_update` writes (stamp, sample index, the
#: running sums before the sample); the stages' rings add their own fields after them
RING_FIELDS = [("t", np.int64), ("x", np.int64), ("c", np.float64, (12,))]
RING_START = 64  # rest-window entries held at first; a ring doubles when a window needs more


def detect_rest(t_ns, gyro, accel=None, cfg: StreamConfig | None = None,
                gyro_std_min: float = 0.0, empty=np.empty) -> RestWindows:
    """:func:`rest_update` over arrays (:func:`rest_rows`, compiled) with the thresholds of
    ``cfg`` (default the table's); the per-sample results come from ``empty(shape, dtype)``."""
    rf, ri = rest_start(StreamConfig() if cfg is None else cfg, gyro_std_min)
    t = check_times(t_ns)
    g, a = (None if x is None else _rows_within(x, name, t.size, 1e6)
            for name, x in (("gyro", gyro), ("accel", accel)))
    size = t.size
    at_rest, oldest = empty(size, bool), empty(size, np.int64)
    gyro_std, accel_std = empty(size, np.float64), empty(size, np.float64)
    ring = np.zeros(RING_START, np.dtype(RING_FIELDS)).view(np.recarray)
    loop = precompiled(rest_rows) or compiled(rest_rows)
    k = 0
    while (k := loop(rf, ri, ring, k, t, g, a is not None, g if a is None else a, at_rest,
                     oldest, gyro_std, accel_std)) < size:
        ring = grown_ring(ring, ri)
    return RestWindows(at_rest, oldest, gyro_std, accel_std, _covered(at_rest, oldest, empty))


def _rows_within(x, name: str, n: int, limit: float) -> np.ndarray:
    """``x`` as C-ordered float rows (n, 3), each value finite and within ±``limit``
    (ValueError else)."""
    try:
        a = np.ascontiguousarray(x, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a numeric (N, 3) array") from None
    if a.shape != (n, 3):
        raise ValueError(f"{name} must have shape ({n}, 3), got {a.shape}")
    if not all_within(a, limit):
        k = int(np.argmax(~np.isfinite(a).all(axis=1) | (np.abs(a) > limit).any(axis=1)))
        raise ValueError(f"{name} sample {k} is not finite or absurdly large: {a[k]}")
    return a


_COVER_CHUNK = 1 << 16  # rest rows marked at a time


def _covered(at_rest: np.ndarray, oldest: np.ndarray, empty=np.empty) -> np.ndarray:
    """Samples lying in at least one rest window: mark [oldest[k], k] for each rest k."""
    n = at_rest.size
    diff = empty(n + 1, np.int64)
    diff.fill(0)
    for c0 in range(0, n, _COVER_CHUNK):  # the rest rows chunk by chunk
        k = np.flatnonzero(at_rest[c0:c0 + _COVER_CHUNK]) + c0
        np.add.at(diff, oldest[k], 1)
        np.add.at(diff, k + 1, -1)
    np.cumsum(diff[:n], out=diff[:n])  # in place: the count of windows over each sample
    covered = empty(n, bool)
    np.greater(diff[:n], 0, out=covered)
    return covered


def true_runs(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Starts and stops (exclusive) of the runs of True in the bool array ``mask``, in order
    (one byte a row of temporaries)."""
    pad = np.zeros(1, np.int8)
    edges = np.diff(np.concatenate((pad, mask.view(np.int8), pad)))
    return np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)


def rest_segments(covered: np.ndarray) -> list[tuple[int, int]]:
    """Runs of rest samples as ``(first, last)`` index pairs (inclusive), in order."""
    starts, stops = true_runs(np.asarray(covered, dtype=bool))
    return list(zip(starts.tolist(), (stops - 1).tolist(), strict=True))


@kernel
def rest_reset(rf, ri):
    """All samples forgotten (after a gap or a restart the window fills again; the thresholds
    and the window length kept)."""
    window_ns = ri[R_WINDOW_NS]
    for i in range(F_STD_MIN):
        rf[i] = 0.0
    for i in range(F_GYRO_STD, F_STD_MIN):
        rf[i] = math.nan
    for i in range(_R_INTS):
        ri[i] = 0
    ri[R_OLDEST] = -1
    ri[R_HAS_ACCEL] = -1
    ri[R_WINDOW_NS] = window_ns


def grown_ring(ring, ri):
    """A rest window's ``ring`` (a record array indexed by the detector's slots) doubled, the
    window's entries (from slot ``ri[R_HEAD]``, ``ri[R_COUNT]`` of them) moved to slot 0 on
    and the detector's head set to 0."""
    head, count = int(ri[R_HEAD]), int(ri[R_COUNT])
    order = (head + np.arange(count)) % ring.shape[0]
    new = np.zeros(2 * ring.shape[0], ring.dtype).view(np.recarray)
    new[:count] = ring[order]
    ri[R_HEAD] = 0
    return new
