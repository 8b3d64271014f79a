"""Gyro bias: none, a fixed parameter, or estimated at rests (zero-rate updates).

Contract (streaming): the kernel :func:`bias_step` once per accepted sample, O(1) amortized,
on the state :func:`bias_start` makes; the bias (3,) rad/s to subtract from that sample is then
``bf[B_BIAS:B_BIAS + 3]``.  With the current attitude estimate (body→ENU) and a latitude it
takes the Earth rate ``C_bn ω_ie^n`` out of the rest average.

Modes:

* ``none``: bias 0.  ``parameter``: the fixed ``gyro_bias_rad_s`` [x, y, z] rad/s given.
* ``auto``: the rest detector (:func:`.rest.rest_update`) finds rests; each rest window
  contributes its *oldest* sample (so every rest sample is followed by a full window of rest,
  see rest.py).  A rest counts once its samples span ``min_rest_s`` (default 1 s, i.e. 1.5 s
  of rest with the 0.5 s window): from then on, while it lasts, and after it, the bias is the
  mean over all qualifying rests so far, each weighted by its length (the pooled sample mean).
  During motion the bias is held.  A window must show at least
  :data:`.rest.NOISE_FLOOR_RAD_S` of gyro noise: on noise-free simulated data a constant slow
  rotation or the Earth rate would otherwise be taken for a bias; an ideal gyro has none to
  estimate.  Before the first qualifying rest it is 0 and the report says so.

Report (:func:`bias_report`, a :class:`GyroBiasReport`): value, rests used, standard error per
axis, and whether the Earth rate was removed.  The standard error is the larger of (a) the
white-noise figure ``σ_within / √N`` and (b) the scatter of the rest means between rests
(needs ≥ 2 rests).
With one rest only (a), a lower bound: MEMS noise has flicker components that averaging does not
beat.  Without latitude and attitude the Earth rate (up to 15 °/h) is absorbed into the bias —
right for an inertial-frame integration, and a consumer MEMS bias (0.1–0.6 °/s here) is 25–150×
larger anyway — but a navigation-frame integration then removes the Earth rate twice.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

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


@kernel(inline=True)
def seg_stats(n, bf):
    """Mean and within-rest squared deviations of the open rest's ``n`` samples."""
    m0 = bf[B_REF] + bf[B_S1] / n
    m1 = bf[B_REF + 1] + bf[B_S1 + 1] / n
    m2 = bf[B_REF + 2] + bf[B_S1 + 2] / n
    d0 = max(bf[B_S2] - bf[B_S1] * bf[B_S1] / n, 0.0)
    d1 = max(bf[B_S2 + 1] - bf[B_S1 + 1] * bf[B_S1 + 1] / n, 0.0)
    d2 = max(bf[B_S2 + 2] - bf[B_S1 + 2] * bf[B_S1 + 2] / n, 0.0)
    return m0, m1, m2, d0, d1, d2


@kernel
def pool_add(bf, bi, n, m0, m1, m2, d0, d1, d2):
    """Pool a completed rest of ``n`` samples, mean ``m``, squared deviations ``d``."""
    bi[J_POOL_K] += 1
    bi[J_POOL_N] += n
    for i, m, d in ((0, m0, d0), (1, m1, d1), (2, m2, d2)):
        bf[B_SUM_NM + i] = bf[B_SUM_NM + i] + n * m
        bf[B_SUM_NM2 + i] = bf[B_SUM_NM2 + i] + n * m * m
        bf[B_SSD + i] = bf[B_SSD + i] + d


