"""How a real sensor samples: bandwidth, output range (saturation), turn-on bias, g-sensitivity.

Each is off unless a scene names it, and only the named ones are evaluated
(``effects_run``: ``bandwidth``, ``saturation``, ``turn_on_bias``, ``g_sensitivity``). In a
sample's path they act in this order (:class:`~gyro_attitude.core.scene.SceneSimulator`)::

    ideal ω_ib or f  →  bandwidth  →  + turn-on bias (+ G f: g-sensitivity, gyro)
                     →  error model (scale, misalignment, bias, noise, quantization)
                     →  output range (clipped to ±range, clipped samples counted)

- **bandwidth** ``mean``: the mean over the sample interval (t_k − Δt, t_k], as an
  integrating MEMS or a decimation filter gives — by 3-point Gauss–Legendre quadrature of
  the closed-form (or fitted) motion, exact for motion polynomial to degree 5 within an
  interval; the first sample averages what lies at t ≥ 0. ``lowpass``: a digital
  Butterworth of ``order`` and ``cutoff_hz`` at the output rate (scipy ``butter``/``sosfilt``,
  state kept across blocks, started in steady state on the first sample).
- **turn-on bias**: drawn once per run (per seed) from N(0, σ²) per axis, constant then.
- **g-sensitivity** (gyro): ``ω += G f^b`` with G in rad/s per m/s² (scalar: G = g·I).
- **range**: the full-scale output ±range per axis; values beyond are clipped to it and
  the samples with any clipped axis counted in ``saturated``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["SamplingParams", "SensorSampler", "BANDWIDTH_FILTERS", "GAUSS_LEGENDRE_3"]

BANDWIDTH_FILTERS = ("mean", "lowpass")
#: 3-point Gauss–Legendre nodes on [−1, 1] and weights (sum 2).
GAUSS_LEGENDRE_3 = (np.array([-np.sqrt(0.6), 0.0, np.sqrt(0.6)]),
                    np.array([5.0 / 9.0, 8.0 / 9.0, 5.0 / 9.0]))


@dataclass(frozen=True)
class SamplingParams:
    """One triad's sampling options (SI); ``None`` = off."""

    bandwidth: str | None = None
    order: int = 2
    cutoff_hz: float | None = None
    range: float | None = None
    turn_on_bias_sigma: np.ndarray | None = None
    g_sensitivity: np.ndarray | None = None

    def active(self) -> tuple[str, ...]:
        on = {"bandwidth": self.bandwidth is not None, "turn_on_bias":
              self.turn_on_bias_sigma is not None, "g_sensitivity": self.g_sensitivity is not None,
              "saturation": self.range is not None}
        return tuple(k for k, v in on.items() if v)


class SensorSampler:
    """State of one triad's sampling options over a run (see module docstring)."""

    def __init__(self, params: SamplingParams, dt: float, seed: np.random.SeedSequence):
        self.params = params
        self.dt = float(dt)
        self.effects_run: set[str] = set()
        self.saturated = 0
        self._bias = None
        if params.turn_on_bias_sigma is not None:
            self._bias = np.asarray(params.turn_on_bias_sigma) * np.random.default_rng(
                seed).standard_normal(3)
        self._sos = self._zi = None
        if params.bandwidth == "lowpass":
            nyquist = 0.5 / self.dt
            if not params.cutoff_hz < nyquist:
                raise ValueError(f"bandwidth.cutoff_hz {params.cutoff_hz:g} Hz must be below "
                                 f"the Nyquist frequency {nyquist:g} Hz of the output rate")
            from scipy.signal import butter  # (imported where used: see sensor_errors)

            self._sos = butter(params.order, params.cutoff_hz, fs=1.0 / self.dt, output="sos")

    @property
    def turn_on_bias(self) -> np.ndarray | None:
        """The bias drawn for this run (None when off)."""
        return self._bias

    @property
    def averages(self) -> bool:
        """Whether the sensor outputs the mean over the sample interval."""
        return self.params.bandwidth == "mean"

    def node_times(self, t: np.ndarray) -> np.ndarray:
        """Quadrature times (n, 3) in each interval (t − Δt, t], clipped at 0."""
        x, _ = GAUSS_LEGENDRE_3
        return np.maximum(t[:, None] - 0.5 * self.dt * (1.0 - x[None, :]), 0.0)

    def mean_of(self, values: np.ndarray) -> np.ndarray:
        """Quadrature mean of node values (n, 3 nodes, 3 axes)."""
        self.effects_run.add("bandwidth")
        _, w = GAUSS_LEGENDRE_3
        return np.einsum("k,nka->na", 0.5 * w, values)

    def before_errors(self, x: np.ndarray, force: np.ndarray | None = None) -> np.ndarray:
        """Low-pass, turn-on bias and g-sensitivity of ideal samples ``x (n,3)``."""
        p = self.params
        if self._sos is not None and x.shape[0]:
            from scipy.signal import sosfilt, sosfilt_zi

            self.effects_run.add("bandwidth")
            if self._zi is None:  # steady state on the first sample: no start transient
                self._zi = sosfilt_zi(self._sos)[:, :, None] * x[0][None, None, :]
            x, self._zi = sosfilt(self._sos, x, axis=0, zi=self._zi)
        if self._bias is not None:
            self.effects_run.add("turn_on_bias")
            x = x + self._bias
        if p.g_sensitivity is not None:
            self.effects_run.add("g_sensitivity")
            x = x + force @ p.g_sensitivity.T
        return x

    def clip(self, x: np.ndarray) -> np.ndarray:
        """Outputs clipped to ±range; counts the samples with a clipped axis."""
        r = self.params.range
        if r is None:
            return x
        self.effects_run.add("saturation")
        over = np.abs(x) > r
        self.saturated += int(np.count_nonzero(over.any(axis=1)))
        return np.clip(x, -r, r)
