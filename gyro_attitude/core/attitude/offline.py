"""Offline attitude over a whole recording: rests, bias and gravity from both sides of a sample.

:func:`estimate_offline` is the non-causal estimator beside :meth:`.stream.AttitudeStream.run`
(the same sample verdicts and :class:`.stream.StreamResult`), an array operation over chunks
of accepted samples per step: 1. rests, 2. gyro bias per rest, 3. integration, 4. tilt from
gravity, 5. covariance, 6. heading from the magnetometer (docs/architecture.md, "Notes:
offline estimator": each step's rule and why).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from gyro_attitude.core.angles import wrap_2pi
from gyro_attitude.core.attitude import NavFrame, integrate_batch
from gyro_attitude.core.attitude import stream as st
from gyro_attitude.core.attitude import validation as v
from gyro_attitude.core.attitude.ahrs import MAG_ABSURD_T, MAG_ZERO_T
from gyro_attitude.core.attitude.alignment import AlignmentResult, heading_of, level_quaternion
from gyro_attitude.core.attitude.chain import SATURATION_MIN_RAD_S, SATURATION_PLATEAU_NS
from gyro_attitude.core.attitude.gyro_bias import GyroBiasReport
from gyro_attitude.core.attitude.modes import Aiding, Frame, GyroBiasMode, HeadingSource
from gyro_attitude.core.attitude.registry import DEFAULT_ALGORITHM
from gyro_attitude.core.attitude.rest import NOISE_FLOOR_RAD_S, detect_rest, true_runs
from gyro_attitude.core.attitude.sample_clock import sample_clock
from gyro_attitude.core.attitude.settings import StreamConfig
from gyro_attitude.core.earth import OMEGA_IE, STANDARD_GRAVITY
from gyro_attitude.core.rotation import (
    _qmul,
    _qrot,
    quat_as_matrix,
    quat_as_rotvec,
    quat_conjugate,
    quat_from_rotvec,
    quat_multiply,
    quat_rotate,
)

__all__ = ["DEFAULT_CHUNK_SAMPLES", "FieldReference", "OfflineRest", "estimate_offline"]

#: Accepted samples per working chunk: ~25 MB of temporaries at most, whatever the length.
DEFAULT_CHUNK_SAMPLES = 1 << 16
# the forward low-pass of a block up to this many samples is kept (40 MB), not recomputed
_KEEP_FORWARD = 1 << 20
# rows each integration chunk reaches into its neighbours (the widest stencil: magnus6, 6)
_OVERLAP = 8
# rows per step of the covariance propagation (interpolated in between: it is smooth)
_COV_BLOCK = 16
# the learned field reference is the median over at most this many samples spread over the run
_REFERENCE_SAMPLES = 1 << 14  # (a median of 16 Ki: within ~1 % of the field's scatter)
# the heading smoother needs this much weight within reach (e^-600: ~600 τ away from any field)
_MAG_WEIGHT_MIN = 1e-260
_IDENTITY = np.array([0.0, 0.0, 0.0, 1.0])


@dataclass
class FieldReference:
    """The heading pass's magnetometer reference, named as the causal aiding stage names it
    (replay's summary): norm (T) and dip (rad, down) given or learned, the hard iron used; never
    replaced (``mag_reference_changes`` 0), no acceleration rejected (the tilt uses every sample)."""

    mag_ref_norm: float | None = None
    mag_ref_dip: float | None = None
    hard_iron: tuple = (0.0, 0.0, 0.0)
    mag_reference_changes: int = 0
    accel_rejected: int | None = None
    learned: bool = False


@dataclass(frozen=True)
class OfflineRest:
    """One rest found over the recording: accepted rows ``[start, stop)``, its mid time on the
    block's clock ``tau_s``, the bias estimate and its standard error (rad/s), mean specific
    force (m/s², NaN without accelerometer) and the per-axis gyro scatter (rad/s)²."""

    start: int
    stop: int
    tau_s: float
    duration_s: float
    bias: np.ndarray
    standard_error: np.ndarray
    accel_mean: np.ndarray
    accel_var: np.ndarray
    gyro_var: np.ndarray


def _chunks(lo: int, hi: int, size: int):
    for c0 in range(lo, hi, size):
        yield c0, min(c0 + size, hi)


def _mean_var(x: np.ndarray, lo: int, hi: int, size: int) -> tuple[np.ndarray, np.ndarray]:
    """Mean and variance (ddof 1) of rows ``x[lo:hi]``, summed chunk-wise about the first row."""
    ref = x[lo].astype(np.float64)
    s1 = np.zeros(3)
    s2 = np.zeros(3)
    for c0, c1 in _chunks(lo, hi, size):
        d = x[c0:c1] - ref
        s1 += d.sum(axis=0)
        s2 += np.einsum("ij,ij->j", d, d)
    n = hi - lo
    mean = ref + s1 / n
    var = np.maximum(s2 - s1 * s1 / n, 0.0) / max(n - 1, 1)
    return mean, var


def _rest_mask(t: np.ndarray, w: np.ndarray, a: np.ndarray | None, cfg,
               window_ns: int, min_ns: int, size: int, out: np.ndarray, zeros) -> None:
    """Mark in ``out`` the rows of one gap-free run that rest (step 1): the newest sample of a
    rest window, followed by a full window of rest, in runs of rest windows whose oldest samples
    span ``min_ns`` (the causal bias stage's test).  ``zeros(n, dtype)`` allocates the flags.
    A window at rest has a mean of ``|ω|²`` of at most ``3 gyro_mean_max² + gyro_std_max²``:
    the windows above (motion) are skipped with one cumulative sum, and
    :func:`.rest.detect_rest` runs only over the stretches that may hold a rest."""
    n = t.size
    bound = (3.0 * cfg.rest_gyro_mean_max ** 2 + cfg.rest_gyro_std_max ** 2) \
        * (1 + 1e-9) + 1e-300
    cand = zeros(n, bool)
    for c0, c1 in _chunks(0, n, size):
        # the windows ending in this chunk, from a cumulative sum started at the oldest
        # sample they reach (temporaries of a chunk, not of the run)
        oldest = np.searchsorted(t, t[c0:c1] - window_ns, side="left")
        p = int(oldest[0])
        ww = np.einsum("ij,ij->i", w[p:c1], w[p:c1])
        cs = np.concatenate(([0.0], np.cumsum(ww)))
        k = np.arange(c0, c1)
        cand[c0:c1] = (cs[k + 1 - p] - cs[oldest - p]) <= bound * (k + 1 - oldest)
    newest = zeros(n, bool)  # the window ending here is at rest
    for e0, e1 in _segments(cand):  # window ends that may be at rest
        s0 = int(np.searchsorted(t, t[e0] - window_ns, side="left"))
        for c0, c1 in _chunks(s0, e1, size):
            p = 0 if c0 == 0 else max(0, int(np.searchsorted(t[:c0], t[c0] - window_ns)) - 1)
            if c1 - p < 2:
                continue
            rw = detect_rest(t[p:c1], w[p:c1], None if a is None else a[p:c1], cfg, NOISE_FLOOR_RAD_S)
            kk = np.flatnonzero(rw.at_rest[c0 - p:]) + (c0 - p)
            if p != 0:  # not starting the run: 'full' counts from the run's first sample
                kk = kk[t[p + kk] - t[0] >= window_ns]
            newest[p + kk] = True
    # Followed by a full window of rest: every sample from the oldest of a run's first rest
    # window to the oldest of its last (on uneven stamps a window may drop two old samples at
    # once: the one skipped is still followed by a window of rest).
    e0, e1 = true_runs(newest)
    o0 = np.searchsorted(t, t[e0] - window_ns, side="left")
    o1 = np.searchsorted(t, t[e1 - 1] - window_ns, side="left")
    keep = t[o1] - t[o0] >= min_ns  # the causal stage's span of the same rest
    # at rest: preceded and followed by a window of rest of the same run, [e0, o1]; a run the
    # causal stage does not count marks nothing (else a flickering rest edge next to a counted
    # run made rests the causal stage never counted: 9 against 7 at 125 Hz, |f| 5 % above g)
    for a, b in zip(e0[keep].tolist(), o1[keep].tolist(), strict=True):
        out[a:b + 1] = True


def _with_standard_errors(rests: list[OfflineRest], k2: float) -> list[OfflineRest]:
    """The rests with their bias's standard error ``√(σ²/n + K² T/3)`` (white noise plus the bias
    walk of density² ``k2`` over the rest's length)."""
    return [replace(r, standard_error=np.sqrt(r.gyro_var / (r.stop - r.start)
                                              + k2 * r.duration_s / 3.0)) for r in rests]


def _segments(mask: np.ndarray) -> list[tuple[int, int]]:
    """The runs of True in ``mask``: (start, stop) pairs."""
    e0, e1 = true_runs(mask)
    return list(zip(e0.tolist(), e1.tolist(), strict=True))


def _up_correction(u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The smallest rotations taking the directions ``u`` (M, 3) to +z as unit quaternions
    ``(cx, cy, 0, cw)``: the arrays ``cx, cy, cw``.  The half-way quaternion ``(u × z, |u| +
    u·z)`` normalised, no trigonometry; exact for every u but straight down (|u| + u_z = 0 and
    u × z = 0: then any horizontal axis, x here)."""
    cx, cy = u[:, 1].copy(), -u[:, 0]
    cw = np.sqrt(np.einsum("ij,ij->i", u, u)) + u[:, 2]
    inv = cx * cx + cy * cy + cw * cw
    down = inv <= 1e-300
    if down.any():
        cx[down], cy[down], cw[down], inv[down] = 1.0, 0.0, 0.0, 1.0
    inv = 1.0 / np.sqrt(inv)
    return cx * inv, cy * inv, cw * inv


def _level_left(u: np.ndarray, q: np.ndarray) -> np.ndarray:
    """``_up_correction(u) ⊗ q`` (M, 4): the correction's z part is 0, so the product has
    three terms fewer per component (the tilt pass's hot step)."""
    cx, cy, cw = _up_correction(u)
    qx, qy, qz, qw = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    out = np.empty_like(q)
    out[:, 0] = cw * qx + cx * qw + cy * qz
    out[:, 1] = cw * qy - cx * qz + cy * qw
    out[:, 2] = cw * qz + cx * qy - cy * qx
    out[:, 3] = cw * qw - cx * qx - cy * qy
    return out


# a decaying sum runs over pieces whose clock spans at most this many time constants
# (e^±200: far from overflow, and terms older than that are below any float's precision)
_SPAN = 200.0


def _decaying_sum(ds: np.ndarray, x: np.ndarray, tau: float, z) -> np.ndarray:
    """``y_k = e^(−ds_k/τ) y_(k−1) + x_k`` over the rows of ``x`` from ``y_(−1) = z`` (None:
    0) as array operations: ``y_k = Σ_j e^(−(s_k − s_j)/τ) x_j`` with ``s`` the running sum of
    ``ds``, summed over pieces of at most ``_SPAN`` time constants against the piece's end."""
    s = np.cumsum(ds) / tau
    y = np.empty_like(x)
    n = s.size
    i0, base = 0, 0.0
    while i0 < n:
        i1 = max(i0 + 1, int(np.searchsorted(s, base + _SPAN, side="right")))
        sp = s[i0:i1] - base
        e = np.exp(sp - sp[-1])[:, None]  # in (e^-SPAN, 1]
        y[i0:i1] = np.cumsum(e * x[i0:i1], axis=0) / e
        if z is not None:
            y[i0:i1] += np.exp(-sp)[:, None] * z
        z = y[i1 - 1]
        base = s[i1 - 1]
        i0 = i1
    return y


def estimate_offline(t_ns, omega, accel=None, *, config: StreamConfig | None = None,
                     q0=None, nav: NavFrame | None = None, mag=None,
                     frame_id: str | list[str] | None = "", angular_velocity_covariance=None,
                     algorithm: str = DEFAULT_ALGORITHM,
                     chunk_samples: int = DEFAULT_CHUNK_SAMPLES, empty=np.empty) -> st.StreamResult:
    """Attitudes of a whole recording, non-causally.  ``t_ns`` (N,) int stamps; ``omega`` (N, 3)
    rad/s; ``accel`` (N, 3) m/s² or None (gyro-only: rests from the gyro alone, no levelling,
    no aiding); ``q0`` the initial attitude (None: ``initial_attitude``, whose tilt the first
    accelerometer sample replaces when :func:`.stream.starts_from_accelerometer`); ``nav`` a
    constant :class:`NavFrame` for q_nb or None for q_ib; ``mag`` (N, 3) T (rows of NaN: none
    there), used with ``aiding="magnetometer"``; ``angular_velocity_covariance`` (N, 9) or
    None.  ``empty(shape, dtype)`` allocates the arrays of the recording's length (a caller may
    give file-backed ones).  ValueError on malformed input and when ``initial_attitude="level"``
    finds no rest to level on."""
    cfg, nav = _checked_arguments(config, nav, chunk_samples)
    q_init = st._unit_quat(cfg.initial_attitude if q0 is None else q0)
    t = np.asarray(t_ns)
    w = np.asarray(omega, dtype=np.float64)
    cls = v.classify(t, w, frame_id, cfg)  # checks t and omega shapes
    n = w.shape[0]
    t = t.astype(np.int64, copy=False)
    cov, acc = st.recording_arrays(n, angular_velocity_covariance, accel)
    act = cls.action
    valid = v.accepted_rows(act, empty, chunk_samples)
    counts = {**cls.counts, v.MISSING_SAMPLES: cls.missing_samples, st.INVALID_COVARIANCE: 0,
              st.INVALID_ACCEL: 0, st.INTEGRATOR_ERROR: 0, st.SATURATED: 0,
              st.RATE_FIT_FALLBACK: 0}
    details = dict(cls.details)
    tv = st.rows(t, valid, empty)
    wv = st.rows(w, valid, empty)
    av, usable = _accel_rows(acc, valid, empty, counts, details)
    start_notes = [st.aiding_note(cfg, av is not None)] if cfg.aided else []
    if st.starts_from_accelerometer(cfg, q0) and av is not None:
        # as the causal step starts (chain.level_from_first): the first usable sample's tilt
        heading = heading_of(q_init)
        q_init, _, _ = level_quaternion(av[int(np.argmax(usable))], heading)
        start_notes.append(st.START_NOTE.format(math.degrees(heading)))
    mv = _mag_rows(cfg, mag, n, valid, empty)
    sig2 = None  # per-row gyro variance (M, 3) from the messages, where known
    if cov is not None:
        var_v, known_v = st.covariance_rows(cov, valid, counts, details)
        if known_v.any():
            sig2 = (var_v, known_v)
    if nav is not None and nav.series_length() is not None:
        if nav.series_length() != n:
            raise ValueError(f"nav time series must have one row per sample ({n}), got "
                             f"{nav.series_length()}")
        nav = st.nav_rows(nav, valid, n)  # (a velocity schedule: one row per accepted sample)
    # saturated samples: counted as the causal path counts them
    count_saturated(tv, wv, counts, details, chunk_samples)
    est = _Estimator(cfg, q_init, nav, algorithm, chunk_samples, tv, wv, av, usable, sig2,
                     st.rows(act, valid), mv, empty)
    q_out, var_out, known_out = est.run()
    fell_back = np.concatenate(est.fit_fallbacks) if est.fit_fallbacks else np.zeros(0, int)
    counts[st.RATE_FIT_FALLBACK] = int(fell_back.size)
    if fell_back.size:
        details.setdefault(st.RATE_FIT_FALLBACK, st.rate_fit_note(int(tv[int(fell_back.min())])))
    notes = est.notes
    if cfg.aiding is Aiding.MAGNETOMETER:
        if mv is None:
            est.mag_counts[st.MAG_MISSING] = valid.size
        counts.update(est.mag_counts)
        for key in (st.INVALID_MAG, st.MAG_DISTURBED, st.MAG_MISSING):
            if counts[key]:
                details.setdefault(key, _MAG_DETAILS[key])
    if av is None:
        notes.insert(0, "no accelerometer: gyro-only offline estimation (rests from the gyro, "
                     "no levelling, no tilt aiding)")
    res = st.StreamResult(valid, q_out, var_out, known_out, act, counts, cls.time_jump_resets,
                          details, est.bias_report(), est.alignment, notes=start_notes + notes)
    res.field_reference = est.field_reference  # None unless aiding magnetometer
    return res


def _checked_arguments(config, nav, chunk_samples) -> tuple[StreamConfig, NavFrame | None]:
    """The settings and the nav frame of :func:`estimate_offline` (ValueError naming a bad
    argument)."""
    cfg = config if config is not None else StreamConfig()
    if not isinstance(cfg, StreamConfig):
        raise ValueError(f"config must be a StreamConfig, got {type(cfg).__name__}")
    if isinstance(chunk_samples, bool) or not isinstance(chunk_samples, int) or \
            not 64 <= chunk_samples <= 1 << 26:
        raise ValueError(f"chunk_samples must be an int in [64, 2**26], got {chunk_samples!r}")
    if cfg.heading_source is HeadingSource.GYROCOMPASS:
        raise ValueError("the offline estimator does not gyrocompass (heading_source "
                         "'gyrocompass'): use --estimator causal or give the heading")
    if nav is None and cfg.frame is Frame.ENU:
        nav = cfg.nav_frame()
    if nav is not None and not isinstance(nav, NavFrame):
        raise ValueError(f"nav must be a NavFrame or None, got {type(nav).__name__}")
    return cfg, nav


def _accel_rows(acc, valid, empty, counts, details):
    """(the accepted rows' specific force, which of them are usable), both None when there is
    no usable one; the unusable ones counted (``invalid_accel``) with the first's detail."""
    if acc is None:
        return None, None
    av = st.rows(acc, valid, empty)
    usable = st.usable_accel(av)
    counts[st.INVALID_ACCEL] = int(valid.size - np.count_nonzero(usable))
    if counts[st.INVALID_ACCEL]:
        k = int(np.flatnonzero(~usable)[0])
        details.setdefault(st.INVALID_ACCEL, f"linear_acceleration {av[k].tolist()} is not "
                              "finite or absurd: not used for rests, levelling or aiding")
    if not usable.any():
        return None, None
    return av, usable


def _mag_rows(cfg, mag, n, valid, empty):
    """The accepted rows' magnetic field (aiding magnetometer and a field given), else None."""
    if cfg.aiding is not Aiding.MAGNETOMETER or mag is None:
        return None
    mag = np.asarray(mag, dtype=np.float64)
    if mag.shape != (n, 3):
        raise ValueError(f"mag must have shape ({n}, 3), got {mag.shape}")
    return st.rows(mag, valid, empty)


# the magnetometer's counts (aiding magnetometer) and the detail of each that occurred
_MAG_DETAILS = {st.MAG_MISSING: "no magnetic field sample for these Imu samples",
                st.INVALID_MAG: "a magnetic field sample not finite, beyond 10 mT or below 0.1 µT",
                st.MAG_DISTURBED: "a field whose norm or dip is off the reference"}


class _BiasTerms:
    """The bias's share of the covariance (step 5), block by block: the error of the bias
    interpolated between the rests' estimates, and the bias random walk (``k2``), on the motion
    clock (it acts only while the attitude is integrated).  Interval s: before rest 0 (s = 0),
    between rests s-1 and s, after the last (s = nr); rest s-1's lever grows with weight 1 − w
    there (``m_fall``), rest s's with w (``m_rise``).  ``rests`` None: one bias of 1σ ``sigma``."""

    def __init__(self, rests, sigma: float, k2: float):
        self.rests, self.k2 = rests, k2
        if rests:
            self.x = np.asarray([r.tau_s for r in rests])
            self.se2 = [r.standard_error ** 2 for r in rests]
            dur = np.array([r.duration_s for r in rests])
            # each interval's motion time: the time between the rests' middles less their halves
            self.t_motion = np.maximum(np.diff(self.x) - 0.5 * (dur[:-1] + dur[1:]), 1e-9) \
                if self.x.size > 1 else np.zeros(0)
        else:
            self.x = np.asarray([0.0])
            self.se2 = [np.full(3, sigma ** 2)]
        self.done = np.zeros(3)  # variance from rests whose weights are complete
        self.rw_done = 0.0
        self.rw_last = 0.0  # the walk's term at the last block of the current interval
        self.mclock = 0.0  # motion time so far
        self.m_node = 0.0  # motion time at the start of the current interval
        self.m_fall = np.zeros((3, 3))
        self.m_rise = np.zeros((3, 3))
        self.j = 0

    def blocks(self, c, dtb, tr) -> np.ndarray:
        """The terms after each block (C_nb ``c``, motion time ``dtb``, rising bias clock ``tr``)."""
        mc = self.mclock + np.cumsum(dtb)  # motion clock after each block
        self.mclock = float(mc[-1])
        seg = np.searchsorted(self.x, tr, side="right")  # interval per block
        edges = np.flatnonzero(np.diff(seg)) + 1
        out = np.zeros((dtb.size, 3))
        for lo, hi in zip([0, *edges.tolist()], [*edges.tolist(), dtb.size], strict=True):
            s = int(seg[lo])
            while self.j < s:  # entering interval j + 1: rest j-1's weight is complete
                self._next_interval(float(mc[lo] - dtb[lo]))
            var_b, rw = self._interval(s, c[lo:hi] * dtb[lo:hi, None, None], tr[lo:hi],
                                       mc[lo:hi])
            out[lo:hi] = self.done + var_b + (self.rw_done + rw)[:, None]
            self.rw_last = float(rw[-1])
        return out

    def _next_interval(self, m_node: float) -> None:
        self.rw_done += self.rw_last  # the walk's share of the interval left is frozen in
        self.rw_last = 0.0
        if self.j >= 1:
            self.done += np.einsum("km,m->k", self.m_fall ** 2, self.se2[self.j - 1])
        self.m_fall, self.m_rise = self.m_rise, np.zeros((3, 3))
        self.j += 1
        self.m_node = m_node

    def _interval(self, s, cd, tr, mc):
        """(bias variance, random-walk variance) of blocks in interval ``s``."""
        x, se2, k2, nr = self.x, self.se2, self.k2, self.x.size
        if 0 < s < nr:
            wgt = ((tr - x[s - 1]) / (x[s] - x[s - 1]))[:, None, None]
            mf = self.m_fall + np.cumsum(cd * (1.0 - wgt), axis=0)
            mr = self.m_rise + np.cumsum(cd * wgt, axis=0)
            var_b = np.einsum("ikm,m->ik", mf ** 2, se2[s - 1]) + np.einsum(
                "ikm,m->ik", mr ** 2, se2[s])
            self.m_fall, self.m_rise = mf[-1], mr[-1]
            sm = mc - self.m_node
            big_t = max(float(self.t_motion[s - 1]), float(sm[-1]))
            return var_b, k2 * (sm ** 3 / 3.0 - sm ** 4 / (4.0 * big_t))
        if s == 0:  # before the first rest: its estimate, held back to the start
            mr = self.m_rise + np.cumsum(cd, axis=0)
            self.m_rise = mr[-1]
            # the first rest's bias applied back to the start: at motion time u of the x0
            # before that rest, Var ∫_0^u (W(τ) − W(x0)) dτ = K² (x0 u² − 2u³/3)
            x0m = max(x[0] - 0.5 * self.rests[0].duration_s, 0.0) if self.rests else 0.0
            um = np.minimum(mc, x0m)
            return (np.einsum("ikm,m->ik", mr ** 2, se2[0]),
                    k2 * (x0m * um ** 2 - 2.0 * um ** 3 / 3.0))
        # after the last rest: its estimate held
        mf = self.m_fall + np.cumsum(cd, axis=0)
        self.m_fall = mf[-1]
        return np.einsum("ikm,m->ik", mf ** 2, se2[nr - 1]), k2 * (mc - self.m_node) ** 3 / 3.0


class _Estimator:
    """The passes of :func:`estimate_offline` over the accepted rows."""

    def __init__(self, cfg, q_init, nav, algorithm, size, t, w, a, usable, sig2, act, mag=None,
                 empty=np.empty):
        self.empty = empty  # allocator of the outputs
        self.cfg, self.q_init, self.nav, self.algorithm = cfg, q_init, nav, algorithm
        self.size = size
        self.t, self.w, self.a, self.usable, self.sig2, self.act = t, w, a, usable, sig2, act
        self.mag = mag
        self.mag_counts = dict.fromkeys(_MAG_DETAILS, 0)
        self.field_reference: FieldReference | None = None
        self.all_usable = usable is not None and bool(usable.all())
        self.nav_series = None if nav is None else nav.series_length()
        self.rests: list[OfflineRest] = []
        self.notes: list[str] = []
        self.alignment: AlignmentResult | None = None
        lat = nav.latitude_rad if nav is not None else (
            cfg.latitude_rad if cfg.latitude_known else None)
        self.latitude = None if lat is None else float(np.asarray(lat).reshape(-1)[0])
        self.window_ns = int(round(cfg.rest_window_s * 1e9))
        self.fit_fallbacks: list[np.ndarray] = []  # rows whose interval's rate fit fell back
        self.k2 = 0.0  # the bias random walk's density², at least the stated one (rests)
        self._align_row = None  # the alignment's rest's first row

    # ------------------------------------------------------------------ the chain
    def run(self):
        m = self.t.size
        q_out = self.empty((m, 4), np.float64)
        var_out = self.empty((m, 3), np.float64)
        var_out.fill(0.0)
        codes = v.ACTION_CODES
        resets = np.flatnonzero(self.act == codes[v.RESET_TIME_JUMP])
        bounds = [0, *resets.tolist(), m]
        starts = np.flatnonzero(self.act != codes[v.ACCEPT])  # START, gap restarts, resets
        self.t_clock = sample_clock(self.t, starts, self.empty)  # intervals: jitter out
        for b0, b1 in zip(bounds[:-1], bounds[1:], strict=True):
            if b1 <= b0:
                continue
            s = starts[(starts >= b0) & (starts < b1)].tolist()
            runs = list(zip(s, [*s[1:], b1], strict=True))
            self._block(b0, b1, runs, q_out, var_out)
        cfg = self.cfg
        if not (self.sig2 is not None or cfg.gyro_noise_density > 0
                or cfg.gyro_bias_sigma_rad_s > 0 or cfg.levelling
                or any(r.gyro_var.any() for r in self.rests)):
            return q_out, None, None
        known = self.empty(m, bool)
        known.fill(True)
        return q_out, var_out, known

    def _block(self, b0, b1, runs, q_out, var_out):
        cfg = self.cfg
        tau = self._clock(b0, b1)
        rest = self._zeros(b1 - b0, bool)
        if cfg.gyro_bias is GyroBiasMode.AUTO or cfg.levelling or cfg.aiding is not Aiding.NONE:
            self._find_rests(b0, runs, rest)
        rests = self._rest_stats(b0, b1, rest, tau)
        self.rests += rests
        held = rest if cfg.gyro_bias is GyroBiasMode.AUTO else None  # the attitude held there
        tt0 = np.full(3, cfg.initial_attitude_variance)
        q_start = self.q_init
        if cfg.levelling:
            q_start, tt0[:2] = self._level_start(b0, rests)
        self._integrate(b0, runs, held, rests, tau, q_start, q_out)
        self._covariance(b0, b1, held, rests, tau, q_out, var_out, tt0)
        if self.a is not None and cfg.aiding is not Aiding.NONE:
            # every aiding: step 4 (the causal filters' differences are causal remedies)
            self._tilt_from_gravity(b0, b1, held, q_out, var_out)
        elif self.a is not None and cfg.levelling:
            self._level_at_rests(b0, b1, rests, tau, q_out)
        if cfg.aiding is Aiding.MAGNETOMETER:
            if self.mag is None:
                self.notes.append("aiding magnetometer without a field: heading gyro-only")
            else:
                self._heading_from_field(b0, b1, q_out, var_out)
                self._aligned_heading_from_field(b0, b1, q_out)

    def _level_start(self, b0, rests):
        """(attitude, tilt variance) a block starts from with ``initial_attitude`` level: its
        first rest with an accelerometer (the recording's first is the alignment), else the
        alignment's."""
        cfg = self.cfg
        r0 = next((r for r in rests if np.isfinite(r.accel_mean).all()), None)
        if r0 is None and self.alignment is None:
            raise ValueError(f"cannot align: no rest of at least {cfg.min_rest_s:g} s with a "
                             "usable accelerometer in the recording (initial_attitude 'level')")
        if r0 is None:
            return self.alignment.q_nb, self.alignment.level_error_expected ** 2
        heading = math.radians(cfg.initial_heading_deg)
        q_start, roll, pitch = level_quaternion(r0.accel_mean, heading)
        sl = math.sqrt(cfg.accel_bias_sigma ** 2 + float(np.mean(r0.accel_var[:2]))
                       / (r0.stop - r0.start)) / float(np.linalg.norm(r0.accel_mean))
        if self.alignment is None:
            self._align_row = b0 + r0.start
            self.alignment = AlignmentResult(
                q_start, roll, pitch, wrap_2pi(heading), "given", sl, math.nan,
                int(self.t[b0 + r0.start]), int(self.t[b0 + r0.stop - 1]), r0.stop - r0.start,
                r0.accel_mean, r0.bias)
        return q_start, sl * sl

    def _zeros(self, shape, dtype) -> np.ndarray:
        """A zeroed array from the allocator (the flags and clocks of a block's length)."""
        a = self.empty(shape, dtype)
        a.fill(0)
        return a

    def _clock(self, b0, b1) -> np.ndarray:
        """Seconds since the block's first row, gaps counted (the bias walks across them)."""
        tau = self.empty(b1 - b0, np.float64)
        for c0, c1 in _chunks(b0, b1, self.size):
            tau[c0 - b0:c1 - b0] = (self.t[c0:c1] - self.t[b0]) * 1e-9
        return tau

    # ------------------------------------------------------------------ 1. rests
    def _find_rests(self, b0, runs, rest):
        t, w, a, ok = self.t, self.w, self.a, self.usable
        min_ns = int(round(self.cfg.min_rest_s * 1e9))
        for r0, r1 in runs:
            pieces = [(r0, r1)]
            if ok is not None and not ok[r0:r1].all():
                pieces = [(r0 + p, r0 + q) for p, q in _segments(ok[r0:r1])]
            for p0, p1 in pieces:
                if p1 - p0 >= 2:
                    _rest_mask(t[p0:p1], w[p0:p1], None if a is None else a[p0:p1], self.cfg,
                               self.window_ns, min_ns, self.size, rest[p0 - b0:p1 - b0],
                               self._zeros)

    def _rest_stats(self, b0, b1, rest, tau) -> list[OfflineRest]:
        cfg = self.cfg
        out = []
        for s0, s1 in _segments(rest):
            if s1 - s0 < 3:  # (the span min_rest_s was tested on the rest as a whole)
                rest[s0:s1] = False  # too short to count: not a rest for any step
                continue
            mean_w, var_w = _mean_var(self.w, b0 + s0, b0 + s1, self.size)
            mean_f = var_f = np.full(3, np.nan)
            if self.a is not None and self.usable[b0 + s0:b0 + s1].all():
                mean_f, var_f = _mean_var(self.a, b0 + s0, b0 + s1, self.size)
                if self.latitude is not None:  # the vertical Earth rate along the measured up
                    up = mean_f / np.linalg.norm(mean_f)
                    mean_w = mean_w - OMEGA_IE * math.sin(self.latitude) * up
            out.append(OfflineRest(s0, s1, float(0.5 * (tau[s0] + tau[s1 - 1])),
                                   float(tau[s1 - 1] - tau[s0]), mean_w, None, mean_f, var_f,
                                   var_w))
        k2 = cfg.gyro_bias_rw ** 2
        out = _with_standard_errors(out, k2)
        # The rests' means differ by more than their white-noise errors when the bias wanders
        # (MEMS: temperature, flicker): the random walk K that explains the differences of
        # neighbouring rests, E[Δb²] = SE_j² + SE_{j+1}² + K² Δt, when it exceeds the stated one.
        if len(out) >= 2 and cfg.gyro_bias is GyroBiasMode.AUTO:
            d = [((r1.bias - r0.bias) ** 2 - r0.standard_error ** 2 - r1.standard_error ** 2)
                 / max(r1.tau_s - r0.tau_s, 1e-9) for r0, r1 in zip(out[:-1], out[1:],
                                                                    strict=True)]
            k2_seen = float(max(np.mean(d), 0.0))
            if k2_seen > k2:
                k2 = k2_seen
                self.notes.append(f"bias random walk {math.sqrt(k2):.2g} rad/s/√s from the "
                                  f"differences between the {len(out)} rests")
                out = _with_standard_errors(out, k2)
        self.k2 = max(k2, self.k2)
        return out

    # ------------------------------------------------------------------ 2.-3. bias, integration
    def _bias_rows(self, rests, tau_rows) -> np.ndarray:
        cfg = self.cfg
        if cfg.gyro_bias is GyroBiasMode.PARAMETER:
            return np.broadcast_to(np.asarray(cfg.gyro_bias_rad_s, dtype=np.float64),
                                   (tau_rows.size, 3))
        if cfg.gyro_bias is GyroBiasMode.NONE or not rests:
            return np.zeros((tau_rows.size, 3))
        xs = np.array([r.tau_s for r in rests])
        b = np.array([r.bias for r in rests])
        return np.column_stack([np.interp(tau_rows, xs, b[:, i]) for i in range(3)])

    def _integrate(self, b0, runs, rest, rests, tau, q_start, q_out):
        """``ω − b(t)`` integrated run by run (a gap holds the attitude), held at rests."""
        q_prev = q_start
        for r0, r1 in runs:
            cuts = [r0, r1]
            if rest is not None:  # pieces of motion and of rest
                mr = rest[r0 - b0:r1 - b0]
                cuts[1:1] = (np.flatnonzero(np.diff(mr.view(np.int8))) + 1 + r0).tolist()
            q_out[r0] = q_prev  # the run's first row: no interval before it
            for p0, p1 in zip(cuts[:-1], cuts[1:], strict=True):
                if rest is not None and rest[p0 - b0]:
                    q_out[p0:p1] = q_prev
                else:
                    self._integrate_piece(b0, p0 if p0 == r0 else p0 - 1, p0, p1, rests, tau,
                                          q_out)
                q_prev = q_out[p1 - 1]

    def _integrate_piece(self, b0, first, p0, p1, rests, tau, q_out):
        """Rows ``p0:p1`` from the attitude at row ``first`` (``p0`` or the row before), in
        chunks that reach _OVERLAP rows into their neighbours (the higher-order fits' samples)
        and are re-anchored at their first row, so that they join as one run does."""
        anchor = None  # the attitude at the chunk's first row, from the chunk before
        for c0, c1 in _chunks(p0, p1, self.size):
            lo, hi = max(first, c0 - _OVERLAP), min(p1, c1 + _OVERLAP)
            if hi - lo == 1:  # a run of one row: nothing to integrate
                continue
            wc = self.w[lo:hi] - self._bias_rows(rests, tau[lo - b0:hi - b0])
            nav = self.nav if self.nav_series is None else st.nav_rows(
                self.nav, np.arange(lo, hi), self.nav_series)
            fb = []
            q = integrate_batch(self.t_clock[lo:hi], wc, q0=q_out[lo], algorithm=self.algorithm,
                                nav=nav, fallbacks=fb)
            for f in fb:  # counted once: the intervals of the rows this chunk keeps
                r = f + lo
                self.fit_fallbacks.append(r[(r >= c0) & (r < c1)])
            if anchor is not None:
                q = quat_multiply(quat_multiply(anchor, quat_conjugate(q[c0 - lo])), q)
            w0 = lo if c0 == p0 else c0
            q_out[w0:c1] = q[w0 - lo:c1 - lo]
            anchor = q[c1 - lo] if c1 < p1 else None

    # ------------------------------------------------------------------ 4. tilt, 6. heading
    def _clock_steps(self, b0, c0, c1, still):
        """Steps (s) of the smoother's clock into each row of ``c0:c1``: the stamp step, 0 at
        the block's first row, at a gap restart and at a row of ``still`` (block-relative:
        the attitude is held there, its error cannot change)."""
        ds = np.empty(c1 - c0)
        ds[1:] = np.diff(self.t[c0:c1]) * 1e-9
        ds[0] = (self.t[c0] - self.t[c0 - 1]) * 1e-9 if c0 > b0 else 0.0
        ds[self.act[c0:c1] != v.ACTION_CODES[v.ACCEPT]] = 0.0
        if still is not None:
            ds[still[c0 - b0:c1 - b0]] = 0.0
        return ds

    def _zero_phase(self, b0, b1, tau_s, columns, apply, still=None):
        """The chain's one zero-phase smoother: the columns of ``columns(c0, c1)`` → (x (rows,
        K), extra), the last the sample's weight ``w``, averaged with the kernel
        ``e^(−|s_k − s_j|/τ)`` on the clock of :meth:`_clock_steps` as a first-order low-pass
        forward plus one backward (``Σ_{j≤k} + Σ_{j≥k} −`` the row itself).
        ``apply(c0, c1, sm, n_eff, extra)`` gets each chunk, last first: the columns scaled so
        that the weight column is 1 with every weight 1 on even stamps, and ``n_eff = (Σ k w)² /
        Σ k² w²`` (4τ/dt on even stamps).  The forward pass keeps its state at chunk starts (and
        its output while the block is short); the backward pass recomputes a chunk's forward
        part before ``apply`` of that chunk, so ``columns`` may read what ``apply`` of later
        chunks changed."""
        t = self.t
        dt = float(np.median(np.diff(t[b0:min(b1, b0 + 100_000)]))) * 1e-9 if b1 - b0 > 1 else 0.01
        alpha = math.exp(-max(dt, 1e-9) / tau_s)
        scale = (1.0 - alpha) / (1.0 + alpha)  # 1 / Σ k on even stamps
        chunks = list(_chunks(b0, b1, self.size))
        keep = b1 - b0 <= _KEEP_FORWARD

        def chunk_rows(c0, c1):
            """The columns and the squared weight (it rides with the squared kernel, τ/2)."""
            x, extra = columns(c0, c1)
            return (np.column_stack((x, x[:, -1] * x[:, -1])), self._clock_steps(b0, c0, c1, still),
                    extra)

        half = 0.5 * tau_s

        def run(ds, x, z):
            if z is None:
                z = (None, None)
            y1 = _decaying_sum(ds, x[:, :-1], tau_s, z[0])
            y2 = _decaying_sum(ds, x[:, -1:], half, z[1])
            # (copies: a view of the last row would keep the chunk's sums alive)
            return np.column_stack((y1, y2)), (y1[-1].copy(), y2[-1].copy())

        z = None
        states, kept = [], []
        for c0, c1 in chunks:  # forward
            states.append(z)
            xk = chunk_rows(c0, c1)
            _, z = run(xk[1], xk[0], z)
            kept.append(xk if keep else None)
        zb = None
        ds_next = 0.0  # the clock step into the row after the chunk (none after the block)
        for (c0, c1), zi, xk in zip(reversed(chunks), reversed(states), reversed(kept),
                                    strict=True):
            x, ds, extra = xk if xk is not None else chunk_rows(c0, c1)
            fwd, _ = run(ds, x, zi)
            # backward: the step from each row to the next, rows reversed
            yb, zb = run(np.concatenate(([ds_next], ds[:0:-1])), x[::-1], zb)
            ds_next = ds[0]
            sm = fwd + yb[::-1] - x  # Σ_{j≤k} + Σ_{j≥k} − the row itself
            s2, sw = sm[:, -1], sm[:, -2]
            n_eff = np.divide(sw * sw, s2, out=np.zeros_like(s2), where=s2 > 0.0)
            apply(c0, c1, sm[:, :-1] * scale, n_eff, extra)

    def _tilt_from_gravity(self, b0, b1, held, q_out, var_out):
        """Step 4, in place; the smoother's clock stops at ``held``."""
        cfg = self.cfg
        g0 = STANDARD_GRAVITY
        noise = [r.accel_var for r in self.rests if np.isfinite(r.accel_var).all()]
        sf2 = float(np.mean(noise)) if noise else 0.0  # per-axis accelerometer noise at rest
        floor = (cfg.accel_bias_sigma / g0) ** 2

        def columns(c0, c1):
            x = np.empty((c1 - c0, 4))
            if self.all_usable:
                x[:, :3] = _qrot(q_out[c0:c1], self.a[c0:c1])
                x[:, 3] = 1.0
            else:
                wt = self.usable[c0:c1]
                x[:, :3] = _qrot(q_out[c0:c1], np.where(wt[:, None], self.a[c0:c1], 0.0))
                x[:, 3] = wt
            return x, None

        def apply(c0, c1, sm, n_eff, _):
            den = sm[:, 3]
            okd = den > 1e-12
            # the smallest rotation taking the smoothed f_i to up (Σ w f_i: scale-free)
            u = np.where(okd[:, None], sm[:, :3], (0.0, 0.0, 1.0))
            q_out[c0:c1] = _level_left(u, q_out[c0:c1])
            # the accelerometer-bias floor plus its noise over the samples averaged
            tilt = floor + sf2 / (g0 * g0) / np.maximum(n_eff, 1.0)
            var_out[c0:c1, :2] = np.where(okd[:, None], tilt[:, None], var_out[c0:c1, :2])

        self._zero_phase(b0, b1, cfg.offline_tilt_tau_s, columns, apply, still=held)
        self.notes.append(f"tilt from gravity: zero-phase low-pass, τ = "
                          f"{cfg.offline_tilt_tau_s:g} s")

    def _field_rows(self, raw, q):
        """The field ``raw`` less the hard iron, rotated into the output frame by ``q`` (zeros
        where unusable), its norm, and which rows are usable / missing: the one validity rule
        of the heading pass and of the reference it learns (a zero reading must not vote)."""
        missing = np.isnan(raw).all(axis=1)
        with np.errstate(invalid="ignore", over="ignore"):
            ok = np.isfinite(raw).all(axis=1) & (np.abs(raw).max(axis=1) <= MAG_ABSURD_T)
            ok &= np.einsum("ij,ij->i", raw, raw) >= MAG_ZERO_T * MAG_ZERO_T
        m = np.where(ok[:, None], raw - np.asarray(self.field_reference.hard_iron), 0.0)
        norm = np.sqrt(np.einsum("ij,ij->i", m, m))
        ok &= norm >= MAG_ZERO_T  # (almost) zero once the hard iron is taken out: no reading
        return _qrot(q, m), norm, ok, missing

    def _count_field(self, ok, missing, good=None):
        """A chunk's field samples counted: missing, invalid (neither ``ok`` nor missing) and,
        with the reference's verdict ``good``, disturbed (``ok`` and not ``good``)."""
        self.mag_counts[st.MAG_MISSING] += int(np.count_nonzero(missing))
        self.mag_counts[st.INVALID_MAG] += int(np.count_nonzero(~ok & ~missing))
        if good is not None:
            self.mag_counts[st.MAG_DISTURBED] += int(np.count_nonzero(ok & ~good))

    def _field_reference(self, b0, b1, q_out) -> FieldReference:
        """Norm and dip of the undisturbed field: ``mag_reference_enu_t`` when given, else the
        medians over (a spread sample of) the usable field in the tilt-corrected output frame
        -- the whole recording votes, so a disturbance shorter than half of it cannot become
        the reference (the causal stage must learn it from the first second)."""
        cfg = self.cfg
        ref = FieldReference(hard_iron=tuple(float(x) for x in cfg.mag_hard_iron_t))
        given = np.asarray(cfg.mag_reference_enu_t, dtype=np.float64)
        if np.any(given != 0.0):
            ref.mag_ref_norm = float(np.linalg.norm(given))
            ref.mag_ref_dip = math.atan2(-given[2], math.hypot(given[0], given[1]))
            return ref
        self.field_reference = ref  # the hard iron, for _field
        step = max(1, (b1 - b0) // _REFERENCE_SAMPLES)
        pick = np.arange(b0, b1, step)
        if pick.size:
            mn, norm, ok, _ = self._field_rows(self.mag[pick], q_out[pick])
            if np.count_nonzero(ok) >= 10:
                ref.mag_ref_norm = float(np.median(norm[ok]))
                ref.mag_ref_dip = float(np.median(np.arctan2(-mn[ok, 2], np.hypot(mn[ok, 0],
                                                                                  mn[ok, 1]))))
                ref.learned = True
        return ref

    def _heading_from_field(self, b0, b1, q_out, var_out):
        """Step 6: the field's horizontal direction in the tilt-corrected output frame, less the
        declination, smoothed zero-phase with weight 1 where the field agrees with the reference;
        the smoothed azimuth is the heading error, taken out about the vertical on the left."""
        cfg = self.cfg
        if self.field_reference is None or self.field_reference.mag_ref_norm is None:
            self.field_reference = self._field_reference(b0, b1, q_out)
        ref = self.field_reference
        if ref.mag_ref_norm is None:
            self.notes.append("magnetometer: too few usable field samples to learn the "
                              "reference: heading gyro-only")
            for c0, c1 in _chunks(b0, b1, self.size):  # no reference: none is disturbed
                self._count_field(*self._field_rows(self.mag[c0:c1], _IDENTITY)[2:])
            return
        ref_n, ref_d = ref.mag_ref_norm, ref.mag_ref_dip
        tol_n, tol_d = cfg.mag_norm_tol * ref_n, math.radians(cfg.mag_dip_tol_deg)
        decl = math.radians(cfg.magnetic_declination_deg)
        cd, sd = math.cos(decl), math.sin(decl)
        coupling = math.tan(min(abs(ref_d), math.radians(89.0))) ** 2

        def columns(c0, c1):
            """(sin, cos) of each sample's azimuth less the declination and its weight; and
            (them, the usable and missing rows) for ``apply``."""
            mn, norm, ok, missing = self._field_rows(self.mag[c0:c1], q_out[c0:c1])
            horiz = np.hypot(mn[:, 0], mn[:, 1])
            dip = np.arctan2(-mn[:, 2], horiz)
            good = ok & (np.abs(norm - ref_n) <= tol_n) & (np.abs(dip - ref_d) <= tol_d)
            good &= horiz >= 1e-3 * norm  # at a magnetic pole the field gives no heading
            hx = np.divide(mn[:, 0], horiz, out=np.zeros_like(horiz), where=good)
            hy = np.divide(mn[:, 1], horiz, out=np.zeros_like(horiz), where=good)
            ex, ey = hx * cd - hy * sd, hy * cd + hx * sd
            return np.column_stack((ex, ey, good.astype(np.float64))), (ex, ey, good, ok, missing)

        scatter = [None]  # the last measured azimuth scatter about the smoothed one (rad²)

        def apply(c0, c1, sm, n_eff, extra):
            ex, ey, good, ok, missing = extra
            self._count_field(ok, missing, good)
            den = sm[:, 2]
            okd = den > _MAG_WEIGHT_MIN
            err = np.where(okd, np.arctan2(sm[:, 0], sm[:, 1]), 0.0)
            # the correction R_z(err) on the left: the smoothed field direction to north
            qz = np.zeros((c1 - c0, 4))
            qz[:, 2] = np.sin(0.5 * err)
            qz[:, 3] = np.cos(0.5 * err)
            q_out[c0:c1] = _qmul(qz, q_out[c0:c1])
            # heading variance: the azimuth scatter of the samples over the n_eff the smoother
            # averages, plus the tilt error about north seen through the dip (δψ = tan(dip) δθ_N)
            if good.any():
                r = (np.arctan2(ex[good], ey[good]) - err[good] + math.pi) % (2 * math.pi) \
                    - math.pi
                scatter[0] = float(np.mean(r * r))
            if scatter[0] is not None:
                head = scatter[0] / np.maximum(n_eff, 1.0) + coupling * var_out[c0:c1, 1]
                var_out[c0:c1, 2] = np.where(okd, head, var_out[c0:c1, 2])

        self._zero_phase(b0, b1, cfg.offline_mag_tau_s, columns, apply)
        if cfg.mag_hard_iron_estimate and not any("hard iron" in n for n in self.notes):
            self.notes.append("mag_hard_iron_estimate: the offline estimator does not estimate "
                              "the hard iron; the given mag_hard_iron_t is used (--estimator "
                              "causal estimates it)")
        self.notes.append(f"heading from the magnetometer: zero-phase low-pass, τ = "
                          f"{cfg.offline_mag_tau_s:g} s; reference |B| {ref_n * 1e6:.1f} µT, dip "
                          f"{math.degrees(ref_d):.1f}° ("
                          + ("learned: medians over the recording" if ref.learned else "given")
                          + ")")

    def _aligned_heading_from_field(self, b0, b1, q_out):
        """The alignment's heading is the field's once the heading pass has run over the
        levelling rest (not the ``initial_heading_deg`` the start was levelled with)."""
        row, a = self._align_row, self.alignment
        if a is None or not b0 <= row < b1 or a.heading_source != "given":
            return
        c = quat_as_matrix(q_out[row])
        heading = wrap_2pi(math.pi / 2 - math.atan2(float(c[1, 0]), float(c[0, 0])))
        self.alignment = replace(a, q_nb=q_out[row].copy(), heading=heading,
                                 heading_source="magnetometer")

    def _level_at_rests(self, b0, b1, rests, tau, q_out):
        """Levelling at every rest, the correction interpolated in time between rests."""
        with_f = [r for r in rests if np.isfinite(r.accel_mean).all()]
        if not with_f:
            return
        xs = np.array([r.tau_s for r in with_f])
        # the correction of each rest as a rotation vector, interpolated between rests
        f = np.array([quat_rotate(q_out[b0 + r.start], r.accel_mean) for r in with_f])
        cx, cy, cw = _up_correction(f)
        rv = quat_as_rotvec(np.column_stack((cx, cy, np.zeros_like(cx), cw)))
        for c0, c1 in _chunks(b0, b1, self.size):
            tr = tau[c0 - b0:c1 - b0]
            r = np.column_stack([np.interp(tr, xs, rv[:, i]) for i in range(3)])
            q_out[c0:c1] = quat_multiply(quat_from_rotvec(r), q_out[c0:c1])
        self.notes.append(f"levelled at {len(with_f)} rest(s)")

    # ------------------------------------------------------------------ 5. covariance
    def _covariance(self, b0, b1, rest, rests, tau, q_out, var_out, tt0):
        """Gyro-only error variance per output axis (step 5), propagated over blocks of
        _COV_BLOCK rows (C_nb and the bias clock at each block's middle row) and interpolated
        linearly to the rows in between."""
        cfg = self.cfg
        size = max(_COV_BLOCK, self.size // _COV_BLOCK * _COV_BLOCK)  # blocks never straddle
        bias = _BiasTerms(rests if cfg.gyro_bias is GyroBiasMode.AUTO else None,
                          cfg.gyro_bias_sigma_rad_s, self.k2)
        rr = [r for r in (rests or self.rests) if r.stop - r.start > 1]  # the noise at rests
        measured = np.average([r.gyro_var for r in rr], axis=0,
                              weights=[r.stop - r.start for r in rr]) if rr else None
        sf2 = cfg.gyro_scale_factor_sigma ** 2
        # ∫ C_nb[k, m] ω_n dτ: the lever of the gyro's gain-and-axes error E[m, n] (never reset)
        m_sf = np.zeros((3, 3, 3))
        arw = np.zeros(3)
        prev_end = tt0.copy()  # variance at the row before the chunk
        for c0, c1 in _chunks(b0, b1, size):
            nrow = c1 - c0
            dt, s2 = self._row_noise(b0, c0, c1, rest, measured)
            nodes = np.arange(0, nrow, _COV_BLOCK)
            mid = np.minimum(nodes + _COV_BLOCK // 2, nrow - 1)
            dtb = np.add.reduceat(dt, nodes)
            c = quat_as_matrix(q_out[c0 + mid])  # C_nb (rows: output axes)
            out = tt0 + arw + np.cumsum(np.einsum("ikm,im->ik", c * c,
                                                  np.add.reduceat(s2, nodes, axis=0)), axis=0)
            arw = out[-1] - tt0
            if sf2 > 0:  # δθ = ∫ C_nb E ω dτ, every element of E of 1σ gyro_scale_factor_sigma
                turn = np.add.reduceat(self.w[c0:c1] * dt[:, None], nodes, axis=0)
                msf = m_sf + np.cumsum(c[:, :, :, None] * turn[:, None, None, :], axis=0)
                out += sf2 * np.einsum("ikmn,ikmn->ik", msf, msf)
                m_sf = msf[-1]
            out += bias.blocks(c, dtb, tau[c0 - b0 + mid])
            # out[i] is the variance after block i (at its last row); rows in between linearly
            last = np.minimum(nodes + _COV_BLOCK, nrow) - 1
            xs_r = np.concatenate(([-1], last))
            row_ix = np.arange(nrow)
            for k in range(3):
                var_out[c0:c1, k] = np.interp(row_ix, xs_r, np.concatenate(([prev_end[k]],
                                                                           out[:, k])))
            prev_end = out[-1].copy()

    def _row_noise(self, b0, c0, c1, rest, measured):
        """(dt, angle-noise variance per row and axis) of rows ``c0:c1``: the gyro noise from
        the messages, else the density, else the scatter measured at rests; the time is the
        smoother's clock (none passes at a gap or a rest: the attitude is held)."""
        dt = self._clock_steps(b0, c0, c1, rest)
        n2 = self.cfg.gyro_noise_density ** 2
        if self.sig2 is not None:
            s2 = np.where(self.sig2[1][c0:c1, None], self.sig2[0][c0:c1], 0.0) * (
                dt * dt)[:, None]
        elif n2 > 0:
            s2 = (n2 * dt)[:, None] * np.ones(3)
        elif measured is not None:
            s2 = measured[None, :] * (dt * dt)[:, None]
        else:
            s2 = np.zeros((c1 - c0, 3))
        return dt, s2

    # ------------------------------------------------------------------ report
    def bias_report(self) -> GyroBiasReport:
        cfg = self.cfg
        if cfg.gyro_bias is GyroBiasMode.PARAMETER:
            return GyroBiasReport("parameter", np.asarray(cfg.gyro_bias_rad_s, float), 0, 0,
                                  np.full(3, np.nan), False, "fixed parameter")
        if cfg.gyro_bias is GyroBiasMode.NONE or not self.rests:
            note = "no rest found: bias 0" if cfg.gyro_bias is GyroBiasMode.AUTO \
                else "not estimated"
            return GyroBiasReport(cfg.gyro_bias.value, np.zeros(3), 0, 0, np.full(3, np.nan),
                                  False, note)
        n = np.array([r.stop - r.start for r in self.rests], dtype=np.float64)
        b = np.average([r.bias for r in self.rests], axis=0, weights=n)
        se = np.sqrt(np.average([r.standard_error ** 2 for r in self.rests], axis=0,
                                weights=n * n) / len(self.rests))
        earth = self.latitude is not None and self.a is not None
        return GyroBiasReport("auto", b, len(self.rests), int(n.sum()), se, earth,
                              f"offline: one estimate per rest ({len(self.rests)}), interpolated "
                              "in time between rests, the value shown is their mean; "
                              + ("vertical Earth rate removed at each rest" if earth else
                                 "Earth rate absorbed into the bias (latitude unknown)"))


def count_saturated(tv: np.ndarray, wv: np.ndarray, counts: dict, details: dict,
                    chunk: int) -> None:
    """Accepted rows (stamps ``tv``, rates ``wv``) pinned on a plateau of an axis: one value
    held at the largest magnitude the axis ever reaches (at least SATURATION_MIN_RAD_S) for
    SATURATION_PLATEAU_NS up to the row -- the causal step's rule with the whole recording's
    largest value (a repeated local peak is no clip).  ``chunk`` rows at a time."""
    n = wv.shape[0]
    top = np.zeros(3)
    for c0 in range(0, n, chunk):
        np.maximum(top, np.abs(wv[c0:c0 + chunk]).max(axis=0, initial=0.0), out=top)
    pinned = set()
    first = None
    for axis in np.flatnonzero(top >= SATURATION_MIN_RAD_S).tolist():
        # the rows at the top: few (a clip, a peak), found a chunk at a time
        at_top = np.concatenate([np.flatnonzero(np.abs(wv[c0:c0 + chunk, axis]) == top[axis])
                                 + c0 for c0 in range(0, n, chunk)])
        for k in at_top.tolist():
            x = wv[k, axis]
            j = k
            while j > 0 and wv[j - 1, axis] == x:  # where this value began
                j -= 1
            if tv[k] - tv[j] >= SATURATION_PLATEAU_NS:
                pinned.add(k)
                if first is None or k < first[0]:
                    first = (k, axis, float(x))
    counts[st.SATURATED] = len(pinned)
    if first is not None:
        details.setdefault(st.SATURATED, st.saturation_note(first[1], first[2]))
