"""The Algorithm protocol (facts, batch and streaming behaviour) and the causal rate algorithm."""

from __future__ import annotations

import numpy as np


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
    #: True when the step checks its rate fit (``integrate`` takes ``fallbacks=``)
    checks_rate_fit = False
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

    def stepper(self, q0: tuple, singular_tol: float):
        """A new per-stream state starting at attitude ``q0`` (tuple of 4 floats)."""
        if not self.causal:
            raise ValueError(f"{self.name} is an offline algorithm (it fits samples after "
                             "each interval) and cannot stream; use integrate_batch / replay, "
                             "or a causal algorithm")
        return self._new_stepper(q0, singular_tol)

    def _new_stepper(self, q0, singular_tol):
        raise NotImplementedError


class RateAlgorithm(Algorithm):
    """A causal quaternion algorithm on rate samples: interval k (sample k-1 to k) becomes a
    body increment ``b_k``, and ``q_k = normalize(exp(−ζ_k) ⊗ q_{k-1} ⊗ b_k)``.

    Its step is one kernel (:mod:`gyro_attitude.core.jit`), ``increment(ts, ws, k, n)`` →
    ``(b_k, fell_back)`` on the last ``n`` ≤ 4 samples held; :mod:`.streaming` dispatches on
    ``code`` (:func:`.streaming.rate_advance`) and both interfaces step it: ``integrate_batch``
    is a compiled loop over that step, ``StreamingIntegrator`` one step per call.
    """

    integrates_into = True

    def __init__(self, name: str, order: int, description: str, cost: str, code: int,
                 fits_rate_polynomial: bool = False):
        super().__init__(name, order, description, cost)
        #: the step's number in :func:`.streaming.body_increment`
        self.code = code
        #: True when the rate is fitted by a polynomial: the first interval's causal linear
        #: fit is redone with the quadratic through samples 0..2 once sample 2 is in, and the
        #: step falls back to the exponential map where the fit cannot be trusted
        #: (:func:`.interpolation.untrusted_fit_scalar`), counted.
        self.fits_rate_polynomial = self.checks_rate_fit = fits_rate_polynomial
