"""Inertial sensor error model for one triad (gyro or accelerometer), numpy only.

For true samples ``x_k`` (rad/s for a gyro, m/s² for an accelerometer) taken every ``dt`` s
the output is

    y_k = Q[(I + diag(s) + M) x_k + b + β_k + r_k + n_k]

* ``b`` constant bias; ``s`` scale-factor error (dimensionless, 1e-6 = 1 ppm); ``M``
  misalignment / cross-axis matrix (rad, zero diagonal): ``M[i, j]`` is the part of true
  axis j read by sensor axis i.
* ``n_k`` white noise of density ``N`` (angle random walk in rad/√s for a gyro, velocity
  random walk in m/s/√s for an accelerometer). A rate sample is the average over ``dt`` of
  white noise of two-sided PSD N², so its standard deviation is ``N/√dt``; the integral of
  the output then has variance ``N² t`` whatever ``dt`` is.
* ``β_k`` bias instability, in either (or both) of two forms:

  - first-order Gauss–Markov with stationary standard deviation σ and correlation time τ,
    discretized exactly: ``β_k = φ β_{k−1} + w_k``, ``φ = e^{−dt/τ}``,
    ``var w = σ²(1 − φ²)``; it starts from its stationary distribution;
  - the datasheet figure B, the flat floor of the Allan deviation (IEEE Std 952:
    ``σ_floor = √(2 ln 2/π)·B ≈ 0.664 B``, flicker noise of two-sided PSD B²/(2πf)).
    Rule: B is realised as a Gaussian process with the autocovariance of a sum of
    :data:`FLOOR_PROCESSES` independent Gauss–Markov processes (each as above) with
    correlation times one decade apart from ``FLOOR_TAU_MIN_S`` = 0.1 s to
    ``FLOOR_TAU_MAX_S`` = 10⁵ s and equal σ_j. Equal σ_j² per log-step give a 1/f PSD
    between the band's corner frequencies (σ_j² ≈ B² ln10/π); σ_j is then scaled so that
    the maximum of the sum's closed-form Allan deviation is exactly 0.664 B. That floor is
    flat within 3.2 % for Allan times from 1 s to 10⁴ s (2.3 % from 3 s to 3000 s); below
    1 s the white noise hides it in any real sensor.
    Realisation (:func:`floor_realisation`): ONE white sequence per axis drives the bank of
    first-order sections ``s_j,k = φ_j s_j,k−1 + g_j w_k``, output Σ_j s_j. The sections
    are then correlated (``E[s_i s_j] = g_i g_j/(1 − φ_iφ_j)``), and the sum's
    autocovariance at lag m ≥ 0 is ``Σ_i φ_i^m Σ_j E[s_i s_j]``; the gains are solved so
    that ``Σ_j E[s_i s_j] = σ_i²`` for every i, which makes it ``Σ_i σ_i² φ_i^m``: exactly
    that of the independent sum, at every rate (and, the process being Gaussian, the same
    distribution), for a seventh of the random draws. The bank starts from its joint
    stationary distribution.
* ``r_k`` rate random walk of coefficient K (rad/s/√s; m/s²/√s for an accelerometer): a
  Wiener process of intensity K² that starts at 0, averaged over each sample interval like
  the white noise. Exact discretization: with the walk ``r(t_{k−1})`` at the start of the
  interval, the sample is ``r(t_{k−1}) + K√dt (z₁/2 + z₂/√12)`` and the walk moves on by
  ``K√dt z₁`` (z₁, z₂ standard normal): the joint Gaussian of the interval average and the
  end value (variances K²dt/3, K²dt, covariance K²dt/2). Its Allan variance is K²τ/3.
* ``Q`` quantization of the integrated output: the instrument emits whole quanta ``q`` of
  angle (rad) or velocity (m/s) per sample and carries the remainder to the next sample, so
  the integrated output never drifts from the integrated input by more than ``q/2``.

Each random process draws from its own generator (children of one ``SeedSequence``), so the
output does not depend on how the samples are split into blocks, and adding one process
does not change the others' draws.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np

__all__ = [
    "SensorErrorParams",
    "SensorErrorModel",
    "ERROR_EFFECTS",
    "FLICKER_FLOOR_FACTOR",
    "gauss_markov_allan_variance",
    "flicker_floor_components",
    "FloorRealisation",
    "floor_realisation",
]

# Names of the error effects, in the order they are applied.
ERROR_EFFECTS = (
    "scale_factor",
    "misalignment",
    "bias",
    "bias_instability",
    "bias_instability_floor",
    "rate_random_walk",
    "white_noise",
    "quantization",
)

# σ_floor / B of flicker rate noise (IEEE Std 952): √(2 ln 2 / π) = 0.6643.
FLICKER_FLOOR_FACTOR = math.sqrt(2.0 * math.log(2.0) / math.pi)
# Correlation times of the Gauss–Markov sum that realises an Allan floor B (module docstring).
FLOOR_TAU_MIN_S = 0.1
FLOOR_TAU_MAX_S = 1.0e5
FLOOR_PROCESSES = 7
# Samples per pass of the Gauss–Markov generator: its (columns x samples) work arrays stay
# in cache instead of streaming hundreds of MB through memory for long blocks.
_GM_BLOCK = 1 << 15


def gauss_markov_allan_variance(sigma, tau_c, tau) -> np.ndarray:
    """Closed-form Allan variance at averaging time ``tau`` of a Gauss–Markov process of
    stationary σ and correlation time τ_c (autocovariance σ² e^{−|t|/τ_c}):
    ``σ²/x² (2x − 3 + 4e^{−x} − e^{−2x})``, x = τ/τ_c."""
    sigma, tau_c, tau = (np.asarray(v, dtype=np.float64) for v in (sigma, tau_c, tau))
    x = tau / tau_c
    # For x ≪ 1 the bracket cancels to 2x³/3 − x⁴/2 + 7x⁵/30 − x⁶/12 + 31x⁷/1260 − ...:
    # below x = 0.01 the series (truncation < 4e-10) beats the closed form (rounding 6e-10).
    series = x**3 * (2.0 / 3.0 + x * (-0.5 + x * (7.0 / 30.0
                                                  + x * (-1.0 / 12.0 + x * 31.0 / 1260.0))))
    with np.errstate(over="ignore", invalid="ignore"):
        full = 2.0 * x - 3.0 + 4.0 * np.exp(-x) - np.exp(-2.0 * x)
    bracket = np.where(x < 0.01, series, full)
    return sigma**2 * bracket / x**2


def flicker_floor_components(floor_b: float) -> tuple[np.ndarray, np.ndarray]:
    """``(sigmas, taus)`` of the Gauss–Markov sum whose Allan floor is ``floor_b`` (B).

    Equal σ_j over log-spaced τ_j (module docstring), scaled so that the maximum of the
    sum's closed-form Allan deviation is ``FLICKER_FLOOR_FACTOR · B``."""
    taus = np.logspace(math.log10(FLOOR_TAU_MIN_S), math.log10(FLOOR_TAU_MAX_S),
                       FLOOR_PROCESSES)
    grid = np.logspace(-1.0, 5.0, 601)
    unit = gauss_markov_allan_variance(1.0, taus[:, None], grid[None, :]).sum(axis=0)
    sigma = FLICKER_FLOOR_FACTOR * floor_b / math.sqrt(unit.max())
    return np.full(FLOOR_PROCESSES, sigma), taus


