"""Sensor error model: deterministic errors exactly, random ones against their statistics."""

import numpy as np
import pytest

from gyro_attitude.core.sensor_errors import SensorErrorModel, SensorErrorParams


def _allan_deviation(rate: np.ndarray, dt: float, tau: float) -> np.ndarray:
    """Non-overlapping Allan deviation per axis of rate samples at cluster time tau."""
    m = int(round(tau / dt))
    k = rate.shape[0] // m
    means = rate[: k * m].reshape(k, m, -1).mean(axis=1)
    return np.sqrt(0.5 * np.mean(np.diff(means, axis=0) ** 2, axis=0))


def test_bias_scale_factor_misalignment_exact():
    b = np.array([1e-3, -2e-3, 5e-4])
    s = np.array([1e-4, -3e-4, 2e-3])
    m = np.array([[0, 1e-3, -2e-3], [5e-4, 0, 3e-3], [-1e-3, 2e-4, 0]])
    model = SensorErrorModel(SensorErrorParams(bias=b, scale_factor=s, misalignment=m), 0.01)
    x = np.random.default_rng(3).normal(size=(100, 3))
    y = model.apply(x)
    # Written out per axis: y_i = (1 + s_i) x_i + Σ_{j≠i} M_ij x_j + b_i.
    for i in range(3):
        expect = (1 + s[i]) * x[:, i] + b[i]
        for j in range(3):
            if j != i:
                expect = expect + m[i, j] * x[:, j]
        assert np.abs(y[:, i] - expect).max() < 1e-15
    assert model.effects_run == {"bias", "scale_factor", "misalignment"}


def test_ideal_sensor_is_identity_and_runs_nothing():
    model = SensorErrorModel(SensorErrorParams(), 0.005, seed=1)
    x = np.random.default_rng(0).normal(size=(50, 3))
    assert np.array_equal(model.apply(x), x)
    assert model.effects_run == set()
    assert np.array_equal(model.variances(), np.zeros(3))


@pytest.mark.parametrize("dt", [0.01, 0.001])
def test_angle_random_walk_scales_with_step(dt):
    n_density = 2e-3  # rad/√s
    model = SensorErrorModel(SensorErrorParams(noise_density=n_density), dt, seed=11)
    total = 1000.0
    y = model.apply(np.zeros((int(round(total / dt)), 3)))
    # Per-sample σ = N/√dt.
    assert y.std() == pytest.approx(n_density / np.sqrt(dt), rel=0.02)
    assert model.variances() == pytest.approx(np.full(3, n_density**2 / dt), rel=1e-14)
    # Integrated angle over T has variance N² T, independent of dt (3000 intervals of 1 s).
    seg = int(round(1.0 / dt))
    angles = y.reshape(-1, seg, 3).sum(axis=1) * dt
    assert angles.var() == pytest.approx(n_density**2 * 1.0, rel=0.08)
    # Allan deviation at τ = 1 s equals N.
    assert _allan_deviation(y, dt, 1.0) == pytest.approx(np.full(3, n_density), rel=0.06)


def test_gauss_markov_stationary_variance_and_exact_correlation():
    sigma = np.array([1e-3, 2e-3, 5e-4])
    tau = np.array([0.05, 1.0, 0.01])
    dt = 0.01
    model = SensorErrorModel(
        SensorErrorParams(bias_instability_sigma=sigma, bias_instability_tau=tau), dt, seed=5
    )
    y = np.concatenate([model.apply(np.zeros((k, 3))) for k in (100_000, 77, 199_923)])
    assert y.std(axis=0) == pytest.approx(sigma, rel=0.03)
    assert model.variances() == pytest.approx(sigma**2, rel=1e-14)
    # Continuous-time autocorrelation e^{−kΔt/τ}: exact at every lag, also at dt = τ, where a
    # first-order (Euler) discretization φ = 1 − dt/τ would give 0 correlation.
    for lag in (1, 3):
        for a in range(3):
            c = np.corrcoef(y[:-lag, a], y[lag:, a])[0, 1]
            assert c == pytest.approx(np.exp(-lag * dt / tau[a]), abs=0.01)


