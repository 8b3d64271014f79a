"""Honest orientation covariance: per-axis attitude/bias error propagation (noise, bias, alignment, aiding).

Per axis ``i`` the error state is ``x = [δθ_i, δb_i]`` (attitude error [rad], error of the gyro
bias subtracted [rad/s]) with covariance ``P = [[tt, tb], [tb, bb]]``.  Over an accepted interval
``dt`` the attitude error integrates the bias error, ``δθ' = δθ − δb dt + n``, and the bias error
walks, ``δb' = δb + w``:

* ``tt += q − 2 dt·tb + dt²·bb``; ``tb −= dt·bb``; ``bb += K² dt``;
* ``q`` is the angle-random-walk increment: ``σ_ω² dt²`` with ``σ_ω²`` the per-sample gyro variance
  of the message's ``angular_velocity_covariance``, else ``N² dt`` from the stated noise density
  ``N`` [rad/s/√Hz]; ``K`` [rad/s/√s] is the bias random walk (bias-uncertainty growth);
* a zero-rate update at a rest (gyro_bias ``auto``) re-estimates the bias from averaged samples
  independent of the past attitude error: ``bb = SE²`` (its standard error), ``tb = 0``;
  when the stream was still since its start and the attitude was corrected back to it with the
  first estimate (stream.py), the attitude error is ``−δb·Δt`` plus the noise so far:
  ``tt = tt₀ + Σq + bb Δt²``, ``tb = −bb Δt`` (:meth:`AttitudeCovariance.first_rest_update`);
* alignment sets ``tt`` to the levelling variance on the tilt axes and the heading variance on
  the third; a time-jump reset goes back to that initial ``tt`` with ``tb = 0`` (``bb`` stays:
  the bias knowledge survives a jump of the clock);
* gravity aiding relaxes the tilt axes (0, 1) toward the levelling floor ``σ_level²`` (the
  accelerometer-bias term, which averaging does not beat) with the loop gain ``k_p``:
  ``tt ← a² tt + (1 − a²) σ_level²``, ``tb ← a tb``, ``a = 1 − k_p dt``; the heading axis stays
  gyro-only and its variance keeps growing.

The axes are the output's (nav) axes fed with the body-axis figures of the same index: exact for a
sensor whose three axes have equal noise and bias uncertainty (then ``C_nb δb`` has the same
statistics as ``δb``), a per-axis approximation otherwise.  Correlations between axes are not
carried (a 3×3 diagonal covariance is published).

:meth:`AttitudeCovariance.run` is the same recurrence over arrays (cumulative sums in the same
order as the per-row adds: identical numbers).
"""

from __future__ import annotations

import numpy as np

from gyro_attitude.core.jit import compiled, kernel

__all__ = ["AttitudeCovariance"]


# the state as one array (what the compiled chain steps): tt, tb, bb and Σq per axis
V_TT, V_TB, V_BB, V_NOISE = 0, 3, 6, 9


class AttitudeCovariance:
    """Per-axis 2×2 attitude/bias error covariance (see the module docstring).

    The state is one array ``c`` (12,) (``tt``, ``tb``, ``bb``, ``noise``: read and set as
    (3,) arrays); the per-row updates (:meth:`propagate`, :meth:`aid_tilt`) are the kernels
    :func:`propagate` and :func:`aid_tilt` on it, which the compiled chain calls too."""

    def __init__(self, initial_tt, bias_sigma: float = 0.0, bias_rw: float = 0.0):
        self.initial_tt = initial_tt
        self.c = np.zeros(12)
        self.c[V_TT:V_TT + 3] = self._it
        self.c[V_BB:V_BB + 3] = float(bias_sigma) ** 2
        self.k2 = float(bias_rw) ** 2

    @staticmethod
    def _three(x) -> list[float]:
        return np.broadcast_to(np.asarray(x, dtype=np.float64), (3,)).tolist()

    def _slot(i):
        def get(self):
            return self.c[i:i + 3].copy()

        def put(self, x):
            self.c[i:i + 3] = self._three(x)
        return property(get, put)

    initial_tt = property(lambda self: np.array(self._it),
                          lambda self, x: setattr(self, "_it", self._three(x)))
    tt = _slot(V_TT)
    tb = _slot(V_TB)
    bb = _slot(V_BB)
    noise = _slot(V_NOISE)
    del _slot


    def propagate(self, dt_s: float, q) -> None:
        """One accepted interval of ``dt_s`` seconds with angle-random-walk increment ``q`` (3,)."""
        compiled(propagate)(self.c, self.k2, dt_s, q[0], q[1], q[2])

    def zero_rate_update(self, standard_error) -> None:
        """A new bias estimate from a rest with per-axis standard error (3,) rad/s."""
        se0, se1, se2 = (float(se) for se in standard_error)
        zero_rate_update(self.c, se0, se1, se2)

    def align(self, tt) -> None:
        """The attitude became known with per-axis variance ``tt`` (also the reset value)."""
        self.initial_tt = tt
        self.reset_attitude()

    def reset_attitude(self) -> None:
        """Back to the initial attitude (time-jump reset)."""
        compiled(reset_attitude)(self.c, np.array(self._it))



@kernel(inline=True)
def propagate(c, k2, dt_s, q0, q1, q2):
    """:meth:`AttitudeCovariance.propagate` on the state array ``c`` (bias random walk ``k2``)."""
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
    """:meth:`AttitudeCovariance.zero_rate_update` on the state array ``c``."""
    for i, se in ((0, se0), (1, se1), (2, se2)):
        c[V_BB + i] = se ** 2
        c[V_TB + i] = 0.0


@kernel(inline=True)
def aid_tilt(c, kp_dt, floor_var):
    """:meth:`AttitudeCovariance.aid_tilt` on the state array ``c``."""
    a = 1.0 - min(kp_dt, 1.0)
    a2 = a * a
    for i in range(2):
        c[V_TT + i] = a2 * c[V_TT + i] + (1.0 - a2) * floor_var
        c[V_TB + i] = a * c[V_TB + i]



@kernel
def first_rest_update(c, it, se0, se1, se2, elapsed_s):
    """:meth:`AttitudeCovariance.first_rest_update` on the state array ``c`` (``it`` the
    initial attitude variance (3,))."""
    e2 = elapsed_s * elapsed_s
    for i, se in ((0, se0), (1, se1), (2, se2)):
        bb = se ** 2
        c[V_BB + i] = bb
        c[V_TT + i] = (it[i] + c[V_NOISE + i]) + e2 * bb
        c[V_TB + i] = -elapsed_s * bb


@kernel
def reset_attitude(c, it):
    """:meth:`AttitudeCovariance.reset_attitude` on the state array ``c``."""
    for i in range(3):
        c[V_TT + i] = it[i]
        c[V_TB + i] = 0.0
        c[V_NOISE + i] = 0.0