@dataclass(frozen=True)
class FloorRealisation:
    """The filter bank that realises an Allan floor B = 1 at step dt (scale it by B).

    Section j: ``s_j,k = phi[j] s_j,k−1 + gain[j] w_k``, one standard normal w_k shared by
    the sections of an axis; ``state_sqrt`` (S, S): a square root of the sections' joint
    stationary covariance (its columns times S standard normals: a stationary start);
    ``variance``: the stationary variance of the sum, Σσ_j²."""

    phi: np.ndarray
    gain: np.ndarray
    state_sqrt: np.ndarray
    variance: float


@functools.lru_cache(maxsize=32)
def floor_realisation(dt: float) -> FloorRealisation:
    """Gains of the shared-input bank for a floor B = 1 at step ``dt`` (module docstring),
    computed once per step (every run of a Monte Carlo set shares it)."""
    sig, taus = flicker_floor_components(1.0)
    r = dt / taus
    phi = np.exp(-r)
    # 1 − φ_iφ_j and 1 − φ² through expm1: full accuracy when dt ≪ τ (φ within 1e-7 of 1).
    one_minus = -np.expm1(-(r[:, None] + r[None, :]))
    one_minus_sq = np.diag(one_minus).copy()
    # Unknowns u_j with g_j = σ_j √(1 − φ_j²) u_j (u = 1: independent inputs). Then
    # E[s_i s_j] = σ_iσ_j ρ_ij u_i u_j with ρ_ij = √((1 − φ_i²)(1 − φ_j²))/(1 − φ_iφ_j) in
    # (0, 1], the correlation of two sections fed the same input, and the equations
    # Σ_j E[s_i s_j] = σ_i² read u_i Σ_j A_ij u_j = 1, A_ij = ρ_ij σ_j/σ_i. Newton from
    # u_i = 1/√(Σ_j A_ij): quadratic, 4-5 steps to rounding;
    # the Jacobian stays well conditioned (cond < 3) at every dt, even where sections
    # coincide (ρ → 1 at low rates: dt ≫ τ_j makes sections white).
    rho = np.sqrt(one_minus_sq[:, None] * one_minus_sq[None, :]) / one_minus
    a = rho * (sig[None, :] / sig[:, None])
    u = 1.0 / np.sqrt(a.sum(axis=1))
    for _ in range(50):
        au = a @ u
        resid = u * au - 1.0
        if np.max(np.abs(resid)) < 1e-14:
            break
        u = u - np.linalg.solve(np.diag(au) + u[:, None] * a, resid)
    else:  # pragma: no cover - not seen at any step from 1e-9 s to 1e6 s
        raise RuntimeError(f"floor gains did not converge at dt={dt:g} s")
    gain = sig * np.sqrt(one_minus_sq) * u
    cov = (sig * u)[:, None] * rho * (sig * u)[None, :]
    # Symmetric square root (eigh): cov is singular where sections coincide.
    w, v = np.linalg.eigh(cov)
    state_sqrt = v * np.sqrt(np.clip(w, 0.0, None))
    return FloorRealisation(phi, gain, state_sqrt, float(np.sum(sig**2)))


