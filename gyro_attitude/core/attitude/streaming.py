"""Streaming attitude integration, one sample per call, with the same results as the batch."""

from __future__ import annotations

import math

import numpy as np

from gyro_attitude.core.attitude.inputs import check_q0
from gyro_attitude.core.attitude.nav_frame import NavFrame, nav_zeta_scalar
from gyro_attitude.core.attitude.quadrature import get_quadrature
from gyro_attitude.core.attitude.registry import DEFAULT_ALGORITHM, get_algorithm

_HISTORY = 4  # samples held: the causal cubic's four nodes


class StreamingIntegrator:
    """Per-sample attitude update with the same results as :func:`integrate_batch`.

    Every causal algorithm streams through its stepper (plain-float step, ~3-10 µs per
    call on the 2-core development machine; the Euler baselines step in numpy, tens of
    µs).  Offline algorithms (``causal`` False, e.g. ``magnus6_quintic``) need samples
    after each interval and are refused with ``ValueError``.

    ``update(t_ns, omega_ib_b)`` takes one rate sample and returns the attitude at
    ``t_ns`` (the first call, or the first after ``reset`` without ``t_ns``, only sets
    the time origin and returns ``q0``).  Increment algorithms get their increments from
    ``quadrature`` exactly as the batch interface does, or directly through
    ``update_increment(t_ns, delta_theta)``.  A NavFrame with time series is indexed by
    the sample count.  Raises ``ValueError`` on a zero/negative step or non-finite input.

    ``update_nav(nav)`` replaces the navigation frame by a constant one from the next
    sample on (a moving carrier whose velocity is measured while integrating): its rate
    ``ω_in^n`` is evaluated once, at the call, and is the nav rate *at the next sample*;
    the interval ending at that sample uses the trapezoid of the previous sample's rate
    and the new one, later intervals the new rate.  A stream whose nav frame is switched
    this way equals :func:`integrate_batch` with the NavFrame time series that holds the
    old values up to the sample before and the new values from that sample on.
    """

    def __init__(self, algorithm: str = DEFAULT_ALGORITHM, q0=(0.0, 0.0, 0.0, 1.0),
                 nav: NavFrame | None = None, t0_ns: int | None = None,
                 quadrature: str = "trapezoid", singular_tol: float = 1e-3):
        self.info = get_algorithm(algorithm)
        self.algorithm = self.info.name
        self._quadrature = get_quadrature(quadrature)
        self.quadrature = quadrature
        self.singular_tol = float(singular_tol)
        if nav is not None and not self.info.supports_nav:
            raise ValueError(f"{algorithm} integrates q_ib only; nav frames need a "
                             "quaternion algorithm")
        self.nav = nav
        self._nav_const = None
        self._nav_rates = None
        self._fallbacks_before = 0
        if nav is not None:
            if not isinstance(nav, NavFrame):
                raise ValueError(f"nav must be a NavFrame or None, got {type(nav).__name__}")
            n = nav.series_length()
            # A series is evaluated once for all samples (as the batch does): per-sample
            # numpy calls would cost ~30 µs per update.
            if n is None:
                self._nav_const = nav.rate_enu(None)
            else:
                self._nav_rates = nav.rate_enu(n)
        self.reset(q0, t0_ns)

    def reset(self, q0, t_ns: int | None = None) -> None:
        """Restart from attitude ``q0`` (at ``t_ns`` if given), dropping all history."""
        self._q = check_q0(q0)
        self._fallbacks_before = self.fit_fallbacks if hasattr(self, "_stepper") else 0
        self.samples = 0
        self.last_t_ns: int | None = None
        self._stepper = self.info.stepper(tuple(float(c) for c in self._q), self._quadrature,
                                          self.singular_tol)
        self._ts: list[int] = []
        self._ws: list[tuple[float, float, float]] = []
        self._nav_hist: list = []
        self._zeta_first = None
        if t_ns is not None:
            t = self._check_time(t_ns)
            rate = self._nav_rate_at(0)
            self.samples = 1
            self.last_t_ns = t
            self._ts = [t]
            self._nav_hist = [] if rate is None else [rate.tolist()]

    @property
    def quaternion(self) -> np.ndarray:
        return np.array(self._q, dtype=np.float64)

    @property
    def fit_fallbacks(self) -> int:
        """Intervals integrated so far (since construction, across resets) whose rate fit could
        not be trusted, integrated with the exponential map (the batch's ``fallbacks``)."""
        return self._fallbacks_before + getattr(self._stepper, "fit_fallbacks", 0)

    def update_nav(self, nav: NavFrame) -> None:
        """Use the constant navigation frame ``nav`` from the next sample on.

        ``ω_in^n`` of ``nav`` (Earth rate plus transport rate) is computed here, once, and
        becomes the nav rate at the next sample: the interval from the last sample to the
        next one integrates the trapezoid of the previous rate and this one, every later
        interval this one (until the next call).  Called before any sample (or between
        ``reset`` and the first sample), it is the rate from the first sample on.  The
        attitude and the history are kept; ``reset`` keeps the new frame.

        Raises ``ValueError`` (and changes nothing) when the integrator was built without a
        nav frame, ``nav`` is not a NavFrame, holds time series, or has an invalid
        latitude (beyond ±π/2) or non-finite values.
        """
        if self.nav is None:
            raise ValueError("update_nav needs an integrator built with a NavFrame (q_nb); "
                             "this one integrates q_ib")
        if not isinstance(nav, NavFrame):
            raise ValueError(f"nav must be a NavFrame, got {type(nav).__name__}")
        rate = nav.rate_enu(None)  # raises on series and on invalid values
        if rate.shape != (3,):
            raise ValueError(f"update_nav needs a constant NavFrame, got rate shape {rate.shape}")
        self.nav = nav
        self._nav_const = rate
        self._nav_rates = None

    def _nav_rate_at(self, index: int) -> np.ndarray | None:
        if self.nav is None:
            return None
        if self._nav_const is not None:
            return self._nav_const
        n = self._nav_rates.shape[0]
        if index >= n:
            raise ValueError(f"NavFrame time series has {n} samples; sample {index} is beyond")
        return self._nav_rates[index]

    def _check_time(self, t_ns) -> int:
        if isinstance(t_ns, float | np.floating) or not isinstance(t_ns, int | np.integer):
            raise ValueError(f"t_ns must be an int number of nanoseconds, got {t_ns!r}")
        t = int(t_ns)
        if self.last_t_ns is not None and t <= self.last_t_ns:
            raise ValueError(f"time step {t - self.last_t_ns} ns is not positive "
                             f"(t_ns={t} after {self.last_t_ns}): samples must be strictly "
                             "increasing in time")
        return t

    def _nav_zeta(self, t: int):
        """Push the nav rate of the new sample; ζ of the interval ending at it (or None)."""
        if self.nav is None:
            return None
        self._nav_hist = (self._nav_hist + [self._nav_rate_at(self.samples).tolist()])[-2:]
        if self.last_t_ns is None:
            return None
        return nav_zeta_scalar(self._nav_hist, (t - self.last_t_ns) * 1e-9)

    def update(self, t_ns: int, omega_ib_b) -> np.ndarray:
        """Consume one rate sample; return the attitude at ``t_ns`` (shape (4,))."""
        try:
            wx, wy, wz = (float(c) for c in omega_ib_b)
        except (TypeError, ValueError):
            raise ValueError(f"omega_ib_b must be 3 finite numbers, got {omega_ib_b!r}") from None
        if not (math.isfinite(wx) and math.isfinite(wy) and math.isfinite(wz)):
            raise ValueError("omega_ib_b contains non-finite values (NaN or inf)")
        return np.array(self.advance(self._check_time(t_ns), (wx, wy, wz)))

    def advance(self, t: int, w: tuple[float, float, float]) -> tuple[float, ...]:
        """:meth:`update` on a sample already checked (``t`` an int after ``last_t_ns``, ``w``
        3 finite floats): the attitude as 4 floats (the stream's per-sample path: no arrays)."""
        zeta = None if self.nav is None else self._nav_zeta(t)
        self.samples += 1
        if self.last_t_ns is None:
            self.last_t_ns = t
            self._ts, self._ws = [t], [w]
            return tuple(self._q)
        if not self._ws:
            self._ws = [w]  # reset(q0, t_ns): hold the first rate back to the start time
        ts, ws = self._ts, self._ws
        ts.append(t)
        ws.append(w)
        if len(ts) > _HISTORY:
            del ts[0]
            del ws[0]
        stepper = self._stepper
        if self.samples == 2:
            self._zeta_first = zeta
        elif self.samples == 3:
            stepper.redo_first(ts, ws, self._zeta_first)
        q = stepper.interval(ts, ws, zeta)
        self.last_t_ns = t
        self._q = q
        return q

    def update_increment(self, t_ns: int, delta_theta) -> np.ndarray:
        """Consume one angle increment over ``(last_t_ns, t_ns]`` (increment algorithms).

        The first call after construction/reset needs ``t0_ns`` (given to the
        constructor or to :meth:`reset`) so the interval is defined.
        """
        if self.info.consumes != "increment":
            raise ValueError(f"{self.algorithm} consumes rate samples; use update()")
        try:
            dx, dy, dz = (float(c) for c in delta_theta)
        except (TypeError, ValueError):
            raise ValueError("delta_theta must have shape (3,): 3 finite numbers, got "
                             f"{delta_theta!r}") from None
        if not (math.isfinite(dx) and math.isfinite(dy) and math.isfinite(dz)):
            raise ValueError("delta_theta contains non-finite values (NaN or inf)")
        t = self._check_time(t_ns)
        if self.last_t_ns is None:
            raise ValueError("update_increment needs a start time: pass t0_ns to the "
                             "constructor or reset(q0, t_ns)")
        zeta = self._nav_zeta(t)
        q = self._stepper.increment((dx, dy, dz), zeta)
        self.last_t_ns = t
        self.samples += 1
        self._q = q
        return np.array(q)
