"""The causal algorithms' steps over their sample history, stepped one sample per call
(:class:`StreamingIntegrator`) or in a compiled loop over a record (:func:`integrate_rows`,
the batch): one code, the same bits."""

from __future__ import annotations

import math

import numpy as np

from gyro_attitude.core.attitude.algorithm import RateAlgorithm
from gyro_attitude.core.attitude.compose import compose_scalar, exp_scalar
from gyro_attitude.core.attitude.coning import (
    F_Q_BLOCK,
    PREVIOUS,
    IncrementAlgorithm,
    coning_step,
)
from gyro_attitude.core.attitude.exp_map import EXP_MAP, exp_map_increment
from gyro_attitude.core.attitude.first_order import (
    DCM_FIRST_ORDER,
    QUAT_FIRST_ORDER,
    dcm_first_order_increment,
    quat_first_order_increment,
)
from gyro_attitude.core.attitude.inputs import check_q0
from gyro_attitude.core.attitude.nav_frame import NavFrame
from gyro_attitude.core.attitude.quadrature import CUBIC as CUBIC_RULE
from gyro_attitude.core.attitude.quadrature import get_quadrature, quadrature_increment
from gyro_attitude.core.attitude.registry import DEFAULT_ALGORITHM, get_algorithm
from gyro_attitude.core.attitude.rk4 import QUAT_RK4, quat_rk4_increment
from gyro_attitude.core.attitude.rotvec import (
    ROTVEC_CUBIC,
    ROTVEC_TRAPEZOID,
    cubic_increment,
    trapezoid_increment,
)
from gyro_attitude.core.jit import compiled, kernel

_HISTORY = 4  # samples held: the causal cubic's four nodes

# Every causal rate algorithm steps through one kernel, :func:`rate_advance` (the coning ones
# through :func:`coning_advance`), whose state is arrays (``RateState``): the batch's compiled
# loop (:func:`batch_rows`), the streaming integrator and the causal estimator's step
# (chain.py) step the same state.  Its int slots:
C_N, C_SAMPLES, C_LAST_T, C_HAS_LAST, C_FALLBACKS, C_FIRST_FELL, C_NEED_W0, C_HAS_ZETA_FIRST, \
    C_HAS_NAV_PREV = range(9)
# and its float slots: the attitude, the stepper's start, ζ of the first interval, the last
# nav rate (4 + 4 + 3 + 3)
F_Q, F_Q_START, F_ZETA_FIRST, F_NAV_PREV = 0, 4, 8, 11
# the algorithms' codes (RateAlgorithm.code): plain ints, constants of the compiled code
_QUAT1, _DCM1, _EXP, _TRAP, _CUBIC, _RK4 = (a.code for a in (
    QUAT_FIRST_ORDER, DCM_FIRST_ORDER, EXP_MAP, ROTVEC_TRAPEZOID, ROTVEC_CUBIC, QUAT_RK4))


@kernel
def body_increment(alg, ts, ws, k, n):
    """The step of the rate algorithm ``alg`` over interval ``k`` of the first ``n`` samples
    held (``ts`` stamps, ``ws`` rates): (increment quaternion, whether its fit fell back)."""
    if alg == _CUBIC:
        return cubic_increment(ts, ws, k, n)
    if alg == _EXP:
        return exp_map_increment(ts, ws, k, n)
    if alg == _RK4:
        return quat_rk4_increment(ts, ws, k, n)
    if alg == _TRAP:
        return trapezoid_increment(ts, ws, k, n)
    if alg == _QUAT1:
        return quat_first_order_increment(ts, ws, k, n)
    return dcm_first_order_increment(ts, ws, k, n)


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
def _compose_into(cf, b, has_z, z0, z1, z2):
    """The stored attitude advanced by the body increment ``b`` (and the nav-frame rotation
    ``z`` over the interval when ``has_z``), stored and returned."""
    q = (cf[F_Q], cf[F_Q + 1], cf[F_Q + 2], cf[F_Q + 3])
    if has_z:
        q = compose_scalar(q, b, (z0, z1, z2))
    else:
        q = compose_scalar(q, b, None)
    cf[F_Q], cf[F_Q + 1], cf[F_Q + 2], cf[F_Q + 3] = q
    return q


