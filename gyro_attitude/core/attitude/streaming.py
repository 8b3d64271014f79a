"""The causal algorithms' steps over their sample history, stepped one sample per call
(:class:`StreamingIntegrator`) or in a compiled loop over a record (:func:`integrate_rows`,
the batch): one code, the same bits."""

from __future__ import annotations

import math

import numpy as np

from gyro_attitude.core.attitude.algorithm import CUBIC, RK4, RateAlgorithm, body_increment
from gyro_attitude.core.attitude.compose import compose_scalar, exp_scalar
from gyro_attitude.core.attitude.coning import (
    F_Q_BLOCK,
    PREVIOUS,
    RULE_CUBIC,
    coning_step,
    get_quadrature,
    quadrature_increment,
)
from gyro_attitude.core.attitude.inputs import check_q0
from gyro_attitude.core.attitude.nav_frame import NavFrame, nav_rate_for
from gyro_attitude.core.attitude.registry import DEFAULT_ALGORITHM, get_algorithm
from gyro_attitude.core.jit import compiled, kernel

# RateState's int slots (a rate algorithm's; the coning state follows, coning.C_BLOCK ...)
C_N, C_SAMPLES, C_LAST_T, C_HAS_LAST, C_FALLBACKS, C_FIRST_FELL, C_NEED_W0, C_HAS_ZETA_FIRST, \
    C_HAS_NAV_PREV = range(9)
# and its float slots: the attitude, the stepper's start, ζ of the first interval, the last
# nav rate (4 + 4 + 3 + 3)
F_Q, F_Q_START, F_ZETA_FIRST, F_NAV_PREV = 0, 4, 8, 11


@kernel(inline=True)
def nav_interval(ci, cf, t, has_nav, r0, r1, r2):
    """ζ of the interval ending at ``t`` -- the trapezoid of the nav rates at its ends
    -- when there is one: (has ζ, ζ); the nav rate ``r`` kept for the next."""
    has_z = False
    z0 = z1 = z2 = 0.0
    if has_nav:
        if ci[C_HAS_LAST] == 1:
            h = (t - ci[C_LAST_T]) * 1e-9
            z0 = 0.5 * (cf[F_NAV_PREV] + r0) * h
            z1 = 0.5 * (cf[F_NAV_PREV + 1] + r1) * h
            z2 = 0.5 * (cf[F_NAV_PREV + 2] + r2) * h
            has_z = True
        cf[F_NAV_PREV], cf[F_NAV_PREV + 1], cf[F_NAV_PREV + 2] = r0, r1, r2
    return has_z, z0, z1, z2


@kernel(inline=True)
def _compose_into(cf, start, b, has_z, z0, z1, z2):
    """The attitude in the slots from ``start`` (the last one, or the start when the first
    interval is redone) advanced by the body increment ``b`` and, when ``has_z``, the
    nav-frame rotation ``z`` over the interval: stored as the attitude and returned."""
    q = (cf[start], cf[start + 1], cf[start + 2], cf[start + 3])
    if has_z:
        q = compose_scalar(q, b, (z0, z1, z2))
    else:
        q = compose_scalar(q, b, None)
    cf[F_Q], cf[F_Q + 1], cf[F_Q + 2], cf[F_Q + 3] = q
    return q


