"""Verdicts on a stream of Imu samples (stamps, rates, frame), per sample or array-wide.

The kernel :func:`validate` classifies each sample before it reaches the integrator (a NaN, an
absurd rate, a stamp that does not rise, a gap or a changed ``frame_id`` would corrupt the
attitude) and counts per reason on a :data:`STAMPS_DTYPE` record (the causal step,
:mod:`.chain`); :func:`classify` gives a whole recording that kernel's verdicts (the offline
estimator's) through a compiled loop, :func:`validate_rows`.  Thresholds are the settings
table's rows (a :class:`~.settings.StreamConfig`).  Times are integer nanoseconds
(``header.stamp``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gyro_attitude.core.attitude.settings import StreamConfig
from gyro_attitude.core.jit import compiled, kernel, precompiled

# Verdicts. ACCEPT: integrate over (last, t]. START: first sample (or first after a restart):
# sets the time base, nothing to integrate yet.
ACCEPT = "accept"
START = "start"
# The sample is integrated from a fresh time base, the attitude kept (see GAP below).
RESTART_AFTER_GAP = "restart_after_gap"
# Backward time jump beyond the threshold (e.g. a bag replay looped, a simulator restarted):
# the attitude resets to the initial one and starts over at this sample.
RESET_TIME_JUMP = "reset_time_jump"
REJECT = "reject"

# Rejection reasons (the sample is dropped, counted, and the state is untouched).
NON_FINITE = "non_finite"
IMPLAUSIBLE_RATE = "implausible_rate"
ZERO_STAMP = "zero_stamp"
DUPLICATE_STAMP = "duplicate_stamp"
OUT_OF_ORDER = "out_of_order"
FRAME_CHANGED = "frame_changed"
# A gap is counted like a rejection of the *interval*: nothing is integrated across it.
# The sample itself becomes the new time base (RESTART_AFTER_GAP), otherwise every later
# sample would also be "after a gap".
GAP = "gap"
# An accepted interval that spans missing samples (a hole of a few sample periods): counted,
# integrated across; a longer hole is a gap.
MISSING_SAMPLES = "missing_samples"
# Intervals of a new time base whose median is the stream's nominal period.
NOMINAL_INTERVALS = 16

REJECT_REASONS: tuple[str, ...] = (
    NON_FINITE,
    IMPLAUSIBLE_RATE,
    ZERO_STAMP,
    DUPLICATE_STAMP,
    OUT_OF_ORDER,
    FRAME_CHANGED,
    GAP,
)

#: the verdict of each code (the step's A_* codes, the arrays of :func:`classify`)
ACTIONS = (REJECT, START, ACCEPT, RESTART_AFTER_GAP, RESET_TIME_JUMP)
ACTION_CODES: dict[str, int] = {a: i for i, a in enumerate(ACTIONS)}


@dataclass(frozen=True)
class Verdict:
    """Outcome of one check: ``action`` is ACCEPT/START/RESTART_AFTER_GAP/RESET_TIME_JUMP
    or REJECT; ``reason`` names the rejection (or the gap/jump) and ``detail`` says why in
    words, for a log line."""

    action: str
    reason: str | None = None
    detail: str = ""

    @property
    def rejected(self) -> bool:
        return self.action == REJECT


def accepted_rows(action: np.ndarray, empty=np.empty, size: int = 1 << 16) -> np.ndarray:
    """The rows of ``action`` (:attr:`Classification.action`) that are not rejected, as
    ``np.flatnonzero`` gives them, into an array from ``empty(shape, dtype)``; ``size`` rows
    at a time (no temporary of the recording's length)."""
    reject = ACTION_CODES[REJECT]
    n = action.shape[0]
    count = sum(int(np.count_nonzero(action[c0:c0 + size] != reject))
                for c0 in range(0, n, size))
    out = empty(count, np.int64)
    k = 0
    for c0 in range(0, n, size):
        got = np.flatnonzero(action[c0:c0 + size] != reject)
        got += c0
        out[k:k + got.size] = got
        k += got.size
    return out


def sample_problem(t_ns, omega, max_rate_rad_s: float) -> tuple[str, str] | None:
    """(reason, detail) when a sample is unusable on its own (:func:`sample_reason`: its
    values, a stamp that is not positive), else None: the checks that need no earlier sample."""
    if isinstance(t_ns, bool) or not isinstance(t_ns, int | np.integer):
        raise ValueError(f"t_ns must be an integer number of nanoseconds, got {t_ns!r}")
    try:
        values = [float(c) for c in (
            omega.tolist() if isinstance(omega, np.ndarray) and omega.ndim == 1 else omega)]
    except (TypeError, ValueError):
        return NON_FINITE, f"not numbers: {omega!r}"
    if len(values) != 3:
        return NON_FINITE, f"non-finite value(s) {values}"
    why = sample_reason(t_ns, values[0], values[1], values[2], max_rate_rad_s)
    if why == 0:
        return None
    name = REASON_NAMES[why]
    return name, reason_words(name, t_ns, values, None, None, (0,) * 5, max_rate_rad_s, 0)


def reason_words(name: str, t_ns: int, values, frame_id, locked, figures, max_rate: float,
                 max_gap_ns: int) -> str:
    """The words of a verdict's reason ``name`` for the sample at ``t_ns`` (``values`` its
    rates as floats, for the value rules; ``frame_id`` and the ``locked`` one; ``figures``
    the validator's ``ev_*`` figures: a record or an array (dt, hole, missing, skipped,
    period); the thresholds ``max_rate`` and ``max_gap_ns``)."""
    if hasattr(figures, "ev_dt"):
        dt, hole, missing, skipped, p = (int(figures.ev_dt), int(figures.ev_hole),
                                         int(figures.ev_missing), int(figures.ev_skipped),
                                         int(figures.ev_period))
    else:
        dt, hole, missing, skipped, p = (int(x) for x in figures)
    if name == NON_FINITE:
        return f"non-finite value(s) {list(values)}"
    if name == IMPLAUSIBLE_RATE:
        return f"rate {list(values)} rad/s beyond max_rate_rad_s = {max_rate:g}"
    if name == ZERO_STAMP:
        return f"stamp {int(t_ns)} ns is not positive (0: unset)"
    if name == FRAME_CHANGED:
        return f"frame_id {frame_id!r} differs from {locked!r}"
    if name == DUPLICATE_STAMP:
        return f"stamp {t_ns} ns repeats the previous one"
    if name == OUT_OF_ORDER:
        return f"stamp {t_ns} ns is {-dt / 1e6:.3f} ms before the previous"
    if name == TIME_JUMP:
        return f"time jumped back by {-dt / 1e9:.3f} s"
    if name == GAP:
        if dt > max_gap_ns:
            return f"gap of {dt / 1e6:.3f} ms"
        return (f"hole of {hole} sample(s) ({missing} missing, {skipped} rejected): "
                f"{dt / 1e6:.3f} ms after the previous at a nominal period of {p / 1e6:.3f} ms "
                "(> max_missing_samples)")
    if name == MISSING_SAMPLES:
        return (f"{missing} missing sample(s): {dt / 1e6:.3f} ms after the previous at a "
                f"nominal period of {p / 1e6:.3f} ms")
    return "non-finite attitude: last good one restored"


@dataclass
class Classification:
    """Verdicts of :func:`classify` for N samples.

    ``action`` (N,) int8 codes of :data:`ACTION_CODES`; ``reason`` (N,) int8, 0 = none, else
    1 + the index in :data:`REJECT_REASONS` (rejections and gaps); ``counts`` per reason;
    ``details`` the first detail line per reason; ``time_jump_resets``; ``accepted``;
    ``frame_id`` the locked frame; ``missing_samples`` counted in accepted intervals.
    """

    action: np.ndarray
    reason: np.ndarray
    counts: dict[str, int]
    details: dict[str, str]
    time_jump_resets: int
    accepted: int
    frame_id: str | None
    missing_samples: int = 0


def _frame_codes(frame_id, n: int) -> tuple[np.ndarray | None, list[str]]:
    """Per-sample frame codes (None: one frame for all) and the names they index."""
    if frame_id is None or isinstance(frame_id, str):
        return None, ["" if frame_id is None else frame_id]
    if not hasattr(frame_id, "__len__") or len(frame_id) != n:
        raise ValueError(f"frame_id must be one string or one per sample ({n}), got "
                         f"{type(frame_id).__name__}")
    names: dict[str, int] = {}
    codes = np.fromiter((names.setdefault(str(f), len(names)) for f in frame_id),
                        dtype=np.int64, count=n)
    return codes, list(names)


#: REP-145: element 0 of a covariance is −1 when the field carries no estimate.
NO_ESTIMATE = -1.0


def no_estimate(covariance):
    """REP-145's "no estimate" rule, the one home of it: element 0 of a row-major covariance
    (9,) — or of every row of (N, 9) — is −1.  A bool, or a bool array (N,)."""
    if isinstance(covariance, list):  # one row as plain floats (the per-sample path)
        return bool(covariance) and covariance[0] == NO_ESTIMATE
    c = np.asarray(covariance)
    if c.ndim == 1:
        return bool(c.size and c[0] == NO_ESTIMATE)
    return c[..., 0] == NO_ESTIMATE


def all_within(a: np.ndarray, limit: float) -> bool:
    """Whether ``a`` is non-empty and every value is finite and within ±``limit``: two
    whole-array reductions (NaN fails both comparisons), much cheaper than per-row checks
    of (N, 3) arrays, which are then needed only when this is False."""
    with np.errstate(invalid="ignore"):
        return bool(a.size and np.max(a) <= limit and np.min(a) >= -limit)


def classify(t_ns, omega, frame_id: str | list[str] | None = "",
             cfg: StreamConfig | None = None) -> Classification:
    """The verdicts :func:`validate` gives to these samples in this order.

    ``t_ns`` (N,) int stamps, ``omega`` (N, 3) rates, ``frame_id`` one string for all samples or
    one per sample. A fresh validator is assumed (no locked frame, no time base).  Frame ids
    are mapped to integer codes here, at the edge; :func:`validate_rows` steps the kernel.
    """
    cfg = StreamConfig() if cfg is None else cfg
    if not isinstance(cfg, StreamConfig):
        raise TypeError(f"the validation thresholds come from a StreamConfig, got {cfg!r}")
    t = np.asarray(t_ns)
    if t.ndim != 1 or not (np.issubdtype(t.dtype, np.integer) or t.size == 0):
        raise ValueError(f"t_ns must be a 1-D integer array of nanoseconds, got {t.dtype} "
                         f"shape {t.shape}")
    t = t.astype(np.int64, copy=False)
    w = np.asarray(omega, dtype=np.float64)
    n = t.shape[0]
    if w.shape != (n, 3):
        raise ValueError(f"omega must have shape ({n}, 3), got {w.shape}")
    codes, names = _frame_codes(frame_id, n)
    frames = np.zeros(1, np.int64) if codes is None else codes  # one for all: no row's own
    action, reason = np.zeros(n, np.int8), np.zeros(n, np.int8)
    record = np.zeros(1, STAMPS_DTYPE)
    first_row = np.full(R_INTEGRATOR + 1, -1, np.int64)
    first_fig = np.zeros((R_INTEGRATOR + 1, 5), np.int64)
    loop = precompiled(validate_rows) or compiled(validate_rows)
    locked = int(loop(record, cfg.max_rate_rad_s, cfg.max_gap_ns, cfg.time_jump_ns,
                      cfg.max_missing_samples, t, w, frames, action, reason, first_row, first_fig))
    details: dict[str, str] = {}
    for why in range(1, R_INTEGRATOR):
        k = int(first_row[why])
        if k >= 0:
            name = REASON_NAMES[why]
            frame = names[0] if codes is None else names[int(codes[k])]
            details[name] = reason_words(name, int(t[k]), w[k].tolist(), frame,
                                         None if locked < 0 else names[locked], first_fig[why],
                                         cfg.max_rate_rad_s, cfg.max_gap_ns)
    v = record[0]
    counts = dict(zip(REJECT_REASONS, v["counts"][1:].tolist(), strict=True))
    return Classification(action, reason, counts, details, int(v["jump_resets"]),
                          int(v["accepted"]), None if locked < 0 else names[locked],
                          int(v["missing"]))


@kernel
def validate_rows(v, max_rate, max_gap_ns, time_jump_ns, max_missing, t, w, frames, action,
                  reason, first_row, first_fig):
    """:func:`validate` over the samples ``t``, ``w`` on the validator's record ``v[0]`` (frame
    codes ``frames``, one per row or one for all; the first accepted sample's is locked in):
    their action and reason codes, and per reason the first row and the validator's figures
    there (for the words).  Returns the locked frame's code (-1: no sample accepted)."""
    s = v[0]
    per_row = frames.shape[0] == t.shape[0]
    locked = -1
    for i in range(t.shape[0]):
        frame = frames[i] if per_row else frames[0]
        act, why = validate(s, max_rate, max_gap_ns, time_jump_ns, max_missing, t[i], w[i, 0],
                            w[i, 1], w[i, 2], locked < 0 or frame == locked)
        action[i] = act
        if act != A_REJECT and locked < 0:
            locked = frame
        if why == 0:
            continue
        if why != R_TIME_JUMP and why != R_MISSING:
            reason[i] = why
        if first_row[why] < 0:
            first_row[why] = i
            first_fig[why, 0], first_fig[why, 1], first_fig[why, 2] = s.ev_dt, s.ev_hole, \
                s.ev_missing
            first_fig[why, 3], first_fig[why, 4] = s.ev_skipped, s.ev_period
    return locked


class IntervalStatistics:
    """Input rate and dt jitter over the last accepted intervals: a face on the step's ring of
    intervals ``ring`` (ns) and its ``fill`` (held, next slot), written by :func:`interval_add`.

    ``rate_hz`` = 1/mean(dt), ``mean_dt_s``, ``jitter_s`` = standard deviation of dt
    (population), ``max_dt_s`` = largest dt in the window; NaN while fewer than 2 are known.
    """

    def __init__(self, ring: np.ndarray, fill: np.ndarray):
        self.ring, self.fill = ring, fill

    def __len__(self) -> int:
        return int(self.fill[0])

    def summary(self) -> dict[str, float]:
        held, nxt = int(self.fill[0]), int(self.fill[1])
        if held < 2:
            return dict.fromkeys(("rate_hz", "mean_dt_s", "jitter_s", "max_dt_s"), math.nan)
        dt = self.ring[(nxt - held + np.arange(held)) % self.ring.shape[0]] * 1e-9  # oldest first
        mean = float(dt.mean())
        return {"rate_hz": 1.0 / mean, "mean_dt_s": mean, "jitter_s": float(dt.std()),
                "max_dt_s": float(dt.max())}


@kernel(inline=True)
def within(x, y, z, bound):
    """Each of ``x``, ``y``, ``z`` a number of magnitude at most ``bound`` (NaN is not).  Not
    ``max(abs(x), abs(y), abs(z)) <= bound``: ``max`` skips a NaN after the first place."""
    return abs(x) <= bound and abs(y) <= bound and abs(z) <= bound


@kernel(inline=True)
def interval_add(ring, fill, dt_ns):
    """One accepted interval into the ring (the oldest one out when it is full)."""
    ring[fill[1]] = dt_ns
    fill[1] = (fill[1] + 1) % ring.shape[0]
    if fill[0] < ring.shape[0]:
        fill[0] += 1


# ---------------------------------------------------------------------------- the step's form
#: the intervals the statistics hold (the stream's input rate and jitter)
RING = 2000
#: verdict codes of the step (the indices in ACTIONS)
A_REJECT, A_START, A_ACCEPT, A_RESTART_AFTER_GAP, A_RESET_TIME_JUMP = range(len(ACTIONS))
#: reason codes of the step (the indices in REASON_NAMES): 1 + the index in REJECT_REASONS,
#: then a time jump, missing samples, a non-finite attitude
R_NON_FINITE, R_IMPLAUSIBLE, R_ZERO, R_DUPLICATE, R_OUT_OF_ORDER, R_FRAME, R_GAP, R_TIME_JUMP, \
    R_MISSING, R_INTEGRATOR = range(1, len(REJECT_REASONS) + 4)

#: a backward jump's reason (reset, not a rejection)
TIME_JUMP = "time_jump"
#: the reason of each code (None: none)
REASON_NAMES = (None, *REJECT_REASONS, TIME_JUMP, MISSING_SAMPLES, "integrator_error")
PLAIN_VERDICTS = tuple(Verdict(a) for a in ACTIONS)

#: the validator's state: the stamp rule's time base (the last accepted stamp, the nominal
#: period learnt from the first NOMINAL_INTERVALS intervals of each time base), the counts
STAMPS_DTYPE = np.dtype([
    ("last", np.int64), ("has_last", np.bool_), ("period", np.int64),
    ("learn", np.int64, (NOMINAL_INTERVALS,)), ("n_learn", np.int64), ("missing", np.int64),
    ("skipped", np.int64), ("accepted", np.int64), ("jump_resets", np.int64),
    ("counts", np.int64, (len(REJECT_REASONS) + 1,)),
    # the last verdict's figures, for its words: the interval, the hole, the samples
    # missing and rejected, the nominal period
    ("ev_dt", np.int64), ("ev_hole", np.int64), ("ev_missing", np.int64),
    ("ev_skipped", np.int64), ("ev_period", np.int64),
    # the sample clock the stamps scatter about (:func:`_clock_start`, :func:`stamp_step`):
    # its period (ns), the one learnt, and where it stood at the last stamp, less that stamp
    ("clock_period", np.float64), ("clock_learnt", np.float64), ("clock_offset", np.float64),
])

#: the sample clock's loop gains per sample: phase and period (a critically damped
#: second-order loop, b = a²/4: it follows a drifting crystal, not one stamp's jitter)
CLOCK_PHASE_GAIN = 1.0 / 8.0
CLOCK_PERIOD_GAIN = 1.0 / 256.0
#: how far the clock's period may move from the one learnt (relative)
CLOCK_PERIOD_RANGE = 0.02


@kernel
def stamps_reset(v):
    """A new time base: no last stamp, the nominal period learnt again."""
    v.has_last = False
    v.period = 0
    v.n_learn = 0


@kernel(inline=True)
def _round_half_even(x):
    """Python's ``round(x)`` of a float (halves to even)."""
    r = math.floor(x)
    d = x - r
    if d > 0.5 or (d == 0.5 and r % 2 == 1):
        r += 1
    return int(r)


@kernel
def nominal_period(learnt):
    """The nominal period of a time base from its first intervals, sorted: their median, less
    a burst's (intervals under a quarter of the median: a driver flushing its buffer at a
    start would pull it low)."""
    m = learnt[learnt.size // 2]
    k = 0
    while 4 * learnt[k] < m:
        k += 1
    return learnt[k + (learnt.size - k) // 2]


@kernel(inline=True)
def _periods_in(dt, p):
    if 4 * dt < p:
        return 0  # a burst (a driver flushing its buffer; jitter of T/3 leaves T/3 at least)
    return 1 if 4 * dt < 7 * p else _round_half_even(dt / p)


@kernel(inline=True)
def _clock_start(v):
    """The sample clock from the learnt intervals: each one period of the clock, none when
    under a quarter of the nominal period (a burst), whole periods when 1.75 of them or longer
    (a hole; a jittered interval reaches 1.66, and a median of them reads low); the period
    their sum over that count, the clock the line through the stamps at it (their mean
    residual), relative to the last stamp."""
    p = v.period
    total = 0
    count = 0
    mean = 0.0
    for i in range(NOMINAL_INTERVALS):
        total += v.learn[i]
        count += _periods_in(v.learn[i], p)
    cp = total / count
    count = 0
    stamp = 0
    for i in range(NOMINAL_INTERVALS):  # residuals of the stamps after the first (the first: 0)
        stamp += v.learn[i]
        count += _periods_in(v.learn[i], p)
        mean += stamp - count * cp
    mean /= NOMINAL_INTERVALS + 1
    v.clock_period = v.clock_learnt = cp
    v.clock_offset = mean - (stamp - count * cp)


@kernel
def stamp_step(v, max_gap_ns, time_jump_ns, max_missing, t):
    """:class:`StampRule`'s step on the record ``v``: (action code, reason code); the
    figures of a gap, a hole or missing samples in ``v.ev_*``."""
    skipped = v.skipped
    if not v.has_last:
        v.last, v.has_last = t, True
        return A_START, 0
    dt = t - v.last
    v.ev_dt = dt
    if dt <= 0:
        if dt == 0:
            return A_REJECT, R_DUPLICATE
        if -dt > time_jump_ns:
            v.last = t
            v.period = 0
            v.n_learn = 0
            return A_RESET_TIME_JUMP, R_TIME_JUMP
        return A_REJECT, R_OUT_OF_ORDER
    v.last = t
    if dt > max_gap_ns:
        v.period = 0
        v.n_learn = 0
        return A_RESTART_AFTER_GAP, R_GAP
    p = v.period
    if p == 0:
        v.learn[v.n_learn] = dt
        v.n_learn += 1
        if v.n_learn == NOMINAL_INTERVALS:
            v.period = nominal_period(np.sort(v.learn))
            _clock_start(v)
        return A_ACCEPT, 0
    # The stamp against the sample clock, not the interval alone: a driver's timing moves
    # stamps by up to half a period about the clock, so one interval can read 1.66 periods
    # without a hole and 1.34 with one (±1/3 of a period); the clock tells them apart.
    cp = v.clock_period
    ahead = dt - v.clock_offset  # from where the clock stood at the last stamp
    k = max(_round_half_even(ahead / cp), 1)
    e = ahead - k * cp
    # (a clock follows a crystal's drift, ppm: bounded, a slip of a sample's jitter past
    # half a period cannot run the period away)
    lo, hi = (1.0 - CLOCK_PERIOD_RANGE) * v.clock_learnt, (1.0 + CLOCK_PERIOD_RANGE) * v.clock_learnt
    v.clock_period = min(max(cp + CLOCK_PERIOD_GAIN * e / k, lo), hi)
    v.clock_offset = -(1.0 - CLOCK_PHASE_GAIN) * e
    # A hole needs both: the clock a whole period behind, and an interval over 1.5 nominal
    # periods (a sampler whose own instants wander — each interval jittered, the stamps a
    # random walk about any clock — misses no sample in a shorter one).  A hole in stamps
    # jittered by ±1/3 of a period can read 1.34 periods: about 3 % of such holes go
    # uncounted, and no jitter is counted as a hole.
    hole = k - 1 if 2 * dt > 3 * p else 0
    if hole == 0:
        return A_ACCEPT, 0
    missing = max(hole - skipped, 0)
    v.ev_hole, v.ev_missing, v.ev_skipped = hole, missing, skipped
    v.ev_period = _round_half_even(cp)
    if hole > max_missing:
        v.period = 0
        v.n_learn = 0
        return A_RESTART_AFTER_GAP, R_GAP
    if missing == 0:
        return A_ACCEPT, 0
    v.missing += missing
    return A_ACCEPT, R_MISSING


@kernel(inline=True)
def sample_reason(t, w0, w1, w2, max_rate):
    """The checks of one sample on its own, in order: its rates finite, each within
    ``max_rate``, its stamp positive.  The reason code of the first it fails (0: none)."""
    if not (math.isfinite(w0) and math.isfinite(w1) and math.isfinite(w2)):
        return R_NON_FINITE
    if not within(w0, w1, w2, max_rate):
        return R_IMPLAUSIBLE
    if t <= 0:
        return R_ZERO
    return 0


@kernel
def validate(v, max_rate, max_gap_ns, time_jump_ns, max_missing, t, w0, w1, w2, frame_ok):
    """One sample's verdict on the record ``v``: the sample's values (finite,
    within ``max_rate``), its stamp (positive), its frame (``frame_ok``: the locked one, or
    none locked yet), then the stamp rule; a rejection is counted and leaves the time base
    alone.  (action code, reason code)."""
    reason = sample_reason(t, w0, w1, w2, max_rate)
    if reason == 0 and not frame_ok:
        reason = R_FRAME
    if reason == 0:
        action, reason = stamp_step(v, max_gap_ns, time_jump_ns, max_missing, t)
        if action != A_REJECT:
            v.skipped = 0
            v.accepted += 1
            if action == A_RESET_TIME_JUMP:
                v.jump_resets += 1
            elif reason == R_GAP:
                v.counts[R_GAP] += 1
            return action, reason
    v.counts[reason] += 1
    v.skipped += 1
    return A_REJECT, reason
