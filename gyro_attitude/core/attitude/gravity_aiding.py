"""Gravity aiding: tilt pulled toward the accelerometer's vertical with gyro-bias feedback (Mahony-style).

Contract (streaming): ``GravityAiding.update(t_ns, gyro, accel, q_nb) -> rate`` once per accepted
sample; ``gyro`` is the rate with the known bias already removed (gyro_bias.py), ``q_nb`` the
current attitude estimate (body→ENU), and the returned rate (3,) rad/s is what the attitude
integrator should integrate for the interval ending at this sample.  O(1), plain floats.
:func:`gravity_aided_attitude` is the batch form; the filter is a feedback loop through the
attitude, so it cannot be vectorized: the batch runs the same per-sample step (with the exact
exponential-map integrator) and returns the same numbers as the stream.

The complementary filter (Mahony et al. 2008, explicit complementary filter): with the measured
up ``a = f/‖f‖`` and the predicted up ``v = C_bn e_up``, the error ``e = a × v`` is the small
rotation (body frame) taking ``v`` to ``a``; the integrated rate is
``ω − b_a + k_p e`` and the bias correction integrates ``ḃ_a = −k_i e``.  The loop is a
first-order low-pass on tilt with time constant ``1/k_p`` (default 1 s; on the BROAD
recordings 1 s and a 2 m/s² gate beat 5 s and 0.3 m/s²): accelerometer noise and
brief accelerations are averaged, gyro errors are bounded.  Gated off — pure gyro integration —
while ``|‖f‖ − g| > accel_tol`` or ``‖ω‖ > rate_max``: during fast translation the specific
force is not gravity.

Fast translation (BROAD trial 16): the norm gate is blind to horizontal acceleration — it
changes ``‖f‖`` only to second order (``√(g² + a_h²) − g``: 6 m/s² sideways passes a 2 m/s²
gate while tilting the measured vertical by 31°) — so a hand moved briskly back and forth
pulled the tilt 34° off (the "heading excursion" of phase 1 was a tilt excursion: the error
was all tilt).  With ``accel_lowpass_s`` > 0 (the stream's default 1 s) the specific force is
low-passed in the nav frame before use, ``f̄_n ← f̄_n + α (C_nb f − f̄_n)``, as VQF does in its
almost-inertial frame: accelerations of a motion that starts and ends at rest average out
(their integral is the velocity change), gravity does not.  On trial 16 this takes the RMS
tilt error over the motion from 14.9° to 1.3° (docs/real_sensors.md).

Heading is not observable from gravity: ``e`` is always horizontal in the nav frame's sense, so
the vertical-axis bias and the heading stay gyro-only and drift (by the residual vertical bias ×
time) without a magnetometer or other heading aid.
"""

from __future__ import annotations

import math

import numpy as np

from gyro_attitude.core.attitude.rest import check_sample, check_samples
from gyro_attitude.core.attitude.streaming import StreamingIntegrator
from gyro_attitude.core.earth import STANDARD_GRAVITY
from gyro_attitude.core.jit import compiled, kernel
from gyro_attitude.core.rotation import as_quat_array

__all__ = ["GravityAiding", "gravity_aided_attitude"]


def _param(name, v, lo=0.0) -> float:
    try:
        x = float(v)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {v!r}") from None
    if not math.isfinite(x) or x < lo or x > 1e6:
        raise ValueError(f"{name} must be a finite number >= {lo}, got {v!r}")
    return x


# The filter's state as arrays (what the compiled chain steps): float slots
G_BIAS, G_F_NAV = 0, 3  # tilt-axis bias estimate (3), low-passed specific force, nav frame (3)
# int slots
G_LAST_T, G_HAS_LAST, G_AIDED, G_HAS_F_NAV = range(4)
# parameters
G_KP, G_KI, G_ACCEL_TOL, G_RATE_MAX, G_GRAVITY, G_LOWPASS_S = range(6)


