"""Rest (zero-motion) detection from gyro and accelerometer statistics over a sliding time window.

Contract (streaming, one call per accepted sample, O(1) amortized):
``RestDetector.update(t_ns, gyro, accel=None) -> bool`` says whether the window that ENDS at this
sample (all samples with ``t >= t_ns - window``) is at rest; ``oldest_index`` is then the index
(counted from the first sample after construction / ``reset``) of the oldest sample in that
window.  A rest window vouches for every sample in it; the consumers (gyro bias, alignment) take
the *oldest* sample of each rest window, so a sample counts once it is followed by a full window
of rest: the gentle start of a motion, which a window can miss for a few samples, never enters a
rest average.  :func:`detect_rest` is the batch form over arrays and gives bit-identical results
(same cumulative sums, same operation order).

A window is at rest when all hold:

* it spans a full ``window_s`` of data since the first sample (no decision on a partial window);
* ``gyro_std_max``: the gyro's deviation from the window mean, ``sqrt(Σ_axes var)``, is small
  (and at least ``gyro_std_min``, default 0; the gyro-bias estimator asks for
  :data:`NOISE_FLOOR_RAD_S`, see gyro_bias.py);
  The deviation, not the magnitude, is tested so that a constant bias (0.1–5 °/s for consumer
  MEMS) does not block rest detection;
* ``gyro_mean_max``: the window-mean rate is below the largest plausible bias **on every
  axis**, so a smooth constant-rate rotation is not called rest.  A steady turn about the
  vertical leaves the accelerometer unchanged and shows no gyro spread: gyro and accelerometer
  cannot tell it from a bias, so this bound alone separates them.  Consumer MEMS biases are
  0.1–0.6 °/s per axis (BROAD over the dataset; 0.12–0.24 °/s on the shared trials), so the
  bound is 0.011 rad/s (0.63 °/s) per axis.  Per axis, because a turn of rate ``|ω|`` about any
  axis has one component of at least ``|ω|/√3``: every steady turn faster than
  ``√3 · 0.011 = 0.019 rad/s`` (1.09 °/s) is refused whatever its axis (a turntable at
  0.02 rad/s, a vehicle's gentle curve, a hand panning a camera), while a bias of 0.6 °/s on
  all three axes (1.04 °/s in norm) still rests.  A gyro with a larger bias needs a larger bound
  (``rest_gyro_mean_max``) and then takes slower turns for rests;
* with an accelerometer: ``accel_std_max`` on the specific force's deviation (the strongest
  motion cue for a hand-held or vehicle IMU) and ``accel_norm_tol`` on ``|‖mean f‖ − g|``.

Defaults (``window_s`` 0.5 s): white gyro noise of density N sampled at rate r has per-axis
std N·√r.  A consumer MEMS gyro (N ≈ 0.01 °/s/√Hz at 100–1000 Hz; the BROAD recordings show
0.08–0.10 °/s per axis at 286 Hz, 0.16 °/s over three axes) stays below 0.01 rad/s (0.57 °/s)
with a wide margin; tactical and navigation-grade gyros are 10–1000× quieter and pass a fortiori,
so one default serves both.  Hand-held motion, even "still" holding, shows 1–10 °/s of tremor and
is rejected.  Accelerometer noise: consumer MEMS 0.03–0.07 m/s² per axis (BROAD: 0.09 m/s² over
three axes), below 0.25 m/s²; ``accel_norm_tol`` 0.5 m/s² covers normal gravity between the
equator and the poles (9.78–9.83 m/s²) plus consumer accelerometer bias and scale error.  For a
noisier sensor or a vibrating vehicle at standstill, raise the std thresholds.

Numerics: window sums are differences of running (cumulative) sums of ``x − x_first`` and its
square.  Referencing the first sample keeps the squares small; the cumulative sums' rounding
grows like ε·N·max|x − x_first|², i.e. a variance error below 1e-8 (rad/s)² or (m/s²)² even after
10⁸ samples, far under the thresholds (1e-4 and 6e-2).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from gyro_attitude.core.earth import STANDARD_GRAVITY

__all__ = ["NOISE_FLOOR_RAD_S", "RestDetector", "RestWindows", "detect_rest", "rest_segments",
           "check_samples"]

# Every real gyro shows noise at rest (a navigation-grade one still ~1e-6 rad/s per sample at
# 100 Hz), so a window whose output is constant to rounding is a noise-free simulation or a stuck
# sensor, not evidence of rest.
NOISE_FLOOR_RAD_S = 1e-9


def _check_param(name: str, value, allow_zero: bool = False) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(v) or v < 0 or (v == 0 and not allow_zero) or v > 1e12:
        raise ValueError(f"{name} must be a finite positive number, got {value!r}")
    return v


def check_samples(t_ns, gyro, accel=None) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Validated batch input: int64 strictly increasing ``t_ns`` (N,), finite ``gyro`` (N, 3)
    rad/s, optional finite ``accel`` (N, 3) m/s² — or ``ValueError`` naming what is wrong."""
    t = np.asarray(t_ns)
    if t.ndim != 1 or t.size == 0:
        raise ValueError(f"t_ns must be a non-empty 1-D array, got shape {t.shape}")
    if not np.issubdtype(t.dtype, np.integer):
        raise ValueError(f"t_ns must hold integer nanoseconds, got dtype {t.dtype}")
    t = t.astype(np.int64)
    if t.size > 1 and np.any(np.diff(t) <= 0):
        k = int(np.argmax(np.diff(t) <= 0)) + 1
        raise ValueError(f"t_ns must be strictly increasing (sample {k}: {t[k]} after {t[k - 1]})")
    out = []
    for name, arr in (("gyro", gyro), ("accel", accel)):
        if arr is None:
            out.append(None)
            continue
        try:
            a = np.asarray(arr, dtype=np.float64)
        except (TypeError, ValueError):
            raise ValueError(f"{name} must be a numeric (N, 3) array") from None
        if a.shape != (t.size, 3):
            raise ValueError(f"{name} must have shape ({t.size}, 3), got {a.shape}")
        if not np.all(np.isfinite(a)) or np.any(np.abs(a) > 1e6):
            k = int(np.argmax(~np.isfinite(a).all(axis=1) | (np.abs(a) > 1e6).any(axis=1)))
            raise ValueError(f"{name} sample {k} is not finite or absurdly large: {a[k]}")
        out.append(a)
    return t, out[0], out[1]


