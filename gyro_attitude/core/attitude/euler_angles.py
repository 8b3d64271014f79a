"""Euler-angle baselines: z-x-z (seed 1-10) and Krylov (seed 1-15) angle kinematics by RK4."""

from __future__ import annotations

import math
import warnings

import numpy as np

from gyro_attitude.core.attitude.algorithm import Algorithm
from gyro_attitude.core.attitude.interpolation import causal_fit_points
from gyro_attitude.core.euler_kinematics import (
    GimbalLockError,
    euler_zxz_rates_from_body_rates,
    krylov_rates_from_body_rates,
    quat_as_euler_zxz,
    quat_as_krylov,
    quat_from_euler_zxz,
    quat_from_krylov,
)


class EulerAnglesRK4(Algorithm):
    """Angle kinematics integrated by classical RK4; the mid-step rate comes from the causal
    cubic through the last four samples.  Divides by the ``divisor`` (sin θ / cos γ):
    raises :class:`GimbalLockError` near the singularity.  Nonlinear in its state: one
    Python step per sample (:class:`EulerStepper`, tens of µs), the batch a loop over it;
    inertial frame only."""

    sequential = True
    supports_nav = False

    def __init__(self, name, order, description, cost, to_angles, from_angles, rates_fn,
                 divisor_name: str, divisor):
        super().__init__(name, order, description, cost)
        self.to_angles = to_angles
        self.from_angles = from_angles
        self.rates_fn = rates_fn
        self.divisor_name = divisor_name
        self.divisor = divisor

    def step(self, angles, w0, wm, w1, h, tol, k, t_ns):
        """One RK4 step of the angle kinematics; raises GimbalLockError near the singularity.

        Two flags: the divisor below ``tol`` at any stage, or a step whose angle change
        exceeds what the body rotated by more than 1/tol — the discrete steps jump over the
        exact singularity, so the second catches the blow-up.
        """
        def f(a, w):
            d = abs(self.divisor(a))
            if d < tol:
                raise GimbalLockError(
                    f"Euler-angle integration reached its singularity at sample {k} "
                    f"(t = {t_ns} ns): |{self.divisor_name}| = {d:.3g} < {tol:g}; "
                    "use a quaternion algorithm")
            return self.rates_fn(a, w, tol=0.0)

        k1 = f(angles, w0)
        k2 = f(angles + 0.5 * h * k1, wm)
        k3 = f(angles + 0.5 * h * k2, wm)
        k4 = f(angles + h * k3, w1)
        step = (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        turned = h * max(float(np.abs(w0).max()), float(np.abs(w1).max()), 1e-300)
        if not np.all(np.isfinite(step)) or float(np.abs(step).max()) > 3.0 * turned / tol:
            raise GimbalLockError(
                f"Euler-angle integration blew up near its singularity at sample {k} "
                f"(t = {t_ns} ns): the angles moved {float(np.abs(step).max()):.3g} rad while "
                f"the body turned {turned:.3g} rad; use a quaternion algorithm")
        return angles + step

    def initial_angles(self, q0, tol):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # lock is reported below instead
            angles = self.to_angles(q0)
        d = abs(self.divisor(angles))
        if d < tol:
            raise GimbalLockError(f"the initial attitude is at the Euler-angle singularity: "
                                  f"|{self.divisor_name}| = {d:.3g} < {tol:g}")
        return angles

    def integrate(self, t, w, q0, rate_n, quadrature, singular_tol):
        """The streaming step over the rows: the attitudes (N, 4)."""
        stepper = EulerStepper(self, tuple(float(c) for c in q0), singular_tol)
        out = np.empty((t.size, 4))
        out[0] = q0
        for i in range(1, t.size):
            out[i] = stepper.interval(t[max(i - 3, 0):i + 1], w[max(i - 3, 0):i + 1], i == 2)
        return out

    def stepper(self, q0: tuple, singular_tol: float) -> EulerStepper:
        """A new per-stream state starting at the attitude ``q0`` (4 floats)."""
        return EulerStepper(self, q0, singular_tol)


class EulerStepper:
    """Streaming state of an :class:`EulerAnglesRK4` algorithm: the angles (numpy step)."""

    def __init__(self, algorithm: EulerAnglesRK4, q0: tuple, tol: float):
        self._alg = algorithm
        self._tol = tol
        self.q = q0
        self._angles = self._angles_start = algorithm.initial_angles(np.array(q0), tol)
        self._intervals = 0

    def interval(self, ts, ws, redo_first: bool = False) -> tuple[float, ...]:
        """Step over the newest interval of the ≤ 4-sample histories ``ts``, ``ws``; with
        ``redo_first`` (as the third sample arrives) interval 1 is first redone with the
        quadratic through samples 0, 1, 2."""
        if redo_first:
            self._angles = self._step(self._angles_start, ts, ws, 1, 3, 1)
        k = len(ts) - 1
        self._intervals += 1
        self._angles = self._step(self._angles, ts, ws, k, k + 1, self._intervals)
        q = self._alg.from_angles(self._angles)
        if float(np.dot(q, self.q)) < 0:
            q = -q
        self.q = tuple(float(c) for c in q)
        return self.q

    def _step(self, angles, ts, ws, k, n, count):
        wm, _, h = causal_fit_points(ts, ws, k, n, 0.5, 0.5)
        return self._alg.step(angles, np.asarray(ws[k - 1], dtype=np.float64), np.array(wm),
                              np.asarray(ws[k], dtype=np.float64), h, self._tol, count,
                              int(ts[k]))


EULER_ZXZ_RK4 = EulerAnglesRK4(
    "euler_zxz_rk4", 4, "z-x-z Euler angles (seed 1-10) integrated by RK4; singular at "
    "theta = 0, pi", "Python loop, ~50-100 us/sample", quat_as_euler_zxz, quat_from_euler_zxz,
    euler_zxz_rates_from_body_rates, "sin(theta)", lambda a: math.sin(a[1]))
EULER_KRYLOV_RK4 = EulerAnglesRK4(
    "euler_krylov_rk4", 4, "Krylov angles (seed 1-15) integrated by RK4; singular at "
    "gamma = +-90 deg", "Python loop, ~50-100 us/sample", quat_as_krylov, quat_from_krylov,
    krylov_rates_from_body_rates, "cos(gamma)", lambda a: math.cos(a[1]))
