"""Static self-alignment at the first rest: levelling from the mean specific force, the heading
given, gyrocompassed or from the mean field, each with its expected error (docs/
architecture.md, "Notes: the estimator's stages").  The kernel :func:`aligner_update` once per
accepted sample (accelerometer required) on the record :func:`aligner_start` makes says when
the first rest of at least ``min_rest_s`` has ended; :func:`aligner_result` then aligns."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gyro_attitude.core.angles import wrap_2pi
from gyro_attitude.core.attitude.ahrs import MAG_ABSURD_T, MAG_ZERO_T
from gyro_attitude.core.attitude.modes import Aiding, GyroBiasMode, HeadingSource
from gyro_attitude.core.attitude.rest import (
    R_AT_REST,
    R_HEAD,
    R_OLDEST,
    RING_FIELDS,
    rest_reset,
    rest_start,
    rest_update,
)
from gyro_attitude.core.attitude.settings import StreamConfig
from gyro_attitude.core.attitude.validation import within
from gyro_attitude.core.earth import OMEGA_IE, check_latitude
from gyro_attitude.core.jit import kernel

__all__ = ["AlignmentResult", "aligner_start", "heading_of", "level_q", "level_quaternion"]


@dataclass(frozen=True)
class AlignmentResult:
    """Initial attitude and how well it is known (angles in rad, 1σ expected errors)."""

    q_nb: np.ndarray  # (4,) x, y, z, w
    roll: float
    pitch: float
    heading: float  # clockwise from north, [0, 2π)
    heading_source: str  # HEADING_SOURCES
    level_error_expected: float
    heading_error_expected: float  # NaN for a given heading (the caller knows its quality)
    rest_start_ns: int
    rest_end_ns: int
    samples: int
    mean_specific_force: np.ndarray  # (3,) m/s²
    mean_rate: np.ndarray  # (3,) rad/s, raw (bias not removed)
    # heading from the field: the mean field over the rest (tesla, body, hard iron removed)
    # and how many rest samples had one; None, 0 otherwise
    mean_magnetic_field: np.ndarray | None = None
    mag_samples: int = 0


@kernel
def level_q(fx, fy, fz, heading):
    """``(usable, x, y, z, w, roll, pitch)``: ``q_nb = Rz(π/2 − heading) Ry(pitch) Rx(roll)``
    with body z along the measured up ``f``; not usable (the identity) when ``f`` is no
    gravity measurement."""
    if not (math.isfinite(fx * fy * fz) and fx * fx + fy * fy + fz * fz >= 1.0):
        return False, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0
    roll = math.atan2(fy, fz)
    pitch = math.atan2(-fx, math.hypot(fy, fz))
    psi = math.pi / 2 - heading
    # Rz(ψ) Ry(θ) Rx(φ) as the product of the three half-angle quaternions (a matrix and
    # quat_from_matrix cost ~30× more)
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cz, sz = math.cos(psi / 2), math.sin(psi / 2)
    x = cz * cp * sr - sz * sp * cr
    y = cz * sp * cr + sz * cp * sr
    z = sz * cp * cr - cz * sp * sr
    w = cz * cp * cr + sz * sp * sr
    if w < 0:  # w >= 0, as quat_from_matrix gives
        return True, -x, -y, -z, -w, roll, pitch
    return True, x, y, z, w, roll, pitch


def heading_of(q_nb) -> float:
    """The heading (rad, clockwise from north: ENU's y axis) of the body x axis of ``q_nb``
    (x, y, z, w): the ``heading`` that :func:`level_q` gives that axis."""
    x, y, z, w = (float(c) for c in q_nb)
    east = 1.0 - 2.0 * (y * y + z * z)
    north = 2.0 * (x * y + z * w)
    return math.atan2(east, north)


def level_quaternion(f_b, heading: float) -> tuple[np.ndarray, float, float]:
    """``(q_nb, roll, pitch)`` of :func:`level_q`, run by the interpreter (one call is not worth
    loading the compiled form)."""
    fx, fy, fz = (float(c) for c in f_b)
    ok, x, y, z, w, roll, pitch = level_q(fx, fy, fz, float(heading))
    if not ok:
        raise ValueError(f"specific force {f_b!r} is not a usable gravity measurement")
    return np.array([x, y, z, w]), roll, pitch


def aligner_start(cfg: StreamConfig, latitude_rad: float | None = None) -> np.recarray:
    """The aligner's record (:data:`ALIGNER_DTYPE`, one) of ``cfg`` before the first sample
    (gyrocompass at ``latitude_rad``)."""
    gc = cfg.heading_source is HeadingSource.GYROCOMPASS
    if gc and latitude_rad is None:
        raise ValueError("gyrocompass alignment needs the latitude (frame enu or latitude_rad)")
    record = np.zeros(1, ALIGNER_DTYPE).view(np.recarray)
    r = record[0]
    r.heading = wrap_2pi(math.radians(cfg.initial_heading_deg))
    r.gyrocompass = gc
    r.lat = float(check_latitude(float(latitude_rad), "latitude_rad")) if gc else 0.0
    r.bias = cfg.gyro_bias_rad_s if cfg.gyro_bias is GyroBiasMode.PARAMETER else (0.0, 0.0, 0.0)
    r.bias_sigma = cfg.gyro_bias_sigma_rad_s if gc else 0.0
    r.accel_bias_sigma = cfg.accel_bias_sigma
    r.limit = math.radians(cfg.heading_error_limit_deg)
    r.min_rest_ns = int(round(cfg.min_rest_s * 1e9))
    r.mag_heading = cfg.aiding is Aiding.MAGNETOMETER
    r.decl = math.radians(cfg.magnetic_declination_deg)
    r.hard_iron = cfg.mag_hard_iron_t
    r.given_heading_var = float(np.broadcast_to(cfg.initial_attitude_variance, (3,))[2])
    r.rest_f, r.rest_i = rest_start(cfg)
    r.last_acc = -1
    return record


def alignment_result(r) -> AlignmentResult:
    """The :class:`AlignmentResult` of an aligner record that aligned."""
    return AlignmentResult(
        np.array(r.q), float(r.roll), float(r.pitch), float(r.heading_out),
        HEADING_SOURCES[int(r.source)], float(r.level_err), float(r.heading_err), int(r.t0),
        int(r.t1), int(r.n), np.array(r.mean_f), np.array(r.mean_w),
        np.array(r.mean_m) if r.has_mean_m else None, int(r.n_m) if r.has_mean_m else 0)


def failure_words(r, failed: int) -> str:
    """Why the aligner record's alignment failed (:func:`aligner_result`'s code), in words."""
    if failed == ALIGN_FAILED_GYROCOMPASS:
        return (f"gyrocompass refused: expected heading error {math.degrees(r.heading_err):.3g}° "
                f"exceeds the limit {math.degrees(r.limit):.3g}° (gyro bias uncertainty "
                f"{math.degrees(r.bias_sigma) * 3600:.3g} °/h against a horizontal Earth rate of "
                f"{math.degrees(r.fail_horizontal) * 3600:.3g} °/h at this latitude); give the "
                "heading")
    return (f"specific force {np.array(r.mean_f)!r} is not a usable gravity measurement")


# ---------------------------------------------------------------------------- the step's form
#: :func:`aligner_result` failures: the gyrocompass refused (its expected heading error beyond
#: the limit), the mean specific force no gravity measurement
ALIGN_FAILED_GYROCOMPASS, ALIGN_FAILED_GRAVITY = 1, 2
#: heading sources of :data:`ALIGNER_DTYPE` (AlignmentResult.heading_source)
HEADING_SOURCES = ("given", "gyrocompass", "magnetometer")
F, W, M = 0, 1, 2  # the rows of the aligner's sums

#: the aligner's rest window: the detector's ring (stamp, index, running sums) and each
#: sample's rate, specific force and usable field (less the hard iron)
ALIGN_RING_DTYPE = np.dtype([*RING_FIELDS, ("g", np.float64, (3,)), ("a", np.float64, (3,)),
                             ("m", np.float64, (3,)), ("hm", np.bool_)])

#: the aligner as one record: its options, its rest detector, the open rest's sums and, once
#: done, the alignment
ALIGNER_DTYPE = np.dtype([
    # options
    ("heading", np.float64), ("gyrocompass", np.bool_), ("lat", np.float64),
    ("bias", np.float64, (3,)), ("bias_sigma", np.float64), ("accel_bias_sigma", np.float64),
    ("limit", np.float64), ("min_rest_ns", np.int64), ("mag_heading", np.bool_),
    ("decl", np.float64), ("hard_iron", np.float64, (3,)), ("given_heading_var", np.float64),
    # the detector and the open rest
    ("rest_f", np.float64, (32,)), ("rest_i", np.int64, (10,)), ("last_acc", np.int64),
    ("has_seg", np.bool_), ("t0", np.int64), ("t1", np.int64), ("n", np.int64),
    ("n_m", np.int64), ("done", np.bool_),
    # rows F, W, M (specific force, rate, field): reference, Σ d, Σ d² of d = v − reference
    ("ref", np.float64, (3, 3)), ("s1", np.float64, (3, 3)), ("s2", np.float64, (3, 3)),
    # the alignment (AlignmentResult) and its per-axis variance
    ("aligned", np.bool_), ("q", np.float64, (4,)), ("roll", np.float64),
    ("pitch", np.float64), ("heading_out", np.float64), ("source", np.int64),
    ("level_err", np.float64), ("heading_err", np.float64), ("mean_f", np.float64, (3,)),
    ("mean_w", np.float64, (3,)), ("mean_m", np.float64, (3,)), ("has_mean_m", np.bool_),
    ("variance", np.float64, (3,)), ("level_var", np.float64), ("fail_horizontal", np.float64),
])


@kernel
def aligner_break(al):
    """The stream broke (gap, time jump, unusable accelerometer sample): the alignment needs
    one unbroken rest, so an open rest is discarded and the window starts afresh."""
    rest_reset(al.rest_f, al.rest_i)
    al.has_seg = False
    al.last_acc = -1


@kernel(inline=True)
def _sums_add(al, row, v):
    for i in range(3):
        d = v[i] - al.ref[row, i]
        al.s1[row, i] += d
        al.s2[row, i] += d * d


@kernel
def _aligner_add(al, t, g, a, hm, m):
    """A rest sample into the open rest's sums."""
    if not al.has_seg:
        al.has_seg, al.t0, al.n, al.n_m = True, t, 0, 0
        al.s1[:] = 0.0
        al.s2[:] = 0.0
        for i in range(3):
            al.ref[F, i], al.ref[W, i] = a[i], g[i]
    if hm:
        if al.n_m == 0:
            for i in range(3):
                al.ref[M, i] = m[i]
        al.n_m += 1
        _sums_add(al, M, m)
    al.t1 = t
    al.n += 1
    _sums_add(al, F, a)
    _sums_add(al, W, g)


