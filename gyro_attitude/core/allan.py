"""Allan-variance noise terms (IEEE Std 952): τ grid, confidence bounds and the term fit (numpy only).

Model of the Allan variance of a rate (or acceleration) signal, one term per noise::

    σ²(τ) = 3Q²/τ²  +  N²/τ  +  (0.664 B)²  +  K² τ / 3
            quantization  angle RW  bias instability  rate RW

(Q in rad, N in rad/√s, B in rad/s, K in rad/s/√s; for an accelerometer m/s, m/s/√s, m/s²,
m/s²/√s). The terms are fitted together by non-negative least squares on σ² with each τ
weighted by its confidence (relative error 1/√(2(K_c − 1)), K_c = number of non-overlapping
clusters), not read off one τ each: where ARW and RRW cross close to the floor, the minimum
of σ alone over-reads B (by 37 % for the shipped ``lab_bench`` gyro). The reported values are
still the IEEE read-outs of the fitted lines: N = the −½ line at τ = 1 s, K = the +½ line at
τ = 3 s, B = the flat line / 0.664. A term is reported as not visible (``None``) unless at
some τ its fitted share of σ² is at least ``VISIBLE_SHARE`` and more than twice the standard
error of the measured σ² there.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gyro_attitude.core.sensor_errors import FLICKER_FLOOR_FACTOR

__all__ = [
    "AllanTerms",
    "TERM_NAMES",
    "VISIBLE_SHARE",
    "log_spaced_cluster_sizes",
    "relative_error",
    "model_variance",
    "fit_terms",
]

TERM_NAMES = ("quantization", "random_walk", "bias_instability", "rate_random_walk")
# A fitted term must carry at least this share of the modelled σ² at some τ to be reported.
VISIBLE_SHARE = 0.05
# Fewest non-overlapping clusters a τ must have to enter the analysis (error ≤ 1/√(2·8)).
MIN_CLUSTERS = 9


@dataclass(frozen=True)
class AllanTerms:
    """Fitted noise terms of one axis (SI; ``None`` = not visible in this recording)."""

    quantization: float | None
    random_walk: float | None
    bias_instability: float | None
    rate_random_walk: float | None
    # τ (s) where each term is read, for plots: N at 1 s, K at 3 s, B at the floor minimum.
    tau_read_s: dict

    def as_dict(self) -> dict:
        return {name: getattr(self, name) for name in TERM_NAMES}


def log_spaced_cluster_sizes(n_samples: int, per_decade: int = 10,
                             min_clusters: int = MIN_CLUSTERS) -> np.ndarray:
    """Distinct cluster sizes m (samples per τ) log-spaced from 1 up to n/min_clusters.

    ``ValueError`` when the recording is too short for even m = 1."""
    if n_samples < 2 * min_clusters + 1:
        raise ValueError(f"{n_samples} samples are too few for an Allan deviation "
                         f"(need at least {2 * min_clusters + 1})")
    m_max = n_samples // min_clusters
    count = max(1, int(math.floor(math.log10(m_max) * per_decade)) + 1)
    m = np.unique(np.round(np.logspace(0.0, math.log10(m_max), count)).astype(np.int64))
    return m[(m >= 1) & (m <= m_max)]


def relative_error(n_samples: int, m) -> np.ndarray:
    """Relative 1-σ error of an Allan deviation from K_c = n/m non-overlapping clusters:
    1/√(2(K_c − 1)) (IEEE Std 952 Annex C; conservative for the overlapping estimator)."""
    clusters = np.floor(n_samples / np.asarray(m, dtype=np.float64))
    return 1.0 / np.sqrt(2.0 * np.maximum(clusters - 1.0, 1.0))


def _basis(tau: np.ndarray) -> np.ndarray:
    """Columns of σ²(τ) per unit coefficient: Q², N², B², K² (see module docstring)."""
    return np.stack([3.0 / tau**2, 1.0 / tau, np.full_like(tau, FLICKER_FLOOR_FACTOR**2),
                     tau / 3.0], axis=1)


def model_variance(tau, terms: AllanTerms | dict) -> np.ndarray:
    """σ²(τ) of the model for given terms (``None`` counts as 0)."""
    tau = np.asarray(tau, dtype=np.float64)
    d = terms.as_dict() if isinstance(terms, AllanTerms) else terms
    coef = np.array([(d.get(n) or 0.0) ** 2 for n in TERM_NAMES])
    return _basis(tau) @ coef


def fit_terms(tau, adev, rel_err) -> AllanTerms:
    """Fit the four terms to an Allan deviation curve ``adev`` at ``tau`` (s).

    ``rel_err``: relative error of each point (weights). ``ValueError`` on non-finite,
    non-positive or mismatched input."""
    tau = np.asarray(tau, dtype=np.float64)
    adev = np.asarray(adev, dtype=np.float64)
    rel = np.asarray(rel_err, dtype=np.float64)
    if tau.ndim != 1 or tau.shape != adev.shape or tau.shape != rel.shape or tau.size == 0:
        raise ValueError(f"tau, adev and rel_err must be 1-D of one length, got "
                         f"{tau.shape}, {adev.shape}, {rel.shape}")
    if not (np.all(np.isfinite(tau)) and np.all(tau > 0)):
        raise ValueError("tau must be finite and > 0")
    if not (np.all(np.isfinite(adev)) and np.all(np.isfinite(rel)) and np.all(rel > 0)):
        raise ValueError("adev and rel_err must be finite (rel_err > 0)")
    from scipy.optimize import nnls  # (imported where used: see sensor_errors)

    avar = adev**2
    basis = _basis(tau)
    scale = avar
    for _ in range(3):
        # Weighted rows: residual / (σ² · 2·rel) is the error in units of its standard
        # deviation (σ² has twice the relative error of σ). The first pass scales by the
        # measured σ², which favours points that scatter low; later passes use the fitted
        # model instead. Columns scaled to unit norm keep NNLS well conditioned over the
        # many decades the basis spans.
        w = 1.0 / (2.0 * rel * np.maximum(scale, np.finfo(float).tiny))
        a = basis * w[:, None]
        norms = np.linalg.norm(a, axis=0)
        norms[norms == 0] = 1.0
        coef, _ = nnls(a / norms, avar * w)
        coef = coef / norms
        scale = basis @ coef
        if not np.all(scale > 0):
            break
    contrib = basis * coef
    total = contrib.sum(axis=1)
    share = contrib / np.where(total > 0, total, 1.0)[:, None]
    # Visible: the term's share of σ² beats VISIBLE_SHARE and, at the same τ, twice the
    # standard error of the measured σ² there (2 · 2·rel), so scatter at long τ with few
    # clusters does not pass for a term.
    visible = np.any((share >= VISIBLE_SHARE) & (share > 4.0 * rel[:, None]), axis=0)
    values = {}
    for i, name in enumerate(TERM_NAMES):
        values[name] = float(math.sqrt(coef[i])) if visible[i] else None
    tau_floor = float(tau[np.argmin(adev)])
    return AllanTerms(**values, tau_read_s={"random_walk": 1.0, "rate_random_walk": 3.0,
                                            "bias_instability": tau_floor})