class GravityAiding:
    """Streaming tilt aiding (see the module docstring).  The per-sample step is the kernel
    :func:`gravity_step` over the arrays ``params``, ``gf`` (float state) and ``gi`` (int
    state); ``bias``, ``last_t_ns`` and ``aided_samples`` read (and the time base resets)
    through them."""

    def __init__(self, kp: float = 1.0, ki: float = 0.002, accel_tol: float = 2.0,
                 rate_max: float = 1.0, gravity: float = STANDARD_GRAVITY, accel_lowpass_s: float = 0.0):
        self.accel_lowpass_s = _param("accel_lowpass_s", accel_lowpass_s)
        self.kp = _param("kp", kp)
        self.ki = _param("ki", ki)
        self.accel_tol = _param("accel_tol", accel_tol)
        self.rate_max = _param("rate_max", rate_max)
        self.gravity = _param("gravity", gravity, 1.0)
        self.params = np.array([self.kp, self.ki, self.accel_tol, self.rate_max, self.gravity,
                                self.accel_lowpass_s])
        self.reset()

    def reset(self) -> None:
        """Back to the start, in place (the compiled chain holds the arrays)."""
        if not hasattr(self, "gf"):
            self.gf = np.zeros(6)
            self.gi = np.zeros(4, dtype=np.int64)
        self.gf[:] = 0.0
        self.gi[:] = 0

    @property
    def bias(self) -> list[float]:
        """Tilt-axis bias estimate, rad/s (subtracted)."""
        return self.gf[G_BIAS:G_BIAS + 3].tolist()

    @property
    def aided_samples(self) -> int:
        return int(self.gi[G_AIDED])

    @property
    def last_t_ns(self) -> int | None:
        """The last sample's stamp (ns), None for a new time base."""
        return int(self.gi[G_LAST_T]) if self.gi[G_HAS_LAST] else None

    def update(self, t_ns: int, gyro, accel, q_nb, mag=None) -> np.ndarray:
        """One sample (``mag`` is not used: the aiding-stage signature of ahrs.py)."""
        t, w, f = check_sample(t_ns, gyro, accel)
        q = as_quat_array(q_nb, "q_nb")
        if q.shape != (4,):
            raise ValueError(f"q_nb must have shape (4,), got {q.shape}")
        return np.array(self.step(t, w, f, q.tolist()))

    def step(self, t: int, w, f, q, mag=None) -> tuple[float, float, float]:
        """:meth:`update` on inputs already checked (what the stream's chain passes): ``t`` int
        ns, ``w`` 3 finite floats, ``f`` 3 finite floats or None, ``q`` 4 floats; the rate as
        a 3-tuple."""
        gi = self.gi
        if gi[G_HAS_LAST] and t <= gi[G_LAST_T]:
            raise ValueError(f"t_ns must increase: {t} after {int(gi[G_LAST_T])}")
        if f is None:
            return compiled(gravity_step)(self.params, self.gf, gi, t, w[0], w[1], w[2], False,
                                          0.0, 0.0, 0.0, q[0], q[1], q[2], q[3])
        return compiled(gravity_step)(self.params, self.gf, gi, t, w[0], w[1], w[2], True,
                                      f[0], f[1], f[2], q[0], q[1], q[2], q[3])


@kernel
def gravity_step(p, gf, gi, t, w0, w1, w2, has_f, f0, f1, f2, x, y, z, s):
    """One sample of the complementary filter (module docstring) on its state arrays: ``t``
    int ns after the last, ``w`` the gyro rate less the known bias, ``f`` the specific force
    (``has_f``), ``(x, y, z, s)`` the current attitude; the rate to integrate."""
    dt = 0.0 if gi[G_HAS_LAST] == 0 else (t - gi[G_LAST_T]) * 1e-9
    gi[G_LAST_T], gi[G_HAS_LAST] = t, 1
    o0, o1, o2 = w0 - gf[G_BIAS], w1 - gf[G_BIAS + 1], w2 - gf[G_BIAS + 2]
    if not has_f:
        return o0, o1, o2
    if dt == 0.0:
        gi[G_HAS_F_NAV] = 0  # a new time base: the low-pass starts again
    fn = math.sqrt(f0 * f0 + f1 * f1 + f2 * f2)
    nq = x * x + y * y + z * z + s * s
    if p[G_LOWPASS_S] > 0.0:
        f0, f1, f2 = _lowpass(p, gf, gi, f0, f1, f2, x, y, z, s, 2.0 / nq, dt)
    wn = math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
    if abs(fn - p[G_GRAVITY]) > p[G_ACCEL_TOL] or wn > p[G_RATE_MAX] or dt == 0.0:
        return o0, o1, o2
    # v = C_bn e_up: the third row of C_nb (unit quaternion, scalar last), normalized.
    v0, v1, v2 = (2 * (x * z - s * y) / nq, 2 * (y * z + s * x) / nq,
                  1 - 2 * (x * x + y * y) / nq)
    fa = math.sqrt(f0 * f0 + f1 * f1 + f2 * f2)
    if fa == 0.0:
        return o0, o1, o2  # no specific force (a gate wide enough to pass 0): no vertical
    a0, a1, a2 = f0 / fa, f1 / fa, f2 / fa
    e0, e1, e2 = a1 * v2 - a2 * v1, a2 * v0 - a0 * v2, a0 * v1 - a1 * v0
    kp, ki = p[G_KP], p[G_KI]
    gf[G_BIAS] = gf[G_BIAS] - ki * e0 * dt
    gf[G_BIAS + 1] = gf[G_BIAS + 1] - ki * e1 * dt
    gf[G_BIAS + 2] = gf[G_BIAS + 2] - ki * e2 * dt
    gi[G_AIDED] += 1
    return o0 + kp * e0, o1 + kp * e1, o2 + kp * e2