@kernel
def aligner_update(al, ring, t, g0, g1, g2, a0, a1, a2, has_m, m0, m1, m2):
    """One sample (``has_m``: with the field ``m``, tesla) into the aligner's record ``al`` and
    its rest window's ``ring``: (the detector's code, <0 a refusal with nothing changed;
    whether the first qualifying rest has ended)."""
    if al.done:
        return 0, True
    slot = rest_update(al.rest_f, al.rest_i, ring.t, ring.x, ring.c, t, g0, g1, g2, True, a0,
                       a1, a2)
    if slot < 0:
        return slot, False
    e = ring[slot]
    e.g[0], e.g[1], e.g[2] = g0, g1, g2
    e.a[0], e.a[1], e.a[2] = a0, a1, a2
    e.hm = al.mag_heading and has_m and within(m0, m1, m2, MAG_ABSURD_T) and \
        m0 * m0 + m1 * m1 + m2 * m2 >= MAG_ZERO_T * MAG_ZERO_T
    if e.hm:
        e.m[0], e.m[1], e.m[2] = m0 - al.hard_iron[0], m1 - al.hard_iron[1], m2 - al.hard_iron[2]
    j = al.rest_i[R_OLDEST]
    if al.rest_i[R_AT_REST] == 1:
        if j > al.last_acc:
            al.last_acc = j
            h = ring[al.rest_i[R_HEAD]]
            _aligner_add(al, h.t, h.g, h.a, h.hm, h.m)
    elif al.has_seg:
        if al.t1 - al.t0 >= al.min_rest_ns:
            al.done = True
        else:
            al.has_seg = False  # too short: wait for a longer rest
    return 0, al.done


