"""Is the accelerometer in m/s²?  The specific force's magnitude at rest against gravity.

An Imu message's ``linear_acceleration`` is m/s² (REP-145), but drivers publish g (|f| ≈ 1 at
rest), mg or cm/s² (≈ 1000 or 981), or zeros when the sensor has none and says nothing.  Taken
as m/s², such a field makes every rest test fail or pass on garbage and turns gravity aiding
into a tilt toward noise, silently.  :func:`check_accel_scale` looks at the median ``|f|`` over
the samples whose gyro says they are still (``|ω|`` below :data:`STILL_RATE_RAD_S`; over the whole
recording when fewer than :data:`MIN_STILL` of them), which is g at rest and, over a recording
of a carrier that starts and stops, g on the median too, and compares it with ``gravity``
within ``tolerance`` (relative; the default accepts a 4-5 % scale error and the 0.3 % of
gravity's change with latitude with room to spare, while g, mg and cm/s² are off by a factor
of ~10 or ~100).

Arrays only (no ROS, no files): replay calls it before the estimator; the live node feeds its
first accepted samples to an :class:`AccelScaleWatch`, which judges them once with the same
function (no second estimator: the node drops the field from what it pushes on a bad verdict).
"""

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
    """The verdict: ``median_norm`` of |f| (NaN when no finite sample), over ``basis``
    (``"still samples"`` or ``"the whole recording"``, ``samples`` of them), ``ok`` when it is
    within the tolerance of gravity, and ``problem``: one line naming what it looks like (None
    when ok)."""

    median_norm: float
    basis: str
    samples: int
    ok: bool
    problem: str | None


def _strided(n: int) -> slice:
    return slice(0, n, max(1, -(-n // MEDIAN_SAMPLES)))


def check_accel_scale(accel, gyro=None, *, gravity: float = STANDARD_GRAVITY,
                      tolerance: float = ACCEL_SCALE_TOLERANCE) -> AccelScale:
    """Whether ``accel`` (N, 3), the specific force as recorded, is in m/s²: its median norm
    over the still samples (``gyro`` (N, 3) rad/s, optional) or over every sample, against
    ``gravity`` within the relative ``tolerance``.  Rows with a non-finite value are left out.
    Raises ValueError on malformed arguments."""
    a = np.asarray(accel)
    if a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f"accel must have shape (N, 3), got {a.shape}")
    if not (isinstance(gravity, int | float) and math.isfinite(gravity) and gravity > 0):
        raise ValueError(f"gravity must be a positive number, got {gravity!r}")
    if not (isinstance(tolerance, int | float) and 0 < tolerance < 1):
        raise ValueError(f"tolerance must be in (0, 1), got {tolerance!r}")
    pick = _strided(a.shape[0])
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
    ``span_s`` of stamps and at least :data:`MIN_STILL` samples, or ``max_samples`` of them.
    :meth:`add` each accepted sample carrying an accelerometer; it returns the verdict on the
    sample that completes the watch (None before and after).  ``use_accel`` says whether to go
    on pushing the field: yes while watching (the estimator's own norm tests refuse a field
    in g, mg, cm/s² or zero meanwhile), then as the verdict says."""

    def __init__(self, span_s: float = WATCH_S, max_samples: int = WATCH_SAMPLES, *,
                 gravity: float = STANDARD_GRAVITY, tolerance: float = ACCEL_SCALE_TOLERANCE):
        if not (isinstance(span_s, int | float) and 0 < span_s < 1e6):
            raise ValueError(f"span_s must be a positive number of seconds, got {span_s!r}")
        if isinstance(max_samples, bool) or not isinstance(max_samples, int) or max_samples < 1:
            raise ValueError(f"max_samples must be a positive int, got {max_samples!r}")
        self._span_ns = int(round(span_s * 1e9))
        self._gravity, self._tolerance = gravity, tolerance
        self._a: np.ndarray | None = np.empty((max_samples, 3))
        self._w = np.empty((max_samples, 3))
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
        if self._n < self._a.shape[0] and (int(t_ns) - self._t0 < self._span_ns
                                           or self._n < MIN_STILL):
            return None
        self.verdict = check_accel_scale(self._a[:self._n], self._w[:self._n],
                                         gravity=self._gravity, tolerance=self._tolerance)
        self._a = self._w = None  # judged: the samples are no longer needed
        return self.verdict
