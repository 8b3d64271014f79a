"""A second sensor's samples (magnetometer) matched to the Imu stamps, the same rule live
(:class:`LatestSamples`) and in replay (:func:`latest_at`), and the field's clock offset
(docs/architecture.md, "Notes: the estimator's edge")."""

from __future__ import annotations

import math
from collections import deque

import numpy as np

__all__ = ["LatestSamples", "field_clock_offset", "latest_at"]


def latest_at(t_ns, src_t_ns, values, max_age_ns: int) -> np.ndarray:
    """``(N, W)`` rows of ``values`` (M, W) for stamps ``t_ns`` (N,): the latest source sample
    with stamp ≤ t and age ≤ ``max_age_ns``, NaN where there is none.  Source stamps need not
    be sorted; of equal stamps the last in file order wins.  A source row of NaN (a message
    whose values are no numbers) is given as +inf: counted invalid, not "no sample"."""
    t = np.asarray(t_ns, dtype=np.int64)
    st = np.asarray(src_t_ns, dtype=np.int64)
    vals = np.asarray(values, dtype=np.float64)
    if vals.ndim != 2 or vals.shape[0] != st.shape[0]:
        raise ValueError(f"values must have shape ({st.shape[0]}, W), got {vals.shape}")
    out = np.full((t.shape[0], vals.shape[1]), np.nan)
    if st.size == 0 or t.size == 0:
        return out
    order = np.argsort(st, kind="stable")
    st, vals = st[order], vals[order]
    no_numbers = np.isnan(vals).all(axis=1)
    if no_numbers.any():
        vals[no_numbers] = np.inf
    k = np.searchsorted(st, t, side="right") - 1
    ok = k >= 0
    ok[ok] = (t[ok] - st[k[ok]]) <= max_age_ns
    out[ok] = vals[k[ok]]
    return out


class LatestSamples:
    """The recent samples of a topic (live): :meth:`add` on each message, :meth:`at` per Imu
    stamp.  Holds at most ``depth`` samples (older ones can no longer serve)."""

    def __init__(self, max_age_ns: int, depth: int = 64):
        self.max_age_ns = int(max_age_ns)
        self._buf: deque = deque(maxlen=depth)

    def add(self, t_ns: int, value) -> None:
        self._buf.append((int(t_ns), value))

    def at(self, t_ns: int):
        """The latest sample with stamp ≤ ``t_ns`` within the maximum age, or None."""
        best = None
        for ts, value in self._buf:
            if ts <= t_ns and (best is None or ts >= best[0]):
                best = (ts, value)
        if best is None or t_ns - best[0] > self.max_age_ns:
            return None
        return best[1]


#: Block length of :func:`field_clock_offset`'s series: the lag's resolution (refined between
#: blocks) and the smoothing that lifts the field's turning above its noise.
OFFSET_BLOCK_S = 0.02
#: At most this much of the recording is searched (a bounded cost whatever its length).
OFFSET_SPAN_S = 1200.0
#: Below this normalised correlation the motion does not explain the field's change (a rest,
#: a disturbed field): no offset is claimed.
OFFSET_MIN_CORRELATION = 0.1
#: The correlation OFFSET_PEAK_WIDTH_S either side of its peak must be OFFSET_PEAK_DROP of
#: the peak below it (hand-held motion, the two BROAD trials: 38 % and 145 %; the steady turn
#: of the magnet_disturbance scene: 0.5-12 %, where the lag it finds is wrong).
OFFSET_PEAK_WIDTH_S = 0.25
OFFSET_PEAK_DROP = 0.2
#: Blocks whose field norm is this far (relative) from the median are left out (disturbed).
OFFSET_NORM_TOL = 0.05