def test_gauss_markov_starts_stationary():
    sigma, dt = 3e-3, 0.01
    first = np.array([
        SensorErrorModel(SensorErrorParams(bias_instability_sigma=sigma,
                                           bias_instability_tau=100.0), dt, seed=s)
        .apply(np.zeros((1, 3)))[0]
        for s in range(600)
    ])
    # 1800 draws: the standard deviation of the first sample is already σ (±5σ/√(2·1800)).
    assert first.std() == pytest.approx(sigma, rel=0.09)


def test_quantization_carries_the_remainder():
    q, dt = 1e-4, 0.01
    model = SensorErrorModel(SensorErrorParams(quantum=q), dt)
    rng = np.random.default_rng(2)
    # A slow constant rate (0.3 quanta per sample) plus a varying part.
    x = 0.3 * q / dt + 0.5 * q / dt * np.sin(np.arange(5000)[:, None] * [0.01, 0.02, 0.05])
    x = x + rng.normal(scale=0.1 * q / dt, size=x.shape)
    y = np.concatenate([model.apply(x[i:i + 700]) for i in range(0, 5000, 700)])
    counts = y * dt / q
    assert np.allclose(counts, np.rint(counts), atol=1e-9)  # whole quanta only
    err = np.cumsum(y - x, axis=0) * dt
    assert np.abs(err).max() <= 0.5 * q * (1 + 1e-9)  # integrated angle never drifts
    # Rounding each sample alone (no carry) would emit 0 for the constant 0.3-quantum rate.
    naive = np.rint(np.full(1000, 0.3)) * q
    assert abs(naive.sum() - 300 * q) > 100 * q
    assert model.variances() == pytest.approx(np.full(3, q**2 / (6 * dt**2)))


def test_quantization_variance_matches_empirical():
    q, dt = 1e-3, 0.002
    model = SensorErrorModel(SensorErrorParams(quantum=q), dt)
    x = np.random.default_rng(8).uniform(-20, 20, size=(200_000, 3))
    err = model.apply(x) - x
    assert err.var(axis=0) == pytest.approx(model.variances(), rel=0.03)


def test_same_seed_identical_and_block_split_invariant():
    p = SensorErrorParams(noise_density=1e-3, bias_instability_sigma=1e-4,
                          bias_instability_tau=2.0, quantum=1e-5, bias=1e-3)
    x = np.zeros((3000, 3))
    a = SensorErrorModel(p, 0.01, seed=42).apply(x)
    b = SensorErrorModel(p, 0.01, seed=42).apply(x)
    assert np.array_equal(a, b)
    m = SensorErrorModel(p, 0.01, seed=42)
    c = np.concatenate([m.apply(x[i:j]) for i, j in ((0, 1), (1, 300), (300, 555), (555, 3000))])
    assert np.allclose(a, c, rtol=0, atol=1e-15)
    d = SensorErrorModel(p, 0.01, seed=43).apply(x)
    assert not np.allclose(a, d)


def test_each_process_has_its_own_stream():
    x = np.zeros((500, 3))
    white = SensorErrorModel(SensorErrorParams(noise_density=1e-3), 0.01, seed=9).apply(x)
    gm_only = SensorErrorModel(
        SensorErrorParams(bias_instability_sigma=1e-4, bias_instability_tau=5.0), 0.01, seed=9
    ).apply(x)
    both = SensorErrorModel(
        SensorErrorParams(noise_density=1e-3, bias_instability_sigma=1e-4,
                          bias_instability_tau=5.0), 0.01, seed=9
    ).apply(x)
    assert np.allclose(both, white + gm_only, rtol=0, atol=1e-15)


def test_bad_parameters_are_refused_by_name():
    with pytest.raises(ValueError, match="noise_density"):
        SensorErrorParams(noise_density=-1.0)
    with pytest.raises(ValueError, match="misalignment"):
        SensorErrorParams(misalignment=np.eye(3))
    with pytest.raises(ValueError, match="bias_instability_tau"):
        SensorErrorParams(bias_instability_sigma=1.0, bias_instability_tau=0.0)
    with pytest.raises(ValueError, match="bias"):
        SensorErrorParams(bias=[1.0, 2.0])
    with pytest.raises(ValueError, match="dt"):
        SensorErrorModel(SensorErrorParams(), 0.0)
    with pytest.raises(ValueError, match="shape"):
        SensorErrorModel(SensorErrorParams(), 0.01).apply(np.zeros((4, 2)))