def _gauss_markov(rng, phi, w_std, state, n: int) -> np.ndarray:
    """``(columns, n)`` samples of independent AR(1) processes β_k = φ β_{k−1} + w_k from
    ``state`` (each column's value one step before the first sample; updated in place)."""
    cols = phi.shape[0]
    # scipy is imported where it is used, here and in the other core modules: scipy.signal's
    # imports (scipy.stats with them) take longer than all else a command, a node or a pool
    # worker loads at start-up, and most scenes never reach this line
    from scipy.signal import lfilter

    out = np.empty((cols, n))
    for lo in range(0, n, _GM_BLOCK):
        m = min(_GM_BLOCK, n - lo)
        # Drawn sample-major (so the stream does not depend on block sizes), filtered
        # column-major: contiguous rows are faster through the filter than strided ones.
        w = rng.standard_normal((m, cols))
        w *= w_std
        w = np.ascontiguousarray(w.T)
        for a in range(cols):
            # scipy's IIR filter runs the sequential recursion in C; zi carries φ·β_prev.
            beta = lfilter([1.0], [1.0, -phi[a]], w[a], zi=[phi[a] * state[a]])[0]
            state[a] = beta[-1]
            out[a, lo:lo + m] = beta
    return out


def _floor_bank(rng, real: FloorRealisation, scale, state, n: int) -> np.ndarray:
    """``(3, n)`` floor samples: the bank ``real`` on one white sequence per axis times
    ``scale`` (B per axis), from ``state`` (3, S) (the sections one step before the first
    sample, in units of B; updated in place)."""
    from scipy.signal import lfilter

    out = np.empty((3, n))
    for lo in range(0, n, _GM_BLOCK):
        m = min(_GM_BLOCK, n - lo)
        w = np.ascontiguousarray(rng.standard_normal((m, 3)).T)  # sample-major draws
        acc = out[:, lo:lo + m]
        for j, (phi, g) in enumerate(zip(real.phi, real.gain, strict=True)):
            s, _ = lfilter([g], [1.0, -phi], w, axis=-1, zi=phi * state[:, j:j + 1])
            state[:, j] = s[:, -1]
            if j == 0:
                acc[...] = s
            else:
                acc += s
        acc *= scale[:, None]
    return out


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
    ``bias_instability_floor`` B (Allan floor), ``rate_random_walk`` K,
    ``quantum`` q (integrated-output quantum), ``misalignment`` 3x3 with zero diagonal.
    """

    bias: np.ndarray = field(default_factory=lambda: np.zeros(3))
    scale_factor: np.ndarray = field(default_factory=lambda: np.zeros(3))
    misalignment: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    noise_density: np.ndarray = field(default_factory=lambda: np.zeros(3))
    bias_instability_sigma: np.ndarray = field(default_factory=lambda: np.zeros(3))
    bias_instability_tau: np.ndarray = field(default_factory=lambda: np.full(3, 100.0))
    quantum: np.ndarray = field(default_factory=lambda: np.zeros(3))
    bias_instability_floor: np.ndarray = field(default_factory=lambda: np.zeros(3))
    rate_random_walk: np.ndarray = field(default_factory=lambda: np.zeros(3))

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
        set_(self, "bias_instability_floor",
             _vec3(self.bias_instability_floor, "bias_instability_floor", True))
        set_(self, "rate_random_walk", _vec3(self.rate_random_walk, "rate_random_walk", True))
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
            "bias_instability_floor": np.any(self.bias_instability_floor > 0),
            "rate_random_walk": np.any(self.rate_random_walk > 0),
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
        # Spawned in two calls so that the first two streams are those of the model before
        # the floor and the rate random walk were added (spawn continues the child count).
        noise_ss, gm_ss = ss.spawn(2)
        floor_ss, rrw_ss = ss.spawn(2)
        self._noise_rng = np.random.default_rng(noise_ss)
        self._gm_rng = np.random.default_rng(gm_ss)
        self._floor_rng = np.random.default_rng(floor_ss)
        self._rrw_rng = np.random.default_rng(rrw_ss)
        self._gain = np.eye(3) + np.diag(params.scale_factor) + params.misalignment
        self._remainder = np.zeros(3)
        p = params
        if "bias_instability" in self.active:
            tau = np.where(p.bias_instability_tau > 0, p.bias_instability_tau, 1.0)
            self._gm = self._gm_setup(p.bias_instability_sigma, tau, self._gm_rng)
        if "bias_instability_floor" in self.active:
            real = floor_realisation(self.dt)
            self._floor_real = real
            self._floor_var = real.variance * p.bias_instability_floor**2
            # Stationary start of each axis's sections (in units of B).
            z = self._floor_rng.standard_normal((3, FLOOR_PROCESSES))
            self._floor_state = z @ real.state_sqrt.T
        self._rrw_state = np.zeros(3)

    def _gm_setup(self, sigma, tau, rng):
        phi = np.exp(-self.dt / tau)
        # 1 − φ² = −expm1(−2dt/τ) keeps full accuracy when dt ≪ τ.
        w_std = sigma * np.sqrt(-np.expm1(-2.0 * self.dt / tau))
        # State one step before the first sample, drawn from the stationary distribution.
        state = sigma * rng.standard_normal(sigma.shape[0])
        return phi, w_std, state

    # ------------------------------------------------------------------ processes
    def _bias_instability(self, n: int) -> np.ndarray:
        phi, w_std, state = self._gm
        return _gauss_markov(self._gm_rng, phi, w_std, state, n).T

    def _bias_instability_floor(self, n: int) -> np.ndarray:
        return _floor_bank(self._floor_rng, self._floor_real, self.params.bias_instability_floor,
                           self._floor_state, n).T

    def _rate_random_walk(self, n: int) -> np.ndarray:
        k_sqrt_dt = self.params.rate_random_walk * math.sqrt(self.dt)
        z = self._rrw_rng.standard_normal((n, 2, 3))
        steps = k_sqrt_dt * z[:, 0]
        # Walk value at the start of each interval (a running sum that continues from the
        # carried state in the same order of additions, so any split into blocks gives the
        # same bits), then the interval average around it.
        walk = np.empty((n + 1, 3))
        walk[0] = self._rrw_state
        walk[1:] = steps
        np.cumsum(walk, axis=0, out=walk)
        self._rrw_state = walk[-1].copy()
        return walk[:-1] + k_sqrt_dt * (0.5 * z[:, 0] + z[:, 1] / math.sqrt(12.0))

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
        if "bias_instability_floor" in act:
            y += self._bias_instability_floor(n)
        if "rate_random_walk" in act:
            y += self._rate_random_walk(n)
        if "white_noise" in act:
            w = self._noise_rng.standard_normal((n, 3))
            w *= self.params.noise_density / np.sqrt(self.dt)  # in place: no second (n, 3)
            y += w
        if "quantization" in act:
            y = self._quantize(y)
        self.effects_run.update(act)
        return y

    def variances(self) -> np.ndarray:
        """Per-axis variance of the random output error per sample, shape ``(3,)``.

        White noise N²/dt + Gauss–Markov σ² (and Σσ_j² of the Allan-floor sum) +
        quantization q²/(6 dt²) (the output error is the difference of two remainders, each
        uniform on ±q/2). Deterministic errors (bias, scale factor, misalignment) and the rate
        random walk (a bias that wanders from 0, variance growing with time, no stationary
        value) are not included; all zeros for an ideal sensor.
        """
        p = self.params
        floor = self._floor_var if "bias_instability_floor" in self.active else 0.0
        return (
            p.noise_density**2 / self.dt
            + p.bias_instability_sigma**2
            + floor
            + p.quantum**2 / (6.0 * self.dt**2)
        )