def check_sample(t_ns, gyro, accel=None) -> tuple[int, tuple, tuple | None]:
    """One validated streaming sample: (int t_ns, gyro 3 floats, accel 3 floats or None)."""
    if isinstance(t_ns, bool) or not isinstance(t_ns, int | np.integer):
        raise ValueError(f"t_ns must be an int number of nanoseconds, got {t_ns!r}")
    vals = []
    for name, v in (("gyro", gyro), ("accel", accel)):
        if v is None:
            vals.append(None)
            continue
        try:
            x, y, z = (float(c) for c in v)
        except (TypeError, ValueError):
            raise ValueError(f"{name} must be 3 finite numbers, got {v!r}") from None
        if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z)) or max(
                abs(x), abs(y), abs(z)) > 1e6:
            raise ValueError(f"{name} must be 3 finite numbers of sane size, got {v!r}")
        vals.append((x, y, z))
    return int(t_ns), vals[0], vals[1]


@dataclass(frozen=True)
class RestThresholds:
    window_s: float = 0.5
    gyro_std_max: float = 0.01  # rad/s, deviation from the window mean, over three axes
    gyro_mean_max: float = 0.011  # rad/s (0.63 °/s) on any axis: the largest bias taken for rest
    accel_std_max: float = 0.25  # m/s², deviation from the window mean, over three axes
    accel_norm_tol: float = 0.5  # m/s², |‖mean f‖ − gravity|
    gravity: float = STANDARD_GRAVITY
    gyro_std_min: float = 0.0  # rad/s: a window less noisy than this is not a rest

    def checked(self) -> RestThresholds:
        for name in ("window_s", "gyro_std_max", "gyro_mean_max", "accel_std_max",
                     "accel_norm_tol", "gravity"):
            _check_param(name, getattr(self, name))
        _check_param("gyro_std_min", self.gyro_std_min, allow_zero=True)
        if not self.gyro_std_min < self.gyro_std_max:
            raise ValueError(f"gyro_std_min ({self.gyro_std_min!r}) must be below gyro_std_max "
                             f"({self.gyro_std_max!r})")
        return self


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


