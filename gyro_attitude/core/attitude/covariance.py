"""Honest orientation covariance: per axis the error state ``[δθ, δb]`` (attitude error, error
of the gyro bias subtracted) with ``P = [[tt, tb], [tb, bb]]``, propagated over accepted
intervals and reset by rests, alignment and aiding (the model: docs/architecture.md, "Notes:
the estimator's stages")."""

from __future__ import annotations

import numpy as np

from gyro_attitude.core.jit import kernel

__all__ = ["covariance_start"]


# the state as one array (in the chain's state record): tt, tb, bb and Σq per axis
V_TT, V_TB, V_BB, V_NOISE = 0, 3, 6, 9


def covariance_start(cfg) -> tuple[np.ndarray, np.ndarray]:
    """The state ``c`` (12,) of a :class:`~.settings.StreamConfig` before the first sample, and
    the initial attitude variance (3,) a reset goes back to: ``tt`` that variance, ``bb`` the
    stated bias uncertainty ``gyro_bias_sigma_rad_s`` squared."""
    initial_tt = np.broadcast_to(np.asarray(cfg.initial_attitude_variance, dtype=np.float64),
                                 (3,)).copy()
    c = np.zeros(12)
    c[V_TT:V_TT + 3] = initial_tt
    c[V_BB:V_BB + 3] = float(cfg.gyro_bias_sigma_rad_s) ** 2
    return c, initial_tt


@kernel(inline=True)
def propagate(c, k2, dt_s, q0, q1, q2):
    """One accepted interval of ``dt_s`` seconds with angle-random-walk increment ``q`` on the
    state array ``c`` (``k2`` the bias random walk squared)."""
    d2 = 2.0 * dt_s
    dd = dt_s * dt_s
    k2dt = k2 * dt_s
    for i, q in ((0, q0), (1, q1), (2, q2)):
        b, t = c[V_BB + i], c[V_TB + i]
        c[V_TT + i] = c[V_TT + i] + ((q - d2 * t) + dd * b)
        c[V_NOISE + i] = c[V_NOISE + i] + q
        c[V_TB + i] = t + -(dt_s * b)
        c[V_BB + i] = b + k2dt


@kernel(inline=True)
def zero_rate_update(c, se0, se1, se2):
    """A new bias estimate from a rest with per-axis standard error ``se`` (rad/s)."""
    for i, se in ((0, se0), (1, se1), (2, se2)):
        c[V_BB + i] = se ** 2
        c[V_TB + i] = 0.0


@kernel(inline=True)
def aid_tilt(c, kp_dt, floor_var):
    """The tilt axes relaxed toward the levelling floor ``floor_var`` by the aiding's gain
    (``kp_dt`` = k_p dt; see the module docstring)."""
    a = 1.0 - min(kp_dt, 1.0)
    a2 = a * a
    for i in range(2):
        c[V_TT + i] = a2 * c[V_TT + i] + (1.0 - a2) * floor_var
        c[V_TB + i] = a * c[V_TB + i]


@kernel
def first_rest_update(c, it, se0, se1, se2, elapsed_s):
    """The first rest's estimate applied back to the start, ``elapsed_s`` ago (``it`` the
    initial attitude variance (3,); see the module docstring)."""
    e2 = elapsed_s * elapsed_s
    for i, se in ((0, se0), (1, se1), (2, se2)):
        bb = se ** 2
        c[V_BB + i] = bb
        c[V_TT + i] = (it[i] + c[V_NOISE + i]) + e2 * bb
        c[V_TB + i] = -elapsed_s * bb


@kernel
def reset_attitude(c, it):
    """Back to the initial attitude ``it`` (an alignment, a time-jump reset)."""
    for i in range(3):
        c[V_TT + i] = it[i]
        c[V_TB + i] = 0.0
        c[V_NOISE + i] = 0.0
