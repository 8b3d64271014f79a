"""Causal AHRS aiding (tilt from the specific force filtered in an almost-inertial frame, heading
from the magnetometer, acceleration and magnetic-disturbance rejection, hard-iron fit): the
kernel :func:`ahrs_step` once per accepted sample on :class:`AhrsFilter`'s state arrays.  It
owns no attitude: every correction is an added body rate (docs/architecture.md, "Notes: the
estimator's stages")."""

from __future__ import annotations

import math

import numpy as np

from gyro_attitude.core.angles import wrap_pi_float
from gyro_attitude.core.attitude.modes import SettingError
from gyro_attitude.core.attitude.settings import StreamConfig
from gyro_attitude.core.attitude.validation import within
from gyro_attitude.core.earth import STANDARD_GRAVITY
from gyro_attitude.core.jit import kernel

__all__ = ["AhrsFilter", "MAG_ABSURD_T", "MAG_ZERO_T"]

MAG_ABSURD_T = 1e-2  # tesla: 10 mT, beyond any magnetometer's range (Earth's field ~25-65 µT)
MAG_ZERO_T = 1e-7  # tesla: 0.1 µT, no magnetometer in a geomagnetic field reads this little
HARD_IRON_SOLVE_S = 1.0
HEADING_INIT_TAU_S = 0.3
HEADING_INIT_S = 2.0
_SQRT2 = math.sqrt(2.0)


def _field_reference(cfg) -> tuple[float, float] | None:
    """(norm T, dip rad) of ``mag_reference_enu_t``, None for zeros (learned)."""
    e, n, u = cfg.mag_reference_enu_t
    norm = math.sqrt(e * e + n * n + u * u)
    if norm == 0.0:
        return None
    if norm < MAG_ZERO_T:
        raise SettingError("mag_reference_enu_t", "mag_reference_enu_t must be zeros (learn it) "
                           f"or a field of at least {MAG_ZERO_T:g} T")
    return norm, math.atan2(-u, math.hypot(e, n))


@kernel(inline=True)
def _butterworth2(tau: float, dt: float) -> tuple[float, float, float, float, float]:
    """(b0, b1, b2, a1, a2) of the second-order Butterworth low-pass by the bilinear transform,
    cutoff ``√2 / (2π τ)`` (so that its step response settles like a first-order filter of
    time constant τ), for sample time ``dt``."""
    fc = _SQRT2 / (2.0 * math.pi * tau)
    c = math.tan(math.pi * min(fc * dt, 0.49))  # prewarped; a cutoff at Nyquist is clamped
    d = c * c + _SQRT2 * c + 1.0
    b0 = c * c / d
    return b0, 2.0 * b0, b0, 2.0 * (c * c - 1.0) / d, (1.0 - _SQRT2 * c + c * c) / d


# The filter's state as arrays (what the compiled chain steps).  Float slots:
A_BIAS, A_LP, A_COEF, A_KEY_TAU, A_REST_S, A_REJECT_S, A_RUN_S, A_SINCE_HEADING, A_REF_ACC, \
    A_CAND, A_HI_SUMS, A_HI_SINCE, A_HARD_IRON, A_REF_NORM, A_REF_DIP, A_LP_OUT = \
    0, 3, 9, 14, 15, 16, 17, 18, 19, 22, 25, 39, 40, 43, 44, 45
_A_FLOATS = 48
# (bias 3; the Butterworth's delay elements s1, s2 in the nav frame 6; its coefficients 5 and
# the time constant they are for; the rest, rejection, run and heading clocks; Σ norm, Σ dip,
# Σ seconds while learning the reference; a steady disturbed field's norm, dip, seconds; the
# 14 sphere-fit sums and the seconds since the last solve; the hard iron; the reference; the
# low-pass's last output, nav frame)
# Int slots:
I_LAST_T, I_HAS_LAST, I_AIDED, I_REJECTED, I_RECOVERIES, I_MAG_USED, I_MAG_DISTURBED, \
    I_MAG_INVALID, I_REF_CHANGES, I_AT_REST, I_HEADING_INIT, I_HAS_LP, I_HAS_KEY, I_KEY_DT, \
    I_HAS_CAND, I_HAS_REF_NORM, I_HAS_REF_DIP, I_HI_ON, I_HI_FITS = range(19)