@kernel
def publish_pooled(bf, bi, n_c, m0, m1, m2, d0, d1, d2):
    """Publish the pooled estimate of the completed rests and an open one (``n_c`` samples,
    mean ``m``, squared deviations ``d``): bias, standard error, rests and samples."""
    k = bi[J_POOL_K] + 1
    n = bi[J_POOL_N] + n_c
    for i, m, d in ((0, m0, d0), (1, m1, d1), (2, m2, d2)):
        snm = bf[B_SUM_NM + i] + n_c * m
        snm2 = bf[B_SUM_NM2 + i] + n_c * m * m
        ssd = bf[B_SSD + i] + d
        bias = snm / n
        white = math.sqrt(ssd / max(n - k, 1) / n)
        between = 0.0
        if k >= 2:
            between = math.sqrt(max(snm2 - n * bias * bias, 0.0) / n / (k - 1))
        bf[B_BIAS + i] = bias
        bf[B_SE + i] = max(white, between)
    bi[J_K], bi[J_N] = k, n


@kernel
def accumulate(bf, bi, min_rest_ns, t, v0, v1, v2, earth):
    """Add the rest sample of time ``t`` with value ``v`` (its rate, less the Earth rate when
    known) to the open rest (opened by the first); publish the pooled estimate once the rest spans
    ``min_rest_ns`` (``J_UPDATED`` then says so)."""
    bi[J_UPDATED] = 0
    if bi[J_HAS_SEG] == 0:
        bi[J_HAS_SEG], bi[J_SEG_T0], bi[J_SEG_N], bi[J_SEG_EARTH] = 1, t, 0, 1
        bf[B_REF], bf[B_REF + 1], bf[B_REF + 2] = v0, v1, v2
        for i in range(3):
            bf[B_S1 + i] = 0.0
            bf[B_S2 + i] = 0.0
    bi[J_SEG_T1] = t
    bi[J_SEG_N] += 1
    for i, v in ((0, v0), (1, v1), (2, v2)):
        d = v - bf[B_REF + i]
        bf[B_S1 + i] = bf[B_S1 + i] + d
        bf[B_S2 + i] = bf[B_S2 + i] + d * d
    if not earth:
        bi[J_SEG_EARTH] = 0
    if bi[J_SEG_T1] - bi[J_SEG_T0] >= min_rest_ns:
        m0, m1, m2, d0, d1, d2 = seg_stats(bi[J_SEG_N], bf)
        publish_pooled(bf, bi, bi[J_SEG_N], m0, m1, m2, d0, d1, d2)
        bi[J_UPDATED] = 1
        bi[J_EARTH_NOW] = 1 if (bi[J_EARTH_ALL] == 1 and bi[J_SEG_EARTH] == 1) else 0


@kernel
def close_rest(bf, bi, min_rest_ns):
    """The open rest ended: pooled when it spans ``min_rest_ns``."""
    bi[J_HAS_SEG] = 0
    if bi[J_SEG_T1] - bi[J_SEG_T0] >= min_rest_ns:
        m0, m1, m2, d0, d1, d2 = seg_stats(bi[J_SEG_N], bf)
        pool_add(bf, bi, bi[J_SEG_N], m0, m1, m2, d0, d1, d2)
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
        e0, e1, e2 = _c_bn_times(x, y, z, u, 2.0 / n, earth_n)
        pv[slot, 0], pv[slot, 1], pv[slot, 2] = g0 - e0, g1 - e1, g2 - e2
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


@kernel(inline=True)
def _c_bn_times(x, y, z, w, s, w_n):
    """``C_bn ω`` with ``s = 2/|q|²``."""
    e0, e1, e2 = float(w_n[0]), float(w_n[1]), float(w_n[2])
    # C_nb from the quaternion (scalar last); C_bn = C_nbᵀ: rows of C_bn are columns of C_nb
    c00, c01, c02 = 1 - s * (y * y + z * z), s * (x * y - z * w), s * (x * z + y * w)
    c10, c11, c12 = s * (x * y + z * w), 1 - s * (x * x + z * z), s * (y * z - x * w)
    c20, c21, c22 = s * (x * z - y * w), s * (y * z + x * w), 1 - s * (x * x + y * y)
    return (c00 * e0 + c10 * e1 + c20 * e2, c01 * e0 + c11 * e1 + c21 * e2,
            c02 * e0 + c12 * e1 + c22 * e2)


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
