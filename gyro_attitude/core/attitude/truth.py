"""Truth attitude at Imu stamps (slerp between the truth samples around each, no
extrapolation, none across a truth gap) and where a truth start begins (docs/architecture.md,
"Notes: the estimator's edge")."""

from __future__ import annotations

import numpy as np

from gyro_attitude.core.rotation import _exp_rotvec, _log_quat, _qmul, quat_conjugate

__all__ = ["TruthStart", "default_max_interval_ns", "initial_attitude_from_truth",
           "truth_at_stamps", "tilt_and_heading_error", "span_words"]


def _stamps(stamps, name: str) -> np.ndarray:
    t = np.asarray(stamps)
    if t.ndim != 1 or t.size == 0 or not np.issubdtype(t.dtype, np.integer):
        raise ValueError(f"{name} stamps must be a non-empty 1-D array of int ns, got shape "
                         f"{t.shape} dtype {t.dtype}")
    return t.astype(np.int64)


def _check(truth_t, truth_q) -> tuple[np.ndarray, np.ndarray]:
    t = _stamps(truth_t, "truth")
    if t.size > 1 and np.any(np.diff(t) <= 0):
        raise ValueError("truth stamps must be strictly increasing")
    q = np.asarray(truth_q, dtype=np.float64)
    if q.shape != (t.size, 4):
        raise ValueError(f"truth quaternions must have shape ({t.size}, 4), got {q.shape}")
    norm = np.linalg.norm(q, axis=1)
    if not np.all(np.isfinite(q)) or np.any(norm < 1e-9):
        k = int(np.argmax(~np.isfinite(q).all(axis=1) | (norm < 1e-9)))
        raise ValueError(f"truth quaternion {k} is not finite or zero: {q[k].tolist()}")
    return t, q / norm[:, None]


#: Intervals the median of :func:`default_max_interval_ns` is taken over at most.
MEDIAN_INTERVALS = 1 << 22