_A_INTS = 19
# Parameters (AhrsFilter.pa: the settings and what follows from them):
P_ACCEL_TAU, P_TILT_TAU, P_REST_ACCEL_TAU, P_REST_RATE_MAX, P_REST_ACCEL_TOL, P_REST_MIN_S, \
    P_GRAVITY, P_ACCEL_NORM_TOL, P_ACCEL_RECOVERY_S, P_BIAS_GAIN, P_MAG_TAU, P_MAG_NORM_TOL, \
    P_MAG_REF_S, P_HI_WINDOW_S, P_DECL, P_REJECT_COS, P_TILT_RATE, P_SETTLE_S, \
    P_RECOVERY_RATE, P_DIP_TOL, P_REF_NORM_GIVEN, P_MAG_RECOVERY_S = range(22)
# the low-pass's phase (I_HAS_LP): none yet, the mean of the first accel_tau_s, the Butterworth
LP_NONE, LP_MEAN, LP_BUTTERWORTH = 0, 2, 1
# a magnetometer sample as the kernel takes it: absent, present but not 3 finite numbers, given
MAG_ABSENT, MAG_NOT_FLOATS, MAG_GIVEN = 0, 1, 2


class AhrsFilter:
    """The aiding stage for the settings ``config``: its parameter row ``pa`` (``P_*``: the
    ``ahrs_*`` and ``mag_*`` settings as the kernels read them), its state arrays ``af``,
    ``ai`` (the compiled chain holds them) and its counters read off them: sample counts
    ``aided_samples`` (tilt corrected), ``accel_rejected``, ``mag_used``, ``mag_disturbed``,
    ``mag_invalid``, ``mag_reference_changes``, ``hard_iron_fits``; ``hard_iron`` (tesla),
    ``mag_ref_norm`` (tesla) and ``mag_ref_dip`` (rad), None until known; ``at_rest``,
    ``heading_initialized``.  The heading is set from the first usable field when the stream
    levels; a given initial attitude keeps its heading and the field pulls it slowly."""

    def __init__(self, config: StreamConfig | None = None):
        self.config = cfg = config if config is not None else StreamConfig()
        ref = _field_reference(cfg)
        self.pa = np.array([
            cfg.ahrs_accel_tau_s, cfg.ahrs_tilt_tau_s, cfg.ahrs_rest_accel_tau_s,
            cfg.ahrs_rest_rate_max, cfg.ahrs_rest_accel_tol, cfg.ahrs_rest_min_s,
            STANDARD_GRAVITY, cfg.ahrs_accel_norm_tol, cfg.ahrs_accel_recovery_s,
            cfg.ahrs_bias_gain, cfg.ahrs_mag_tau_s, cfg.mag_norm_tol, cfg.mag_reference_s,
            cfg.mag_hard_iron_window_s, math.radians(cfg.magnetic_declination_deg),
            math.cos(math.radians(cfg.ahrs_accel_reject_deg)),
            math.radians(cfg.ahrs_tilt_rate_max_deg_s), 2.0 * cfg.ahrs_accel_tau_s,
            math.radians(cfg.ahrs_recovery_rate_deg_s), math.radians(cfg.mag_dip_tol_deg),
            1.0 if ref is not None else 0.0, cfg.mag_recovery_s])
        # the tilt's effective gain for the covariance stage: the low-pass sets the time constant
        self.kp = 1.0 / max(cfg.ahrs_accel_tau_s, cfg.ahrs_tilt_tau_s)
        self.af = af = np.zeros(_A_FLOATS)
        self.ai = ai = np.zeros(_A_INTS, dtype=np.int64)
        ai[I_HEADING_INIT] = not cfg.levelling
        ai[I_HI_ON] = bool(cfg.mag_hard_iron_estimate)
        af[A_HARD_IRON:A_HARD_IRON + 3] = [float(c) for c in cfg.mag_hard_iron_t]
        if ref is not None:
            af[A_REF_NORM], af[A_REF_DIP] = ref
            ai[I_HAS_REF_NORM] = ai[I_HAS_REF_DIP] = 1

    # ------------------------------------------------------------------ the state, read
    def _count(i):
        return property(lambda self: int(self.ai[i]))

    aided_samples = _count(I_AIDED)
    accel_rejected = _count(I_REJECTED)
    mag_used = _count(I_MAG_USED)
    mag_disturbed = _count(I_MAG_DISTURBED)
    mag_invalid = _count(I_MAG_INVALID)
    mag_reference_changes = _count(I_REF_CHANGES)
    hard_iron_fits = _count(I_HI_FITS)
    del _count
    at_rest = property(lambda self: bool(self.ai[I_AT_REST]))
    heading_initialized = property(lambda self: bool(self.ai[I_HEADING_INIT]))
    hard_iron = property(lambda self: self.af[A_HARD_IRON:A_HARD_IRON + 3].tolist())
    mag_ref_norm = property(lambda self: float(self.af[A_REF_NORM]) if self.ai[I_HAS_REF_NORM]
                            else None)
    mag_ref_dip = property(lambda self: float(self.af[A_REF_DIP]) if self.ai[I_HAS_REF_DIP]
                           else None)


