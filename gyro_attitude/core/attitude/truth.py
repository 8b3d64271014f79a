"""Truth attitude at an Imu stamp: slerp between the truth samples around it, and where integration may start.

A truth stream (optical tracking, a simulator's ``truth/attitude``) is sampled on its own clock;
the integration starts at an Imu stamp.  :func:`truth_at` interpolates the truth there by slerp
(constant-rate rotation between the two neighbouring truth samples: exact for a constant
angular velocity, second order otherwise) and refuses to extrapolate: a stamp before
the first truth sample, after the last, or in a truth gap longer than ``max_interval_ns`` (the
tracker lost the markers) has no truth.  :func:`initial_attitude_from_truth` picks the first Imu
sample that has one.
"""

from __future__ import annotations

import numpy as np

from gyro_attitude.core.rotation import _exp_rotvec, _log_quat, _qmul, quat_conjugate

__all__ = ["truth_at", "initial_attitude_from_truth", "default_max_interval_ns"]


def _check(truth_t, truth_q) -> tuple[np.ndarray, np.ndarray]:
    t = np.asarray(truth_t)
    if t.ndim != 1 or t.size == 0 or not np.issubdtype(t.dtype, np.integer):
        raise ValueError(f"truth stamps must be a non-empty 1-D array of int ns, got "
                         f"shape {t.shape} dtype {t.dtype}")
    t = t.astype(np.int64)
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


def default_max_interval_ns(truth_t) -> int:
    """Longest truth interval to interpolate across: 1.5 × the median (a dropped sample or
    two of jitter pass, a tracking gap does not)."""
    t = np.asarray(truth_t, dtype=np.int64)
    if t.size < 2:
        return 0
    return int(1.5 * float(np.median(np.diff(t))))


def truth_at(truth_t, truth_q, t_ns: int, max_interval_ns: int | None = None) -> np.ndarray:
    """Truth quaternion (4,) x, y, z, w at ``t_ns``, or ValueError when the truth does not
    cover it (outside the truth's span or inside a gap longer than ``max_interval_ns``)."""
    t, q = _check(truth_t, truth_q)
    t_ns = int(t_ns)
    k = int(np.searchsorted(t, t_ns, side="left"))
    if k < t.size and t[k] == t_ns:
        return q[k].copy()
    if k == 0 or k == t.size:
        raise ValueError(f"no truth at {t_ns} ns: the truth spans [{t[0]}, {t[-1]}] ns "
                         "(no extrapolation)")
    limit = default_max_interval_ns(t) if max_interval_ns is None else int(max_interval_ns)
    if t[k] - t[k - 1] > limit:
        raise ValueError(f"no truth at {t_ns} ns: it falls in a truth gap of "
                         f"{(t[k] - t[k - 1]) * 1e-9:.3g} s")
    # Slerp q_a ⊗ exp(f · log(q_a* ⊗ q_b)) (the shorter way round), with core.rotation's
    # exp/log (tested against scipy): scipy.spatial's Slerp would add 0.16 s of imports
    # to every replay for this one call.  f from int ns (no precision lost on long stamps).
    f = (t_ns - int(t[k - 1])) / int(t[k] - t[k - 1])
    out = _qmul(q[k - 1], _exp_rotvec(f * _log_quat(_qmul(quat_conjugate(q[k - 1]), q[k]))))
    return out / np.sqrt(np.dot(out, out))


def initial_attitude_from_truth(imu_t, truth_t, truth_q,
                                max_interval_ns: int | None = None) -> tuple[np.ndarray, int, int]:
    """``(q0, first_index, skipped)``: the truth at the first Imu stamp it covers.

    ``first_index`` the Imu sample where integration starts (its stamp is the first one at or
    after the first truth stamp that the truth covers); ``skipped`` how many Imu samples come
    before it (0 when the truth starts with the Imu).  ValueError when no Imu stamp is covered.
    """
    t, q = _check(truth_t, truth_q)
    imu = np.asarray(imu_t)
    if imu.ndim != 1 or imu.size == 0 or not np.issubdtype(imu.dtype, np.integer):
        raise ValueError(f"Imu stamps must be a non-empty 1-D array of int ns, got shape "
                         f"{imu.shape} dtype {imu.dtype}")
    imu = imu.astype(np.int64)
    start = int(np.argmax(imu >= t[0])) if np.any(imu >= t[0]) else imu.size
    for k in range(start, imu.size):
        if imu[k] > t[-1]:
            break
        try:
            return truth_at(t, q, int(imu[k]), max_interval_ns), k, k
        except ValueError:
            continue  # inside a truth gap: try the next Imu sample
    raise ValueError(f"no Imu stamp lies within the truth's span [{t[0]}, {t[-1]}] ns: "
                     "cannot take the initial attitude from the truth")
