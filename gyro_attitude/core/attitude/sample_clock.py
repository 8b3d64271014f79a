"""The sample clock of a regular stream whose stamps jitter (issue 38 item 1): the clock the
stamps jitter about, for the offline integration's intervals (the output keeps the stamps).

A run's residuals ``r_i = t_i − t_0 − i·T`` are a line plus the jitter, with a step of ``m·T``
where ``m`` samples are missing; the steps cut the run into segments, and each sample's clock is
the mean of ``r`` over ±:data:`HALF_WINDOW` samples, near a segment's ends the line through the
nearest sample whose window fits (docs/architecture.md, "Notes: offline estimator").
"""

from __future__ import annotations

import numpy as np

from gyro_attitude.core.attitude.rest import true_runs

#: samples each side of the clock's mean (a hardware clock drifts by ppm: seconds are a line)
HALF_WINDOW = 256
#: samples each side compared to find a missing sample's step in the residuals
STEP_SAMPLES = 16
#: intervals whose median is the run's period
MEDIAN_INTERVALS = 100_000
#: a chunk whose stamps all lie this close to their clock keeps its stamps (ns)
KEEP_NS = 1_000
#: samples a chunk computes at a time (plus its margins): temporaries bounded, not the run's
CHUNK = 1 << 16


def sample_clock(t_ns: np.ndarray, starts: np.ndarray, empty=np.empty,
                 chunk: int = CHUNK) -> np.ndarray:
    """The stamps ``t_ns`` (int64, rising within a run) on the clock they jitter about;
    ``starts`` the rows that begin a run (no clock spans a gap restart or a time reset).
    ``t_ns`` itself when every stamp is kept, else a copy from ``empty(shape, dtype)``."""
    t = np.asarray(t_ns)
    n = t.size
    bounds = sorted({0, n, *np.asarray(starts, dtype=np.int64).tolist()})
    out = t
    for r0, r1 in zip(bounds[:-1], bounds[1:], strict=True):
        if r1 - r0 < 2 * STEP_SAMPLES + 3:
            continue
        period = run_period(t[r0:r1])
        if period <= 0:
            continue
        margin = 2 * HALF_WINDOW + 2 * STEP_SAMPLES + 2  # an anchor's window: 2 W away
        for c0 in range(r0, r1, chunk):
            c1 = min(c0 + chunk, r1)
            e0, e1 = max(r0, c0 - margin), min(r1, c1 + margin)
            tau = _clock(t[e0:e1], period, r0 == e0, r1 == e1)
            tau = tau[c0 - e0:c1 - e0]
            off = np.abs(tau - t[c0:c1]).max()
            # kept: stamps on their clock, or a clock that is no clock of jitter (more than
            # half a period off: the rate changed, or the stamps wander)
            if off <= KEEP_NS or 2 * off > period:
                continue
            if out is t:
                out = empty(n, np.int64)
                out[:] = t
            out[c0:c1] = tau
        if out is not t and not _rising(out, r0, r1, chunk):
            out[r0:r1] = t[r0:r1]  # a clock that steps back at a cut: the stamps, as they are
    return out


def _rising(a: np.ndarray, r0: int, r1: int, chunk: int) -> bool:
    """Whether ``a[r0:r1]`` rises strictly (``chunk`` rows at a time)."""
    return all(bool((np.diff(a[max(c0 - 1, r0):min(c0 + chunk, r1)]) > 0).all())
               for c0 in range(r0, r1, chunk))


def run_period(t_ns: np.ndarray) -> int:
    """The period (ns) of one run's stamps: the median of its first :data:`MEDIAN_INTERVALS`
    intervals within ±1/2 of their median (the intervals over missing samples would pull it
    up: 1 % at 5 % missing); 0 with fewer than two stamps."""
    dt = np.diff(np.asarray(t_ns)[:MEDIAN_INTERVALS + 1])
    if dt.size == 0:
        return 0
    rough = np.median(dt)
    near = dt[np.abs(dt - rough) < 0.5 * rough]
    return int(np.median(near)) if rough > 0 and near.size else int(rough)


def _clock(t: np.ndarray, period: int, starts_run: bool, ends_run: bool) -> np.ndarray:
    """The clock of one stretch of a run (its ends are the run's when ``starts_run`` /
    ``ends_run``; otherwise margins whose own values are not used)."""
    m = t.size
    idx = np.arange(m, dtype=np.int64)
    r = (t - t[0] - idx * period).astype(np.float64)  # the line plus the jitter and the steps
    c = np.zeros(m + 1)
    np.cumsum(r, out=c[1:])
    # the step before sample i: the mean of r[i:i+S] over that of r[i-S:i] (fewer samples
    # where the stretch ends)
    s = STEP_SAMPLES
    i = np.arange(1, m)
    kl, kr = np.minimum(i, s), np.minimum(m - i, s)
    d = np.full(m, -np.inf)
    d[1:] = (c[i + kr] - c[i]) / kr - (c[i] - c[i - kl]) / kl
    cut = np.zeros(m + 1, bool)  # cut[i]: a segment begins at sample i
    cut[0] = cut[m] = True
    high = d > 0.5 * period
    if high.any():
        # an excursion of d above T/2 holds a step (it begins ~S/2 samples before it): each
        # sample's residual from the mean of those before the excursion (since the last cut)
        # is a whole number of periods plus its jitter, below T/2 — cut where that number
        # changes (steps closer than S samples share an excursion).  The largest interval is
        # no mark: at ±T/3 of jitter a hole's 2 T can read 1.34 T, an interval 1.66 T.
        last = 0
        for a, b in zip(*true_runs(high), strict=True):
            base = r[max(a - s, last):a].mean()
            level = np.rint((r[a - 1:min(b + 1, m)] - base) / period)
            steps = a + np.flatnonzero(np.diff(level))
            cut[steps] = True
            if steps.size:
                last = int(steps[-1])
    if not starts_run:
        cut[0] = False
    if not ends_run:
        cut[m] = False
    # the segment of each sample, [lo, hi) (beyond a margin's end: far enough not to bind)
    cuts = np.concatenate(([-HALF_WINDOW - 1], np.flatnonzero(cut), [m + HALF_WINDOW]))
    seg = np.searchsorted(cuts, idx, side="right") - 1
    lo, hi = cuts[seg], cuts[seg + 1]
    h = np.minimum.reduce([np.full(m, HALF_WINDOW), idx - lo, hi - 1 - idx, idx, m - 1 - idx])
    line = (c[idx + h + 1] - c[idx - h]) / (2 * h + 1)
    # within h_max of a segment's end the window cannot be full: the line through its anchor
    # (the first / last sample whose window is) with the slope of that window's two halves
    # (a margin's segment is cut at the stretch's edge: only its own, unused, samples change)
    lo, hi = np.maximum(lo, 0), np.minimum(hi, m)
    h_max = np.minimum(HALF_WINDOW, (hi - lo - 1) // 2)
    for zone, anchor in ((idx - lo < h_max, lo + h_max), (hi - 1 - idx < h_max, hi - 1 - h_max)):
        if zone.any():
            a, k = anchor[zone], h_max[zone]
            slope = ((c[a + k + 1] - c[a + 1]) - (c[a] - c[a - k])) / (k * (k + 1))
            line[zone] = line[a] + (idx[zone] - a) * slope
    return t[0] + idx * period + np.round(line).astype(np.int64)