@kernel(inline=True)
def c_nb(x, y, z, s):
    """The rows of ``C_nb`` (body → nav) of the quaternion ``(x, y, z, s)``, normalized."""
    k = 2.0 / (x * x + y * y + z * z + s * s)
    return (1.0 - k * (y * y + z * z), k * (x * y - z * s), k * (x * z + y * s),
            k * (x * y + z * s), 1.0 - k * (x * x + z * z), k * (y * z - x * s),
            k * (x * z - y * s), k * (y * z + x * s), 1.0 - k * (x * x + y * y))


@kernel
def heading_from_field(af, ai, seconds, x, y, z, u, vx, vy, vz):
    """The heading was just set from the mean field ``v`` (body) over ``seconds`` of rest (the
    alignment, attitude ``(x, y, z, u)``): the filter goes on as a running average that has
    seen that much field, and that field's norm and dip are the reference unless one is given."""
    # the field in the nav frame: v + u t + q × t with t = 2 q × v (rotation.quat_rotate)
    tx, ty, tz = 2.0 * (y * vz - z * vy), 2.0 * (z * vx - x * vz), 2.0 * (x * vy - y * vx)
    e0 = vx + u * tx + (y * tz - z * ty)
    e1 = vy + u * ty + (z * tx - x * tz)
    e2 = vz + u * tz + (x * ty - y * tx)
    ai[I_HEADING_INIT] = 1
    af[A_SINCE_HEADING] = HEADING_INIT_S + seconds
    if ai[I_HAS_REF_NORM] == 0:
        af[A_REF_NORM], ai[I_HAS_REF_NORM] = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2), 1
    if ai[I_HAS_REF_DIP] == 0:
        af[A_REF_DIP], ai[I_HAS_REF_DIP] = math.atan2(-e2, math.hypot(e0, e1)), 1