@kernel(inline=True)
def _level_frame(roll, pitch, x, y, z):
    """``C_lb v``: body → level frame (yaw 0), Ry(pitch) Rx(roll)."""
    cr, sr, cp, sp = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch)
    return (cp * x + sp * sr * y + sp * cr * z, cr * y - sr * z,
            -sp * x + cp * sr * y + cp * cr * z)


@kernel(inline=True)
def _var(al, row, n, i):
    return max(al.s2[row, i] - al.s1[row, i] * al.s1[row, i] / n, 0.0) / max(n - 1, 1)


@kernel
def aligner_result(al):
    """The alignment over the rest into the record's result fields: 0, or why it failed
    (:data:`ALIGN_FAILED_GYROCOMPASS`, :data:`ALIGN_FAILED_GRAVITY`)."""
    n = al.n
    for i in range(3):
        al.mean_f[i] = al.ref[F, i] + al.s1[F, i] / n
        al.mean_w[i] = al.ref[W, i] + al.s1[W, i] / n
    f0, f1, f2 = al.mean_f[0], al.mean_f[1], al.mean_f[2]
    g = math.sqrt(f0 * f0 + f1 * f1 + f2 * f2)
    heading = al.heading
    ok, _, _, _, _, roll, pitch = level_q(f0, f1, f2, heading)
    if not ok:
        return ALIGN_FAILED_GRAVITY
    var_f = 0.5 * (_var(al, F, n, 0) + _var(al, F, n, 1))
    sigma_level = math.sqrt(al.accel_bias_sigma ** 2 + var_f / n) / g
    source = 0
    sigma_heading = math.nan
    if al.gyrocompass:
        horizontal = OMEGA_IE * math.cos(al.lat)
        var_w = 0.5 * (_var(al, W, n, 0) + _var(al, W, n, 1))
        sigma_heading = math.sqrt((al.bias_sigma ** 2 + var_w / n) / max(horizontal, 1e-300) ** 2
                                  + (sigma_level * math.tan(al.lat)) ** 2)
        if not sigma_heading <= al.limit:
            al.heading_err, al.fail_horizontal = sigma_heading, horizontal
            return ALIGN_FAILED_GYROCOMPASS
        # heading from the bias-free mean rate at rest: in the levelled frame the horizontal
        # Earth rate is ω_ie cos L · [sin ψ, cos ψ], so ψ = atan2(ω_x, ω_y)
        wl0, wl1, _ = _level_frame(roll, pitch, al.mean_w[0] - al.bias[0],
                                   al.mean_w[1] - al.bias[1], al.mean_w[2] - al.bias[2])
        heading = (math.pi / 2 - math.atan2(wl0, wl1)) % (2.0 * math.pi)
        source = 1
    al.has_mean_m = False
    if al.mag_heading and al.n_m > 0:
        nm = al.n_m
        for i in range(3):
            al.mean_m[i] = al.ref[M, i] + al.s1[M, i] / nm
        al.has_mean_m = True
        mm0, mm1, mm2 = al.mean_m[0], al.mean_m[1], al.mean_m[2]
        ml0, ml1, ml2 = _level_frame(roll, pitch, mm0, mm1, mm2)
        horizontal = math.hypot(ml0, ml1)
        if horizontal >= 1e-3 * math.sqrt(mm0 * mm0 + mm1 * mm1 + mm2 * mm2):  # not at a pole
            # in the yaw-0 level frame the horizontal field lies atan2(−m_y, m_x) clockwise of
            # the body x axis; the x axis is at heading h, the field at the declination
            heading = (al.decl - math.atan2(-ml1, ml0)) % (2.0 * math.pi)
            source = 2
            tan_dip = abs(ml2) / horizontal
            var_m = (_var(al, M, nm, 0) + _var(al, M, nm, 1) + _var(al, M, nm, 2)) / 3.0
            sigma_heading = math.sqrt(var_m / nm / horizontal ** 2
                                      + (tan_dip * sigma_level) ** 2)
    _, x, y, z, w, roll, pitch = level_q(f0, f1, f2, heading)  # (roll, pitch: the same)
    al.q[0], al.q[1], al.q[2], al.q[3] = x, y, z, w
    al.roll, al.pitch, al.heading_out, al.source = roll, pitch, heading, source
    al.level_err, al.heading_err = sigma_level, sigma_heading
    # per-axis variance of the levelled attitude: levelling on the tilt axes, the heading's
    # (given or measured) on the vertical one; q_nb = Rz(ψ) Ry(θ) Rx(φ): a roll error δφ is a
    # rotation about Rz Ry(θ) e_x, whose vertical component −sin θ·δφ turns the heading too
    lv = sigma_level * sigma_level
    heading_var = al.given_heading_var if source == 0 else sigma_heading * sigma_heading
    s_p = math.sin(pitch)
    al.variance[0], al.variance[1], al.variance[2] = lv, lv, heading_var + s_p * s_p * lv
    al.level_var = lv
    al.aligned = True
    return 0
