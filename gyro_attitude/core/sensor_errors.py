"""Inertial sensor error model for one triad (gyro or accelerometer), numpy only.

For true samples ``x_k`` (rad/s for a gyro, m/s² for an accelerometer) taken every ``dt`` s
the output is

    y_k = Q[(I + diag(s) + M) x_k + b + β_k + n_k]

* ``b`` constant bias; ``s`` scale-factor error (dimensionless, 1e-6 = 1 ppm); ``M``
  misalignment / cross-axis matrix (rad, zero diagonal): ``M[i, j]`` is the part of true
  axis j read by sensor axis i.
* ``n_k`` white noise of density ``N`` (angle random walk in rad/√s for a gyro, velocity
  random walk in m/s/√s for an accelerometer). A rate sample is the average over ``dt`` of
  white noise of two-sided PSD N², so its standard deviation is ``N/√dt``; the integral of
  the output then has variance ``N² t`` whatever ``dt`` is.
* ``β_k`` first-order Gauss–Markov bias instability with stationary standard deviation σ
  and correlation time τ, discretized exactly: ``β_k = φ β_{k−1} + w_k``, ``φ = e^{−dt/τ}``,
  ``var w = σ²(1 − φ²)``; it starts from its stationary distribution.
* ``Q`` quantization of the integrated output: the instrument emits whole quanta ``q`` of
  angle (rad) or velocity (m/s) per sample and carries the remainder to the next sample, so
  the integrated output never drifts from the integrated input by more than ``q/2``.

Each random process draws from its own generator (children of one ``SeedSequence``), so the
output does not depend on how the samples are split into blocks, and adding one process
does not change the others' draws.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["SensorErrorParams", "SensorErrorModel", "ERROR_EFFECTS"]

# Names of the error effects, in the order they are applied.
ERROR_EFFECTS = (
    "scale_factor",
    "misalignment",
    "bias",
    "bias_instability",
    "white_noise",
    "quantization",
)

# Gauss–Markov samples are generated in chunks of this many with one lower-triangular
# Toeplitz matrix φ^(j−i): the AR(1) recursion is sequential, and a Python loop per sample
# would cost ~100x more than this (m multiply-adds per sample, m = 256).
_GM_CHUNK = 256


def _vec3(value, name: str, nonnegative: bool = False) -> np.ndarray:
    a = np.asarray(value, dtype=np.float64)
    if a.shape == ():
        a = np.full(3, float(a))
    if a.shape != (3,):
        raise ValueError(f"{name} must be a scalar or 3 values, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} contains non-finite values")
    if nonnegative and np.any(a < 0):
        raise ValueError(f"{name} must be >= 0, got {a.tolist()}")
    return a


@dataclass(frozen=True)
class SensorErrorParams:
    """Error parameters of one triad; scalars apply to all three axes. See module docstring.

    ``noise_density`` N, ``bias_instability_sigma`` σ and ``bias_instability_tau`` τ (s),
    ``quantum`` q (integrated-output quantum), ``misalignment`` 3x3 with zero diagonal.
    """

    bias: np.ndarray = field(default_factory=lambda: np.zeros(3))
    scale_factor: np.ndarray = field(default_factory=lambda: np.zeros(3))
    misalignment: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    noise_density: np.ndarray = field(default_factory=lambda: np.zeros(3))
    bias_instability_sigma: np.ndarray = field(default_factory=lambda: np.zeros(3))
    bias_instability_tau: np.ndarray = field(default_factory=lambda: np.full(3, 100.0))
    quantum: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self):
        set_ = object.__setattr__
        set_(self, "bias", _vec3(self.bias, "bias"))
        set_(self, "scale_factor", _vec3(self.scale_factor, "scale_factor"))
        set_(self, "noise_density", _vec3(self.noise_density, "noise_density", True))
        set_(self, "bias_instability_sigma",
             _vec3(self.bias_instability_sigma, "bias_instability_sigma", True))
        set_(self, "bias_instability_tau",
             _vec3(self.bias_instability_tau, "bias_instability_tau", True))
        set_(self, "quantum", _vec3(self.quantum, "quantum", True))
        m = np.asarray(self.misalignment, dtype=np.float64)
        if m.shape != (3, 3) or not np.all(np.isfinite(m)):
            raise ValueError(f"misalignment must be a finite 3x3 matrix, got shape {m.shape}")
        if np.any(np.diag(m) != 0):
            raise ValueError("misalignment must have a zero diagonal (use scale_factor)")
        set_(self, "misalignment", m)
        if np.any((self.bias_instability_sigma > 0) & ~(self.bias_instability_tau > 0)):
            raise ValueError("bias_instability_tau must be > 0 where bias_instability_sigma > 0")

    def active_effects(self) -> tuple[str, ...]:
        """Names (from :data:`ERROR_EFFECTS`) of the effects these parameters switch on."""
        on = {
            "scale_factor": np.any(self.scale_factor != 0),
            "misalignment": np.any(self.misalignment != 0),
            "bias": np.any(self.bias != 0),
            "bias_instability": np.any(self.bias_instability_sigma > 0),
            "white_noise": np.any(self.noise_density > 0),
            "quantization": np.any(self.quantum > 0),
        }
        return tuple(name for name in ERROR_EFFECTS if on[name])


class SensorErrorModel:
    """Applies :class:`SensorErrorParams` to blocks of samples at a fixed step ``dt`` (s).

    Resumable: state (Gauss–Markov bias, quantization remainder, generators) carries over
    between calls to :meth:`apply`. ``seed`` is an int, a ``numpy.random.SeedSequence`` or
    ``None`` (fresh entropy). Only active effects are evaluated; ``effects_run`` records
    the names of those that have been.
    """

    def __init__(self, params: SensorErrorParams, dt: float, seed=None):
        if not (np.isfinite(dt) and dt > 0):
            raise ValueError(f"dt must be a finite positive step in s, got {dt}")
        self.params = params
        self.dt = float(dt)
        self.active = params.active_effects()
        self.effects_run: set[str] = set()
        ss = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
        noise_ss, gm_ss = ss.spawn(2)
        self._noise_rng = np.random.default_rng(noise_ss)
        self._gm_rng = np.random.default_rng(gm_ss)
        self._gain = np.eye(3) + np.diag(params.scale_factor) + params.misalignment
        self._remainder = np.zeros(3)
        if "bias_instability" in self.active:
            p = params
            tau = np.where(p.bias_instability_tau > 0, p.bias_instability_tau, 1.0)
            self._phi = np.exp(-self.dt / tau)
            # 1 − φ² = −expm1(−2dt/τ) keeps full accuracy when dt ≪ τ.
            self._w_std = p.bias_instability_sigma * np.sqrt(-np.expm1(-2.0 * self.dt / tau))
            # State one step before the first sample, drawn from the stationary distribution.
            self._gm_state = p.bias_instability_sigma * self._gm_rng.standard_normal(3)
            j = np.arange(_GM_CHUNK)
            lag = j[:, None] - j[None, :]
            # toeplitz[a, j, i] = φ_a^(j−i) for i <= j, else 0.
            with np.errstate(under="ignore"):
                self._toeplitz = np.where(
                    lag[None] >= 0,
                    np.exp((-self.dt / tau)[:, None, None] * np.maximum(lag, 0)[None]),
                    0.0,
                )
                self._powers = self._phi[None, :] ** (j[:, None] + 1)  # (m, 3): φ^(j+1)

    # ------------------------------------------------------------------ processes
    def _bias_instability(self, n: int) -> np.ndarray:
        w = self._w_std * self._gm_rng.standard_normal((n, 3))
        out = np.empty((n, 3))
        for start in range(0, n, _GM_CHUNK):
            m = min(_GM_CHUNK, n - start)
            # β_j = φ^(j+1) β_prev + Σ_{i<=j} φ^(j−i) w_i for the m samples of this chunk.
            chunk = w[start:start + m]
            for a in range(3):  # three matrix-vector products (BLAS) beat one einsum 5x
                out[start:start + m, a] = self._toeplitz[a, :m, :m] @ chunk[:, a]
            out[start:start + m] += self._powers[:m] * self._gm_state
            self._gm_state = out[start + m - 1].copy()
        return out

    def _quantize(self, y: np.ndarray) -> np.ndarray:
        q = self.params.quantum
        has_q = q > 0
        safe_q = np.where(has_q, q, 1.0)
        # Cumulative integrated output plus the carried remainder; whole quanta emitted up to
        # sample k are round(cum_k / q), identical to carrying the remainder sample by sample.
        cum = self._remainder + np.cumsum(y * self.dt, axis=0)
        counts = np.rint(cum / safe_q)
        emitted = np.diff(counts, axis=0, prepend=np.zeros((1, 3))) * safe_q / self.dt
        self._remainder = np.where(has_q, cum[-1] - counts[-1] * safe_q, 0.0)
        return np.where(has_q, emitted, y)

    # ------------------------------------------------------------------ public
    def apply(self, x) -> np.ndarray:
        """Measured samples ``(n, 3)`` for true samples ``x`` ``(n, 3)``."""
        x = np.asarray(x, dtype=np.float64)
        if x.ndim != 2 or x.shape[1] != 3:
            raise ValueError(f"samples must have shape (n, 3), got {x.shape}")
        n = x.shape[0]
        if n == 0:
            return x.copy()
        act = self.active
        if "scale_factor" in act or "misalignment" in act:
            y = x @ self._gain.T
        else:
            y = x.copy()
        if "bias" in act:
            y += self.params.bias
        if "bias_instability" in act:
            y += self._bias_instability(n)
        if "white_noise" in act:
            y += (self.params.noise_density / np.sqrt(self.dt)) * self._noise_rng.standard_normal(
                (n, 3)
            )
        if "quantization" in act:
            y = self._quantize(y)
        self.effects_run.update(act)
        return y

    def variances(self) -> np.ndarray:
        """Per-axis variance of the random output error per sample, shape ``(3,)``.

        White noise N²/dt + Gauss–Markov σ² + quantization q²/(6 dt²) (the output error is
        the difference of two remainders, each uniform on ±q/2). Deterministic errors (bias,
        scale factor, misalignment) are not random and are not included; all zeros for an
        ideal sensor.
        """
        p = self.params
        return (
            p.noise_density**2 / self.dt
            + p.bias_instability_sigma**2
            + p.quantum**2 / (6.0 * self.dt**2)
        )