@kernel(inline=True)
def ahrs_step(pa, af, ai, t, w0, w1, w2, has_f, fx, fy, fz, x, y, z, s, mag_state, mx, my, mz):
    """One sample of the filter (module docstring) on its state arrays: ``t`` int ns after the
    last, ``w`` the gyro rate less the known bias, ``f`` the specific force (``has_f``), ``(x,
    y, z, s)`` the current attitude q_nb, the field ``m`` (``mag_state``); the rate to
    integrate for the interval ending here."""
    dt = 0.0 if ai[I_HAS_LAST] == 0 else (t - ai[I_LAST_T]) * 1e-9
    ai[I_LAST_T], ai[I_HAS_LAST] = t, 1
    ox, oy, oz = w0 - af[A_BIAS], w1 - af[A_BIAS + 1], w2 - af[A_BIAS + 2]
    if dt == 0.0:
        ai[I_HAS_LP] = LP_NONE  # a new time base: the low-pass starts again
    c00, c01, c02, c10, c11, c12, c20, c21, c22 = c_nb(x, y, z, s)
    dx = dy = dz = 0.0  # the nav-frame correction (rotation vector) of this sample
    learn_tilt = learn_heading = False
    hdt = dt
    if has_f:
        # q_nb is the attitude at the previous sample: the vector seen then is, to first
        # order, v + (ω dt) × v (half-steps: the mean rate of the interval is not known yet,
        # the current one over half the step is its midpoint estimate); without this a body
        # turning at 1 rad/s reads the vertical 0.3° late at 200 Hz
        fx, fy, fz = (fx + hdt * (oy * fz - oz * fy), fy + hdt * (oz * fx - ox * fz),
                      fz + hdt * (ox * fy - oy * fx))
        dx, dy, learn_tilt = _tilt(pa, af, ai, dt, ox, oy, oz, fx, fy, fz, c00, c01, c02, c10,
                                   c11, c12, c20, c21, c22)
    if dt == 0.0:
        return ox, oy, oz  # a new time base: no interval to correct over
    if mag_state != MAG_ABSENT:
        dz, learn_heading = _heading(pa, af, ai, dt, mag_state, mx, my, mz, ox * hdt,
                                     oy * hdt, oz * hdt, c00, c01, c02, c10, c11, c12, c20,
                                     c21, c22)
    if dx == 0.0 and dy == 0.0 and dz == 0.0:
        return ox, oy, oz
    rotate_lowpass(af, ai, dx, dy, dz)
    # the nav-frame rotation as a body rate over this interval: C_bn δ / dt
    ex = c00 * dx + c10 * dy + c20 * dz
    ey = c01 * dx + c11 * dy + c21 * dz
    ez = c02 * dx + c12 * dy + c22 * dz
    g = pa[P_BIAS_GAIN]
    if g > 0.0 and (learn_tilt or learn_heading):
        # the bias integral learns from the steady corrections only (not from the first
        # seconds of a low-pass, a recovery or the heading set from the field)
        lx, ly, lz = (dx, dy, 0.0) if learn_tilt else (0.0, 0.0, 0.0)
        if learn_heading:
            lz = dz
        af[A_BIAS] -= g * (c00 * lx + c10 * ly + c20 * lz)
        af[A_BIAS + 1] -= g * (c01 * lx + c11 * ly + c21 * lz)
        af[A_BIAS + 2] -= g * (c02 * lx + c12 * ly + c22 * lz)
    inv = 1.0 / dt
    return ox + ex * inv, oy + ey * inv, oz + ez * inv


@kernel(inline=True)
def rotate_lowpass(af, ai, dx, dy, dz):
    """A small nav-frame rotation ``d`` of the attitude applied to the low-pass's state too
    (to first order: v + d × v), so that it stays in the frame the gyro alone would give
    (almost-inertial)."""
    if ai[I_HAS_LP] == LP_NONE:
        return
    for i in (A_LP, A_LP + 3, A_LP_OUT):
        ax, ay, az = af[i], af[i + 1], af[i + 2]
        af[i] = ax + dy * az - dz * ay
        af[i + 1] = ay + dz * ax - dx * az
        af[i + 2] = az + dx * ay - dy * ax