@kernel(inline=True)
def _take_sample(ci, ts, ws, cf, t, w0, w1, w2, has_nav, r0, r1, r2):
    """The sample ``t`` (int ns after the last), rate ``(w0, w1, w2)`` and nav rate
    ``(r0, r1, r2)`` at it (``has_nav``) into the history of the last four samples (``ci``
    int slots, ``ts`` (4,) stamps, ``ws`` (4, 3) rates, ``cf`` float slots): (samples now
    held, 0 when this one only starts a time base; the nav rotation ζ of its interval)."""
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


@kernel(inline=True)
def _first_redone(cf, ci, b):
    """The attitude of the first interval from the start with the increment ``b`` (and the
    first interval's nav rotation), stored."""
    q_start = (cf[F_Q_START], cf[F_Q_START + 1], cf[F_Q_START + 2], cf[F_Q_START + 3])
    if ci[C_HAS_ZETA_FIRST] == 1:
        q = compose_scalar(q_start, b, (cf[F_ZETA_FIRST], cf[F_ZETA_FIRST + 1],
                                        cf[F_ZETA_FIRST + 2]))
    else:
        q = compose_scalar(q_start, b, None)
    cf[F_Q], cf[F_Q + 1], cf[F_Q + 2], cf[F_Q + 3] = q
    return q


@kernel
def rate_advance(alg, ci, ts, ws, cf, t, w0, w1, w2, has_nav, r0, r1, r2):
    """One sample (:func:`_take_sample`) through the rate algorithm ``alg``: the attitude as 4
    floats.  For the algorithms that fit a polynomial (rotvec_cubic, quat_rk4) the first
    interval is redone as the third sample arrives (the quadratic through 0, 1, 2) and the
    fit's fallbacks are counted."""
    n, has_z, z0, z1, z2 = _take_sample(ci, ts, ws, cf, t, w0, w1, w2, has_nav, r0, r1, r2)
    if n == 0:
        return cf[F_Q], cf[F_Q + 1], cf[F_Q + 2], cf[F_Q + 3]
    if ci[C_SAMPLES] == 3 and (alg == _CUBIC or alg == _RK4):
        b, fell = body_increment(alg, ts, ws, 1, 3)
        ci[C_FALLBACKS] += (1 if fell else 0) - ci[C_FIRST_FELL]
        ci[C_FIRST_FELL] = 1 if fell else 0
        _first_redone(cf, ci, b)
    b, fell = body_increment(alg, ts, ws, n - 1, n)
    if fell:
        ci[C_FALLBACKS] += 1
    if n == 2:
        ci[C_FIRST_FELL] = 1 if fell else 0
    return _compose_into(cf, b, has_z, z0, z1, z2)


@kernel(inline=True)
def cubic_advance(ci, ts, ws, cf, t, w0, w1, w2, has_nav, r0, r1, r2):
    """:func:`rate_advance` of rotvec_cubic (the causal estimator's default)."""
    return rate_advance(_CUBIC, ci, ts, ws, cf, t, w0, w1, w2, has_nav, r0, r1, r2)


@kernel(inline=True)
def exp_advance(ci, ts, ws, cf, t, w0, w1, w2, has_nav, r0, r1, r2):
    """:func:`rate_advance` of exp_map."""
    return rate_advance(_EXP, ci, ts, ws, cf, t, w0, w1, w2, has_nav, r0, r1, r2)


