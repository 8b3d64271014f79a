"""The Algorithm protocol (facts, batch and streaming behaviour) and the rate-algorithm template."""

from __future__ import annotations

import numpy as np

from gyro_attitude.core.attitude.compose import (
    LeftPrefix,
    compose_chunked,
    compose_scalar,
    first_interval_output,
)
from gyro_attitude.core.attitude.interpolation import NODES
from gyro_attitude.core.attitude.nav_frame import nav_zeta
from gyro_attitude.core.rotation import _exp_rotvec


class Algorithm:
    """One attitude update algorithm.

    Facts: ``name``; ``consumes`` ("rate": ω samples, "increment": angle increments Δθ);
    ``order`` (global order in the sample period on smooth motion with exact input);
    ``description``; ``cost``; ``causal`` (False: needs samples after the interval, batch
    only); ``samples_per_update`` (N of the N-sample coning algorithms); ``sequential``
    (True: a Python loop per sample on a nonlinear state); ``supports_nav`` (False: q_ib
    only).  Behaviour: :meth:`integrate` (batch over all samples) and :meth:`stepper`
    (the per-stream state of :class:`~gyro_attitude.core.attitude.StreamingIntegrator`).
    """

    consumes = "rate"
    causal = True
    samples_per_update = 1
    sequential = False
    supports_nav = True
    #: True when :meth:`integrate` takes ``out=`` (writes the attitudes into a given array)
    integrates_into = False

    def __init__(self, name: str, order: int, description: str, cost: str):
        self.name = name
        self.order = order
        self.description = description
        self.cost = cost

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.name}: {self.consumes}, order {self.order}>"

    def integrate(self, t, w, q0, rate_n, quadrature, singular_tol) -> np.ndarray:
        """Attitudes (N, 4) from checked rate samples ``w`` at times ``t``.

        ``rate_n``: ``ω_in^n`` ((3,) or (N, 3)) or None; ``quadrature``: a
        :class:`~gyro_attitude.core.attitude.quadrature.Quadrature` (increment algorithms).
        """
        raise NotImplementedError

    def stepper(self, q0: tuple, quadrature, singular_tol: float):
        """A new per-stream state starting at attitude ``q0`` (tuple of 4 floats)."""
        if not self.causal:
            raise ValueError(f"{self.name} is an offline algorithm (it fits samples after "
                             "each interval) and cannot stream; use integrate_batch / replay, "
                             "or a causal algorithm")
        return self._new_stepper(q0, quadrature, singular_tol)

    def _new_stepper(self, q0, quadrature, singular_tol):
        raise NotImplementedError


class RateAlgorithm(Algorithm):
    """A quaternion algorithm on rate samples: interval k (sample k-1 to k) becomes a body
    increment ``b_k``, and ``q_k = exp(−ζ_k) ⊗ q_{k-1} ⊗ b_k``.

    Subclasses give the batch kernel :meth:`body_increments` and, if causal, its plain-float
    twin :meth:`body_increment_scalar` for streaming (numpy per call on one sample would cost
    ~10x the scalar step); the batch == streaming tests hold the two together.
    """

    #: True when the rate is fitted by a polynomial: the first interval's causal linear fit
    #: is redone with the quadratic through samples 0..2 once sample 2 is in.
    fits_rate_polynomial = False
    #: True when the step checks its rate fit and falls back to the exponential map where the
    #: fit cannot be trusted (:func:`.interpolation.untrusted_fits`): ``body_increments`` takes
    #: ``fallbacks`` (a list that collects the intervals that fell back).
    checks_rate_fit = False

    def body_increments(self, t_ns, omega, k, lookahead=False) -> np.ndarray:
        """Body increments ``b_k`` (len(k), 4) of intervals ``k``."""
        raise NotImplementedError

    def body_increment_scalar(self, ts, ws, k, nodes):
        """``b_k`` of interval ``k`` from plain-float histories fitted on ``nodes``."""
        raise NotImplementedError

    def body_increment_checked(self, ts, ws, k, nodes):
        """``(b_k, fell_back)``: :meth:`body_increment_scalar` and whether its fit could not be
        trusted (the step then is the exponential map's)."""
        return self.body_increment_scalar(ts, ws, k, nodes), False

    integrates_into = True

    def integrate(self, t, w, q0, rate_n, quadrature, singular_tol, fallbacks=None, out=None):
        kw = {"fallbacks": fallbacks} if self.checks_rate_fit else {}

        def increments(k):
            b = self.body_increments(t, w, k, lookahead=True, **kw)
            if rate_n is None:
                return b, None
            if rate_n.ndim == 1:
                # A constant nav rate turns the frame about one fixed axis: the increments
                # exp(−ω h_j) commute, and their product from the chunk's first interval is
                # exp(−ω (t_k − t_k0−1)) in closed form (the span exact in int ns), with no
                # scan and no rounding accumulated over the products.
                span = ((t[k] - t[k[0] - 1]) * 1e-9)[:, None]
                return b, LeftPrefix(_exp_rotvec(-rate_n[None, :] * span))
            return b, _exp_rotvec(-nav_zeta(t, rate_n, k))

        q = compose_chunked(t.size, q0, 1, increments, out=out)
        if t.size >= 3 and self.fits_rate_polynomial:
            # Emitted q[1] is causal (linear fit); the chain used the redone interval 1.
            b1 = self.body_increments(t[:2], w[:2], np.array([1]))[0]
            q[1] = first_interval_output(q0, b1, t, rate_n)
        return q

    def _new_stepper(self, q0, quadrature, singular_tol):
        return RateStepper(self, q0)


class RateStepper:
    """Streaming state of a :class:`RateAlgorithm`: the attitude, one scalar step per sample.

    Every stepper has ``q`` (tuple), ``interval(ts, ws, zeta)`` (consume the newest
    interval of the ≤ 4-sample histories, return the attitude) and
    ``redo_first(ts, ws, zeta_first)`` (called as the third sample arrives).
    """

    def __init__(self, algorithm: RateAlgorithm, q0: tuple):
        self._step = algorithm.body_increment_checked
        self._redo = algorithm.fits_rate_polynomial
        self.q = self._q_start = q0
        #: intervals whose step fell back to the exponential map (the batch's count: the first
        #: interval is counted as redone, not as first emitted)
        self.fit_fallbacks = 0
        self._first_fell_back = False

    def interval(self, ts, ws, zeta):
        n = len(ts)
        b, fell_back = self._step(ts, ws, n - 1, NODES[n])
        if fell_back:
            self.fit_fallbacks += 1
        if n == 2:
            self._first_fell_back = fell_back
        self.q = compose_scalar(self.q, b, zeta)
        return self.q

    def redo_first(self, ts, ws, zeta_first):
        if self._redo:  # the quadratic through samples 0, 1, 2, as the batch
            b, fell_back = self._step(ts, ws, 1, NODES[3])
            self.fit_fallbacks += int(fell_back) - int(self._first_fell_back)
            self.q = compose_scalar(self._q_start, b, zeta_first)
