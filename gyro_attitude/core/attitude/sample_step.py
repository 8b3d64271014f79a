"""One accepted sample through the causal chain, compiled: what :meth:`AttitudeStream.push` does
for the common sample in one call, and the integration step it shares with :meth:`run`'s loop.

:func:`advance_accepted` is steps 4.-6. of :meth:`AttitudeStream._integrate` for an accepted
sample (aiding, the causal cubic, the covariance) on the stages' state arrays;
:func:`.stream_loop.accept_rows` calls it per row.  :func:`push_sample` is the whole chain for
one sample that nothing special happens to: the validator's plain accept (finite rates within
``max_rate_rad_s``, a stamp after the last by less than 1.5 nominal periods and ``max_gap_s``),
a usable accelerometer sample (or none, as before), saturation, the bias stage's step
(:func:`.gyro_bias.bias_step`: the rest window and the accumulation; a new estimate is a
zero-rate update), then :func:`advance_accepted` and the interval statistics.  Where anything
else happens it stops, and the stream's Python steps take over from that point:

* :data:`NOT_PLAIN` before it changed anything (a sample the validator does not simply accept,
  an unusable or changed accelerometer, the rest window's ring full);
* :data:`AFTER_BIAS` after the bias stage, when a new estimate may still be applied back to the
  start; :data:`BIAS_REFUSED` when the bias stage refused the sample (the window to break);
* :data:`NOT_FINITE` after a non-finite attitude (the interval not yet counted);
* :data:`ALIGN` after the bias stage while aligning (the aligner's step is Python's); the
  bias stage then takes the Earth rate out at the level attitude of the sample's specific force
  (:func:`.alignment.level_q`), as :meth:`AttitudeStream._bias_attitude` does.

So the node's per-sample path runs the same kernels as :meth:`run` and :meth:`push`'s Python
form, in one interpreter call.
"""

from __future__ import annotations

import math

from gyro_attitude.core.attitude.ahrs import I_AIDED, ahrs_step
from gyro_attitude.core.attitude.alignment import level_q
from gyro_attitude.core.attitude.covariance import aid_tilt, propagate, zero_rate_update
from gyro_attitude.core.attitude.gravity_aiding import G_AIDED, gravity_step
from gyro_attitude.core.attitude.gyro_bias import B_BIAS, B_SE, J_UPDATED, bias_step
from gyro_attitude.core.attitude.rest import R_COUNT, R_HAS_ACCEL
from gyro_attitude.core.attitude.streaming import C_FALLBACKS, C_LAST_T, cubic_advance
from gyro_attitude.core.attitude.validation import interval_add, within
from gyro_attitude.core.jit import kernel

__all__ = ["AFTER_BIAS", "ALIGN", "BIAS_REFUSED", "DONE", "NOT_FINITE", "NOT_PLAIN",
           "advance_accepted", "push_sample", "saturation_step"]

#: :func:`push_sample`'s codes
DONE, NOT_PLAIN, AFTER_BIAS, BIAS_REFUSED, NOT_FINITE, ALIGN = 0, 1, 2, 3, 4, 5


@kernel
def saturation_step(sat, w0, w1, w2, sat_min):
    """The axis (-1: none) on which the accepted sample ``w`` repeats the previous value at the
    largest magnitude seen (at least ``sat_min``): a clip.  ``sat`` holds the largest |ω| per
    axis (0:3) and the last ω (3:6), updated."""
    pinned = -1
    for i, x in ((0, w0), (1, w1), (2, w2)):
        a = abs(x)
        if a > sat[i]:
            sat[i] = a
        if a == sat[i] and x == sat[3 + i] and a >= sat_min:
            pinned = i
        sat[3 + i] = x
    return pinned


@kernel
def advance_accepted(kind, gp, gf, gi, pa, af, ai, ci, ts, ws, cf, has_nav, n0, n1, n2, c, k2,
                     noise2, kp, floor_var, aided_seen, t, w0, w1, w2, has_a, a0, a1, a2,
                     m_state, m0, m1, m2, var_ok, s0, s1, s2, x, y, z, u):
    """Steps 4.-6. of :meth:`AttitudeStream._integrate` for an accepted sample at ``t`` with the
    rate ``w`` (bias taken out), from the attitude ``(x, y, z, u)``: aiding ``kind`` (0 none,
    1 gravity, 2 AHRS) on its arrays, the causal cubic on ``ci``/``ts``/``ws``/``cf``, the
    covariance ``c`` (angle random walk from the sample's variances ``s`` when ``var_ok``,
    else from ``noise2``; the aiding's tilt update when it aided).  Returns (whether the
    attitude is finite, fits that fell back, the aiding's sample count, the interval in ns,
    the attitude); the covariance is left alone when the attitude is not finite."""
    if kind == 1:
        w0, w1, w2 = gravity_step(gp, gf, gi, t, w0, w1, w2, has_a, a0, a1, a2, x, y, z, u)
    elif kind == 2:
        w0, w1, w2 = ahrs_step(pa, af, ai, t, w0, w1, w2, has_a, a0, a1, a2, x, y, z, u,
                               m_state, m0, m1, m2)
    last = ci[C_LAST_T]
    fell = ci[C_FALLBACKS]
    qx, qy, qz, qu = cubic_advance(ci, ts, ws, cf, t, w0, w1, w2, has_nav, n0, n1, n2)
    n_fb = ci[C_FALLBACKS] - fell
    if not (math.isfinite(qx) and math.isfinite(qy) and math.isfinite(qz)
            and math.isfinite(qu)):
        return False, n_fb, aided_seen, 0, x, y, z, u
    dt = t - last
    dt_s = dt * 1e-9
    # angle random walk: σ_ω² dt² per axis from the message, else N² dt (_integrate)
    if var_ok:
        d2 = dt_s * dt_s
        propagate(c, k2, dt_s, s0 * d2, s1 * d2, s2 * d2)
    else:
        nd = noise2 * dt_s
        propagate(c, k2, dt_s, nd, nd, nd)
    if kind != 0:
        aided = gi[G_AIDED] if kind == 1 else ai[I_AIDED]
        if aided != aided_seen:
            aid_tilt(c, kp * dt_s, floor_var)
        aided_seen = aided
    return True, n_fb, aided_seen, dt, qx, qy, qz, qu


