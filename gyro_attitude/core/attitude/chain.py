"""The causal estimator's one step, in the shape of VQF's core: the settings as coefficients
(:data:`COEF_DTYPE`), everything carried between samples as one record (:data:`STATE_DTYPE`),
:func:`step` chaining the stages for one Imu sample (validate → rest → gyro bias → alignment
→ aiding → integrate → covariance) and :func:`run_rows`, a recording as the same step in a
compiled loop.  Three rings hold the rest windows' samples; a full one is the step's code
(nothing changed: the caller doubles it and steps again).  What a sample did leaves as codes
(verdict, reason, event bits), the words are made at the edge (:mod:`.stream`).  Every
function here is a kernel (:mod:`gyro_attitude.core.jit`)."""

from __future__ import annotations

import math
from enum import IntEnum

import numpy as np

from gyro_attitude.core.attitude.ahrs import (
    I_AIDED,
    I_HAS_LAST,
    MAG_ABSENT,
    MAG_GIVEN,
    ahrs_step,
    c_nb,
    heading_from_field,
)
from gyro_attitude.core.attitude.algorithm import CUBIC, EXP
from gyro_attitude.core.attitude.alignment import (
    ALIGNER_DTYPE,
    aligner_break,
    aligner_result,
    aligner_update,
    level_q,
)
from gyro_attitude.core.attitude.compose import exp_scalar, qmul_scalar
from gyro_attitude.core.attitude.covariance import (
    V_TT,
    aid_tilt,
    first_rest_update,
    propagate,
    reset_attitude,
    zero_rate_update,
)
from gyro_attitude.core.attitude.gyro_bias import (
    B_BIAS,
    B_SE,
    J_HAS_SEG,
    J_POOL_K,
    J_SEG_T0,
    J_UPDATED,
    bias_break,
    bias_step,
)
from gyro_attitude.core.attitude.rest import R_COUNT, R_WINDOW_NS, RING_FIELDS, RING_FULL
from gyro_attitude.core.attitude.streaming import (
    C_FALLBACKS,
    C_HAS_LAST,
    C_LAST_T,
    rate_advance,
    rate_reset,
)
from gyro_attitude.core.attitude.validation import (
    A_ACCEPT,
    A_REJECT,
    A_RESET_TIME_JUMP,
    A_RESTART_AFTER_GAP,
    A_START,
    R_INTEGRATOR,
    RING,
    STAMPS_DTYPE,
    interval_add,
    stamps_reset,
    validate,
    within,
)
from gyro_attitude.core.jit import kernel

__all__ = ["ALIGN_BUFFER_DTYPE", "BIAS_RING_DTYPE", "COEF_DTYPE", "STATE_DTYPE", "run_rows",
           "step"]



class StepPhase(IntEnum):
    """The chain's phase in the state record (modes.Phase at the edge)."""

    RUNNING = 0
    ALIGNING = 1
    FAILED = 2


class AidingKind(IntEnum):
    """The aiding filter the step runs (modes.Aiding: every aided mode is the AHRS)."""

    NONE = 0
    AHRS = 1


class StepAlgorithm(IntEnum):
    """The integration algorithms compiled into the step."""

    CUBIC = 0  # rotvec_cubic
    EXP_MAP = 1


class BiasKind(IntEnum):
    """The gyro bias stage's mode (modes.GyroBiasMode)."""

    NONE = 0
    PARAMETER = 1
    AUTO = 2


RUNNING, ALIGNING, FAILED = StepPhase.RUNNING, StepPhase.ALIGNING, StepPhase.FAILED
AID_NONE, AID_AHRS = AidingKind.NONE, AidingKind.AHRS
ALG_CUBIC, ALG_EXP_MAP = StepAlgorithm.CUBIC, StepAlgorithm.EXP_MAP
BIAS_NONE, BIAS_PARAMETER, BIAS_AUTO = BiasKind.NONE, BiasKind.PARAMETER, BiasKind.AUTO