@kernel(inline=True)
def _tilt(pa, af, ai, dt, ox, oy, oz, fx, fy, fz, c00, c01, c02, c10, c11, c12, c20, c21, c22):
    """The tilt correction (nav x, y rotation) of one accelerometer sample."""
    if not (abs(fx) <= 1e6 and abs(fy) <= 1e6 and abs(fz) <= 1e6):
        return 0.0, 0.0, False  # not finite or absurd: the stream counts it
    nx = c00 * fx + c01 * fy + c02 * fz
    ny = c10 * fx + c11 * fy + c12 * fz
    nz = c20 * fx + c21 * fy + c22 * fz
    fn = math.sqrt(fx * fx + fy * fy + fz * fz)
    g0 = pa[P_GRAVITY]
    if ox * ox + oy * oy + oz * oz < pa[P_REST_RATE_MAX] * pa[P_REST_RATE_MAX] \
            and abs(fn - g0) < pa[P_REST_ACCEL_TOL]:
        af[A_REST_S] += dt
    else:
        af[A_REST_S] = 0.0
    rest = af[A_REST_S] >= pa[P_REST_MIN_S]
    ai[I_AT_REST] = 1 if rest else 0
    gx, gy, gz = _lowpass(pa, af, ai, dt, pa[P_REST_ACCEL_TAU] if rest else pa[P_ACCEL_TAU],
                          nx, ny, nz)
    af[A_LP_OUT], af[A_LP_OUT + 1], af[A_LP_OUT + 2] = gx, gy, gz
    gn = math.sqrt(gx * gx + gy * gy + gz * gz)
    if gn < 1e-9:
        return 0.0, 0.0, False
    h = math.sqrt(gx * gx + gy * gy)
    if h < 1e-12 * gn:
        return 0.0, 0.0, False
    # the rotation about the horizontal axis ĝ × e_up taking ĝ to the vertical
    angle = math.atan2(h, gz)
    learn = False
    if af[A_RUN_S] < pa[P_SETTLE_S]:
        pass  # a new low-pass: the accelerometer is all there is, trusted in full
    elif gz < pa[P_REJECT_COS] * gn or abs(fn - g0) > pa[P_ACCEL_NORM_TOL]:
        af[A_REJECT_S] += dt
        if af[A_REJECT_S] < pa[P_ACCEL_RECOVERY_S]:
            ai[I_REJECTED] += 1
            return 0.0, 0.0, False
        if af[A_REJECT_S] - dt < pa[P_ACCEL_RECOVERY_S]:
            ai[I_RECOVERIES] += 1
        # recovering: no faster than a gyro can drift, so that an acceleration that lasts
        # pulls the tilt by that rate only
        angle = min(angle, pa[P_RECOVERY_RATE] * dt)
    else:
        af[A_REJECT_S] = 0.0
        if pa[P_TILT_TAU] > 0.0 and not rest:
            angle *= min(1.0, dt / pa[P_TILT_TAU])
        angle = min(angle, pa[P_TILT_RATE] * dt)
        learn = True
    ai[I_AIDED] += 1
    f = angle / h
    return f * gy, -f * gx, learn


@kernel(inline=True)
def _lowpass(pa, af, ai, dt, tau, nx, ny, nz):
    """The specific force ``n`` (nav frame) through the filter's low-pass of time constant
    ``tau``: its output (the filtered vertical, not normalized)."""
    lp = A_LP
    if ai[I_HAS_LP] == 0:
        # a new low-pass: the mean of the samples so far for its first accel_tau_s (as VQF),
        # then the Butterworth from the steady state at that mean
        af[lp], af[lp + 1], af[lp + 2] = nx, ny, nz
        af[lp + 3], af[lp + 4], af[lp + 5] = 0.0, 0.0, 0.0
        ai[I_HAS_LP] = LP_MEAN
        af[A_RUN_S] = 0.0
        gx, gy, gz = nx, ny, nz
    elif ai[I_HAS_LP] == LP_MEAN:
        af[A_RUN_S] += dt
        # the time-weighted mean (the first sample weighs one interval): 1/(k+1) at a steady
        # rate; it lives in the almost-inertial frame like the Butterworth's state
        w = dt / (af[A_RUN_S] + dt)
        for i, n in ((0, nx), (1, ny), (2, nz)):
            af[lp + i] += w * (n - af[lp + i])
        gx, gy, gz = af[lp], af[lp + 1], af[lp + 2]
        if af[A_RUN_S] >= pa[P_ACCEL_TAU]:
            _, c1, c2, c3, c4 = _coefficients(af, ai, tau, dt)
            r1 = c1 - c3 + c2 - c4
            r2 = c2 - c4
            af[lp], af[lp + 1], af[lp + 2] = r1 * gx, r1 * gy, r1 * gz
            af[lp + 3], af[lp + 4], af[lp + 5] = r2 * gx, r2 * gy, r2 * gz
            ai[I_HAS_LP] = LP_BUTTERWORTH
    else:
        af[A_RUN_S] += dt
        ob0, ob2, oa2 = af[A_COEF], af[A_COEF + 2], af[A_COEF + 4]
        b0, b1, b2, a1, a2 = _coefficients(af, ai, tau, dt)  # (set when the mean ended)
        if b0 != ob0 or b2 != ob2 or a2 != oa2:
            # new coefficients (the time constant switched at a rest's start or end, or the
            # interval changed): the state moved by the difference of the two steady states
            # at the last output, so the output goes on from where it was instead of jumping
            # (a 0.5 s → 3 s switch would swell it 4× for seconds)
            d1, d2 = ob0 - b0, (b2 - a2) - (ob2 - oa2)
            for i in range(3):
                af[lp + i] += d1 * af[A_LP_OUT + i]
                af[lp + 3 + i] += d2 * af[A_LP_OUT + i]
        for i, n in ((0, nx), (1, ny), (2, nz)):  # direct form II transposed
            g = b0 * n + af[lp + i]
            af[lp + i] = b1 * n - a1 * g + af[lp + 3 + i]
            af[lp + 3 + i] = b2 * n - a2 * g
            af[A_LP_OUT + i] = g
        gx, gy, gz = af[A_LP_OUT], af[A_LP_OUT + 1], af[A_LP_OUT + 2]
    return gx, gy, gz


