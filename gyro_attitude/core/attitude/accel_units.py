"""Is the accelerometer in m/s²?  The median specific force at rest against gravity
(docs/architecture.md, "Notes: the estimator's edge")."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gyro_attitude.core.earth import STANDARD_GRAVITY

__all__ = ["ACCEL_SCALE_TOLERANCE", "AccelScale", "AccelScaleWatch", "check_accel_scale"]

#: Relative distance of the median |f| from gravity still taken for m/s².
ACCEL_SCALE_TOLERANCE = 0.2
#: A sample is still enough to show gravity when its rate is below this (rad/s, 3 °/s).
STILL_RATE_RAD_S = 0.05
#: Still samples needed to judge from them alone.
MIN_STILL = 50
#: Samples the median is taken over at most (evenly strided: a threshold needs no more).
MEDIAN_SAMPLES = 1 << 20
#: Seconds of samples the live watch judges (and at most this many samples: 2 s at 8 kHz).
WATCH_S = 2.0
WATCH_SAMPLES = 1 << 14


@dataclass(frozen=True)
class AccelScale:
    """The verdict: ``median_norm`` of |f| (NaN when no finite sample) over ``samples`` of
    ``basis`` (``"still samples"`` or ``"the whole recording"``); ``problem`` one line naming
    what it looks like when not ``ok``."""

    median_norm: float
    basis: str
    samples: int
    ok: bool
    problem: str | None


def check_accel_scale(accel, gyro=None) -> AccelScale:
    """Whether ``accel`` (N, 3), the specific force as recorded, is in m/s²: its median norm
    over the still samples (``gyro`` (N, 3) rad/s, optional) or over every sample, against
    gravity within :data:`ACCEL_SCALE_TOLERANCE`.  Rows with a non-finite value are left out.
    Raises ValueError on malformed arguments."""
    a = np.asarray(accel)
    if a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f"accel must have shape (N, 3), got {a.shape}")
    gravity, tolerance = STANDARD_GRAVITY, ACCEL_SCALE_TOLERANCE
    pick = slice(0, a.shape[0], max(1, -(-a.shape[0] // MEDIAN_SAMPLES)))
    f = np.asarray(a[pick], dtype=np.float64)
    with np.errstate(over="ignore", invalid="ignore"):
        norm = np.sqrt(np.einsum("ij,ij->i", f, f))
    finite = np.isfinite(norm)
    basis, use = "the whole recording", finite
    if gyro is not None:
        g = np.asarray(gyro)
        if g.shape != a.shape:
            raise ValueError(f"gyro must have the shape of accel {a.shape}, got {g.shape}")
        w = np.asarray(g[pick], dtype=np.float64)
        with np.errstate(over="ignore", invalid="ignore"):
            still = finite & (np.einsum("ij,ij->i", w, w) < STILL_RATE_RAD_S ** 2)
        if np.count_nonzero(still) >= MIN_STILL:
            basis, use = "still samples", still
    m = int(np.count_nonzero(use))
    if m == 0:
        return AccelScale(math.nan, basis, 0, False, "linear_acceleration has no finite sample")
    med = float(np.median(norm[use]))
    if abs(med - gravity) <= tolerance * gravity:
        return AccelScale(med, basis, m, True, None)
    ratio = med / gravity
    if med == 0.0:
        looks = "all zero: no accelerometer?"
    elif abs(ratio * gravity - 1.0) <= tolerance:
        looks = "in g?"
    elif abs(ratio / 100.0 - 1.0) <= 0.1 or abs(ratio / (1000.0 / gravity) - 1.0) <= 0.1:
        looks = "in mg or cm/s²?"
    else:
        looks = "not a specific force"
    where = "still samples" if basis.startswith("still") else "samples"
    return AccelScale(med, basis, m, False,
                      f"linear_acceleration is not in m/s² (REP-145): median |f| {med:.4g} over "
                      f"{m} {where}, gravity is {gravity:.5g} m/s² ({looks})")


class AccelScaleWatch:
    """:func:`check_accel_scale` on the first samples of a stream, judged once: after
    :data:`WATCH_S` of stamps and at least :data:`MIN_STILL` samples, or :data:`WATCH_SAMPLES`
    of them.  :meth:`add` each accepted sample carrying an accelerometer; it returns the
    verdict on the sample that completes the watch (None before and after).  ``use_accel``:
    whether to go on pushing the field (yes while watching: the estimator's own norm tests
    refuse a field in g, mg, cm/s² or zero meanwhile; then as the verdict says)."""

    def __init__(self):
        self._a: np.ndarray | None = np.empty((WATCH_SAMPLES, 3))
        self._w = np.empty((WATCH_SAMPLES, 3))
        self._n = 0
        self._t0: int | None = None
        self.verdict: AccelScale | None = None

    @property
    def use_accel(self) -> bool:
        return self.verdict is None or self.verdict.ok

    def add(self, t_ns: int, accel, gyro) -> AccelScale | None:
        if self.verdict is not None:
            return None
        if self._t0 is None:
            self._t0 = int(t_ns)
        self._a[self._n] = accel
        self._w[self._n] = gyro
        self._n += 1
        if self._n < WATCH_SAMPLES and (int(t_ns) - self._t0 < int(WATCH_S * 1e9)
                                        or self._n < MIN_STILL):
            return None
        self.verdict = check_accel_scale(self._a[:self._n], self._w[:self._n])
        self._a = self._w = None  # judged: the samples are no longer needed
        return self.verdict