#: m/s²: a specific force beyond this (1e5 g) is no accelerometer reading
ACCEL_ABSURD = 1e6
#: (rad/s)²: a gyro variance beyond this (σ = 1000 rad/s) is no estimate of a real gyro's noise
MAX_GYRO_VARIANCE = 1.0e6
#: rad/s: a value held at the largest magnitude seen is a clip only this high
SATURATION_MIN_RAD_S = 1.0
#: ns: a clip holds the axis's largest value this long; a smooth peak quantized repeats its top
#: value for a few samples only (the BROAD gyros at 286 Hz: up to 4 samples, 11 ms, at
#: 2.5-5.7 rad/s; a 3 rad/s peak of a 0.2 Hz motion stays within 1e-3 rad/s for ~10 ms)
SATURATION_PLATEAU_NS = 20_000_000
#: REP-145: element 0 of a covariance is −1 when the field carries no estimate
NO_ESTIMATE = -1.0

COEF_DTYPE = np.dtype([
    # validation
    ("max_gap_ns", np.int64), ("time_jump_ns", np.int64), ("max_rate", np.float64),
    ("max_missing", np.int64),
    # gyro bias
    ("bias_mode", np.int64), ("earth", np.bool_), ("earth_n", np.float64, (3,)),
    ("min_rest_ns", np.int64), ("heading", np.float64),
    # alignment, aiding, integration, covariance
    ("levelling", np.bool_), ("level_first", np.bool_), ("aiding", np.int64),
    ("mag_mode", np.bool_), ("ahrs", np.float64, (22,)), ("kp", np.float64),
    ("algorithm", np.int64), ("n2", np.float64), ("k2", np.float64),
    ("accel_floor_var", np.float64),
])

STATE_DTYPE = np.dtype([
    ("stamps", STAMPS_DTYPE),
    # the chain: attitude handed out, the one a reset goes back to, the one to resume from
    ("q", np.float64, (4,)), ("q_initial", np.float64, (4,)), ("resume_q", np.float64, (4,)),
    ("has_resume", np.bool_), ("phase", np.int64), ("start_t", np.int64),
    ("has_start", np.bool_), ("accel_present", np.int64), ("first_rest_pending", np.bool_),
    ("level_pending", np.bool_), ("levelled_first", np.bool_),
    ("variance_known", np.bool_), ("noise_unknown", np.bool_), ("aided_seen", np.int64),
    ("sat", np.float64, (6,)), ("sat_t0", np.int64, (3,)),
    # counts of the chain's own events
    ("invalid_covariance", np.int64), ("invalid_accel", np.int64),
    ("integrator_error", np.int64), ("saturated", np.int64), ("rate_fit_fallback", np.int64),
    ("mag_missing", np.int64),
    # the last sample's events, for the words made at the edge
    ("events", np.int64), ("ev_sat_axis", np.int64), ("ev_fallbacks", np.int64),
    # why the alignment has not started (0 none, 1 no accelerometer, 1 + ALIGN_FAILED_*)
    ("align_error", np.int64),
    # stages
    ("rest_f", np.float64, (32,)), ("rest_i", np.int64, (10,)),
    ("bias_f", np.float64, (24,)), ("bias_i", np.int64, (13,)),
    ("aligner", ALIGNER_DTYPE),
    ("ahrs_f", np.float64, (48,)), ("ahrs_i", np.int64, (19,)),
    ("cubic_i", np.int64, (9,)), ("cubic_t", np.int64, (4,)), ("cubic_w", np.float64, (4, 3)),
    ("cubic_f", np.float64, (14,)), ("has_nav", np.bool_), ("nav_rate", np.float64, (3,)),
    ("cov", np.float64, (12,)), ("initial_tt", np.float64, (3,)),
    ("intervals", np.int64, (RING,)), ("interval_fill", np.int64, (2,)),
    ("align_head", np.int64), ("align_count", np.int64),
])

#: the bias stage's rest window: stamp, sample index, running sums before it, and what the
#: sample gives a rest (its rate less the Earth rate, whether that was taken out)
BIAS_RING_DTYPE = np.dtype([*RING_FIELDS, ("pv", np.float64, (3,)), ("pe", np.bool_)])
#: the samples from the aligner's last rest sample on (integrated once aligned)
ALIGN_BUFFER_DTYPE = np.dtype([("t", np.int64), ("w", np.float64, (3,)),
                               ("a", np.float64, (3,)), ("v", np.float64, (3,)),
                               ("vok", np.bool_), ("ms", np.int64), ("m", np.float64, (3,))])