@kernel(inline=True)
def _coefficients(af, ai, tau, dt):
    """The low-pass coefficients for ``tau`` and ``dt``, kept while both stay (0.1 µs steps
    of dt: a jittery clock reuses them)."""
    key_dt = round(dt * 1e7)
    if ai[I_HAS_KEY] == 0 or af[A_KEY_TAU] != tau or ai[I_KEY_DT] != key_dt:
        ai[I_HAS_KEY], ai[I_KEY_DT], af[A_KEY_TAU] = 1, key_dt, tau
        (af[A_COEF], af[A_COEF + 1], af[A_COEF + 2], af[A_COEF + 3],
         af[A_COEF + 4]) = _butterworth2(tau, dt)
    return af[A_COEF], af[A_COEF + 1], af[A_COEF + 2], af[A_COEF + 3], af[A_COEF + 4]


@kernel
def _heading(pa, af, ai, dt, mag_state, m0, m1, m2, hx, hy, hz, c00, c01, c02, c10, c11, c12,
             c20, c21, c22):
    """(heading correction (nav z rotation), steady) of one magnetometer sample (tesla);
    ``h`` the body rotation over half the step (see :func:`ahrs_step`)."""
    if mag_state != MAG_GIVEN or not within(m0, m1, m2, MAG_ABSURD_T):
        ai[I_MAG_INVALID] += 1
        return 0.0, False
    mx, my, mz = m0 - af[A_HARD_IRON], m1 - af[A_HARD_IRON + 1], m2 - af[A_HARD_IRON + 2]
    norm = math.sqrt(mx * mx + my * my + mz * mz)
    if norm < MAG_ZERO_T or m0 * m0 + m1 * m1 + m2 * m2 < MAG_ZERO_T * MAG_ZERO_T:
        # a reading of (almost) zero is no reading, whatever the hard iron
        ai[I_MAG_INVALID] += 1
        return 0.0, False
    if ai[I_HI_ON] == 1:
        _hard_iron_step(pa, af, ai, dt, m0, m1, m2)
    mx, my, mz = mx + hy * mz - hz * my, my + hz * mx - hx * mz, mz + hx * my - hy * mx
    ex = c00 * mx + c01 * my + c02 * mz
    ey = c10 * mx + c11 * my + c12 * mz
    ez = c20 * mx + c21 * my + c22 * mz
    horiz = math.sqrt(ex * ex + ey * ey)
    dip = math.atan2(-ez, horiz)
    learned = ai[I_HAS_REF_NORM] == 1 and ai[I_HAS_REF_DIP] == 1
    if not _reference_ok(pa, af, ai, dt, norm, dip) and (learned or ai[I_HEADING_INIT] == 1):
        # disturbed, or the reference not learned yet once the heading is set (the first
        # field sets the heading at once: waiting for the reference would set it in motion)
        return 0.0, False
    if horiz < 1e-3 * norm:
        return 0.0, False  # at a magnetic pole the horizontal field gives no heading
    err = wrap_pi_float(math.atan2(ex, ey) - pa[P_DECL])
    ai[I_MAG_USED] += 1
    if ai[I_HEADING_INIT] == 0:
        ai[I_HEADING_INIT] = 1
        af[A_SINCE_HEADING] = 0.0
    af[A_SINCE_HEADING] += dt
    # The heading is set from the field by a fast first phase (time constant
    # HEADING_INIT_TAU_S for HEADING_INIT_S: any initial error falls by e^-6.7), then the
    # time constant grows with the time since (a running average) up to mag_tau_s.  Not
    # one jump: a correction is a body rate, and a 90° spike in one interval is not
    # integrated faithfully by the higher-order integrators.
    since = af[A_SINCE_HEADING] - HEADING_INIT_S
    tau = min(pa[P_MAG_TAU], max(HEADING_INIT_TAU_S, since))
    return err * min(1.0, dt / tau), since >= pa[P_MAG_TAU]