def default_max_interval_ns(truth_t) -> int:
    """Longest truth interval to interpolate across: 1.5 × the median (a dropped sample or
    two of jitter pass, a tracking gap does not).  Over more than :data:`MEDIAN_INTERVALS`
    intervals, the median of an evenly strided sample of that many (a 24 h recording's
    intervals would be 0.7 GB of temporaries; a threshold needs no more)."""
    t = np.asarray(truth_t, dtype=np.int64)
    if t.size < 2:
        return 0
    step = -(-(t.size - 1) // MEDIAN_INTERVALS)
    dt = np.diff(t) if step == 1 else t[1::step] - t[0:-1:step]
    return int(1.5 * float(np.median(dt)))


def _slerp(t: np.ndarray, q: np.ndarray, k: np.ndarray, t_ns: np.ndarray) -> np.ndarray:
    """Truth at ``t_ns`` (M,) between truth samples ``k - 1`` and ``k`` (M,): slerp
    q_a ⊗ exp(f · log(q_a* ⊗ q_b)) with core.rotation's exp/log (scipy's Slerp would add
    0.16 s of imports to every replay), f from int ns differences (no precision lost)."""
    a, b = q[k - 1], q[k]
    f = (t_ns - t[k - 1]) / (t[k] - t[k - 1])
    out = _qmul(a, _exp_rotvec(f[:, None] * _log_quat(_qmul(quat_conjugate(a), b))))
    return out / np.linalg.norm(out, axis=1, keepdims=True)


def truth_at_stamps(truth_t, truth_q, t_ns,
                    max_interval_ns: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(q, covered)``: the truth at every stamp of ``t_ns`` (M,) that it covers (a
    coinciding truth sample as is, else the slerp between the two around it; nothing outside
    the truth's span or in a gap longer than ``max_interval_ns``, default
    :func:`default_max_interval_ns`).  ``covered`` (M,) bool; ``q`` (covered.sum(), 4)."""
    t, q = _check(truth_t, truth_q)
    return _covered(t, q, np.asarray(t_ns, dtype=np.int64).reshape(-1), max_interval_ns)


def _covered(t: np.ndarray, q: np.ndarray, s: np.ndarray,
             max_interval_ns: int | None) -> tuple[np.ndarray, np.ndarray]:
    """:func:`truth_at_stamps` on a truth :func:`_check` has checked and normalized (the one
    rule of where the truth is, for every caller)."""
    k = np.searchsorted(t, s, side="left")
    exact = (k < t.size) & (t[np.minimum(k, t.size - 1)] == s)
    limit = default_max_interval_ns(t) if max_interval_ns is None else int(max_interval_ns)
    inside = ~exact & (k > 0) & (k < t.size)
    between = np.zeros(s.size, bool)
    if t.size > 1:  # (one truth sample covers its own stamp only)
        kk = np.clip(k, 1, t.size - 1)
        between = inside & (t[kk] - t[kk - 1] <= limit)
    out = np.empty((s.size, 4))
    out[exact] = q[k[exact]]
    if between.any():
        out[between] = _slerp(t, q, k[between], s[between])
    covered = exact | between
    return out[covered], covered


def tilt_and_heading_error(q_est, q_true) -> tuple[np.ndarray, np.ndarray]:
    """``(tilt, heading)`` (M,) rad of estimates ``q_est`` against ``q_true`` (M, 4), both
    body to a z-up frame (ENU): ``tilt`` the angle between the estimated and the true up seen
    in the body, whatever the heading; ``heading`` the signed rotation about up of the error
    ``q_est ⊗ q_true⁻¹`` (its twist about z), in (−π, π]."""
    qe = np.asarray(q_est, dtype=np.float64)
    qt = np.asarray(q_true, dtype=np.float64)

    def up_in_body(q):
        # the third row of C_nb(q): the frame's up in body coordinates (unit q not assumed)
        x, y, z, w = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
        s = 2.0 / np.einsum("ij,ij->i", q, q)
        return np.column_stack((s * (x * z - y * w), s * (y * z + x * w),
                                1.0 - s * (x * x + y * y)))

    u, v = up_in_body(qe), up_in_body(qt)
    # the angle from atan2(|u × v|, u·v): accurate near 0 and π, where arccos is not
    tilt = np.arctan2(np.linalg.norm(np.cross(u, v), axis=1), np.einsum("ij,ij->i", u, v))
    e = _qmul(qe, quat_conjugate(qt))
    heading = 2.0 * np.arctan2(e[:, 2], e[:, 3])
    heading = (heading + np.pi) % (2.0 * np.pi) - np.pi
    heading[heading == -np.pi] = np.pi
    return tilt, heading


def span_words(t0_ns: int, t1_ns: int) -> str:
    """``[t0, t1] s`` of two stamps, to the millisecond (epoch or boot clock alike)."""
    return f"[{t0_ns * 1e-9:.3f}, {t1_ns * 1e-9:.3f}] s"


def initial_attitude_from_truth(imu_t, truth_t, truth_q, *,
                                usable=None) -> tuple[np.ndarray, int, int]:
    """``(q0, first_index, skipped)``: the truth at the first usable Imu stamp it covers.

    ``usable(k) -> bool``: whether the estimator would accept Imu sample ``k`` as a start
    (:func:`.validation.sample_problem` finds nothing; default all) — the truth is taken at
    the sample where the attitude starts, never at one the estimator then rejects.
    ``first_index`` that sample; ``skipped`` how many Imu samples come before it.
    ValueError when no usable Imu stamp is covered.
    """
    t, q = _check(truth_t, truth_q)
    imu = _stamps(imu_t, "Imu")
    limit = default_max_interval_ns(t)
    for k in np.flatnonzero((imu >= t[0]) & (imu <= t[-1])).tolist():  # usually the first
        if usable is not None and not usable(k):
            continue
        got, covered = _covered(t, q, imu[k:k + 1], limit)
        if covered[0]:  # (else inside a truth gap: try the next Imu sample)
            return got[0], k, k
    raise ValueError(f"no Imu stamp lies within the truth's span {span_words(t[0], t[-1])} "
                     f"(the Imu spans {span_words(int(imu.min()), int(imu.max()))}): cannot "
                     "take the initial attitude from the truth")


class TruthStart:
    """The truth start of a live stream: Imu samples wait (at most ``kept``) until the truth
    covers the first one the estimator can start from; that one gets the truth slerped to its
    stamp.  Truth samples must come in stamp order (others are refused with a reason).

    ``usable(t_ns, omega) -> bool`` says whether the estimator would accept a sample as a start
    (the sample-local checks of :func:`.validation.sample_problem`); unusable samples and
    usable ones the truth does not cover are skipped (``skipped`` counts both).
    """

    def __init__(self, usable, kept: int = 5000):
        self._usable = usable
        self.kept = int(kept)
        self._t: list[int] = []
        self._q: list[np.ndarray] = []
        self._pending: list[tuple[int, object]] = []
        self.skipped = 0

    def add_truth(self, t_ns: int, q) -> str | None:
        """Keep a truth sample; the reason when it is refused (not finite, zero, not after
        the previous one)."""
        q = np.asarray(q, dtype=np.float64)
        norm = float(np.sqrt(np.dot(q, q))) if q.shape == (4,) else 0.0
        if not np.all(np.isfinite(q)) or not norm >= 1e-9:
            return "a non-finite or zero truth quaternion"
        if self._t and t_ns <= self._t[-1]:
            return "a truth message not after the previous one"
        self._t.append(int(t_ns))
        self._q.append(q / norm)
        if len(self._t) > self.kept:
            del self._t[0], self._q[0]
        return None

    def add_sample(self, t_ns: int, omega, payload) -> None:
        """Keep an Imu sample (``payload`` is handed back by :meth:`start`)."""
        if not self._usable(t_ns, omega):
            self.skipped += 1
            return
        self._pending.append((int(t_ns), payload))
        if len(self._pending) > self.kept:
            del self._pending[0]
            self.skipped += 1

    def start(self) -> tuple[np.ndarray, list] | None:
        """``(q0, payloads)`` once the truth covers a waiting sample: its attitude and the
        payloads from that sample on (to be pushed in order); None while waiting."""
        pending = self._pending
        while pending and self._t:
            t_ns = pending[0][0]
            if t_ns > self._t[-1]:
                return None  # the truth around it has not arrived yet
            q0, covered = truth_at_stamps(self._t, self._q, [t_ns])
            if covered[0]:
                payloads = [p for _, p in pending]
                pending.clear()
                self._t.clear()
                self._q.clear()
                return q0[0], payloads
            pending.pop(0)  # before the first truth sample (or in a gap): skipped
            self.skipped += 1
        return None