#: step codes besides the verdict's action (A_ACCEPT ...): the ring of the bias stage, the
#: aligner or its buffer is full (nothing changed: grow it and step again)
BIAS_RING_FULL, ALIGN_RING_FULL = -2, -3
#: bits of :func:`step`'s events: what happened besides the verdict (words at the edge)
E_INVALID_COV, E_INVALID_ACCEL, E_SATURATED, E_FALLBACK, E_MAG_MISSING, E_NOISE_UNKNOWN, \
    E_ALIGN = 1, 2, 4, 8, 16, 32, 64


@kernel
def integrator_reset(c, s, qx, qy, qz, qw, has_t, t):
    """The integrator starts again from ``q`` (at ``t`` when ``has_t``: that sample is the
    first of the new time base, its rate taken from the next one), normalized here as
    StreamingIntegrator.reset takes it."""
    n = math.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
    rate_reset(s.cubic_i, s.cubic_t, s.cubic_w, s.cubic_f, qx / n, qy / n, qz / n, qw / n, has_t,
               t, s.has_nav, s.nav_rate[0], s.nav_rate[1], s.nav_rate[2])


@kernel
def aiding_step(c, s, t, w0, w1, w2, has_a, a0, a1, a2, x, y, z, u, ms, m0, m1, m2):
    """The aiding stage: the rate to integrate."""
    if c.aiding == AID_AHRS:
        return ahrs_step(c.ahrs, s.ahrs_f, s.ahrs_i, t, w0, w1, w2, has_a, a0, a1, a2, x, y,
                         z, u, ms, m0, m1, m2)
    return w0, w1, w2


@kernel
def break_windows(c, s):
    """A rest never spans a gap, a jump, a restart or an unusable accelerometer sample."""
    bias_break(s.bias_f, s.bias_i, s.rest_f, s.rest_i, c.min_rest_ns)
    if s.phase == ALIGNING:
        aligner_break(s.aligner)
        s.align_count = 0
    s.ahrs_i[I_HAS_LAST] = 0


#: :func:`covariance_verdict`'s codes: REP-145's "no estimate", all zeros (unknown), an
#: invalid diagonal (treated as unknown, counted), variances known
COV_NO_ESTIMATE, COV_ZEROS, COV_INVALID, COV_KNOWN = 0, 1, 2, 3


@kernel(inline=True)
def covariance_verdict(cv):
    """(code, s0, s1, s2) of a row-major 3x3 ``angular_velocity_covariance`` (9,), the one
    home of the policy: "no estimate" (REP-145: element 0 is −1); an invalid diagonal
    (non-finite, negative, beyond MAX_GYRO_VARIANCE, or a row that is not 9 numbers: NaN);
    all zeros (unknown); else the diagonal's variances."""
    if cv[0] == NO_ESTIMATE:
        return COV_NO_ESTIMATE, 0.0, 0.0, 0.0
    d0, d1, d2 = cv[0], cv[4], cv[8]
    # a chained comparison is False for NaN, so this refuses non-finite values too
    if not (0.0 <= d0 <= MAX_GYRO_VARIANCE and 0.0 <= d1 <= MAX_GYRO_VARIANCE
            and 0.0 <= d2 <= MAX_GYRO_VARIANCE):
        return COV_INVALID, 0.0, 0.0, 0.0
    for i in range(9):
        if cv[i] != 0.0:
            return COV_KNOWN, d0, d1, d2
    return COV_ZEROS, 0.0, 0.0, 0.0


@kernel
def covariance_verdicts(cov, var, code):
    """:func:`covariance_verdict` of every row of ``cov`` (N, 9) into ``var`` (N, 3) and
    ``code`` (N,) (the offline estimator's rows)."""
    for k in range(cov.shape[0]):
        code[k], var[k, 0], var[k, 1], var[k, 2] = covariance_verdict(cov[k])


@kernel
def judge_covariance(s, cv):
    """(variances known, s0, s1, s2) of a sample's covariance: "no estimate" an event the
    first time, an invalid one counted."""
    code, d0, d1, d2 = covariance_verdict(cv)
    if code == COV_NO_ESTIMATE:
        if not s.noise_unknown:
            s.events |= E_NOISE_UNKNOWN
        s.noise_unknown = True
    elif code == COV_INVALID:
        s.invalid_covariance += 1
        s.events |= E_INVALID_COV
    elif code == COV_KNOWN:
        s.variance_known = True
        return True, d0, d1, d2
    return False, 0.0, 0.0, 0.0