@kernel
def _lowpass(p, gf, gi, f0, f1, f2, x, y, z, s, k, dt):
    """The specific force low-passed in the nav frame, seen in the body (see the module
    docstring): ``f_n = C_nb f`` is averaged with time constant ``accel_lowpass_s``."""
    c00, c01, c02 = 1 - k * (y * y + z * z), k * (x * y - z * s), k * (x * z + y * s)
    c10, c11, c12 = k * (x * y + z * s), 1 - k * (x * x + z * z), k * (y * z - x * s)
    c20, c21, c22 = k * (x * z - y * s), k * (y * z + x * s), 1 - k * (x * x + y * y)
    n0 = c00 * f0 + c01 * f1 + c02 * f2
    n1 = c10 * f0 + c11 * f1 + c12 * f2
    n2 = c20 * f0 + c21 * f1 + c22 * f2
    if gi[G_HAS_F_NAV] == 0:
        gf[G_F_NAV], gf[G_F_NAV + 1], gf[G_F_NAV + 2] = n0, n1, n2
        gi[G_HAS_F_NAV] = 1
    else:
        alpha = dt / (p[G_LOWPASS_S] + dt)
        gf[G_F_NAV] = gf[G_F_NAV] + alpha * (n0 - gf[G_F_NAV])
        gf[G_F_NAV + 1] = gf[G_F_NAV + 1] + alpha * (n1 - gf[G_F_NAV + 1])
        gf[G_F_NAV + 2] = gf[G_F_NAV + 2] + alpha * (n2 - gf[G_F_NAV + 2])
    l0, l1, l2 = gf[G_F_NAV], gf[G_F_NAV + 1], gf[G_F_NAV + 2]
    return (c00 * l0 + c10 * l1 + c20 * l2, c01 * l0 + c11 * l1 + c21 * l2,
            c02 * l0 + c12 * l1 + c22 * l2)


def gravity_aided_attitude(t_ns, gyro, accel, q0, *, kp: float = 1.0, ki: float = 0.002,
                           accel_tol: float = 2.0, rate_max: float = 1.0,
                           gravity: float = STANDARD_GRAVITY) -> tuple[np.ndarray, np.ndarray]:
    """Batch: attitudes (N, 4) and the tilt-axis bias estimate (N, 3) from bias-free ``gyro``.

    Integrates with the exponential map of the trapezoid increment (``exp_map``); the aiding
    sees the attitude at the previous sample (causal).
    """
    t, w, f = check_samples(t_ns, gyro, accel)
    aid = GravityAiding(kp, ki, accel_tol, rate_max, gravity)
    integ = StreamingIntegrator("exp_map", q0=q0)
    q = np.empty((t.size, 4))
    bias = np.empty((t.size, 3))
    cur = integ.quaternion
    for k in range(t.size):
        rate = aid.update(int(t[k]), w[k], None if f is None else f[k], cur)
        cur = integ.update(int(t[k]), rate)
        q[k] = cur
        bias[k] = aid.bias
    return q, bias
