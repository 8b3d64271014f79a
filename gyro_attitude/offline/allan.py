"""Allan analysis of a static IMU recording: deviation per axis, fitted terms, JSON, scene, plot.

Allan analysis describes the noise of a sensor at rest: motion in the record reads as huge
bias instability and random walks.  :func:`find_rests` finds the stretches where the IMU is
still, and :func:`analyse_mcap` analyses the whole record only when it is still throughout;
otherwise the longest rest, and says so (or refuses when no rest is long enough)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import allantools
import numpy as np

from gyro_attitude.core.allan import (
    AllanTerms,
    fit_terms,
    log_spaced_cluster_sizes,
    model_variance,
    relative_error,
)
from gyro_attitude.core.attitude.sample_clock import run_period, sample_clock
from gyro_attitude.core.attitude.settings import setting
from gyro_attitude.core.attitude.validation import no_estimate
from gyro_attitude.core.sensor_errors import FLICKER_FLOOR_FACTOR
from gyro_attitude.core.units import format_si
from gyro_attitude.io.imu_fast import read_imu_arrays

__all__ = ["AxisAllan", "AllanResult", "allan_deviation", "analyse_rates", "analyse_mcap",
           "KALIBR_KEYS", "RestSearch", "find_rests", "MIN_REST_S"]

#: Kalibr / VIO IMU noise-model keys: (sensor, term) -> key.
KALIBR_KEYS = {
    ("gyro", "random_walk"): "gyroscope_noise_density",
    ("gyro", "rate_random_walk"): "gyroscope_random_walk",
    ("accelerometer", "random_walk"): "accelerometer_noise_density",
    ("accelerometer", "rate_random_walk"): "accelerometer_random_walk",
}

AXES = ("x", "y", "z")
# Unit kinds of each term, per sensor (gyro_attitude.core.units) and the scene keys they
# go to (core/scene.py datasheet keys).
_GYRO_TERMS = {
    "random_walk": ("angle random walk", "arw"),
    "bias_instability": ("angular rate", "bias_instability"),
    "rate_random_walk": ("rate random walk", "rate_random_walk"),
}
_ACCEL_TERMS = {
    "random_walk": ("velocity random walk", "vrw"),
    "bias_instability": ("acceleration", "bias_instability"),
    "rate_random_walk": ("acceleration random walk", "acceleration_random_walk"),
}
# JSON names of the terms, per sensor (SI units in the name).
_GYRO_JSON = {"quantization": "quantization_rad", "random_walk": "arw_rad_sqrt_s",
              "bias_instability": "bias_instability_rad_s",
              "rate_random_walk": "rrw_rad_s_sqrt_s"}
_ACCEL_JSON = {"quantization": "quantization_m_s", "random_walk": "vrw_m_s_sqrt_s",
               "bias_instability": "bias_instability_m_s2",
               "rate_random_walk": "acc_rw_m_s2_sqrt_s"}


@dataclass
class AxisAllan:
    """One axis: overlapping Allan deviation, its 1-σ bounds and the fitted terms."""

    adev: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    terms: AllanTerms


@dataclass
class AllanResult:
    """Allan analysis of one Imu topic. ``accel`` is ``None`` without accelerometer data."""

    topic: str
    samples: int
    dt_s: float
    tau_s: np.ndarray
    gyro: dict[str, AxisAllan]
    accel: dict[str, AxisAllan] | None = None
    notes: list[str] = field(default_factory=list)
    #: where the IMU is still, ``(start, end)`` seconds after the first sample (None: not
    #: searched, e.g. :func:`analyse_rates` on arrays)
    rests_s: list[tuple[float, float]] | None = None
    #: the part analysed, seconds after the first sample (None: every sample)
    analysed_s: tuple[float, float] | None = None
    #: the IMU moves somewhere in the record (the terms are those of ``analysed_s`` then,
    #: or of a moving record when the whole was asked for)
    moving: bool = False

    def to_json(self) -> dict:
        """The ``--json`` document (SI units in the key names)."""
        out = {"topic": self.topic, "samples": self.samples, "dt_s": self.dt_s,
               "tau_s": self.tau_s.tolist(), "moving": self.moving,
               "rests_s": None if self.rests_s is None else [list(r) for r in self.rests_s],
               "analysed_s": None if self.analysed_s is None else list(self.analysed_s)}
        for key, axes, names in (("", self.gyro, _GYRO_JSON), ("accel_", self.accel, _ACCEL_JSON)):
            if axes is None:
                continue
            unit = "rad_s" if not key else "m_s2"
            out[f"{key}adev_{unit}"] = {a: axes[a].adev.tolist() for a in AXES}
            out[f"{key}adev_lower_{unit}"] = {a: axes[a].lower.tolist() for a in AXES}
            out[f"{key}adev_upper_{unit}"] = {a: axes[a].upper.tolist() for a in AXES}
            out[f"{key}axes"] = {a: {names[t]: v for t, v in axes[a].terms.as_dict().items()}
                                 for a in AXES}
        out["notes"] = list(self.notes)
        return out

    def kalibr(self) -> tuple[dict, list[str]]:
        """The Kalibr IMU noise model (``imu.yaml``) and what was bounded, not fitted.

        Kalibr takes one value per sensor: the largest of the three axes (the conservative
        choice). Noise density = the fitted ARW / VRW N (continuous time, rad/s/√Hz or
        m/s²/√Hz); random walk = the fitted RRW / AccRW K (rad/s²/√Hz, m/s³/√Hz). A term
        the record does not show is written as the upper bound the deviation allows (white
        noise: σ(τ_min)·√τ_min; random walk: σ(τ_max)·√(3/τ_max)) and listed in the notes.
        """
        out: dict = {}
        notes: list[str] = []
        for sensor, axes in (("accelerometer", self.accel), ("gyro", self.gyro)):
            if axes is None:
                continue
            for term, bound in (("random_walk", lambda ax: ax.adev[0] * math.sqrt(
                    self.tau_s[0])), ("rate_random_walk", lambda ax: ax.adev[-1] * math.sqrt(
                        3.0 / self.tau_s[-1]))):
                key = KALIBR_KEYS[(sensor, term)]
                fitted = [getattr(axes[a].terms, term) for a in AXES]
                if all(v is not None for v in fitted):
                    out[key] = float(max(fitted))
                else:
                    out[key] = float(max(bound(axes[a]) for a in AXES))
                    notes.append(f"{key}: not visible in this record; written as the upper "
                                 "bound its Allan deviation allows")
        out["rostopic"] = "/" + self.topic.lstrip("/")
        out["update_rate"] = round(1.0 / self.dt_s, 6)
        return out, notes

    def scene_errors(self) -> dict:
        """``{"gyro": {...}, "accelerometer": {...}}`` error blocks (datasheet keys, values
        with units) that the scene loader reads; terms not visible are left out."""
        blocks = {}
        for sensor, axes, terms in (("gyro", self.gyro, _GYRO_TERMS),
                                    ("accelerometer", self.accel, _ACCEL_TERMS)):
            if axes is None:
                continue
            block = {}
            for term, (kind, key) in terms.items():
                vals = [getattr(axes[a].terms, term) for a in AXES]
                if all(v is None for v in vals):
                    continue
                block[key] = [format_si(v or 0.0, kind) for v in vals]
            blocks[sensor] = block
        return blocks


#: Missing samples accepted in a record, as a fraction of its samples: a few dropped
#: messages are left out of the cluster averages; more than this is not a static record.
MAX_MISSING_FRACTION = 1e-3


def allan_deviation(samples: np.ndarray, dt: float, m: np.ndarray) -> np.ndarray:
    """Overlapping Allan deviation (allantools.oadev) of rate samples ``(n,)`` at τ = m·dt."""
    taus, adev, _, _ = allantools.oadev(np.asarray(samples, dtype=np.float64), rate=1.0 / dt,
                                        data_type="freq", taus=np.asarray(m) * dt)
    if taus.shape != m.shape:
        raise ValueError("allantools dropped averaging times; recording too short")
    return adev


def _stretch_deviation(samples: np.ndarray, starts: np.ndarray, dt: float,
                       m: np.ndarray) -> np.ndarray:
    """Overlapping Allan deviation of a record with holes: every cluster pair that spans no
    hole, i.e. allantools' deviation of each gap-free stretch (``starts``: where stretches
    begin) weighted by its number of terms (n_s − 2m + 1). allantools has no notion of a
    hole in rate data (its phase, the running sum, would carry the hole onward)."""
    if starts.size == 1:
        return allan_deviation(samples, dt, m)
    num = np.zeros(m.size)
    den = np.zeros(m.size)
    for s in np.split(samples, starts[1:]):
        terms = s.size - 2 * m + 1
        ok = terms > 0
        if ok.any():
            num[ok] += allan_deviation(s, dt, m[ok]) ** 2 * terms[ok]
            den[ok] += terms[ok]
    if not (den > 0).all():
        raise ValueError("the gap-free stretches are too short for the longest averaging times")
    return np.sqrt(num / den)


def _constant_axes(data: np.ndarray) -> list[str]:
    return [a for a, i in zip(AXES, range(3), strict=True) if np.ptp(data[:, i]) == 0.0]


def _analyse(data: np.ndarray, dt: float, m: np.ndarray, n: int, sensor: str,
             starts: np.ndarray) -> dict[str, AxisAllan]:
    constant = _constant_axes(data)
    if constant:
        raise ValueError(f"{sensor} {', '.join(constant)}: every one of the {n} samples is "
                         "the same: no noise to fit")
    rel = relative_error(n, m)
    tau = m * dt
    out = {}
    for i, axis in enumerate(AXES):
        adev = _stretch_deviation(data[:, i], starts, dt, m)
        out[axis] = AxisAllan(adev, adev * (1.0 - rel), adev * (1.0 + rel),
                              fit_terms(tau, adev, rel))
    return out


def analyse_rates(gyro: np.ndarray, dt: float, accel: np.ndarray | None = None,
                  topic: str = "", stretch_starts=None) -> AllanResult:
    """Allan analysis of evenly spaced samples ``(n, 3)`` (rad/s; accel m/s²) every ``dt`` s.

    ``stretch_starts``: indices where a gap-free stretch begins after a hole (missing
    samples), ``[0]`` or None for a record without holes; cluster pairs spanning a hole
    are left out."""
    gyro = np.asarray(gyro, dtype=np.float64)
    if gyro.ndim != 2 or gyro.shape[1] != 3:
        raise ValueError(f"gyro samples must have shape (n, 3), got {gyro.shape}")
    if not (np.isfinite(dt) and dt > 0):
        raise ValueError(f"sample interval must be finite and > 0, got {dt}")
    if not np.all(np.isfinite(gyro)):
        raise ValueError("gyro samples contain NaN or inf")
    starts = np.zeros(1, np.int64) if stretch_starts is None else \
        np.asarray(stretch_starts, np.int64)
    n = gyro.shape[0]
    m = log_spaced_cluster_sizes(n)
    result = AllanResult(topic, n, float(dt), m * dt, _analyse(gyro, dt, m, n, "gyro", starts))
    if accel is not None:
        accel = np.asarray(accel, dtype=np.float64)
        if accel.shape != gyro.shape or not np.all(np.isfinite(accel)):
            raise ValueError("accelerometer samples must be finite and shaped like the gyro's")
        result.accel = _analyse(accel, dt, m, n, "accelerometer", starts)
    return result


#: Rest search (:func:`find_rests`): blocks of about this long (and at least
#: :data:`REST_BLOCK_MIN_SAMPLES` samples) are judged still or moving.
REST_BLOCK_S = 1.0
REST_BLOCK_MIN_SAMPLES = 32
#: A block is still when its deviation on every axis stays within this factor of the record's
#: quiet blocks' (the 5th percentile of the block deviations, per axis and sensor).
REST_STD_FACTOR = 3.0
REST_QUIET_PERCENTILE = 5.0
#: ... and its mean rate within this of the still blocks' median on every axis (rad/s): a
#: steady turn shows no spread (the rest detector's bound for a bias, core/attitude/rest.py)
REST_MEAN_TOL_RAD_S = setting("rest_gyro_mean_max").default
#: (or within this many standard errors of a block mean, for a noisy gyro)
REST_MEAN_NOISE_FACTOR = 6.0
#: Shortest rest analysed on its own: τ up to about 1 s, where the ARW is read.
MIN_REST_S = 10.0


@dataclass(frozen=True)
class RestSearch:
    """Still stretches of a record, ``(first, last)`` sample indices (inclusive), in order;
    ``still`` when one stretch holds every sample."""

    segments: tuple[tuple[int, int], ...]
    samples: int

    @property
    def still(self) -> bool:
        return self.segments == ((0, self.samples - 1),)

    def longest(self) -> tuple[int, int] | None:
        return max(self.segments, key=lambda s: s[1] - s[0]) if self.segments else None


def _block_stats(x: np.ndarray, size: int) -> tuple[np.ndarray, np.ndarray]:
    """Per-axis mean and standard deviation of consecutive blocks of ``size`` samples (the
    last, partial block left out), block by block: no copy of the record."""
    nb = x.shape[0] // size
    mean = np.empty((nb, x.shape[1]))
    std = np.empty((nb, x.shape[1]))
    step = max(1, (1 << 20) // size)  # blocks per pass: about a million samples
    for b0 in range(0, nb, step):
        b1 = min(nb, b0 + step)
        part = x[b0 * size:b1 * size].reshape(b1 - b0, size, x.shape[1])
        mean[b0:b1] = part.mean(axis=1)
        std[b0:b1] = part.std(axis=1)
    return mean, std


def _quiet_std(std: np.ndarray) -> np.ndarray:
    """Per axis, the deviation of the record's quiet blocks: the low percentile of the blocks'
    deviations (blocks of identical samples left out: a quantized sensor's, which a noise
    floor of 0 would make every other block exceed)."""
    out = np.zeros(std.shape[1])
    for i in range(std.shape[1]):
        s = std[:, i][std[:, i] > 0]
        out[i] = np.percentile(s, REST_QUIET_PERCENTILE) if s.size else 0.0
    return out


def find_rests(gyro: np.ndarray, dt: float, accel: np.ndarray | None = None) -> RestSearch:
    """Where the IMU of evenly spaced samples ``(n, 3)`` every ``dt`` s is still.

    The record is cut into blocks of about :data:`REST_BLOCK_S`.  A block is still when on
    every axis its deviation is at most :data:`REST_STD_FACTOR` times that of the record's
    quiet blocks (gyro, and accelerometer when given) and its mean rate lies within
    :data:`REST_MEAN_TOL_RAD_S` (or :data:`REST_MEAN_NOISE_FACTOR` standard errors of a block
    mean) of the still blocks' median.  The thresholds are relative to the record's own
    noise, not absolute like the estimator's rest detector: a static record of a noisy or
    strongly biased gyro is still throughout, whatever its grade, as long as its bias wanders
    by less than the tolerance over the record.  (For white noise over a block of L ≥ 32
    samples the deviation scatters by about 1/√(2L) ≤ 13 %, so a still block of a static
    record is never taken for motion.)  Runs of still blocks are the
    rests; a rest bordered by motion loses one block at that side (the block where the motion
    starts or ends may look still).  A record still in every block is one rest holding every
    sample (the tail shorter than a block included).  A slow creep of the mean, under the
    tolerance, is not seen."""
    n = gyro.shape[0]
    size = max(REST_BLOCK_MIN_SAMPLES, int(round(REST_BLOCK_S / dt)))
    nb = n // size
    if nb < 2:  # too short to judge: taken as one rest (the analysis says if too short)
        return RestSearch(((0, n - 1),), n)
    mean, std = _block_stats(gyro, size)
    quiet = _quiet_std(std)
    still = (std <= REST_STD_FACTOR * quiet).all(axis=1)
    if accel is not None:
        _, a_std = _block_stats(accel, size)
        still &= (a_std <= REST_STD_FACTOR * _quiet_std(a_std)).all(axis=1)
    if still.any():
        ref = np.median(mean[still], axis=0)
        # the white noise alone scatters a block's mean by σ/√L: never a motion below 6 of it
        tol = np.maximum(REST_MEAN_TOL_RAD_S, REST_MEAN_NOISE_FACTOR * quiet / math.sqrt(size))
        still &= (np.abs(mean - ref) <= tol).all(axis=1)
    if still.all():
        return RestSearch(((0, n - 1),), n)
    edges = np.diff(np.concatenate([[0], still.astype(np.int8), [0]]))
    segments = []
    for b0, b1 in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True):
        first, last = int(b0), int(b1) - 1  # blocks, inclusive
        if first > 0:
            first += 1
        if b1 < nb:  # motion follows (an unjudged tail shorter than a block is left out)
            last -= 1
        if last >= first:
            segments.append((first * size, (last + 1) * size - 1))
    return RestSearch(tuple(segments), n)


def _check_stamps(t: np.ndarray, path: Path, topic: str) -> None:
    """One line naming what is wrong with the stamps: unset (zero), repeated or going back."""
    where = f"{path}: Imu stamps on {topic!r}"
    if t.size < 2:
        raise ValueError(f"{path}: only {t.size} Imu message on topic {topic!r}: Allan "
                         "analysis needs a record")
    zero = int(np.count_nonzero(t == 0))
    # (one stamp 0 at the start is a clock's origin: a simulated record starts there)
    if zero > 1 or (zero and t[0] != 0):
        which = "every one" if zero == t.size else f"{zero} of the {t.size}"
        first = int(np.flatnonzero(t == 0)[0])
        raise ValueError(f"{where}: {which} is zero (header.stamp not set by the driver; "
                         f"first at message {first}): Allan analysis needs the sample times")
    steps = np.diff(t)
    back, same = steps < 0, steps == 0
    if back.any() or same.any():
        parts = []
        for mask, what in ((back, "go back"), (same, "repeat")):
            if mask.any():
                k = int(np.flatnonzero(mask)[0]) + 1
                parts.append(f"{what} {int(mask.sum())} time(s) (first at message {k}, "
                             f"{(t[k] - t[0]) * 1e-9:g} s after the first)")
        raise ValueError(f"{where} {' and '.join(parts)}: Allan analysis needs strictly "
                         "increasing stamps")


def _span(t: np.ndarray, first: int, last: int) -> tuple[float, float]:
    return (round(float(t[first] - t[0]) * 1e-9, 3), round(float(t[last] - t[0]) * 1e-9, 3))


def _rest_list(rests: list[tuple[float, float]], limit: int = 6) -> str:
    text = ", ".join(f"{a:g}–{b:g} s" for a, b in rests[:limit])
    return text + (f" and {len(rests) - limit} more" if len(rests) > limit else "")


def analyse_mcap(path, topic: str = "imu/data_raw", whole_record: bool = False) -> AllanResult:
    """Read every ``sensor_msgs/Imu`` of ``topic`` from an MCAP file and analyse it.

    The accelerometer is analysed when the messages carry one (linear acceleration
    covariance element 0 is not −1).  Where the IMU moves (:func:`find_rests`), the longest
    rest is analysed instead of the whole (``moving`` set and a note saying so), unless
    ``whole_record``; ``ValueError`` when no rest lasts :data:`MIN_REST_S`, naming the rests.
    ``ValueError`` with one line on a bad file, no Imu, bad or uneven stamps or too few
    samples."""
    path = Path(path)
    try:
        imu = read_imu_arrays(path, topic)  # a file, a bag directory or a split bag
    except ValueError:
        raise
    except Exception as exc:  # the reader's own errors for damaged files
        raise ValueError(f"{path}: cannot read: {exc}") from None
    if len(imu) == 0:
        raise ValueError(f"{path}: no sensor_msgs/Imu messages on topic {topic!r}")
    t = imu.stamp_ns.astype(np.int64)
    _check_stamps(t, path, topic)
    # A regular stream's stamps scatter by less than half a step about the clock they were
    # taken on (a driver stamping on receipt: ±1/3 of the step, so an interval may be off by
    # 2/3): judge each stamp against that clock, not each interval.  A step of the clock of
    # k >= 2 periods is a hole of k - 1 missing samples.
    period = float(run_period(t))
    tau = sample_clock(t, [0])
    off = np.abs(t - tau) / period
    k = np.rint(np.diff(tau) / period)
    if off.max() >= 0.5 or (k < 1).any():
        bad = np.flatnonzero(off >= 0.5)
        first = int(bad[0]) if bad.size else int(np.flatnonzero(k < 1)[0]) + 1
        raise ValueError(f"{path}: Imu stamps on {topic!r} are not a regular stream: they lie "
                         f"up to {off.max():.0%} of the {period / 1e6:g} ms step from the clock "
                         f"they scatter about (first at message {first}, "
                         f"{(t[first] - t[0]) * 1e-9:g} s after the first; a regular stream's "
                         "lie within half a step); Allan analysis needs evenly spaced samples")
    spread = float(off.max())
    dt_ns = float(tau[-1] - tau[0]) / float(k.sum())  # the clock's step over the whole record
    notes = []
    holes = k >= 2
    starts = np.r_[0, np.flatnonzero(holes) + 1]
    if holes.any():
        missing = int((k[holes] - 1).sum())
        where = (tau[int(np.flatnonzero(holes)[0])] + period - tau[0]) * 1e-9  # first missing
        what = (f"{missing} samples missing in {int(holes.sum())} holes (first {where:g} s "
                f"after the start)")
        limit = int(MAX_MISSING_FRACTION * (t.size + missing))
        if missing > limit:
            raise ValueError(f"{path}: {what} on {topic!r}: at most {limit} "
                             f"({MAX_MISSING_FRACTION:.1%} of the record) are accepted; "
                             "Allan analysis needs an unbroken static record")
        notes.append(f"{what}: cluster pairs spanning a hole are left out")
    if spread > 0.01:
        notes.append(f"stamps scatter up to {spread:.1%} of the step about their clock "
                     "(treated as even)")
    has_accel = not no_estimate(imu.linear_acceleration_covariance).any()
    gyro = imu.angular_velocity
    accel = imu.linear_acceleration if has_accel else None
    rests = None
    if np.all(np.isfinite(gyro)) and (accel is None or np.all(np.isfinite(accel))):
        rests = find_rests(gyro, dt_ns / 1e9, accel)  # (non-finite samples: refused below)
    first, last = 0, t.size - 1
    moving = rests is not None and not rests.still
    if moving:
        spans = [_span(t, a, b) for a, b in rests.segments]
        if not whole_record:
            longest = rests.longest()
            if longest is None or (t[longest[1]] - t[longest[0]]) * 1e-9 < MIN_REST_S:
                found = (f"rests: {_rest_list(spans)}" if spans else "no rest found")
                raise ValueError(
                    f"{path}: the IMU on {topic!r} moves: no rest lasts {MIN_REST_S:g} s "
                    f"({found}); Allan analysis needs the sensor at rest (--whole-record "
                    "analyses every sample anyway)")
            first, last = longest
            notes.append(f"the IMU moves in this record (rests at {_rest_list(spans)}): "
                         f"analysed the longest rest, {_span(t, first, last)[0]:g}–"
                         f"{_span(t, first, last)[1]:g} s ({last - first + 1} samples)")
        else:
            notes.append(f"the IMU moves in this record (rests at "
                         f"{_rest_list(spans) if spans else 'none'}): every sample analysed "
                         "as asked (--whole-record): the terms include the motion")
    sub = slice(first, last + 1)
    if first or last < t.size - 1:
        starts = np.r_[0, starts[(starts > first) & (starts <= last)] - first]
    try:
        result = analyse_rates(gyro[sub], dt_ns / 1e9,
                               accel[sub] if accel is not None else None, topic, starts)
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None
    result.notes += notes
    result.moving = moving
    if rests is not None:
        result.rests_s = [_span(t, a, b) for a, b in rests.segments]
    if moving and not whole_record:
        result.analysed_s = _span(t, first, last)
    return result


def plot(result: AllanResult, path, title: str = "") -> None:
    """Log-log Allan deviation per axis with bounds, the fitted term lines and read points."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sensors = [("gyro", result.gyro, "rad/s")]
    if result.accel is not None:
        sensors.append(("accelerometer", result.accel, "m/s²"))
    fig, axs = plt.subplots(1, len(sensors), figsize=(6.5 * len(sensors), 5), squeeze=False)
    tau = result.tau_s
    line = {"quantization": ("Q: −1", lambda v, t: np.sqrt(3.0) * v / t),
            "random_walk": ("N: −½", lambda v, t: v / np.sqrt(t)),
            "bias_instability": ("B: 0", lambda v, t: np.full_like(t, FLICKER_FLOOR_FACTOR * v)),
            "rate_random_walk": ("K: +½", lambda v, t: v * np.sqrt(t / 3.0))}
    for ax, (name, axes, unit) in zip(axs[0], sensors, strict=True):
        for axis, color in zip(AXES, ("C0", "C1", "C2"), strict=True):
            a = axes[axis]
            ax.loglog(tau, a.adev, color=color, lw=1.6, label=f"{axis}")
            ax.fill_between(tau, a.lower, a.upper, color=color, alpha=0.15, lw=0)
            ax.loglog(tau, np.sqrt(model_variance(tau, a.terms)), color=color, lw=0.8, ls=":")
            for term, (_label, f) in line.items():
                v = getattr(a.terms, term)
                if v is None:
                    continue
                ax.loglog(tau, f(v, tau), color=color, lw=0.6, ls="--", alpha=0.6)
                t_read = a.terms.tau_read_s.get(term)
                if t_read is not None:
                    ax.plot([t_read], [f(v, np.array([t_read]))[0]], "o", color=color, ms=4)
        # Low enough to show every read-out point (K at 3 s often sits far below the curve).
        lows = [axes[x].adev.min() / 3 for x in AXES] + [
            getattr(axes[x].terms, term) / 1.5 for x in AXES
            for term in ("random_walk", "rate_random_walk") if getattr(axes[x].terms, term)]
        ax.set_ylim(min(lows), np.max([axes[x].adev.max() for x in AXES]) * 3)
        ax.set_xlabel("τ [s]")
        ax.set_ylabel(f"Allan deviation [{unit}]")
        ax.set_title(f"{name}: dashed = fitted terms (N@1 s, B floor, K@3 s: dots)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