@kernel
def saturation_step(s, t, w0, w1, w2):
    """Count an accepted sample pinned on a plateau: an axis that has held one value at the
    largest magnitude seen (at least SATURATION_MIN_RAD_S) for SATURATION_PLATEAU_NS up to
    this sample ``t`` (the event's figure: the axis).  ``s.sat`` holds the largest |ω| per axis
    (0:3) and the last ω (3:6), ``s.sat_t0`` the stamp where the last ω's value began."""
    sat = s.sat
    pinned = -1
    for i, x in ((0, w0), (1, w1), (2, w2)):
        a = abs(x)
        if a > sat[i]:
            sat[i] = a
        if x != sat[3 + i]:
            s.sat_t0[i] = t
        elif a == sat[i] and a >= SATURATION_MIN_RAD_S and t - s.sat_t0[i] >= \
                SATURATION_PLATEAU_NS:
            pinned = i
        sat[3 + i] = x
    if pinned >= 0:
        s.saturated += 1
        s.ev_sat_axis = pinned
        s.events |= E_SATURATED


@kernel
def first_rest_back(c, s, p0, p1, p2):
    """The bias stage published a new estimate (bias before it ``p``); with the stream still
    since its start, the first one is applied back to the start: the samples so far were
    integrated with the previous bias, the body did not turn, so the attitude error is the
    bias change times the elapsed time, a body-frame rotation taken back here."""
    bf, bi = s.bias_f, s.bias_i
    ci = s.cubic_i
    if s.first_rest_pending and s.phase == RUNNING and bi[J_HAS_SEG] == 1 \
            and bi[J_SEG_T0] - s.start_t <= s.rest_i[R_WINDOW_NS] and ci[C_HAS_LAST] == 1 \
            and bi[J_POOL_K] == 0:
        t_prev = ci[C_LAST_T]
        elapsed = (t_prev - s.start_t) * 1e-9
        ex, ey, ez = (-(bf[B_BIAS] - p0) * elapsed, -(bf[B_BIAS + 1] - p1) * elapsed,
                      -(bf[B_BIAS + 2] - p2) * elapsed)
        qf = s.cubic_f
        q = (qf[0], qf[1], qf[2], qf[3])
        if c.aiding == AID_AHRS:
            # the tilt filter has already taken out part of the tilt this bias caused (how
            # much, its state does not say): the tilt is left to it, only the part about the
            # vertical (C_nb e)_z goes back
            _, _, _, _, _, _, c20, c21, c22 = c_nb(qf[0], qf[1], qf[2], qf[3])
            x, y, z, u = qmul_scalar(exp_scalar(0.0, 0.0, c20 * ex + c21 * ey + c22 * ez), q)
        else:
            x, y, z, u = qmul_scalar(q, exp_scalar(ex, ey, ez))
        integrator_reset(c, s, x, y, z, u, True, t_prev)
        s.q[0], s.q[1], s.q[2], s.q[3] = x, y, z, u
        first_rest_update(s.cov, s.initial_tt, bf[B_SE], bf[B_SE + 1], bf[B_SE + 2], elapsed)
    else:
        zero_rate_update(s.cov, bf[B_SE], bf[B_SE + 1], bf[B_SE + 2])
    s.first_rest_pending = False


@kernel
def level_from_first(c, s, a0, a1, a2):
    """``initial_attitude_source: accelerometer``: the initial attitude's roll and pitch from
    the first sample's specific force (heading ``c.heading``), as VQF and imu_tools start; its
    tilt variance the accelerometer bias's (one sample's noise is far below it)."""
    ok, x, y, z, u, _, _ = level_q(a0, a1, a2, c.heading)
    if not ok:
        return
    s.q_initial[0], s.q_initial[1], s.q_initial[2], s.q_initial[3] = x, y, z, u
    s.q[0], s.q[1], s.q[2], s.q[3] = x, y, z, u
    s.initial_tt[0] = s.initial_tt[1] = c.accel_floor_var
    reset_attitude(s.cov, s.initial_tt)
    s.levelled_first = True