@kernel
def push_sample(t, w0, w1, w2, has_a, a0, a1, a2, accel_present, m_state, m0, m1, m2, var_ok,
                s0, s1, s2, last_t, period, max_gap_ns, max_rate, accel_absurd, sat_min, sat,
                auto, first_rest_pending, aligning, heading, bf, bi, min_rest_ns, rf, ri, wt, wx, wc, pv, pe,
                earth_n, earth, ring, fill, kind, gp, gf, gi, pa, af, ai, ci, ts, ws, cf, has_nav,
                n0, n1, n2, c, k2, noise2, kp, floor_var, aided_seen, x, y, z, u):
    """One sample through the chain (module docstring): (code, the saturated axis or -1,
    fits that fell back, the aiding's sample count, the attitude).  ``accel_present`` the
    accelerometer's presence so far (-1 not known); ``last_t``/``period`` the validator's last
    stamp and nominal period (0 while being learnt); ``earth`` whether the bias stage takes
    the Earth rate out at the attitude (while ``aligning``: at the level attitude with
    ``heading``, rad)."""
    # 1. the validator's plain accept, and the accelerometer usable as before: or Python
    if not (abs(w0) <= max_rate and abs(w1) <= max_rate and abs(w2) <= max_rate):
        return NOT_PLAIN, -1, 0, aided_seen, x, y, z, u
    dt = t - last_t
    if dt <= 0 or dt > max_gap_ns or period <= 0 or 2 * dt >= 3 * period:
        return NOT_PLAIN, -1, 0, aided_seen, x, y, z, u
    if has_a and not within(a0, a1, a2, accel_absurd):  # NaN, inf or absurd: Python counts it
        return NOT_PLAIN, -1, 0, aided_seen, x, y, z, u
    if accel_present >= 0 and has_a != (accel_present == 1):
        return NOT_PLAIN, -1, 0, aided_seen, x, y, z, u
    if aligning and not has_a:  # the alignment needs the accelerometer: Python says so
        return NOT_PLAIN, -1, 0, aided_seen, x, y, z, u
    if auto and (ri[R_COUNT] == wt.shape[0] or (ri[R_HAS_ACCEL] >= 0
                                                and has_a != (ri[R_HAS_ACCEL] == 1))):
        return NOT_PLAIN, -1, 0, aided_seen, x, y, z, u
    pinned = saturation_step(sat, w0, w1, w2, sat_min)
    # 2. rest -> gyro bias
    if auto:
        ex, ey, ez, eu = x, y, z, u
        if aligning and earth:
            earth, ex, ey, ez, eu, _, _ = level_q(a0, a1, a2, heading)
        if bias_step(bf, bi, min_rest_ns, rf, ri, wt, wx, wc, pv, pe, earth_n, t, w0, w1, w2,
                     has_a, a0, a1, a2, earth, ex, ey, ez, eu) < 0:
            return BIAS_REFUSED, pinned, 0, aided_seen, x, y, z, u
        if bi[J_UPDATED] == 1:
            if first_rest_pending:
                return AFTER_BIAS, pinned, 0, aided_seen, x, y, z, u
            zero_rate_update(c, bf[B_SE], bf[B_SE + 1], bf[B_SE + 2])
    if aligning:
        return ALIGN, pinned, 0, aided_seen, x, y, z, u
    # 4.-6. aiding, integration, covariance
    ok, n_fb, seen, dt, qx, qy, qz, qu = advance_accepted(
        kind, gp, gf, gi, pa, af, ai, ci, ts, ws, cf, has_nav, n0, n1, n2, c, k2, noise2, kp,
        floor_var, aided_seen, t, w0 - bf[B_BIAS], w1 - bf[B_BIAS + 1], w2 - bf[B_BIAS + 2],
        has_a, a0, a1, a2, m_state, m0, m1, m2, var_ok, s0, s1, s2, x, y, z, u)
    if not ok:
        return NOT_FINITE, pinned, n_fb, aided_seen, x, y, z, u
    interval_add(ring, fill, dt)
    return DONE, pinned, n_fb, seen, qx, qy, qz, qu