@kernel
def _reference_ok(pa, af, ai, dt, norm, dip) -> bool:
    """Whether the field agrees with the reference (learning or replacing it as needed)."""
    tol = pa[P_MAG_NORM_TOL]
    dip_tol = pa[P_DIP_TOL]
    if ai[I_HAS_REF_NORM] == 0 or ai[I_HAS_REF_DIP] == 0:
        acc = A_REF_ACC
        if af[acc + 2] > 0.0 and (abs(norm - af[acc] / af[acc + 2]) > tol * norm
                                  or abs(dip - af[acc + 1] / af[acc + 2]) > dip_tol):
            af[acc], af[acc + 1], af[acc + 2] = 0.0, 0.0, 0.0  # not steady: learn again
        w = max(dt, 1e-3)
        af[acc] += norm * w
        af[acc + 1] += dip * w
        af[acc + 2] += w
        if af[acc + 2] >= pa[P_MAG_REF_S]:
            if ai[I_HAS_REF_NORM] == 0:
                af[A_REF_NORM], ai[I_HAS_REF_NORM] = af[acc] / af[acc + 2], 1
            if ai[I_HAS_REF_DIP] == 0:
                af[A_REF_DIP], ai[I_HAS_REF_DIP] = af[acc + 1] / af[acc + 2], 1
        return False
    ref_n, ref_d = af[A_REF_NORM], af[A_REF_DIP]
    if abs(norm - ref_n) <= tol * ref_n and abs(dip - ref_d) <= dip_tol:
        ai[I_HAS_CAND] = 0
        return True
    ai[I_MAG_DISTURBED] += 1
    c = A_CAND
    if ai[I_HAS_CAND] == 0 or abs(norm - af[c]) > tol * af[c] or abs(dip - af[c + 1]) > dip_tol:
        af[c], af[c + 1], af[c + 2] = norm, dip, 0.0
        ai[I_HAS_CAND] = 1
    else:
        af[c + 2] = af[c + 2] + dt
        if af[c + 2] >= pa[P_MAG_RECOVERY_S] and (af[c + 1] > 0.0) == (ref_d > 0.0):
            af[A_REF_NORM], af[A_REF_DIP] = af[c], af[c + 1]
            ai[I_REF_CHANGES] += 1
            ai[I_HAS_CAND] = 0
    return False


@kernel
def _hard_iron_step(pa, af, ai, dt, m0, m1, m2):
    """Accumulate the sphere-fit sums in µT (well scaled) and solve every second."""
    x, y, z = m0 * 1e6, m1 * 1e6, m2 * 1e6
    r = x * x + y * y + z * z
    terms = (x * x, x * y, x * z, y * y, y * z, z * z, x, y, z, 1.0, r * x, r * y, r * z, r)
    for i in range(14):
        af[A_HI_SUMS + i] += terms[i]
    af[A_HI_SINCE] += dt
    if af[A_HI_SINCE] >= HARD_IRON_SOLVE_S:
        forget = math.exp(-af[A_HI_SINCE] / pa[P_HI_WINDOW_S])
        af[A_HI_SINCE] = 0.0
        _solve_hard_iron(pa, af, ai)
        for i in range(14):
            af[A_HI_SUMS + i] *= forget


