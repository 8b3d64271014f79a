"""Input checks shared by the batch and streaming integrators (times, rates, initial attitude)."""

from __future__ import annotations

import numpy as np

from gyro_attitude.core.rotation import as_quat_array, as_vector_array


def first_step_back(t: np.ndarray, size: int = 1 << 16) -> int | None:
    """Index of the first stamp of ``t`` (1-D ints) not after the one before it, or None when
    they rise strictly; ``size`` intervals at a time (no temporary of the recording's
    length)."""
    for c0 in range(0, t.size - 1, size):
        bad = np.diff(t[c0:c0 + size + 1]) <= 0
        if bad.any():
            return c0 + int(np.argmax(bad)) + 1
    return None


def check_times(t_ns) -> np.ndarray:
    """1-D strictly increasing int64 nanoseconds, at least one sample (``ValueError`` else)."""
    t = np.asarray(t_ns)
    if t.ndim != 1:
        raise ValueError(f"t_ns must be a 1-D array of int nanoseconds, got shape {t.shape}")
    if t.size and not np.issubdtype(t.dtype, np.integer):
        raise ValueError(f"t_ns must hold integer nanoseconds, got dtype {t.dtype}")
    t = t.astype(np.int64, copy=False)
    if t.size < 1:
        raise ValueError("t_ns is empty: at least one sample is needed")
    k = first_step_back(t)
    if k is not None:
        raise ValueError(f"time step t_ns[{k}] - t_ns[{k - 1}] = {int(t[k] - t[k - 1])} ns is "
                         "not positive: samples must be strictly increasing in time")
    return t


def check_rates(omega_ib_b, n_samples: int) -> np.ndarray:
    """Finite rate samples of shape ``(n_samples, 3)`` in rad/s."""
    w = as_vector_array(omega_ib_b, "omega_ib_b")
    if w.shape != (n_samples, 3):
        raise ValueError(f"omega_ib_b must have shape ({n_samples}, 3), got {w.shape}")
    return w


def check_q0(q0) -> np.ndarray:
    """Initial attitude: a finite, non-zero quaternion of shape (4,), returned normalized."""
    q = as_quat_array(q0, "q0")
    if q.shape != (4,):
        raise ValueError(f"q0 must have shape (4,), got {q.shape}")
    n = float(np.linalg.norm(q))
    if n < 1e-12:
        raise ValueError("q0 has zero norm")
    return q / n
