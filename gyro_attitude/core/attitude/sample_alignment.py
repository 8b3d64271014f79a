"""A second sensor's samples (magnetometer) matched to the Imu stamps: the latest sample at or
before each stamp, no older than a maximum age.

One rule for the live node and replay: the node keeps the recent samples of the topic
(:class:`LatestSamples`) and asks for the one at each Imu stamp; replay takes whole arrays
(:func:`latest_at`).  Both give the same rows when every sample has arrived before the Imu
sample of the same stamp (a recording; live, a sample that arrives after its Imu sample serves
the next one).
"""

from __future__ import annotations

from collections import deque

import numpy as np

__all__ = ["LatestSamples", "latest_at"]


def latest_at(t_ns, src_t_ns, values, max_age_ns: int) -> np.ndarray:
    """``(N, W)`` rows of ``values`` (M, W) for stamps ``t_ns`` (N,): the latest source sample
    with stamp ≤ t and age ≤ ``max_age_ns``, NaN where there is none.  Source stamps need not
    be sorted (a recording's file order); of equal stamps the last in file order wins.

    A source row of NaN is a message whose values are no numbers, not a missing message: it is
    given as +inf, so that it stays unusable (counted invalid by the consumer, as the live path
    counts the message itself) instead of reading as "no sample"."""
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