@kernel
def _solve_hard_iron(pa, af, ai):
    """Solve ``m·m = 2 b·m + c`` in the least-squares sense from the sums: accepted when the
    field's directions are spread (the smallest eigenvalue of the scatter of m at least
    (r/3)²/3, as from rotations of ±40° or more about two axes) and the fit is of Earth-field
    size.  Written out (numba's LAPACK bindings take ~15 s to compile): Cholesky of the
    symmetric normal matrix (not positive definite: a degenerate fit), and Sylvester's
    criterion on scatter − λI for the eigenvalue bound."""
    sm = A_HI_SUMS
    n = af[sm + 9]
    if n < 50:
        return
    s00, s01, s02, s11, s12, s22 = (af[sm], af[sm + 1], af[sm + 2], af[sm + 3], af[sm + 4],
                                    af[sm + 5])
    x0, x1, x2 = af[sm + 6], af[sm + 7], af[sm + 8]
    # the normal equations A [b, c] = rhs, A = [[4 Sxx, 2 Sx], [2 Sxᵀ, n]] (lower triangle)
    a = np.zeros((4, 4))
    a[0, 0], a[1, 0], a[1, 1] = 4.0 * s00, 4.0 * s01, 4.0 * s11
    a[2, 0], a[2, 1], a[2, 2] = 4.0 * s02, 4.0 * s12, 4.0 * s22
    a[3, 0], a[3, 1], a[3, 2], a[3, 3] = 2.0 * x0, 2.0 * x1, 2.0 * x2, n
    rhs = np.array([2.0 * af[sm + 10], 2.0 * af[sm + 11], 2.0 * af[sm + 12], af[sm + 13]])
    # Cholesky A = L Lᵀ in place (lower triangle), then L y = rhs, Lᵀ sol = y
    for j in range(4):
        d = a[j, j]
        for k in range(j):
            d -= a[j, k] * a[j, k]
        if not d > 0.0:
            return  # not positive definite: the field seen from too few directions
        a[j, j] = math.sqrt(d)
        for i in range(j + 1, 4):
            e = a[i, j]
            for k in range(j):
                e -= a[i, k] * a[j, k]
            a[i, j] = e / a[j, j]
    sol = np.empty(4)
    for i in range(4):
        e = rhs[i]
        for k in range(i):
            e -= a[i, k] * sol[k]
        sol[i] = e / a[i, i]
    for i in range(3, -1, -1):
        e = sol[i]
        for k in range(i + 1, 4):
            e -= a[k, i] * sol[k]
        sol[i] = e / a[i, i]
    b0, b1, b2 = sol[0], sol[1], sol[2]
    r2 = sol[3] + (b0 * b0 + b1 * b1 + b2 * b2)
    if not (math.isfinite(b0) and math.isfinite(b1) and math.isfinite(b2)
            and math.isfinite(sol[3])) or not r2 > 0:
        return
    r = math.sqrt(r2)
    if not 5.0 <= r <= 1000.0:  # µT: an Earth-like field (and a nearby steel structure)
        return
    # scatter − λI positive definite (Sylvester: its leading minors positive)
    lam = (r / 3.0) ** 2 / 3.0
    m0, m1, m2 = x0 / n, x1 / n, x2 / n
    c00 = s00 / n - m0 * m0 - lam
    c01 = s01 / n - m0 * m1
    c02 = s02 / n - m0 * m2
    c11 = s11 / n - m1 * m1 - lam
    c12 = s12 / n - m1 * m2
    c22 = s22 / n - m2 * m2 - lam
    minor2 = c00 * c11 - c01 * c01
    minor3 = (c00 * (c11 * c22 - c12 * c12) - c01 * (c01 * c22 - c12 * c02)
              + c02 * (c01 * c12 - c11 * c02))
    if not (c00 > 0.0 and minor2 > 0.0 and minor3 > 0.0):
        return
    af[A_HARD_IRON], af[A_HARD_IRON + 1], af[A_HARD_IRON + 2] = b0 * 1e-6, b1 * 1e-6, b2 * 1e-6
    ai[I_HI_FITS] += 1
    if pa[P_REF_NORM_GIVEN] == 0.0:
        af[A_REF_NORM], ai[I_HAS_REF_NORM] = r * 1e-6, 1