class RestDetector:
    """Streaming rest detector (see the module docstring for the contract and defaults)."""

    def __init__(self, window_s: float = RestThresholds.window_s,
                 gyro_std_max: float = RestThresholds.gyro_std_max,
                 gyro_mean_max: float = RestThresholds.gyro_mean_max,
                 accel_std_max: float = RestThresholds.accel_std_max,
                 accel_norm_tol: float = RestThresholds.accel_norm_tol,
                 gravity: float = STANDARD_GRAVITY, gyro_std_min: float = 0.0):
        self.thresholds = RestThresholds(window_s, gyro_std_max, gyro_mean_max, accel_std_max,
                                         accel_norm_tol, gravity, gyro_std_min).checked()
        self._window_ns = int(round(self.thresholds.window_s * 1e9))
        self.reset()

    @property
    def window_ns(self) -> int:
        """The window length in ns."""
        return self._window_ns

    def reset(self) -> None:
        """Forget all samples (after a gap or a restart the window fills again)."""
        self.samples = 0
        self.last_t_ns: int | None = None
        self.oldest_index = -1
        self.at_rest = False
        self.gyro_std = math.nan
        self.accel_std = math.nan
        self.gyro_mean = (math.nan,) * 3
        self.accel_mean = (math.nan,) * 3
        self._has_accel: bool | None = None
        self._t_first = 0
        self._ref_g = self._ref_a = (0.0, 0.0, 0.0)
        self._c = [0.0] * 12  # running sums: gyro x, gyro x², accel x, accel x² (3 each)
        self._window: deque = deque()  # (t_ns, index, running sums before this sample)

    def update(self, t_ns: int, gyro, accel=None) -> bool:
        """Add one sample; return whether the window ending at it is at rest."""
        t, g, a = check_sample(t_ns, gyro, accel)
        return self.update_checked(t, g, a)

    def update_checked(self, t: int, g: tuple, a: tuple | None) -> bool:
        """:meth:`update` for a sample already through :func:`check_sample`."""
        if self.last_t_ns is not None and t <= self.last_t_ns:
            raise ValueError(f"t_ns must increase: {t} after {self.last_t_ns}")
        if self._has_accel is None:
            self._has_accel = a is not None
            self._t_first = t
            self._ref_g = g
            self._ref_a = a if a is not None else (0.0, 0.0, 0.0)
        elif (a is not None) != self._has_accel:
            raise ValueError("accel must be given for every sample or for none "
                             "(reset the detector when the sensor changes)")
        c = self._c
        self._window.append((t, self.samples, tuple(c)))
        for i in range(3):
            d = g[i] - self._ref_g[i]
            c[i] = c[i] + d
            c[3 + i] = c[3 + i] + d * d
            if a is not None:
                e = a[i] - self._ref_a[i]
                c[6 + i] = c[6 + i] + e
                c[9 + i] = c[9 + i] + e * e
        lo = t - self._window_ns
        win = self._window
        while win[0][0] < lo:
            win.popleft()
        self.samples += 1
        self.last_t_ns = t
        _, self.oldest_index, c0 = win[0]
        n = float(self.samples - self.oldest_index)
        self.at_rest = self._decide(t, n, c, c0)
        return self.at_rest

    def _decide(self, t: int, n: float, c: list, c0: tuple) -> bool:
        # written out per axis (it runs once per live sample); the same operations in the same
        # order as detect_rest's arrays, so the decisions stay bit-identical
        th = self.thresholds
        m0, m1, m2 = (c[0] - c0[0]) / n, (c[1] - c0[1]) / n, (c[2] - c0[2]) / n
        v0 = (c[3] - c0[3]) / n - m0 * m0
        v1 = (c[4] - c0[4]) / n - m1 * m1
        v2 = (c[5] - c0[5]) / n - m2 * m2
        r0, r1, r2 = self._ref_g
        self.gyro_mean = gm0, gm1, gm2 = r0 + m0, r1 + m1, r2 + m2
        full = t - self._t_first >= self._window_ns
        self.gyro_std = math.sqrt(max(v0 + v1 + v2, 0.0)) if full else math.nan
        ok = full and th.gyro_std_min <= self.gyro_std <= th.gyro_std_max and max(
            abs(gm0), abs(gm1), abs(gm2)) <= th.gyro_mean_max
        if self._has_accel:
            m0, m1, m2 = (c[6] - c0[6]) / n, (c[7] - c0[7]) / n, (c[8] - c0[8]) / n
            v0 = (c[9] - c0[9]) / n - m0 * m0
            v1 = (c[10] - c0[10]) / n - m1 * m1
            v2 = (c[11] - c0[11]) / n - m2 * m2
            self.accel_std = math.sqrt(max(v0 + v1 + v2, 0.0)) if full else math.nan
            r0, r1, r2 = self._ref_a
            self.accel_mean = f0, f1, f2 = r0 + m0, r1 + m1, r2 + m2
            norm = math.sqrt(f0 * f0 + f1 * f1 + f2 * f2)
            ok = ok and self.accel_std <= th.accel_std_max and abs(norm - th.gravity) <= th.accel_norm_tol
        return bool(ok)


