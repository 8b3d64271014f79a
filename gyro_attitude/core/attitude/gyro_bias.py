"""Gyro bias: none, a fixed parameter, or estimated at rests (the pooled mean of the rests so
far, the Earth rate taken out when the attitude and latitude are known; docs/architecture.md,
"Notes: the estimator's stages").  The kernel :func:`bias_step` once per accepted sample,
O(1) amortized, on the state :func:`bias_start` makes; the bias to subtract is then
``bf[B_BIAS:B_BIAS + 3]``."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gyro_attitude.core.attitude.ahrs import c_nb
from gyro_attitude.core.attitude.modes import GyroBiasMode
from gyro_attitude.core.attitude.rest import (
    NOISE_FLOOR_RAD_S,
    R_AT_REST,
    R_HEAD,
    R_OLDEST,
    rest_reset,
    rest_start,
    rest_update,
)
from gyro_attitude.core.jit import kernel

__all__ = ["GyroBiasReport", "bias_report", "bias_start", "bias_step"]


@dataclass(frozen=True)
class GyroBiasReport:
    """What the bias is and how well it is known (rad/s)."""

    mode: str
    bias: np.ndarray  # (3,)
    rests_used: int
    rest_samples: int
    standard_error: np.ndarray  # (3,), NaN when not estimated
    earth_rate_removed: bool
    note: str


# The accumulation state as two arrays (in the chain's state record).  Float slots:
# the published bias and its standard error; the pooled sums of the completed rests (Σ n_i m_i,
# Σ n_i m_i², Σ within-rest squared deviations); the open rest's reference and running sums
B_BIAS, B_SE, B_SUM_NM, B_SUM_NM2, B_SSD, B_REF, B_S1, B_S2 = 0, 3, 6, 9, 12, 15, 18, 21
_B_FLOATS = 24
# int slots: the published estimate's rests and samples, the completed rests and their samples,
# whether the last step published, the Earth-rate flags (all rests so far, the published one),
# the open rest (open, first and last stamp, samples, Earth rate taken out of all of them)
# (the streaming step's own: the window index of the last rest sample accumulated)
J_K, J_N, J_POOL_K, J_POOL_N, J_UPDATED, J_EARTH_ALL, J_EARTH_NOW, J_HAS_SEG, J_SEG_T0, \
    J_SEG_T1, J_SEG_N, J_SEG_EARTH, J_LAST_ACC = range(13)
_B_INTS = 13
#: :func:`bias_step`'s code when the attitude to take the Earth rate out at is unusable (the
#: detector stepped; the caller breaks the window)
BAD_ATTITUDE = -3


@kernel
def pool_open_rest(bf, bi, publish):
    """The open rest's mean and within-rest squared deviations joined to the completed rests'
    sums: ``publish`` the pooled estimate (bias, standard error: the larger of the white-noise
    figure and the scatter between rests; rests and samples), else pool the rest (it ended)."""
    n_c = bi[J_SEG_N]
    k = bi[J_POOL_K] + 1
    n = bi[J_POOL_N] + n_c
    for i in range(3):
        s1 = bf[B_S1 + i]
        m = bf[B_REF + i] + s1 / n_c
        snm = bf[B_SUM_NM + i] + n_c * m
        snm2 = bf[B_SUM_NM2 + i] + n_c * m * m
        ssd = bf[B_SSD + i] + max(bf[B_S2 + i] - s1 * s1 / n_c, 0.0)
        if not publish:
            bf[B_SUM_NM + i], bf[B_SUM_NM2 + i], bf[B_SSD + i] = snm, snm2, ssd
            continue
        bias = snm / n
        white = math.sqrt(ssd / max(n - k, 1) / n)
        between = 0.0
        if k >= 2:
            between = math.sqrt(max(snm2 - n * bias * bias, 0.0) / n / (k - 1))
        bf[B_BIAS + i] = bias
        bf[B_SE + i] = max(white, between)
    if publish:
        bi[J_K], bi[J_N] = k, n
    else:
        bi[J_POOL_K], bi[J_POOL_N] = k, n


@kernel
def accumulate(bf, bi, min_rest_ns, t, v0, v1, v2, earth):
    """Add the rest sample of time ``t`` with value ``v`` (its rate, less the Earth rate when
    known) to the open rest (opened by the first); publish the pooled estimate once the rest spans
    ``min_rest_ns`` (``J_UPDATED`` then says so)."""
    bi[J_UPDATED] = 0
    if bi[J_HAS_SEG] == 0:
        bi[J_HAS_SEG], bi[J_SEG_T0], bi[J_SEG_N], bi[J_SEG_EARTH] = 1, t, 0, 1
        bf[B_REF], bf[B_REF + 1], bf[B_REF + 2] = v0, v1, v2
        bf[B_S1:B_S2 + 3] = 0.0  # Σ d, Σ d²
    bi[J_SEG_T1] = t
    bi[J_SEG_N] += 1
    for i, v in ((0, v0), (1, v1), (2, v2)):
        d = v - bf[B_REF + i]
        bf[B_S1 + i] = bf[B_S1 + i] + d
        bf[B_S2 + i] = bf[B_S2 + i] + d * d
    if not earth:
        bi[J_SEG_EARTH] = 0
    if bi[J_SEG_T1] - bi[J_SEG_T0] >= min_rest_ns:
        pool_open_rest(bf, bi, True)
        bi[J_UPDATED] = 1
        bi[J_EARTH_NOW] = 1 if (bi[J_EARTH_ALL] == 1 and bi[J_SEG_EARTH] == 1) else 0


@kernel
def close_rest(bf, bi, min_rest_ns):
    """The open rest ended: pooled when it spans ``min_rest_ns``."""
    bi[J_HAS_SEG] = 0
    if bi[J_SEG_T1] - bi[J_SEG_T0] >= min_rest_ns:
        pool_open_rest(bf, bi, False)
        if bi[J_SEG_EARTH] == 0:
            bi[J_EARTH_ALL] = 0


@kernel
def bias_step(bf, bi, min_rest_ns, rf, ri, wt, wx, wc, pv, pe, earth_n, t, g0, g1, g2, has_a,
              a0, a1, a2, has_q, x, y, z, u):
    """One sample through the bias stage (mode auto) on the state arrays: the detector's window
    ending at this sample (:func:`~gyro_attitude.core.attitude.rest.rest_update`), the value
    this sample gives a rest (less the Earth rate at ``(x, y, z, u)`` when ``has_q``), and the
    accumulation of the window's oldest sample when at rest (or the open rest closed).  The
    ring slot, or a refusal code of the detector's (nothing changed) or :data:`BAD_ATTITUDE`."""
    bi[J_UPDATED] = 0
    slot = rest_update(rf, ri, wt, wx, wc, t, g0, g1, g2, has_a, a0, a1, a2)
    if slot < 0:
        return slot
    if has_q:
        n = x * x + y * y + z * z + u * u
        if not (math.isfinite(n) and n > 1e-18):
            return BAD_ATTITUDE
        # C_bn ω_ie^n: the rows of C_bn are the columns of C_nb
        c00, c01, c02, c10, c11, c12, c20, c21, c22 = c_nb(x, y, z, u)
        e0, e1, e2 = float(earth_n[0]), float(earth_n[1]), float(earth_n[2])
        pv[slot, 0] = g0 - (c00 * e0 + c10 * e1 + c20 * e2)
        pv[slot, 1] = g1 - (c01 * e0 + c11 * e1 + c21 * e2)
        pv[slot, 2] = g2 - (c02 * e0 + c12 * e1 + c22 * e2)
    else:
        pv[slot, 0], pv[slot, 1], pv[slot, 2] = g0, g1, g2
    pe[slot] = has_q
    if ri[R_AT_REST] == 1:
        j = ri[R_OLDEST]
        if j > bi[J_LAST_ACC]:
            h = ri[R_HEAD]
            accumulate(bf, bi, min_rest_ns, wt[h], pv[h, 0], pv[h, 1], pv[h, 2], pe[h])
            bi[J_LAST_ACC] = j
    elif bi[J_HAS_SEG] == 1:
        close_rest(bf, bi, min_rest_ns)
    return slot