@kernel(inline=True)
def _take_sample(ci, ts, ws, cf, t, w0, w1, w2, has_nav, r0, r1, r2):
    """The sample ``t`` (int ns after the last), rate ``w`` and nav rate ``r`` (``has_nav``)
    into the history of the last four samples (``ts``, ``ws``): (samples now held, 0 when this
    one only starts a time base; the nav rotation ζ of its interval)."""
    has_z, z0, z1, z2 = nav_interval(ci, cf, t, has_nav, r0, r1, r2)
    if has_nav:
        ci[C_HAS_NAV_PREV] = 1
    ci[C_SAMPLES] += 1
    if ci[C_HAS_LAST] == 0:
        ci[C_LAST_T], ci[C_HAS_LAST], ci[C_N], ci[C_NEED_W0] = t, 1, 1, 0
        ts[0] = t
        ws[0, 0], ws[0, 1], ws[0, 2] = w0, w1, w2
        return 0, has_z, z0, z1, z2
    if ci[C_NEED_W0] == 1:  # reset(q0, t_ns): the first rate held back to the start time
        ws[0, 0], ws[0, 1], ws[0, 2] = w0, w1, w2
        ci[C_NEED_W0] = 0
    n = ci[C_N]
    if n == 4:
        for i in range(3):
            ts[i] = ts[i + 1]
            ws[i, 0], ws[i, 1], ws[i, 2] = ws[i + 1, 0], ws[i + 1, 1], ws[i + 1, 2]
        n = 3
    ts[n] = t
    ws[n, 0], ws[n, 1], ws[n, 2] = w0, w1, w2
    n += 1
    ci[C_N] = n
    ci[C_LAST_T] = t
    if ci[C_SAMPLES] == 2:
        cf[F_ZETA_FIRST], cf[F_ZETA_FIRST + 1], cf[F_ZETA_FIRST + 2] = z0, z1, z2
        ci[C_HAS_ZETA_FIRST] = 1 if has_z else 0
    return n, has_z, z0, z1, z2


@kernel
def rate_advance(alg, ci, ts, ws, cf, t, w0, w1, w2, has_nav, r0, r1, r2):
    """One sample through the rate algorithm ``alg``: the attitude as 4 floats.  One that
    checks its rate fit redoes the first interval as the third sample arrives (the quadratic
    through 0, 1, 2) and counts the fit's fallbacks."""
    n, has_z, z0, z1, z2 = _take_sample(ci, ts, ws, cf, t, w0, w1, w2, has_nav, r0, r1, r2)
    if n == 0:
        return cf[F_Q], cf[F_Q + 1], cf[F_Q + 2], cf[F_Q + 3]
    if ci[C_SAMPLES] == 3 and (alg == CUBIC or alg == RK4):
        b, fell = body_increment(alg, ts, ws, 1, 3)
        ci[C_FALLBACKS] += (1 if fell else 0) - ci[C_FIRST_FELL]
        ci[C_FIRST_FELL] = 1 if fell else 0
        _compose_into(cf, F_Q_START, b, ci[C_HAS_ZETA_FIRST] == 1, cf[F_ZETA_FIRST],
                      cf[F_ZETA_FIRST + 1], cf[F_ZETA_FIRST + 2])
    b, fell = body_increment(alg, ts, ws, n - 1, n)
    if fell:
        ci[C_FALLBACKS] += 1
    if n == 2:
        ci[C_FIRST_FELL] = 1 if fell else 0
    return _compose_into(cf, F_Q, b, has_z, z0, z1, z2)


@kernel
def coning_advance(alg, rule, ci, ts, ws, cf, blk, t, w0, w1, w2, has_nav, r0, r1, r2):
    """One sample through the coning algorithm ``alg`` fed by the quadrature ``rule``: the
    attitude as 4 floats.  The cubic rule redoes the first increment as the third sample
    arrives (in the open block; one sample per update: that interval's attitude redone)."""
    n, has_z, z0, z1, z2 = _take_sample(ci, ts, ws, cf, t, w0, w1, w2, has_nav, r0, r1, r2)
    if n == 0:
        return cf[F_Q], cf[F_Q + 1], cf[F_Q + 2], cf[F_Q + 3]
    if ci[C_SAMPLES] == 3 and rule == RULE_CUBIC:
        d0, d1, d2 = quadrature_increment(rule, ts, ws, 1, 3)
        blk[4, 0], blk[4, 1], blk[4, 2] = d0, d1, d2
        if alg == PREVIOUS or alg == 1:
            q = _compose_into(cf, F_Q_START, exp_scalar(d0, d1, d2), ci[C_HAS_ZETA_FIRST] == 1,
                              cf[F_ZETA_FIRST], cf[F_ZETA_FIRST + 1], cf[F_ZETA_FIRST + 2])
            cf[F_Q_BLOCK], cf[F_Q_BLOCK + 1], cf[F_Q_BLOCK + 2], cf[F_Q_BLOCK + 3] = q
        else:
            blk[0, 0], blk[0, 1], blk[0, 2] = d0, d1, d2
    d0, d1, d2 = quadrature_increment(rule, ts, ws, n - 1, n)
    return coning_step(alg, ci, cf, blk, d0, d1, d2, has_z, z0, z1, z2)