@kernel
def bias_stage(c, s, ring, t, w0, w1, w2, has_a, a0, a1, a2):
    """Rest → gyro bias for an accepted sample: the ring code (<0: full), the bias published
    (in ``s.bias_f``).  ``auto``: the window ending here, the Earth rate taken out at the
    current attitude (while aligning: levelled from this sample's specific force)."""
    if c.bias_mode != BIAS_AUTO:
        return 0
    bf = s.bias_f
    p0, p1, p2 = bf[B_BIAS], bf[B_BIAS + 1], bf[B_BIAS + 2]
    has_q = False
    x = y = z = 0.0
    u = 1.0
    if c.earth:
        if s.phase == RUNNING:
            has_q = True
            x, y, z, u = s.q[0], s.q[1], s.q[2], s.q[3]
        elif has_a:
            has_q, x, y, z, u, _, _ = level_q(a0, a1, a2, c.heading)
    code = bias_step(bf, s.bias_i, c.min_rest_ns, s.rest_f, s.rest_i, ring.t, ring.x, ring.c,
                     ring.pv, ring.pe, c.earth_n, t, w0, w1, w2, has_a, a0, a1, a2, has_q, x,
                     y, z, u)
    if code == RING_FULL:
        return BIAS_RING_FULL
    if code < 0:  # a value the rest statistics refuse (BAD_ATTITUDE, ...): no rest here
        bias_break(bf, s.bias_i, s.rest_f, s.rest_i, c.min_rest_ns)
        return 0
    if s.bias_i[J_UPDATED] == 1:
        first_rest_back(c, s, p0, p1, p2)
    return 0


@kernel
def integrate(c, s, action, fresh, t, w0, w1, w2, has_a, a0, a1, a2, vok, v0, v1, v2, ms, m0,
              m1, m2):
    """Aiding, integration and covariance of one sample (bias taken out of ``w``); False when
    the attitude is not finite (counted: the last good one restored, a fresh time base)."""
    last_t = s.cubic_i[C_LAST_T]
    fell = s.cubic_i[C_FALLBACKS]
    if action == A_ACCEPT:
        w0, w1, w2 = aiding_step(c, s, t, w0, w1, w2, has_a, a0, a1, a2, s.q[0], s.q[1],
                                 s.q[2], s.q[3], ms, m0, m1, m2)
    else:
        q0 = s.q_initial
        if action == A_RESET_TIME_JUMP:
            reset_attitude(s.cov, s.initial_tt)
            s.interval_fill[0], s.interval_fill[1] = 0, 0
        elif action == A_RESTART_AFTER_GAP:
            q0 = s.q
        elif not fresh and s.has_resume:
            q0 = s.resume_q
        if not fresh and action == A_START:
            s.has_resume = False
        integrator_reset(c, s, q0[0], q0[1], q0[2], q0[3], False, 0)
        s.ahrs_i[I_HAS_LAST] = 0  # a new time base for the aiding filter
        w0, w1, w2 = aiding_step(c, s, t, w0, w1, w2, has_a, a0, a1, a2, q0[0], q0[1], q0[2],
                                 q0[3], ms, m0, m1, m2)
    nav = s.nav_rate
    x, y, z, u = rate_advance(CUBIC if c.algorithm == ALG_CUBIC else EXP, s.cubic_i, s.cubic_t,
                              s.cubic_w, s.cubic_f, t, w0, w1, w2, s.has_nav, nav[0], nav[1],
                              nav[2])
    n_fb = s.cubic_i[C_FALLBACKS] - fell
    if n_fb > 0:
        s.rate_fit_fallback += n_fb
        s.ev_fallbacks = n_fb
        s.events |= E_FALLBACK
    if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z) and math.isfinite(u)):
        s.integrator_error += 1
        s.resume_q[:] = s.q
        s.has_resume = True
        s.first_rest_pending = False  # a new time base: no longer still since the start
        integrator_reset(c, s, s.q[0], s.q[1], s.q[2], s.q[3], False, 0)
        stamps_reset(s.stamps)  # the next sample starts a fresh time base
        s.ahrs_i[I_HAS_LAST] = 0  # a new time base for the aiding filter
        return False
    if action == A_ACCEPT:
        dt = t - last_t
        interval_add(s.intervals, s.interval_fill, dt)
        dt_s = dt * 1e-9
        # angle random walk: each interval adds an independent angle error of variance
        # σ_ω² dt² per axis (σ_ω² per sample), i.e. N² dt with the noise density N
        if vok:
            d2 = dt_s * dt_s
            propagate(s.cov, c.k2, dt_s, v0 * d2, v1 * d2, v2 * d2)
        else:
            nd = c.n2 * dt_s
            propagate(s.cov, c.k2, dt_s, nd, nd, nd)
        if s.ahrs_i[I_AIDED] != s.aided_seen:
            aid_tilt(s.cov, c.kp * dt_s, s.aligner.level_var if s.aligner.aligned
                     else c.accel_floor_var)
    s.aided_seen = s.ahrs_i[I_AIDED]
    s.q[0], s.q[1], s.q[2], s.q[3] = x, y, z, u
    return True