@np.errstate(all="ignore")
def field_clock_offset(t_ns, omega, field, max_offset_s: float = 30.0) -> float | None:
    """How late (s; negative: early) the field rows ``field`` (N, 3), aligned to the gyro's
    stamps ``t_ns`` (NaN: no sample), are against the gyro ``omega`` (N, 3): the lag at which
    the field's change best matches the change the gyro predicts for it.  None when the
    recording cannot tell (too short, no motion, no field).

    A constant field seen from a turning body changes as ``ṁ(t) = −ω(t − τ) × m(t)`` when its
    stamps are τ late, so ``ṁ × m = |m|² ω⊥(t − τ)``, the rate across the field: the
    cross-correlation of ``ṁ × m`` with the gyro's ``ω`` over lags peaks at τ (hard iron adds
    a constant to ``m``, which the derivative drops).  Both are averaged over OFFSET_BLOCK_S
    blocks first (the field's noise would swamp its change per sample), over the first
    OFFSET_SPAN_S of the recording (stamps in any order), leaving out blocks whose field norm
    is off the median by more than OFFSET_NORM_TOL (a disturbance changes the field, a
    turn does not change its norm); the peak is refined by a parabola through its neighbours.
    Absurd values (1e300, inf) leave their blocks out or give None, silently: the filter
    counts them.
    """
    t = np.asarray(t_ns, dtype=np.int64)
    if t.shape[0] < 3:
        return None
    # the span from a robust start (the median of the first stamps: a zero or a far-off
    # stamp among them, which the validator rejects, does not move it); samples out of the
    # span, backward stamps included, are left out, and the order does not matter
    t0 = int(np.median(t[:101]))
    rows = np.flatnonzero((t >= t0) & (t - t0 <= int(OFFSET_SPAN_S * 1e9)))
    if rows.size < 3:
        return None
    blocks = ((t[rows] - t0) // int(round(OFFSET_BLOCK_S * 1e9))).astype(np.int64)
    nb = int(blocks.max()) + 1
    m = np.asarray(field, dtype=np.float64)[rows]
    w = np.asarray(omega, dtype=np.float64)[rows]
    ok = np.isfinite(m).all(axis=1) & np.isfinite(w).all(axis=1)
    count = np.bincount(blocks[ok], minlength=nb)
    if nb < 8 or np.count_nonzero(count) < 8:
        return None
    mean_m = np.stack([np.bincount(blocks[ok], m[ok, i], nb) for i in range(3)], axis=1)
    mean_w = np.stack([np.bincount(blocks[ok], w[ok, i], nb) for i in range(3)], axis=1)
    full = count > 0
    mean_m[full] /= count[full, None]
    mean_w[full] /= count[full, None]
    # a turn keeps |m|; a block whose norm is off the median is disturbed (a magnet near):
    # its change is not the gyro's and would only blur the correlation
    size_m = np.sqrt(np.einsum("ij,ij->i", mean_m, mean_m))
    if full.any():
        median = float(np.median(size_m[full]))
        full &= np.abs(size_m - median) <= OFFSET_NORM_TOL * median
    # central differences between full neighbours; rows without them weigh nothing
    g = np.zeros((nb, 3))
    r = np.zeros((nb, 3))
    inner = full[:-2] & full[1:-1] & full[2:]
    rate = (mean_m[2:][inner] - mean_m[:-2][inner]) / (2.0 * OFFSET_BLOCK_S)
    g[1:-1][inner] = np.cross(rate, mean_m[1:-1][inner])
    r[1:-1][inner] = mean_w[1:-1][inner]
    norm = math.sqrt(float(np.sum(g * g)) * float(np.sum(r * r)))
    if not (norm > 0.0 and math.isfinite(norm)):  # nothing turned, or absurd values
        return None
    max_lag = min(int(max_offset_s / OFFSET_BLOCK_S), nb - 2)
    size = 1 << int(math.ceil(math.log2(2 * nb)))
    cc = np.zeros(size)
    for i in range(3):  # Σ_k g[k]·ω[k − lag], for every lag at once
        cc += np.fft.irfft(np.fft.rfft(g[:, i], size) * np.conj(np.fft.rfft(r[:, i], size)), size)
    lags = np.r_[np.arange(-max_lag, 0), np.arange(0, max_lag + 1)]
    vals = cc[lags] / norm
    k = int(np.argmax(vals))
    if not vals[k] >= OFFSET_MIN_CORRELATION:
        return None
    # only the rate's changes tell a delay (a steady turn matches the field at any lag): the
    # peak must stand out of its surroundings, else the recording cannot tell
    apart = int(round(OFFSET_PEAK_WIDTH_S / OFFSET_BLOCK_S))
    around = vals[[j for j in (k - apart, k + apart) if 0 <= j < vals.size]]
    if around.size == 0 or vals[k] - around.max() < OFFSET_PEAK_DROP * vals[k]:
        return None
    frac = 0.0
    if 0 < k < lags.size - 1:
        a, b, c = vals[k - 1], vals[k], vals[k + 1]
        den = a - 2.0 * b + c
        frac = 0.5 * (a - c) / den if den < 0.0 else 0.0
    return (lags[k] + frac) * OFFSET_BLOCK_S


#: A field this late or early is worth a warning: turning at 1 rad/s, 50 ms put the heading's
#: reference 2.9° off (BROAD's magnetometer: 11 ms late, measured by :func:`field_clock_offset`).
OFFSET_WARN_S = 0.05


def field_clock_warning(offset_s: float | None) -> str | None:
    """One line for a field offset (:func:`field_clock_offset`) worth a warning, else None."""
    if offset_s is None or abs(offset_s) < OFFSET_WARN_S:
        return None
    late = offset_s > 0
    return (f"the magnetic field's stamps look {abs(offset_s) * 1e3:.0f} ms "
            f"{'late' if late else 'early'} against the gyro's (the field turns as the gyro says "
            f"that much {'later' if late else 'earlier'}): while turning at ω the heading "
            "reference is off by about ω times that; fix the magnetometer's stamps")