@kernel
def increment_advance(alg, ci, cf, blk, t, d0, d1, d2, has_nav, r0, r1, r2):
    """The angle increment ``d`` over ``(last, t]`` (a time base started) through the coning
    algorithm ``alg``: the attitude as 4 floats."""
    has_z, z0, z1, z2 = nav_interval(ci, cf, t, has_nav, r0, r1, r2)
    ci[C_SAMPLES] += 1
    ci[C_LAST_T] = t
    return coning_step(alg, ci, cf, blk, d0, d1, d2, has_z, z0, z1, z2)


@kernel
def batch_rows(kind, alg, rule, ci, ts, ws, cf, blk, t, w, nav, rates, out, fell):
    """The batch: one of the steps over the rows of ``t`` (N,), the attitudes into ``out``
    (N, 4).  ``kind`` 0: :func:`rate_advance` of the rates ``w`` (N, 3), ``fell[k]`` (N,) set
    to 1 where the step of interval k fell back (interval 1 as redone at row 2); 1:
    :func:`coning_advance` of the rates ``w``; 2: :func:`increment_advance` of the increments
    ``w`` (N-1, 3) from row 1 on (a time base started at row 0).  ``nav`` 0: no nav frame, 1:
    the rate ``rates[0]`` throughout, 2: ``rates[i]`` at row i."""
    for i in range(1 if kind == 2 else 0, t.shape[0]):
        r = rates[i if nav == 2 else 0]
        if kind == 2:
            q = increment_advance(alg, ci, cf, blk, t[i], w[i - 1, 0], w[i - 1, 1],
                                  w[i - 1, 2], nav > 0, r[0], r[1], r[2])
        elif kind == 1:
            q = coning_advance(alg, rule, ci, ts, ws, cf, blk, t[i], w[i, 0], w[i, 1], w[i, 2],
                               nav > 0, r[0], r[1], r[2])
        else:
            before, first_before = ci[C_FALLBACKS], ci[C_FIRST_FELL]
            q = rate_advance(alg, ci, ts, ws, cf, t[i], w[i, 0], w[i, 1], w[i, 2], nav > 0,
                             r[0], r[1], r[2])
            d = ci[C_FALLBACKS] - before
            if i == 2:  # interval 1 redone: its flag is the redo's
                d -= ci[C_FIRST_FELL] - first_before
                fell[1] = ci[C_FIRST_FELL]
            if i > 0:
                fell[i] = d
        out[i, 0], out[i, 1], out[i, 2], out[i, 3] = q