@kernel
def align_stage(c, s, ring, buf, t, w0, w1, w2, has_a, a0, a1, a2, b0, b1, b2, vok, v0, v1,
                v2, ms, m0, m1, m2):
    """Alignment (phase aligning) of an accepted sample: the ring code (<0: full), whether an
    attitude was handed out (aligned with this sample)."""
    if s.phase == FAILED:
        return 0, False
    if not has_a:
        s.align_error = 1  # alignment needs the accelerometer
        return 0, False
    s.align_error = 0
    al = s.aligner
    code, done = aligner_update(al, ring, t, w0, w1, w2, a0, a1, a2, ms == MAG_GIVEN, m0, m1,
                                m2)
    if code == RING_FULL:
        return ALIGN_RING_FULL, False
    if code < 0:  # a sample the detector refuses: the aligner starts again
        aligner_break(al)
        s.align_count = 0
        return 0, False
    # the samples from the last rest sample on, integrated once aligned
    cap = buf.shape[0]
    if s.align_count == cap:
        return ALIGN_RING_FULL, False
    k = (s.align_head + s.align_count) % cap
    e = buf[k]
    e.t = t
    e.w[0], e.w[1], e.w[2] = w0, w1, w2
    e.a[0], e.a[1], e.a[2] = a0, a1, a2
    e.v[0], e.v[1], e.v[2] = v0, v1, v2
    e.vok, e.ms = vok, ms
    e.m[0], e.m[1], e.m[2] = m0, m1, m2
    s.align_count += 1
    if al.has_seg == 0:
        s.align_head = k
        s.align_count = 1
    else:
        while buf[s.align_head].t < al.t1:
            s.align_head = (s.align_head + 1) % cap
            s.align_count -= 1
    if not done:
        return 0, False
    failed = aligner_result(al)
    if failed != 0:
        s.phase = FAILED
        s.align_error = 1 + failed
        return 0, False
    # aligned: the attitude, its covariance and the integrator start from the alignment
    s.phase = RUNNING
    s.q_initial[:] = al.q
    s.q[:] = al.q
    s.has_resume = False
    s.initial_tt[:] = al.variance
    reset_attitude(s.cov, s.initial_tt)
    integrator_reset(c, s, al.q[0], al.q[1], al.q[2], al.q[3], False, 0)
    s.ahrs_i[I_HAS_LAST] = 0  # a new time base for the aiding filter
    if c.aiding == AID_AHRS and al.source == 2:  # the heading is the mean field's
        heading_from_field(s.ahrs_f, s.ahrs_i, (al.t1 - al.t0) * 1e-9, al.q[0], al.q[1],
                           al.q[2], al.q[3], al.mean_m[0], al.mean_m[1], al.mean_m[2])
    action = A_START
    fresh = True
    got = False
    for j in range(s.align_count):
        e = buf[(s.align_head + j) % cap]
        got = integrate(c, s, action, fresh, e.t, e.w[0] - b0, e.w[1] - b1, e.w[2] - b2, True,
                        e.a[0], e.a[1], e.a[2], e.vok, e.v[0], e.v[1], e.v[2], e.ms, e.m[0],
                        e.m[1], e.m[2])
        action = A_ACCEPT
        fresh = False
    s.align_count = 0
    return 0, got


