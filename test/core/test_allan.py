"""Allan term fit: exact recovery on closed-form curves, visibility, bad input."""

import numpy as np
import pytest

from gyro_attitude.core.allan import (
    fit_terms,
    log_spaced_cluster_sizes,
    model_variance,
    relative_error,
)

_FLOOR = np.sqrt(2 * np.log(2) / np.pi)  # IEEE 952: σ_floor = 0.664 B


def _curve(tau, q=0.0, n=0.0, b=0.0, k=0.0):
    """IEEE Std 952 Allan deviation of the four terms, written out in the test."""
    return np.sqrt(3 * q**2 / tau**2 + n**2 / tau + (_FLOOR * b) ** 2 + k**2 * tau / 3)


def test_fit_recovers_exact_terms():
    tau = np.logspace(-2, 3.5, 60)
    truth = dict(q=2e-6, n=4e-5, b=1.5e-5, k=1e-6)
    t = fit_terms(tau, _curve(tau, **truth), np.full(tau.shape, 0.05))
    assert t.quantization == pytest.approx(truth["q"], rel=1e-6)
    assert t.random_walk == pytest.approx(truth["n"], rel=1e-6)
    assert t.bias_instability == pytest.approx(truth["b"], rel=1e-6)
    assert t.rate_random_walk == pytest.approx(truth["k"], rel=1e-6)
    # IEEE read-outs: the −½ line at τ = 1 s is N, the +½ line at τ = 3 s is K.
    assert t.tau_read_s["random_walk"] == 1.0 and t.tau_read_s["rate_random_walk"] == 3.0
    assert np.sqrt(model_variance(tau, t)) == pytest.approx(_curve(tau, **truth), rel=1e-6)


def test_fit_beats_reading_the_minimum_when_terms_crowd_the_floor():
    # The shipped lab_bench gyro: ARW and RRW cross near the floor, σ_min/0.664 over-reads B
    # by 37 %; the joint fit not.
    tau = np.logspace(-2, 3.5, 60)
    adev = _curve(tau, n=2.909e-5, b=1.45e-5, k=2.424e-6)
    naive = adev.min() / 0.664
    assert naive > 1.3 * 1.45e-5
    t = fit_terms(tau, adev, np.full(tau.shape, 0.05))
    assert t.bias_instability == pytest.approx(1.45e-5, rel=1e-6)


def test_invisible_terms_are_none():
    tau = np.logspace(-1, 2, 30)
    t = fit_terms(tau, _curve(tau, n=1e-4), np.full(tau.shape, 0.1))
    assert t.random_walk == pytest.approx(1e-4, rel=1e-6)
    assert t.quantization is None and t.bias_instability is None
    assert t.rate_random_walk is None


def test_cluster_sizes_and_errors():
    m = log_spaced_cluster_sizes(100_000)
    assert m[0] == 1 and m[-1] <= 100_000 // 9 and np.all(np.diff(m) > 0)
    assert np.all(np.diff(np.log10(m[m > 100])) < 0.11)  # ~10 per decade
    # 1/√(2(K−1)) with K = n/m non-overlapping clusters.
    assert relative_error(1000, [1, 100]) == pytest.approx(
        [1 / np.sqrt(2 * 999), 1 / np.sqrt(2 * 9)], rel=1e-12)
    with pytest.raises(ValueError, match="too few"):
        log_spaced_cluster_sizes(10)


@pytest.mark.parametrize("tau,adev,rel,match", [
    ([1.0, 2.0], [1.0], [0.1, 0.1], "one length"),
    ([1.0, -2.0], [1.0, 1.0], [0.1, 0.1], "tau must be finite"),
    ([1.0, 2.0], [1.0, np.nan], [0.1, 0.1], "finite"),
    ([1.0, 2.0], [1.0, 1.0], [0.1, 0.0], "finite"),
    ([], [], [], "one length"),
])
def test_fit_refuses_bad_input(tau, adev, rel, match):
    with pytest.raises(ValueError, match=match):
        fit_terms(tau, adev, rel)