def integrate_rows(alg, t, w, q0, rate_n, rule=0, fallbacks=None, out=None,
                   increments=False) -> np.ndarray:
    """``integrate_batch`` of the causal algorithm ``alg`` on checked input: :func:`batch_rows`
    from ``q0`` over rates (a coning algorithm's increments by the rule ``rule``) or, with
    ``increments``, over increments ``w`` (N-1, 3); the intervals whose fit fell back appended
    to ``fallbacks`` (an int array, when there are any)."""
    q = np.empty((t.size, 4)) if out is None else out
    rates = np.zeros((1, 3)) if rate_n is None else np.ascontiguousarray(
        rate_n, dtype=np.float64).reshape(-1, 3)
    kind = 0 if isinstance(alg, RateAlgorithm) else 2 if increments else 1
    state = RateState(tuple(float(c) for c in q0), int(t[0]) if kind == 2 else None,
                      rates[0] if kind == 2 and rate_n is not None else None)
    q[0] = q0
    fell = np.zeros(t.size if kind == 0 else 0, dtype=np.int8)
    compiled(batch_rows)(kind, alg.code, rule, state.ci, state.ts, state.ws, state.cf,
                         state.blk, t, np.ascontiguousarray(w, dtype=np.float64),
                         0 if rate_n is None else 1 if rate_n.ndim == 1 else 2, rates, q, fell)
    if fallbacks is not None and fell.any():
        fallbacks.append(np.flatnonzero(fell))
    return q


@kernel
def rate_reset(ci, ts, ws, cf, qx, qy, qz, qw, has_t, t, has_nav, r0, r1, r2):
    """A rate algorithm's slots started again from the attitude ``q`` (at ``t`` when
    ``has_t``: that sample is the first of the new time base, its rate taken from the next
    one; with the nav rate ``r`` there when ``has_nav``)."""
    ci[:] = 0
    ts[:] = 0
    ws[:] = 0.0
    cf[:] = 0.0
    cf[F_Q], cf[F_Q + 1], cf[F_Q + 2], cf[F_Q + 3] = qx, qy, qz, qw
    cf[F_Q_START], cf[F_Q_START + 1], cf[F_Q_START + 2], cf[F_Q_START + 3] = qx, qy, qz, qw
    if has_t:
        ci[C_SAMPLES], ci[C_LAST_T], ci[C_HAS_LAST], ci[C_N], ci[C_NEED_W0] = 1, t, 1, 1, 1
        ts[0] = t
        if has_nav:
            cf[F_NAV_PREV], cf[F_NAV_PREV + 1], cf[F_NAV_PREV + 2] = r0, r1, r2
            ci[C_HAS_NAV_PREV] = 1


class RateState:
    """A rate or coning algorithm's streaming state as arrays (see :func:`rate_advance`,
    :func:`coning_advance`; the rate algorithms use the first 9 int and 14 float slots)."""

    __slots__ = ("ci", "ts", "ws", "cf", "blk")

    def __init__(self, q0: tuple, t_ns: int | None, nav_rate):
        self.ci = np.zeros(11, dtype=np.int64)
        self.ts = np.zeros(4, dtype=np.int64)  # the last four samples: the causal cubic's nodes
        self.ws = np.zeros((4, 3))
        self.cf = np.zeros(21)
        self.blk = np.zeros((5, 3))
        self.reset(q0, t_ns, nav_rate)

    def reset(self, q0: tuple, t_ns: int | None, nav_rate) -> None:
        """:func:`rate_reset` (run as Python), and the coning state from ``q0``."""
        r = (0.0, 0.0, 0.0) if nav_rate is None else nav_rate
        rate_reset(self.ci, self.ts, self.ws, self.cf, *q0, t_ns is not None, t_ns or 0,
                   nav_rate is not None, *r)
        self.cf[F_Q_BLOCK:F_Q_BLOCK + 4] = q0
        self.blk[:] = 0.0


def _three_floats(v, name: str) -> tuple[float, float, float]:
    """``v`` as 3 finite floats, or ValueError naming ``name``."""
    try:
        x, y, z = (float(c) for c in v)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must have shape (3,): 3 finite numbers, got {v!r}") from None
    if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z)):
        raise ValueError(f"{name} contains non-finite values (NaN or inf)")
    return x, y, z