@kernel(inline=True)
def step(ca, sa, bias_ring, align_ring, align_buf, t, w0, w1, w2, frame_ok, has_a, a0, a1, a2,
         has_cov, cv, ms, m0, m1, m2):
    """One Imu sample through the chain: (code, reason, whether an attitude was handed out,
    events (bits E_*), the attitude).  ``code`` the verdict's action (A_REJECT ...
    A_RESET_TIME_JUMP), or :data:`BIAS_RING_FULL` / :data:`ALIGN_RING_FULL` (nothing
    changed); ``reason`` the validator's (0 none, 1 + index in validation.REJECT_REASONS,
    TIME_JUMP, MISSING) or R_INTEGRATOR.  ``ca``, ``sa`` the coefficients and the state (one
    record each); ``frame_ok`` whether the sample's frame is the locked one (or none is);
    ``has_a``/``a`` the specific force (NaN: not numbers); ``has_cov``/``cv`` the angular_velocity_covariance
    (9,); ``ms``/``m`` the field (ahrs.MAG_*)."""
    code, reason, got = chain_step(ca, sa, bias_ring, align_ring, align_buf, t, w0, w1, w2,
                                   frame_ok, has_a, a0, a1, a2, has_cov, cv, ms, m0, m1, m2)
    s = sa[0]
    return code, reason, got, s.events, s.q[0], s.q[1], s.q[2], s.q[3]


@kernel(inline=True)
def chain_step(ca, sa, bias_ring, align_ring, align_buf, t, w0, w1, w2, frame_ok, has_a, a0,
               a1, a2, has_cov, cv, ms, m0, m1, m2):
    """:func:`step` but for its events (in ``s.events``) and attitude (in ``s.q``)."""
    c = ca[0]
    s = sa[0]
    s.events = 0
    # rings full before anything changes: grow and step again
    if c.bias_mode == BIAS_AUTO and s.rest_i[R_COUNT] == bias_ring.shape[0]:
        return BIAS_RING_FULL, 0, False
    if s.phase == ALIGNING and (s.aligner.rest_i[R_COUNT] == align_ring.shape[0]
                                or s.align_count == align_buf.shape[0]):
        return ALIGN_RING_FULL, 0, False
    # 1. validate
    action, reason = validate(s.stamps, c.max_rate, c.max_gap_ns, c.time_jump_ns,
                              c.max_missing, t, w0, w1, w2, frame_ok)
    if action == A_REJECT:
        return action, reason, False
    vok = False
    v0 = v1 = v2 = 0.0
    if has_cov:
        vok, v0, v1, v2 = judge_covariance(s, cv)
    if has_a and not within(a0, a1, a2, ACCEL_ABSURD):
        s.invalid_accel += 1
        s.events |= E_INVALID_ACCEL
        break_windows(c, s)
        s.accel_present = -1
        has_a = False
    else:
        if s.accel_present >= 0 and has_a != (s.accel_present == 1):
            break_windows(c, s)  # the rest detectors need the accelerometer for all or none
        s.accel_present = 1 if has_a else 0
    if c.mag_mode and ms == MAG_ABSENT:
        s.mag_missing += 1
        s.events |= E_MAG_MISSING
    if s.level_pending and action == A_START:
        s.level_pending = False  # the first sample only: later ones would make the tilt jump
        if has_a and s.phase == RUNNING:
            level_from_first(c, s, a0, a1, a2)
    if not s.has_start or action == A_RESET_TIME_JUMP:
        # the start the first rest's estimate may be applied back to: a jump back starts the
        # attitude again from the initial one, a fresh start
        s.has_start, s.start_t = True, t
    elif action == A_RESTART_AFTER_GAP:
        s.first_rest_pending = False  # the samples before the gap are not the rest's
    if action != A_ACCEPT:
        break_windows(c, s)
    saturation_step(s, t, w0, w1, w2)
    # 2. rest -> gyro bias
    if bias_stage(c, s, bias_ring, t, w0, w1, w2, has_a, a0, a1, a2) < 0:
        return BIAS_RING_FULL, 0, False  # (not reached: the ring was checked above)
    bf = s.bias_f
    b0, b1, b2 = bf[B_BIAS], bf[B_BIAS + 1], bf[B_BIAS + 2]
    # 3. alignment
    if s.phase != RUNNING:
        before = s.align_error
        _, got = align_stage(c, s, align_ring, align_buf, t, w0, w1, w2, has_a, a0, a1, a2,
                             b0, b1, b2, vok, v0, v1, v2, ms, m0, m1, m2)
        if s.align_error != before:
            s.events |= E_ALIGN
        return action, reason, got
    # 4.-6. aiding, integration, covariance
    if not integrate(c, s, action, False, t, w0 - b0, w1 - b1, w2 - b2, has_a, a0, a1, a2,
                     vok, v0, v1, v2, ms, m0, m1, m2):
        return A_REJECT, R_INTEGRATOR, False
    return action, reason, True


