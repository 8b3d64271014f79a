"""Gyro bias: none, a fixed parameter, or estimated at rests (zero-rate updates), streaming and batch.

Contract (streaming): ``GyroBiasEstimator.update(t_ns, gyro, accel=None, q_nb=None) -> bias``
once per accepted sample, O(1) amortized; the returned bias (3,) rad/s is what to subtract from
that sample before integration.  ``q_nb`` is the current attitude estimate (body→ENU) when the
caller has one; with a latitude it lets the estimator take the Earth rate ``C_bn ω_ie^n`` out of
the rest average.  :func:`estimate_gyro_bias` is the batch form over arrays with bit-identical
results (same rest decisions, same sequential sums).

Modes:

* ``none``: bias 0.  ``parameter``: the fixed ``bias`` [x, y, z] rad/s given.
* ``auto``: a :class:`~gyro_attitude.core.attitude.rest.RestDetector` finds rests; each rest
  window contributes its *oldest* sample (so every rest sample is followed by a full window of
  rest, see rest.py).  A rest counts once its samples span ``min_rest_s`` (default 1 s, i.e.
  1.5 s of rest with the 0.5 s window): from then on, while it lasts, and after it, the bias is
  the mean over all qualifying rests so far, each weighted by its length (the pooled sample
  mean).  During motion the bias is held.  A window must show at least
  :data:`~gyro_attitude.core.attitude.rest.NOISE_FLOOR_RAD_S` of gyro noise (unless ``rest``
  says otherwise): on noise-free simulated data a constant slow rotation or the Earth rate
  would otherwise be taken for a bias; an ideal gyro has none to estimate.  Before the first
  qualifying rest it is 0 (or the optional ``initial`` bias) and the report says so.

Report (:class:`GyroBiasReport`): value, rests used, standard error per axis, and whether the
Earth rate was removed.  The standard error is the larger of (a) the white-noise figure
``σ_within / √N`` and (b) the scatter of the rest means between rests (needs ≥ 2 rests).
With one rest only (a), a lower bound: MEMS noise has flicker components that averaging does not
beat.  Without latitude and attitude the Earth rate (up to 15 °/h) is absorbed into the bias —
right for an inertial-frame integration, and a consumer MEMS bias (0.1–0.6 °/s here) is 25–150×
larger anyway — but a navigation-frame integration then removes the Earth rate twice.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gyro_attitude.core.attitude.modes import GyroBiasMode, parse_mode
from gyro_attitude.core.attitude.rest import (
    NOISE_FLOOR_RAD_S,
    R_AT_REST,
    R_HEAD,
    R_OLDEST,
    RING_FULL,
    RestDetector,
    check_sample,
    check_samples,
    rest_reset,
    rest_update,
)
from gyro_attitude.core.earth import check_latitude, earth_rate_enu
from gyro_attitude.core.jit import compiled, kernel
from gyro_attitude.core.rotation import as_quat_array

__all__ = ["BIAS_MODES", "GyroBiasEstimator", "GyroBiasReport", "estimate_gyro_bias"]

BIAS_MODES = tuple(m.value for m in GyroBiasMode)


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


def _check_vector(name: str, v) -> tuple[float, float, float]:
    try:
        x = tuple(float(c) for c in v)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be 3 finite numbers (rad/s), got {v!r}") from None
    if len(x) != 3 or not all(math.isfinite(c) and abs(c) < 1e3 for c in x):
        raise ValueError(f"{name} must be 3 finite numbers (rad/s), got {v!r}")
    return x  # type: ignore[return-value]


# The accumulation state as arrays (what the compiled chain steps, stream_loop.py).  Float slots:
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
    """Add the rest sample of time ``t`` with value ``v`` (:meth:`GyroBiasEstimator.value`) to
    the open rest (opened by the first); publish the pooled estimate once the rest spans
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
    """:meth:`GyroBiasEstimator.step` (mode auto) on the state arrays: the detector's window
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
    """``C_bn ω`` with ``s = 2/|q|²``; floats or arrays alike (same operations, same bits)."""
    e0, e1, e2 = float(w_n[0]), float(w_n[1]), float(w_n[2])
    # C_nb from the quaternion (scalar last); C_bn = C_nbᵀ: rows of C_bn are columns of C_nb
    c00, c01, c02 = 1 - s * (y * y + z * z), s * (x * y - z * w), s * (x * z + y * w)
    c10, c11, c12 = s * (x * y + z * w), 1 - s * (x * x + z * z), s * (y * z - x * w)
    c20, c21, c22 = s * (x * z - y * w), s * (y * z + x * w), 1 - s * (x * x + y * y)
    return (c00 * e0 + c10 * e1 + c20 * e2, c01 * e0 + c11 * e1 + c21 * e2,
            c02 * e0 + c12 * e1 + c22 * e2)



class GyroBiasEstimator:
    """Streaming gyro bias (see the module docstring for modes and the contract)."""

    def __init__(self, mode: str = "auto", bias=None, *, min_rest_s: float = 1.0,
                 latitude_rad: float | None = None, initial=None, rest: dict | None = None):
        mode = parse_mode(GyroBiasMode, mode, "gyro bias mode")
        if mode is GyroBiasMode.PARAMETER and bias is None:
            raise ValueError("gyro bias mode 'parameter' needs bias=[x, y, z] in rad/s")
        if mode is not GyroBiasMode.PARAMETER and bias is not None:
            raise ValueError(f"a fixed bias is only used with mode 'parameter', not {mode!r}")
        self.mode = mode
        self._fixed = _check_vector("bias", bias) if bias is not None else (0.0, 0.0, 0.0)
        self._initial = _check_vector("initial", initial) if initial is not None else (0.0,) * 3
        if not (isinstance(min_rest_s, int | float) and math.isfinite(min_rest_s)
                and 0 < min_rest_s < 1e6):
            raise ValueError(f"min_rest_s must be a positive number of seconds, got {min_rest_s!r}")
        self.min_rest_ns = int(round(min_rest_s * 1e9))
        self._earth_n = None
        if latitude_rad is not None:
            self._earth_n = earth_rate_enu(check_latitude(float(latitude_rad), "latitude_rad"))
        self._rest_params = {"gyro_std_min": NOISE_FLOOR_RAD_S, **(rest or {})}
        self.detector = RestDetector(**self._rest_params)
        self.reset()

    def break_window(self) -> None:
        """The stream broke (gap, time jump, unusable accelerometer sample): close the open rest
        and start a fresh window; the rests pooled so far and the estimate are kept."""
        compiled(bias_break)(self.bf, self.bi, self.detector.rf, self.detector.ri,
                             self.min_rest_ns)

    @property
    def standard_error(self) -> np.ndarray:
        """Standard error (3,) of the current estimate, NaN before the first qualifying rest."""
        return np.array(self._se)

    def reset(self) -> None:
        """Forget rests and the window (the fixed/initial bias stays)."""
        self.detector.reset()
        # the accumulation state (B_*, J_*), reset in place: the compiled chain holds the arrays
        if not hasattr(self, "bf"):
            self.bf = np.zeros(_B_FLOATS)
            self.bi = np.zeros(_B_INTS, dtype=np.int64)
            # what each sample of the detector's window gives a rest (its value, whether the
            # Earth rate was taken out), in the detector's ring slots
            self.pv = np.zeros((self.detector.wt.shape[0], 3))
            self.pe = np.zeros(self.detector.wt.shape[0], dtype=np.bool_)
            self.earth_n = np.zeros(3) if self._earth_n is None else np.asarray(
                self._earth_n, dtype=np.float64)
        self.bf[:] = 0.0
        self.bi[:] = 0
        self.bi[J_EARTH_ALL] = 1
        self.bi[J_LAST_ACC] = -1
        self._bias = self._fixed if self.mode is GyroBiasMode.PARAMETER else (
            self._initial if self.mode is GyroBiasMode.AUTO else (0.0, 0.0, 0.0))
        self._se = (math.nan,) * 3

    def _floats(i):
        def get(self):
            return tuple(self.bf[i:i + 3].tolist())

        def put(self, x):
            self.bf[i:i + 3] = x
        return property(get, put)

    def _int(i, kind=int):
        def get(self):
            return kind(self.bi[i])

        def put(self, x):
            self.bi[i] = x
        return property(get, put)

    _bias = _floats(B_BIAS)
    _se = _floats(B_SE)
    _k = _int(J_K)
    _n = _int(J_N)
    updated = _int(J_UPDATED, bool)  # the last update() published a new estimate
    _earth_all = _int(J_EARTH_ALL, bool)
    _earth_now = _int(J_EARTH_NOW, bool)
    del _floats, _int

    @property
    def bias(self) -> np.ndarray:
        return np.array(self._bias)


    def update(self, t_ns: int, gyro, accel=None, q_nb=None) -> np.ndarray:
        """Consume one sample; return the bias (3,) rad/s to subtract from it."""
        t, g, a = check_sample(t_ns, gyro, accel)
        return np.array(self.step(t, g, a, q_nb))

    def step(self, t: int, g: tuple, a: tuple | None, q_nb=None) -> tuple:
        """:meth:`update` on a sample already through :func:`check_sample`; the bias as 3
        floats.  The rest decision of the window ending here is the detector's; what it
        accumulates (:meth:`value`, :meth:`accumulate`, :meth:`close_rest`) is the estimator's
        own step, which the stream's array-and-loop form drives from the array form of the
        detector (:meth:`rests`)."""
        self.updated = False
        if self.mode is not GyroBiasMode.AUTO:
            return self._bias
        has_a = a is not None
        a0, a1, a2 = a if has_a else (0.0, 0.0, 0.0)
        has_q = self._earth_n is not None and q_nb is not None
        x, y, z, u = (float(c) for c in q_nb) if has_q else (0.0, 0.0, 0.0, 1.0)
        det = self.detector
        while True:
            code = compiled(bias_step)(self.bf, self.bi, self.min_rest_ns, det.rf, det.ri, det.wt,
                                       det.wx, det.wc, self.pv, self.pe, self.earth_n, t, g[0],
                                       g[1], g[2], has_a, a0, a1, a2, has_q, x, y, z, u)
            if code != RING_FULL:
                break
            self.pv, self.pe = det.grow(self.pv, self.pe)
        if code == BAD_ATTITUDE:
            raise ValueError(f"q_nb must be a finite non-zero quaternion, got {q_nb!r}")
        if code < 0:
            raise ValueError(det.refusal(code, t))
        return self._bias



    def report(self) -> GyroBiasReport:
        if self.mode is GyroBiasMode.NONE:
            return GyroBiasReport("none", np.zeros(3), 0, 0, np.full(3, np.nan), False,
                                  "bias not corrected (mode none)")
        if self.mode is GyroBiasMode.PARAMETER:
            return GyroBiasReport("parameter", np.array(self._fixed), 0, 0, np.full(3, np.nan),
                                  False, "fixed bias given as a parameter")
        if self._k == 0:
            return GyroBiasReport("auto", np.array(self._bias), 0, 0, np.full(3, np.nan), False,
                                  "no rest of at least "
                                  f"{self.min_rest_ns / 1e9:g} s yet: bias not estimated")
        earth = bool(getattr(self, "_earth_now", False))
        note = ("Earth rate removed (latitude and attitude known)" if earth else
                "Earth rate absorbed into the bias (latitude or attitude unknown)")
        return GyroBiasReport("auto", np.array(self._bias), self._k, self._n, np.array(self._se),
                              earth, note)



def estimate_gyro_bias(t_ns, gyro, accel=None, q_nb=None, *, mode: str = "auto", bias=None,
                       min_rest_s: float = 1.0, latitude_rad: float | None = None, initial=None,
                       rest: dict | None = None) -> tuple[np.ndarray, GyroBiasReport]:
    """Batch :class:`GyroBiasEstimator`: the bias for every sample (N, 3) and the final report.

    The streaming estimator over the samples (one code path); ``q_nb`` (N, 4), with
    ``latitude_rad``, removes the Earth rate as in the stream.
    """
    est = GyroBiasEstimator(mode, bias, min_rest_s=min_rest_s, latitude_rad=latitude_rad,
                            initial=initial, rest=rest)
    t, g, a = check_samples(t_ns, gyro, accel)
    q = None
    if latitude_rad is not None and q_nb is not None:
        q = as_quat_array(q_nb, "q_nb")
        if q.shape != (t.size, 4):
            raise ValueError(f"q_nb must have shape ({t.size}, 4), got {q.shape}")
        q = q.tolist()
    out = np.empty((t.size, 3))
    for k, (tk, gk) in enumerate(zip(t.tolist(), g.tolist(), strict=True)):
        out[k] = est.step(tk, gk, None if a is None else a[k].tolist(),
                          None if q is None else q[k])
    return out, est.report()


@kernel
def bias_break(bf, bi, rf, ri, min_rest_ns):
    """:meth:`GyroBiasEstimator.break_window` on the state arrays: the open rest closed (pooled
    when long enough), a fresh window; the estimate and the rests pooled so far kept."""
    if bi[J_HAS_SEG] == 1:
        close_rest(bf, bi, min_rest_ns)
    rest_reset(rf, ri)
    bi[J_LAST_ACC] = -1
