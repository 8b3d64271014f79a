"""Input checks for a stream of Imu samples (numpy only; used by the attitude_integrator node).

An attitude integrator must never let one bad message corrupt its state: a NaN rate
poisons the quaternion forever, a duplicate or out-of-order stamp gives ``dt <= 0``,
a gap makes the rate-times-time step meaningless, and a changed ``frame_id`` means the
rates are no longer about the axes the attitude is for. :class:`ImuStreamValidator`
classifies each sample *before* it reaches the integrator and keeps counts per reason,
so the node can report them on ``/diagnostics``. :class:`IntervalStatistics` keeps the
input rate and dt jitter over a sliding window.

Times are integer nanoseconds (the ``header.stamp`` of the message).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

# Verdicts of ImuStreamValidator.check(). ACCEPT: integrate over (last, t]. START: first
# sample (or first after a restart): sets the time base, nothing to integrate yet.
ACCEPT = "accept"
START = "start"
# The sample is integrated from a fresh time base, the attitude kept (see GAP below).
RESTART_AFTER_GAP = "restart_after_gap"
# Backward time jump beyond the threshold (e.g. a bag replay looped, a simulator restarted):
# the integrator should reset its attitude and start over at this sample.
RESET_TIME_JUMP = "reset_time_jump"

# Rejection reasons (the sample is dropped, counted, and the state is untouched).
NON_FINITE = "non_finite"
ZERO_STAMP = "zero_stamp"
DUPLICATE_STAMP = "duplicate_stamp"
OUT_OF_ORDER = "out_of_order"
FRAME_CHANGED = "frame_changed"
# A gap is counted like a rejection of the *interval*: nothing is integrated across it.
# The sample itself becomes the new time base (RESTART_AFTER_GAP), otherwise every later
# sample would also be "after a gap".
GAP = "gap"

REJECT_REASONS: tuple[str, ...] = (
    NON_FINITE,
    ZERO_STAMP,
    DUPLICATE_STAMP,
    OUT_OF_ORDER,
    FRAME_CHANGED,
    GAP,
)


@dataclass(frozen=True)
class ImuCheckConfig:
    """Thresholds of :class:`ImuStreamValidator`.

    max_gap_ns: a forward step longer than this is a gap (not integrated across).
    time_jump_ns: a backward step longer than this is a time jump (reset); a backward
        step up to this long is an out-of-order sample (rejected).
    """

    max_gap_ns: int = 100_000_000
    time_jump_ns: int = 1_000_000_000

    def __post_init__(self):
        for name in ("max_gap_ns", "time_jump_ns"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | np.integer):
                raise ValueError(f"{name} must be an integer number of nanoseconds, got {value!r}")
            if value <= 0:
                raise ValueError(f"{name} must be > 0 ns, got {value}")


@dataclass(frozen=True)
class Verdict:
    """Outcome of one check: ``action`` is ACCEPT/START/RESTART_AFTER_GAP/RESET_TIME_JUMP
    or ``"reject"``; ``reason`` names the rejection (or the gap/jump) and ``detail`` says
    why in words, for a log line."""

    action: str
    reason: str | None = None
    detail: str = ""

    @property
    def rejected(self) -> bool:
        return self.action == "reject"


class ImuStreamValidator:
    """Classify each Imu sample of a stream; count rejections by reason.

    The frame of the first accepted sample is locked in; ``reset()`` forgets it and the
    time base. A rejected sample leaves the state (last stamp, frame) untouched, so one
    bad message costs exactly one sample.
    """

    def __init__(self, config: ImuCheckConfig | None = None):
        self.config = config if config is not None else ImuCheckConfig()
        self.counts: dict[str, int] = {reason: 0 for reason in REJECT_REASONS}
        self.accepted = 0
        self.time_jump_resets = 0
        self.last_t_ns: int | None = None
        self.frame_id: str | None = None

    @property
    def rejected_total(self) -> int:
        return sum(self.counts[r] for r in REJECT_REASONS if r != GAP)

    def reset(self) -> None:
        """Forget the time base and the locked frame (counts are kept)."""
        self.last_t_ns = None
        self.frame_id = None

    def _reject(self, reason: str, detail: str) -> Verdict:
        self.counts[reason] += 1
        return Verdict("reject", reason, detail)

    def check(self, t_ns: int, omega, frame_id: str = "") -> Verdict:
        """Classify one sample and update the state.

        t_ns: header stamp in ns; omega: angular rate (3,) [rad/s] (any other value the
        caller wants checked for finiteness can be appended); frame_id: header.frame_id.
        """
        t_ns = int(t_ns)
        values = np.asarray(omega, dtype=float)
        if not np.all(np.isfinite(values)):
            return self._reject(NON_FINITE, f"non-finite value(s) {values.tolist()}")
        if t_ns <= 0:
            return self._reject(ZERO_STAMP, f"stamp {t_ns} ns is zero/unset")
        if self.frame_id is not None and frame_id != self.frame_id:
            return self._reject(
                FRAME_CHANGED, f"frame_id {frame_id!r} differs from {self.frame_id!r}"
            )
        last = self.last_t_ns
        if last is None:
            self.last_t_ns = t_ns
            self.frame_id = frame_id
            self.accepted += 1
            return Verdict(START)
        dt = t_ns - last
        if dt == 0:
            return self._reject(DUPLICATE_STAMP, f"stamp {t_ns} ns repeats the previous one")
        if dt < 0:
            if -dt > self.config.time_jump_ns:
                self.time_jump_resets += 1
                self.last_t_ns = t_ns
                self.accepted += 1
                return Verdict(
                    RESET_TIME_JUMP, "time_jump", f"time jumped back by {-dt / 1e9:.3f} s"
                )
            return self._reject(
                OUT_OF_ORDER, f"stamp {t_ns} ns is {-dt / 1e6:.3f} ms before the previous"
            )
        self.last_t_ns = t_ns
        self.accepted += 1
        if dt > self.config.max_gap_ns:
            self.counts[GAP] += 1
            return Verdict(RESTART_AFTER_GAP, GAP, f"gap of {dt / 1e6:.3f} ms")
        return Verdict(ACCEPT)


class IntervalStatistics:
    """Input rate and dt jitter over the last ``window`` accepted intervals.

    ``rate_hz`` = 1/mean(dt); ``jitter_s`` = standard deviation of dt (population);
    ``max_dt_s`` = largest dt in the window. NaN while fewer than 2 intervals are known.
    """

    def __init__(self, window: int = 1000):
        if int(window) < 2:
            raise ValueError(f"window must be >= 2 intervals, got {window}")
        self._dt_ns: deque[int] = deque(maxlen=int(window))

    def add(self, dt_ns: int) -> None:
        self._dt_ns.append(int(dt_ns))

    def clear(self) -> None:
        self._dt_ns.clear()

    def __len__(self) -> int:
        return len(self._dt_ns)

    def summary(self) -> dict[str, float]:
        if len(self._dt_ns) < 2:
            nan = math.nan
            return {"rate_hz": nan, "mean_dt_s": nan, "jitter_s": nan, "max_dt_s": nan}
        dt = np.fromiter(self._dt_ns, dtype=np.int64, count=len(self._dt_ns)) * 1e-9
        mean = float(dt.mean())
        return {
            "rate_hz": 1.0 / mean,
            "mean_dt_s": mean,
            "jitter_s": float(dt.std()),
            "max_dt_s": float(dt.max()),
        }