@kernel
def run_rows(ca, sa, bias_ring, align_ring, align_buf, r0, t, w, frames, locked, has_a, acc,
             has_cov, cov, has_mag, ms, mag, action_out, got_out, q_out, var_out, known_out,
             first_row, first_fig, m):
    """:func:`step` over rows ``r0`` … of a recording (``frames`` per-row frame codes,
    ``locked`` the locked frame's code, -1 none; ``ms`` per-row field states): each row's
    action into ``action_out``, and for the rows that got an attitude (from the ``m``-th on)
    the row, the attitude and the orientation variance.  ``first_row`` (per reason code)
    the first row of each event and ``first_fig`` the validator's figures there, for the words
    at the edge.  Returns (the row it stopped at: len(t) when done, else a ring was full there;
    the attitudes so far; the locked frame)."""
    s = sa[0]
    n = t.shape[0]
    z3 = np.zeros(3)
    z9 = np.zeros(9)
    for k in range(r0, n):
        frame_ok = locked < 0 or frames[k] == locked
        a = acc[k] if has_a else z3
        cv = cov[k] if has_cov else z9
        mm = mag[k] if has_mag else z3
        code, reason, got, ev, x, y, z, u = step(
            ca, sa, bias_ring, align_ring, align_buf, t[k], w[k, 0], w[k, 1], w[k, 2],
            frame_ok, has_a, a[0], a[1], a[2], has_cov, cv, ms[k], mm[0], mm[1], mm[2])
        if code < A_REJECT:
            return k, m, locked
        if code == A_START and locked < 0:
            locked = frames[k]
        action_out[k] = code
        if reason > 0 or ev != 0:
            _note_first(s, first_row, first_fig, k, reason, ev)
        if got:
            got_out[m] = k
            q_out[m, 0], q_out[m, 1], q_out[m, 2], q_out[m, 3] = x, y, z, u
            known_out[m] = s.variance_known
            for i in range(3):
                var_out[m, i] = s.cov[V_TT + i] if s.variance_known else 0.0
            m += 1
    return n, m, locked


#: events whose first row run_rows keeps (index into ``first_row``), after the validator's
#: reason codes: the chain's own
EV_INVALID_COV, EV_INVALID_ACCEL, EV_SATURATED, EV_FALLBACK, EV_MAG_MISSING, \
    EV_NOISE_UNKNOWN = range(R_INTEGRATOR + 1, R_INTEGRATOR + 7)
N_EVENTS = EV_NOISE_UNKNOWN + 1


@kernel
def _note_first(s, first_row, first_fig, k, reason, ev):
    if reason > 0 and first_row[reason] < 0:
        first_row[reason] = k
        v = s.stamps
        first_fig[reason, 0], first_fig[reason, 1], first_fig[reason, 2] = (v.ev_dt, v.ev_hole,
                                                                           v.ev_missing)
        first_fig[reason, 3], first_fig[reason, 4] = v.ev_skipped, v.ev_period
    for e, bit in ((EV_INVALID_COV, E_INVALID_COV), (EV_INVALID_ACCEL, E_INVALID_ACCEL),
                   (EV_SATURATED, E_SATURATED), (EV_FALLBACK, E_FALLBACK),
                   (EV_MAG_MISSING, E_MAG_MISSING), (EV_NOISE_UNKNOWN, E_NOISE_UNKNOWN)):
        if ev & bit and first_row[e] < 0:
            first_row[e] = k
            first_fig[e, 0] = s.ev_sat_axis if e == EV_SATURATED else s.ev_fallbacks