_STATS_CHUNK = 1 << 16  # rows of window statistics computed at a time


def _window_stats(t: np.ndarray, x: np.ndarray, oldest: np.ndarray, window_ns: int):
    """The window statistics of :func:`detect_rest`, a chunk of rows at a time: per chunk
    ``(r0, r1, full, std, mean)`` for the windows ending at rows r0 … r1−1 (``std`` NaN where
    the window is not yet full).

    The running sums C[k] = Σ_{j<k} (x_j − x_0) and of their squares are the streaming
    detector's, added in the same order (``np.cumsum`` adds sequentially; each chunk's sums
    start from the last sum of the one before), so the statistics are the same numbers; only
    the sums from the oldest row of the chunk's first window on are held, so the memory is a
    chunk and a window, not the recording."""
    size = x.shape[0]
    ref = x[0]
    base = 0  # sample index of the first sum held
    c1 = np.zeros((1, 3))  # C[base …]: starts as C[0] = 0
    c2 = np.zeros((1, 3))
    for r0 in range(0, size, _STATS_CHUNK):
        r1 = min(r0 + _STATS_CHUNK, size)
        lo = int(oldest[r0])  # the oldest sum any window of this chunk looks back to
        keep = r0 + 1 - lo  # sums C[lo … r0] carried over
        d = x[r0:r1] - ref
        d2 = d * d
        # C[r0 + 1 … r1] continue from C[r0]: the carry added to the first difference is the
        # streaming detector's first addition (a + b == b + a exactly), cumsum the rest
        d[0] += c1[-1]
        d2[0] += c2[-1]
        held1 = np.empty((keep + r1 - r0, 3))
        held2 = np.empty((keep + r1 - r0, 3))
        held1[:keep] = c1[lo - base:]
        held2[:keep] = c2[lo - base:]
        np.cumsum(d, axis=0, out=held1[keep:])
        np.cumsum(d2, axis=0, out=held2[keep:])
        del d, d2
        c1, c2, base = held1, held2, lo
        o = oldest[r0:r1] - base
        n = (np.arange(r0, r1) + 1 - oldest[r0:r1]).astype(np.float64)[:, None]
        m = (c1[keep:] - c1[o]) / n
        v = (c2[keep:] - c2[o]) / n - m * m
        std = np.sqrt(np.maximum(v[:, 0] + v[:, 1] + v[:, 2], 0.0))
        full = t[r0:r1] - t[0] >= window_ns
        std[~full] = np.nan
        yield r0, r1, full, std, ref + m