def bias_start(cfg) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The rest detector's and the bias stage's state arrays (``rf``, ``ri``, ``bf``, ``bi``)
    of a :class:`~.settings.StreamConfig` before the first sample: the fixed bias in mode
    ``parameter``, else 0; the rest thresholds of the table, windows less noisy than the noise
    floor refused."""
    rf, ri = rest_start(cfg, NOISE_FLOOR_RAD_S)
    bf = np.zeros(_B_FLOATS)
    bi = np.zeros(_B_INTS, dtype=np.int64)
    bi[J_EARTH_ALL] = 1
    bi[J_LAST_ACC] = -1
    if cfg.gyro_bias is GyroBiasMode.PARAMETER:
        bf[B_BIAS:B_BIAS + 3] = cfg.gyro_bias_rad_s
    return rf, ri, bf, bi


def bias_report(mode: GyroBiasMode, bf, bi, min_rest_ns: int) -> GyroBiasReport:
    """What the bias stage's state ``bf``, ``bi`` knows, for a report."""
    bias, nan = np.array(bf[B_BIAS:B_BIAS + 3]), np.full(3, np.nan)
    if mode is GyroBiasMode.NONE:
        return GyroBiasReport("none", bias, 0, 0, nan, False, "bias not corrected (mode none)")
    if mode is GyroBiasMode.PARAMETER:
        return GyroBiasReport("parameter", bias, 0, 0, nan, False,
                              "fixed bias given as a parameter")
    if bi[J_K] == 0:
        return GyroBiasReport("auto", bias, 0, 0, nan, False,
                              f"no rest of at least {min_rest_ns / 1e9:g} s yet: bias not estimated")
    earth = bool(bi[J_EARTH_NOW])
    note = ("Earth rate removed (latitude and attitude known)" if earth else
            "Earth rate absorbed into the bias (latitude or attitude unknown)")
    return GyroBiasReport("auto", bias, int(bi[J_K]), int(bi[J_N]),
                          np.array(bf[B_SE:B_SE + 3]), earth, note)


@kernel
def bias_break(bf, bi, rf, ri, min_rest_ns):
    """The stream broke (gap, time jump, unusable accelerometer sample): the open rest closed
    (pooled when long enough), a fresh window; the estimate and the rests pooled so far kept."""
    if bi[J_HAS_SEG] == 1:
        close_rest(bf, bi, min_rest_ns)
    rest_reset(rf, ri)
    bi[J_LAST_ACC] = -1