@kernel
def coning_advance(alg, rule, ci, ts, ws, cf, blk, t, w0, w1, w2, has_nav, r0, r1, r2):
    """One sample (:func:`_take_sample`) through the coning algorithm ``alg`` fed by the
    quadrature ``rule``: the attitude as 4 floats.  A fitting rule redoes the first interval
    as the third sample arrives (the quadratic through 0, 1, 2): the open block's first
    increment is replaced (one sample per update: the attitude of that interval redone)."""
    n, has_z, z0, z1, z2 = _take_sample(ci, ts, ws, cf, t, w0, w1, w2, has_nav, r0, r1, r2)
    if n == 0:
        return cf[F_Q], cf[F_Q + 1], cf[F_Q + 2], cf[F_Q + 3]
    if ci[C_SAMPLES] == 3 and rule == CUBIC_RULE:
        d0, d1, d2 = quadrature_increment(rule, ts, ws, 1, 3)
        blk[4, 0], blk[4, 1], blk[4, 2] = d0, d1, d2
        if alg == PREVIOUS or alg == 1:
            q = _first_redone(cf, ci, exp_scalar(d0, d1, d2))
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
    """``integrate_batch`` of the causal algorithm ``alg`` on checked input: the compiled
    loop :func:`batch_rows` from ``q0``, over rates (a rate algorithm; a coning algorithm fed
    by the quadrature ``rule``'s code) or, with ``increments``, over angle increments ``w``
    (N-1, 3) (a coning algorithm); the intervals whose fit fell back appended to the list
    ``fallbacks`` (an int array, when there are any)."""
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


class RateState:
    """A rate or coning algorithm's streaming state as arrays (see :func:`rate_advance`,
    :func:`coning_advance`; the rate algorithms use the first 9 int and 14 float slots)."""

    __slots__ = ("ci", "ts", "ws", "cf", "blk")

    def __init__(self, q0: tuple, t_ns: int | None, nav_rate):
        self.ci = np.zeros(11, dtype=np.int64)
        self.ts = np.zeros(_HISTORY, dtype=np.int64)
        self.ws = np.zeros((_HISTORY, 3))
        self.cf = np.zeros(21)
        self.blk = np.zeros((5, 3))
        self.reset(q0, t_ns, nav_rate)

    def reset(self, q0: tuple, t_ns: int | None, nav_rate) -> None:
        """Start again from ``q0`` (at ``t_ns``, with the nav rate ``nav_rate`` there), in
        place."""
        for a in (self.ci, self.ts, self.ws, self.cf, self.blk):
            a[:] = 0
        for slot in (F_Q, F_Q_START, F_Q_BLOCK):
            self.cf[slot:slot + 4] = q0
        if t_ns is not None:
            ci = self.ci
            ci[C_SAMPLES], ci[C_LAST_T], ci[C_HAS_LAST], ci[C_N], ci[C_NEED_W0] = 1, t_ns, 1, 1, 1
            self.ts[0] = t_ns
            if nav_rate is not None:
                self.cf[F_NAV_PREV:F_NAV_PREV + 3] = nav_rate
                ci[C_HAS_NAV_PREV] = 1