class StreamingIntegrator:
    """Per-sample attitude update with the same results as :func:`integrate_batch` (the same
    kernels; the Euler baselines' Python step, tens of µs).  Offline algorithms (``causal``
    False, e.g. ``magnus6_quintic``) are refused with ``ValueError``.

    ``update(t_ns, omega_ib_b)`` takes one rate sample and returns the attitude at ``t_ns``
    (the first call, or the first after ``reset`` without ``t_ns``, only sets the time origin
    and returns ``q0``).  Increment algorithms get their increments from ``quadrature`` as the
    batch does, or directly through ``update_increment(t_ns, delta_theta)``.  A NavFrame's
    series is indexed by the sample count.  ``ValueError`` on a zero/negative step or
    non-finite input.
    """

    def __init__(self, algorithm: str = DEFAULT_ALGORITHM, q0=(0.0, 0.0, 0.0, 1.0),
                 nav: NavFrame | None = None, t0_ns: int | None = None,
                 quadrature: str = "trapezoid", singular_tol: float = 1e-3):
        self.info = get_algorithm(algorithm)
        self.algorithm = self.info.name
        if not self.info.causal:
            raise ValueError(f"{self.algorithm} is an offline algorithm (it fits samples after "
                             "each interval) and cannot stream; use integrate_batch / replay, "
                             "or a causal algorithm")
        self._rule = get_quadrature(quadrature).code
        self.quadrature = quadrature
        self.singular_tol = float(singular_tol)
        if nav is not None and not self.info.supports_nav:
            raise ValueError(f"{algorithm} integrates q_ib only; nav frames need a "
                             "quaternion algorithm")
        # ω_in^n, (3,) or a series (N, 3) evaluated once for all samples (as the batch does):
        # per-sample numpy calls would cost ~30 µs per update
        self._nav_rates = nav_rate_for(nav)
        self.nav = nav
        self._rates = RateState((0.0, 0.0, 0.0, 1.0), None, None)  # every algorithm's history
        self._fallbacks_before = 0
        self.reset(q0, t0_ns)

    def reset(self, q0, t_ns: int | None = None) -> None:
        """Restart from attitude ``q0`` (at ``t_ns`` if given), dropping all history."""
        q = tuple(float(c) for c in check_q0(q0))
        self._fallbacks_before = self.fit_fallbacks
        self._rates.reset(q, None, None)  # no time base: t_ns is not checked against the old
        if t_ns is not None:
            self._rates.reset(q, self._check_time(t_ns), self._nav_rate_at(0))
        self._stepper = self.info.stepper(q, self.singular_tol) if self.info.sequential else None

    @property
    def quaternion(self) -> np.ndarray:
        return self._rates.cf[F_Q:F_Q + 4].copy()

    @property
    def samples(self) -> int:
        """Samples since the last reset (a start time counts as one)."""
        return int(self._rates.ci[C_SAMPLES])

    @property
    def last_t_ns(self) -> int | None:
        ci = self._rates.ci
        return int(ci[C_LAST_T]) if ci[C_HAS_LAST] else None

    @property
    def fit_fallbacks(self) -> int:
        """Intervals integrated so far (since construction, across resets) whose rate fit could
        not be trusted, integrated with the exponential map (the batch's ``fallbacks``)."""
        return self._fallbacks_before + int(self._rates.ci[C_FALLBACKS])

    def update_nav(self, nav: NavFrame) -> None:
        """Use the constant navigation frame ``nav`` from the next sample on: its ``ω_in^n``,
        computed here once, is the nav rate at the next sample (the interval ending there
        integrates the trapezoid of the previous rate and this one).  The attitude and the
        history are kept; ``reset`` keeps the new frame.  A stream switched before sample s
        equals :func:`integrate_batch` with the NavFrame series holding the new values from s
        on.  ``ValueError`` (nothing changed) as :func:`constant_nav_rate` says."""
        self._nav_rates = constant_nav_rate(self.nav, nav)
        self.nav = nav

    def _nav_rate_at(self, index: int) -> np.ndarray | None:
        r = self._nav_rates
        if r is not None and r.ndim == 2:
            if index >= r.shape[0]:
                raise ValueError(f"NavFrame time series has {r.shape[0]} samples; sample {index} "
                                 "is beyond")
            return r[index]
        return r

    def _check_time(self, t_ns) -> int:
        if isinstance(t_ns, float | np.floating) or not isinstance(t_ns, int | np.integer):
            raise ValueError(f"t_ns must be an int number of nanoseconds, got {t_ns!r}")
        t, last = int(t_ns), self.last_t_ns
        if last is not None and t <= last:
            raise ValueError(f"time step {t - last} ns is not positive (t_ns={t} after {last}): "
                             "samples must be strictly increasing in time")
        return t

    def update(self, t_ns: int, omega_ib_b) -> np.ndarray:
        """Consume one rate sample; return the attitude at ``t_ns`` (shape (4,))."""
        w = _three_floats(omega_ib_b, "omega_ib_b")
        t = self._check_time(t_ns)
        rs = self._rates
        if self._stepper is None:
            # the first sample of a time base only starts the history: the kernel run as
            # Python (a stream that ends there needs no compiler)
            step = rate_advance if isinstance(self.info, RateAlgorithm) else coning_advance
            return self._kernel_step(step, t, w, not rs.ci[C_HAS_LAST])
        n = _take_sample(rs.ci, rs.ts, rs.ws, rs.cf, t, *w, False, 0.0, 0.0, 0.0)[0]
        if n > 0:
            rs.cf[F_Q:F_Q + 4] = self._stepper.interval(rs.ts[:n], rs.ws[:n],
                                                         rs.ci[C_SAMPLES] == 3)
        return self.quaternion

    def update_increment(self, t_ns: int, delta_theta) -> np.ndarray:
        """Consume one angle increment over ``(last_t_ns, t_ns]`` (increment algorithms; the
        first after construction or reset needs the start time ``t0_ns`` or ``reset``'s)."""
        if self.info.consumes != "increment":
            raise ValueError(f"{self.algorithm} consumes rate samples; use update()")
        d = _three_floats(delta_theta, "delta_theta")
        t = self._check_time(t_ns)
        if self.last_t_ns is None:
            raise ValueError("update_increment needs a start time: pass t0_ns to the "
                             "constructor or reset(q0, t_ns)")
        return self._kernel_step(increment_advance, t, d)

    def _kernel_step(self, step, t: int, v, as_python: bool = False) -> np.ndarray:
        """The sample ``t`` (rate or increment ``v``) through the step kernel ``step``."""
        rs = self._rates
        r = self._nav_rate_at(self.samples)
        nav = (False, 0.0, 0.0, 0.0) if r is None else (True, float(r[0]), float(r[1]),
                                                        float(r[2]))
        fn = step if as_python else compiled(step)
        if step is rate_advance:
            q = fn(self.info.code, rs.ci, rs.ts, rs.ws, rs.cf, t, *v, *nav)
        elif step is coning_advance:
            q = fn(self.info.code, self._rule, rs.ci, rs.ts, rs.ws, rs.cf, rs.blk, t, *v, *nav)
        else:
            q = fn(self.info.code, rs.ci, rs.cf, rs.blk, t, *v, *nav)
        return np.array(q)


def constant_nav_rate(current, nav) -> np.ndarray:
    """The rate ``ω_in^n`` (3,) of the constant NavFrame ``nav`` that replaces ``current``
    (:meth:`StreamingIntegrator.update_nav`), or ValueError: no frame to replace (q_ib), not a
    NavFrame, a time series, an invalid latitude or non-finite values."""
    if current is None:
        raise ValueError("update_nav needs an integrator built with a NavFrame (q_nb); "
                         "this one integrates q_ib")
    if not isinstance(nav, NavFrame):
        raise ValueError(f"nav must be a NavFrame, got {type(nav).__name__}")
    return nav.rate_enu(None)  # raises on series and on invalid values