def detect_rest(t_ns, gyro, accel=None, window_s: float = RestThresholds.window_s,
                gyro_std_max: float = RestThresholds.gyro_std_max,
                gyro_mean_max: float = RestThresholds.gyro_mean_max,
                accel_std_max: float = RestThresholds.accel_std_max,
                accel_norm_tol: float = RestThresholds.accel_norm_tol,
                gravity: float = STANDARD_GRAVITY, gyro_std_min: float = 0.0) -> RestWindows:
    """Batch :class:`RestDetector` over arrays (bit-identical decisions, vectorized)."""
    th = RestThresholds(window_s, gyro_std_max, gyro_mean_max, accel_std_max, accel_norm_tol,
                        gravity, gyro_std_min).checked()
    t, g, a = check_samples(t_ns, gyro, accel)
    window_ns = int(round(th.window_s * 1e9))
    size = t.size
    oldest = np.empty(size, dtype=np.int64)
    for r0 in range(0, size, _STATS_CHUNK):
        r1 = min(r0 + _STATS_CHUNK, size)
        oldest[r0:r1] = np.searchsorted(t, t[r0:r1] - window_ns, side="left")
    gyro_std = np.empty(size)
    ok = np.empty(size, dtype=bool)
    for r0, r1, full, std, mean in _window_stats(t, g, oldest, window_ns):
        gyro_std[r0:r1] = std
        with np.errstate(invalid="ignore"):
            # the mean rate on every axis (the largest one) within the bound
            ok[r0:r1] = full & (std >= th.gyro_std_min) & (std <= th.gyro_std_max) & (
                np.abs(mean).max(axis=1) <= th.gyro_mean_max)
    accel_std = np.full(size, np.nan)
    if a is not None:
        for r0, r1, _, std, mean in _window_stats(t, a, oldest, window_ns):
            accel_std[r0:r1] = std
            norm = np.sqrt(mean[:, 0] * mean[:, 0] + mean[:, 1] * mean[:, 1]
                           + mean[:, 2] * mean[:, 2])
            with np.errstate(invalid="ignore"):
                ok[r0:r1] &= (std <= th.accel_std_max) & (np.abs(norm - th.gravity)
                                                          <= th.accel_norm_tol)
    covered = _covered(ok, oldest)
    return RestWindows(ok, oldest, gyro_std, accel_std, covered)


def _covered(at_rest: np.ndarray, oldest: np.ndarray) -> np.ndarray:
    """Samples lying in at least one rest window: mark [oldest[k], k] for each rest k."""
    n = at_rest.size
    diff = np.zeros(n + 1, dtype=np.int64)
    k = np.flatnonzero(at_rest)
    np.add.at(diff, oldest[k], 1)
    np.add.at(diff, k + 1, -1)
    return np.cumsum(diff[:n]) > 0


def rest_segments(covered: np.ndarray) -> list[tuple[int, int]]:
    """Runs of rest samples as ``(first, last)`` index pairs (inclusive), in order."""
    c = np.asarray(covered, dtype=bool)
    edges = np.diff(np.concatenate([[False], c, [False]]).astype(np.int8))
    starts = np.flatnonzero(edges == 1)
    ends = np.flatnonzero(edges == -1) - 1
    return list(zip(starts.tolist(), ends.tolist(), strict=True))