class StreamingIntegrator:
    """Per-sample attitude update with the same results as :func:`integrate_batch`.

    Every causal rate algorithm steps through :func:`rate_advance` (compiled, the batch's
    own step: the two give the same bits), the coning algorithms through their stepper
    (plain floats) and the Euler baselines in numpy (tens of µs).  Offline algorithms
    (``causal`` False, e.g. ``magnus6_quintic``) need samples after each interval and are
    refused with ``ValueError``.

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
        self._fallbacks_before = self.fit_fallbacks if hasattr(self, "_rates") else 0
        self.samples = 0
        self.last_t_ns: int | None = None
        q_start = tuple(float(c) for c in self._q)
        kernels = isinstance(self.info, RateAlgorithm | IncrementAlgorithm)
        self._stepper = None if kernels else self.info.stepper(q_start, self.singular_tol)
        self._ts: list[int] = []
        self._ws: list[tuple[float, float, float]] = []
        t = rate = None
        if t_ns is not None:
            t = self._check_time(t_ns)
            rate = self._nav_rate_at(0)
            self.samples = 1
            self.last_t_ns = t
            self._ts = [t]
        # a rate or coning algorithm keeps its history in arrays and steps through one kernel
        self._rates = RateState(q_start, t, rate) if kernels else None

    @property
    def quaternion(self) -> np.ndarray:
        return np.array(self._q, dtype=np.float64)

    @property
    def fit_fallbacks(self) -> int:
        """Intervals integrated so far (since construction, across resets) whose rate fit could
        not be trusted, integrated with the exponential map (the batch's ``fallbacks``)."""
        if self._rates is not None:
            return self._fallbacks_before + int(self._rates.ci[C_FALLBACKS])
        return self._fallbacks_before

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
        rate = constant_nav_rate(self.nav, nav)
        self.nav = nav
        self._nav_const = rate
        self._nav_rates = None

    def set_nav_rate(self, rate: np.ndarray) -> None:
        """The nav rate ``ω_in^n`` (3,) at the next sample (as :meth:`update_nav` sets it from
        a constant frame): a recording's time series fed row by row."""
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
        rs = self._rates
        if rs is not None:
            # the first sample of a time base only starts the history: the kernel run as
            # Python (a stream that ends there needs no compiler)
            return self._kernel_step(rate_advance if isinstance(self.info, RateAlgorithm)
                                     else coning_advance, t, w, not rs.ci[C_HAS_LAST])
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
        if self.samples == 3:
            self._stepper.redo_first(ts, ws)
        q = self._stepper.interval(ts, ws)
        self.last_t_ns = t
        self._q = q
        return q

    def _kernel_step(self, step, t: int, v, as_python: bool = False) -> tuple[float, ...]:
        """The sample ``t`` (rate or increment ``v``) through the step kernel ``step``."""
        rs = self._rates
        rate = self._nav_rate_at(self.samples)
        nav = (False, 0.0, 0.0, 0.0) if rate is None else (True, float(rate[0]),
                                                           float(rate[1]), float(rate[2]))
        fn = step if as_python else compiled(step)
        if step is rate_advance:
            q = fn(self.info.code, rs.ci, rs.ts, rs.ws, rs.cf, t, v[0], v[1], v[2], *nav)
        elif step is coning_advance:
            q = fn(self.info.code, self._quadrature.code, rs.ci, rs.ts, rs.ws, rs.cf, rs.blk, t,
                   v[0], v[1], v[2], *nav)
        else:
            q = fn(self.info.code, rs.ci, rs.cf, rs.blk, t, v[0], v[1], v[2], *nav)
        self.samples += 1
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
        return np.array(self._kernel_step(increment_advance, t, (dx, dy, dz)))


@kernel
def cubic_reset(ci, ts, ws, cf, qx, qy, qz, qw, has_t, t, has_nav, r0, r1, r2):
    """The causal estimator's :meth:`RateState.reset` of a rate algorithm's slots (chain.py:
    its integrator restarts inside the compiled step) from the attitude ``q`` (normalized here,
    as :meth:`StreamingIntegrator.reset` takes it; at ``t`` when ``has_t``, with the nav rate
    ``r`` there when ``has_nav``)."""
    n = math.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
    qx, qy, qz, qw = qx / n, qy / n, qz / n, qw / n
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


def constant_nav_rate(current, nav) -> np.ndarray:
    """The rate ``ω_in^n`` (3,) of the constant NavFrame ``nav`` that replaces ``current``
    (:meth:`StreamingIntegrator.update_nav`), or ValueError: no frame to replace (q_ib), not a
    NavFrame, a time series, an invalid latitude or non-finite values."""
    if current is None:
        raise ValueError("update_nav needs an integrator built with a NavFrame (q_nb); "
                         "this one integrates q_ib")
    if not isinstance(nav, NavFrame):
        raise ValueError(f"nav must be a NavFrame, got {type(nav).__name__}")
    rate = nav.rate_enu(None)  # raises on series and on invalid values
    if rate.shape != (3,):
        raise ValueError(f"update_nav needs a constant NavFrame, got rate shape {rate.shape}")
    return rate
