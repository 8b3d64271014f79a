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


# ---------------------------------------------------------------- datasheet terms
def _gm_avar_closed_form(sigma, tau_c, tau):
    """Allan variance of a Gauss–Markov process (autocovariance σ² e^{−|t|/τc}), derived
    in the test from σ²_A = Var(ȳ) − Cov(ȳ₁, ȳ₂) of adjacent τ-averages."""
    x = tau / tau_c
    var_mean = 2 * sigma**2 / x**2 * (x - 1 + np.exp(-x))
    cov_adjacent = sigma**2 / x**2 * (1 - np.exp(-x)) ** 2
    return var_mean - cov_adjacent


def _oadev(rate: np.ndarray, dt: float, m: int) -> np.ndarray:
    """Overlapping Allan deviation (docs/equations.md formula) per column at τ = m·dt."""
    theta = np.concatenate([np.zeros((1, rate.shape[1])), np.cumsum(rate, axis=0) * dt])
    d = theta[2 * m:] - 2 * theta[m:-m] + theta[:-2 * m]
    return np.sqrt(np.mean(d**2, axis=0) / (2 * (m * dt) ** 2))


def test_gauss_markov_closed_form_matches_the_module():
    from decimal import Decimal, getcontext

    from gyro_attitude.core.sensor_errors import gauss_markov_allan_variance

    getcontext().prec = 60
    tau = np.logspace(-6, 4, 60)
    # The closed form cancels catastrophically for τ ≪ τc: evaluate it with 60 digits.
    ref = []
    for t in tau:
        x = Decimal(float(t)) / Decimal(3)
        br = 2 * x - 3 + 4 * (-x).exp() - (-2 * x).exp()
        ref.append(float(Decimal(4) * br / x**2))
    got = gauss_markov_allan_variance(2.0, 3.0, tau)  # series and full branches both
    assert np.allclose(got, ref, rtol=2e-9, atol=0)  # series / rounding limits: 1e-9
    wide = tau > 0.1  # the test's own form, in doubles where it does not cancel
    assert np.allclose(got[wide], _gm_avar_closed_form(2.0, 3.0, tau[wide]), rtol=1e-9, atol=0)


def test_allan_floor_of_the_gauss_markov_sum_is_b():
    from gyro_attitude.core.sensor_errors import flicker_floor_components

    b = 1.5e-5
    sig, taus = flicker_floor_components(b)
    tau = np.logspace(0, 4, 200)
    adev = np.sqrt(sum(_gm_avar_closed_form(s, c, tau) for s, c in zip(sig, taus, strict=True)))
    floor = np.sqrt(2 * np.log(2) / np.pi) * b  # IEEE 952: σ_floor = 0.664 B
    # Flat floor: within 3.2 % of 0.664 B from 1 s to 1e4 s, never above it (documented).
    assert np.all(np.abs(adev / floor - 1) < 0.032)
    assert adev.max() == pytest.approx(floor, rel=1e-3)
    # And B read back as σ_min/0.664 over the flat part (3 s .. 3000 s) is within 2.5 %.
    mid = (tau > 3) & (tau < 3000)
    assert adev[mid].max() / 0.664 == pytest.approx(b, rel=0.025)


def test_allan_floor_simulated_samples():
    b, dt = 2e-5, 0.05
    model = SensorErrorModel(SensorErrorParams(bias_instability_floor=b), dt, seed=4)
    y = np.concatenate([model.apply(np.zeros((n, 3))) for n in (100_000, 300_000)])
    # 400k samples = 2e4 s; at τ = 20 s and 200 s there are 1000 and 100 clusters per axis,
    # three axes: the estimate scatters by ~1/√(2·K·3) → tolerance 12 %.
    for m in (400, 4000):
        assert _oadev(y, dt, m).mean() == pytest.approx(0.6643 * b, rel=0.12)
    assert model.effects_run == {"bias_instability_floor"}


def _independent_sum_autocovariance(dt, lags):
    """Autocovariance at ``lags`` (samples) of the sum of independent Gauss–Markov processes
    of the B = 1 floor: Σ_j σ_j² e^(−m·dt/τ_j)."""
    from gyro_attitude.core.sensor_errors import flicker_floor_components

    sig, taus = flicker_floor_components(1.0)
    return np.array([np.sum(sig**2 * np.exp(-m * dt / taus)) for m in lags])


@pytest.mark.parametrize("dt", [1e-3, 0.01, 1.0, 100.0, 1e4])
def test_shared_input_floor_bank_has_the_autocovariance_of_the_independent_sum(dt):
    """The bank on one white input per axis: its sections are correlated, and the sum's
    autocovariance Σ_ij φ_i^m g_i g_j/(1 − φ_iφ_j) (the double geometric series of the
    impulse responses) equals the independent sum's Σ σ_j² φ_j^m at every lag, from 1 kHz
    down to 1e-4 Hz (where the short sections are white and coincide)."""
    from gyro_attitude.core.sensor_errors import flicker_floor_components, floor_realisation

    real = floor_realisation(dt)
    taus = flicker_floor_components(1.0)[1]
    assert np.allclose(real.phi, np.exp(-dt / taus), rtol=1e-15, atol=0)
    phi, g = real.phi, real.gain
    # 1 − φ_iφ_j = −expm1(−dt(1/τ_i + 1/τ_j)): 1 − φ_iφ_j in doubles loses 8 digits at 1 kHz
    rate = 1.0 / taus
    cross = g[:, None] * g[None, :] / -np.expm1(-dt * (rate[:, None] + rate[None, :]))
    lags = np.array([0, 1, 3, 10, 100, 10_000, 1_000_000])
    got = np.array([np.sum(phi[:, None] ** m * cross) for m in lags])
    want = _independent_sum_autocovariance(dt, lags)
    assert np.allclose(got, want, rtol=1e-9, atol=1e-12 * want[0])
    # the stationary start: the square root reproduces the sections' cross-covariance
    assert np.allclose(real.state_sqrt @ real.state_sqrt.T, cross, rtol=1e-9,
                       atol=1e-12 * want[0])


def test_floor_bank_impulse_response_gives_the_target_autocovariance():
    """Independent of the geometric-series algebra: the bank's impulse response
    h_k = Σ_j g_j φ_j^k summed numerically, R(m) = Σ_k h_k h_(k+m) (unit white input), at
    0.1 Hz (the slowest section, τ = 1e5 s, decays over 10⁴ samples)."""
    from gyro_attitude.core.sensor_errors import floor_realisation

    dt = 10.0
    real = floor_realisation(dt)
    k = np.arange(400_000)
    h = sum(g * np.exp(k * np.log(p)) if p > 0 else g * (k == 0)
            for p, g in zip(real.phi, real.gain, strict=True))
    lags = [0, 1, 5, 100, 10_000]
    got = [np.dot(h[: h.size - m], h[m:]) for m in lags]
    assert np.allclose(got, _independent_sum_autocovariance(dt, lags), rtol=1e-9, atol=0)


def test_floor_starts_stationary_with_the_sum_variance():
    from gyro_attitude.core.sensor_errors import flicker_floor_components

    b, dt = 2e-5, 0.01
    first = np.array([SensorErrorModel(SensorErrorParams(bias_instability_floor=b), dt, seed=s)
                      .apply(np.zeros((1, 3)))[0] for s in range(300)])
    var = np.sum(flicker_floor_components(b)[0] ** 2)
    # 900 draws: the sample std scatters by 1/√(2·900) = 2.4 %; 5σ (a start from the
    # sections' own variances without their cross terms is 40 % low)
    assert first.std() == pytest.approx(np.sqrt(var), rel=0.12)


def test_allan_floor_simulated_at_a_low_rate():
    """0.01 Hz: the samples are point values of the processes (not interval averages), so
    the sections faster than the step are white at it and the Allan deviation lies above
    0.664 B at short τ (as with independent processes); it must be that of samples of the
    independent sum, from its autocovariance R: σ²(m) = Var(ȳ_m) − Cov(ȳ_m, next ȳ_m)."""
    b, dt = 2e-5, 100.0
    y = SensorErrorModel(SensorErrorParams(bias_instability_floor=b), dt, seed=8).apply(
        np.zeros((200_000, 3)))
    for m in (1, 10, 100):
        lag = np.arange(-(m - 1), m)
        w = (m - np.abs(lag)) / m**2
        r = _independent_sum_autocovariance(dt, np.abs(lag)) * b**2
        r_next = _independent_sum_autocovariance(dt, lag + m) * b**2
        want = np.sqrt(np.sum(w * r) - np.sum(w * r_next))
        # 2e5, 2e4 and 2e3 clusters per axis, three axes: within 12 % as above
        assert _oadev(y, dt, m).mean() == pytest.approx(want, rel=0.12), m
    assert want == pytest.approx(0.6643 * b, rel=0.05)  # the floor itself at τ = 1e4 s


def test_rate_random_walk_allan_slope_and_exact_discretization():
    k, dt = 1e-4, 0.01
    model = SensorErrorModel(SensorErrorParams(rate_random_walk=k), dt, seed=6)
    y = np.concatenate([model.apply(np.zeros((n, 3))) for n in (1, 99_999, 100_000)])
    # σ(τ) = K √(τ/3) exactly for interval-averaged samples; at τ = 1 s (2000 clusters per
    # axis) and 10 s (200): tolerance ~3/√(2·K·3).
    for m, tol in ((100, 0.05), (1000, 0.15)):
        assert _oadev(y, dt, m).mean() == pytest.approx(k * np.sqrt(m * dt / 3), rel=tol)
    # First sample: the average over the first interval of a walk starting at 0 has
    # variance K² dt/3 (not K² dt of the end value): 3000 seeds.
    first = np.array([SensorErrorModel(SensorErrorParams(rate_random_walk=k), dt, seed=s)
                      .apply(np.zeros((1, 3)))[0] for s in range(1000)]).ravel()
    assert first.var() == pytest.approx(k**2 * dt / 3, rel=0.08)
    # Second minus first sample: K² dt (1/3 + 1/3 + 1 − 2·1/2) = K² dt·2/3.
    pairs = np.array([SensorErrorModel(SensorErrorParams(rate_random_walk=k), dt, seed=s)
                      .apply(np.zeros((2, 3))) for s in range(1000)])
    assert (pairs[:, 1] - pairs[:, 0]).var() == pytest.approx(k**2 * dt * 2 / 3, rel=0.08)


def test_new_processes_block_split_invariant_and_separate_streams():
    p = SensorErrorParams(noise_density=1e-3, bias_instability_floor=1e-4,
                          rate_random_walk=1e-5)
    x = np.zeros((70_000, 3))
    whole = SensorErrorModel(p, 0.01, seed=3).apply(x)
    m = SensorErrorModel(p, 0.01, seed=3)
    parts = np.concatenate([m.apply(x[i:j]) for i, j in ((0, 1), (1, 40_000), (40_000, 70_000))])
    # Bit for bit: gyro_sim (small blocks) and offline simulate (large) must agree exactly.
    assert np.array_equal(whole, parts)
    # The white noise draws are those of a model without the new processes.
    white = SensorErrorModel(SensorErrorParams(noise_density=1e-3), 0.01, seed=3).apply(x)
    floor = SensorErrorModel(SensorErrorParams(bias_instability_floor=1e-4), 0.01, seed=3)
    rrw = SensorErrorModel(SensorErrorParams(rate_random_walk=1e-5), 0.01, seed=3)
    assert np.allclose(whole, white + floor.apply(x) + rrw.apply(x), rtol=0, atol=1e-14)


def test_floor_variance_in_per_sample_variances():
    from gyro_attitude.core.sensor_errors import flicker_floor_components

    m = SensorErrorModel(SensorErrorParams(bias_instability_floor=[1e-5, 2e-5, 0.0],
                                           rate_random_walk=1.0), 0.01)
    sig = [np.sum(flicker_floor_components(b)[0] ** 2) for b in (1e-5, 2e-5)]
    assert m.variances() == pytest.approx([sig[0], sig[1], 0.0], rel=1e-12)


# ---------------------------------------------------------------- units
_DEG = np.pi / 180


@pytest.mark.parametrize("text,kind,si", [
    ("0.15 deg/sqrt(h)", "angle random walk", 0.15 * _DEG / 60),
    ("0.15 deg/√h", "angle random walk", 0.15 * _DEG / 60),
    ("0.01 deg/s/sqrt(Hz)", "angle random walk", 0.01 * _DEG),
    ("5e-5 rad/sqrt(s)", "angle random walk", 5e-5),
    ("3 deg/h", "angular rate", 3 * _DEG / 3600),
    ("1 deg/hr", "angular rate", _DEG / 3600),
    ("0.02 deg/h/sqrt(h)", "rate random walk", 0.02 * _DEG / 3600 / 60),
    ("2 deg/h^2/sqrt(Hz)", "rate random walk", 2 * _DEG / 3600**2),
    ("40 ug", "acceleration", 40e-6 * 9.80665),
    ("0.5 mg", "acceleration", 0.5e-3 * 9.80665),
    ("0.06 m/s/sqrt(h)", "velocity random walk", 0.06 / 60),
    ("100 ug/sqrt(Hz)", "velocity random walk", 100e-6 * 9.80665),
    ("1e-3 m/s^2/sqrt(s)", "acceleration random walk", 1e-3),
    (2.5e-5, "angle random walk", 2.5e-5),
    ("7e-6", "angular rate", 7e-6),
])
def test_units_to_si(text, kind, si):
    from gyro_attitude.core.units import to_si

    assert to_si(text, kind, "k") == pytest.approx(si, rel=1e-12)


@pytest.mark.parametrize("kind", ["angle random walk", "angular rate", "rate random walk",
                                  "acceleration", "velocity random walk"])
def test_units_format_reads_back(kind):
    from gyro_attitude.core.units import format_si, to_si

    assert to_si(format_si(1.234567e-5, kind, digits=12), kind, "k") == pytest.approx(
        1.234567e-5, rel=1e-10)


@pytest.mark.parametrize("value,match", [
    ("3 furlong/h", r"^gyro\.errors\.arw: unknown unit 'furlong'"),
    ("3 deg/h", r"^gyro\.errors\.arw: '3 deg/h' is not a angle random walk"),
    ("nan deg/sqrt(h)", r"^gyro\.errors\.arw: expected '<number> <unit>'"),
    ("1e400 deg/sqrt(h)", r"^gyro\.errors\.arw: must be finite"),
    (float("inf"), r"^gyro\.errors\.arw: must be finite"),
    (True, r"^gyro\.errors\.arw: must be a number"),
    ({"a": 1}, r"^gyro\.errors\.arw: must be a number"),
    ("0.1 deg/sqrt(h", r"^gyro\.errors\.arw: missing '\)'"),
])
def test_units_refused_with_the_key_path(value, match):
    from gyro_attitude.core.units import to_si

    with pytest.raises(ValueError, match=match):
        to_si(value, "angle random walk", "gyro.errors.arw")


def _scene(errors, accel=None):
    d = {"description": "t", "seed": 1, "earth": {"latitude_deg": 45.0},
         "motion": {"type": "stationary"}, "gyro": {"errors": errors}}
    if accel is not None:
        d["accelerometer"] = {"errors": accel}
    return d


def test_scene_accepts_datasheet_terms():
    from gyro_attitude.core.scene import SceneSpec

    s = SceneSpec.from_dict(_scene(
        {"arw": "0.15 deg/sqrt(h)", "bias_instability": ["3 deg/h", "2 deg/h", 1e-5],
         "rate_random_walk": "0.02 deg/h/sqrt(h)", "bias_rad_s": 1e-4},
        {"vrw": "0.06 m/s/sqrt(h)", "bias_instability": "40 ug",
         "acceleration_random_walk": 1e-4}))
    g = s.gyro_errors
    assert g.noise_density == pytest.approx(np.full(3, 0.15 * _DEG / 60), rel=1e-12)
    assert g.bias_instability_floor == pytest.approx(
        [3 * _DEG / 3600, 2 * _DEG / 3600, 1e-5], rel=1e-12)
    assert g.rate_random_walk == pytest.approx(np.full(3, 0.02 * _DEG / 3600 / 60), rel=1e-12)
    assert g.bias == pytest.approx(np.full(3, 1e-4))
    a = s.accel_errors
    assert a.noise_density == pytest.approx(np.full(3, 1e-3), rel=1e-12)
    assert a.bias_instability_floor == pytest.approx(np.full(3, 40e-6 * 9.80665), rel=1e-12)
    assert a.rate_random_walk == pytest.approx(np.full(3, 1e-4))


@pytest.mark.parametrize("errors,match", [
    ({"arw": "1 furlong"}, r"^gyro\.errors\.arw: unknown unit"),
    ({"bias_instability": "3 deg/sqrt(h)"}, r"^gyro\.errors\.bias_instability: .* not a angular"),
    ({"bias_instability": ["3 deg/h", "1 m", 0.0]}, r"^gyro\.errors\.bias_instability\[1\]: "),
    ({"rate_random_walk": "-1 deg/h/sqrt(h)"}, r"^gyro\.errors\.rate_random_walk: must be >= 0"),
    ({"arw": [1e-5, 2e-5]}, r"^gyro\.errors\.arw: must be one value or 3"),
    ({"arw": 1e-5, "arw_rad_sqrt_s": 1e-5}, r"^gyro\.errors\.arw: give either"),
    ({"rrw": 1.0}, r"^gyro\.errors\.rrw: unknown key"),
])
def test_scene_refuses_bad_datasheet_terms(errors, match):
    from gyro_attitude.core.scene import SceneSpec

    with pytest.raises(ValueError, match=match):
        SceneSpec.from_dict(_scene(errors))
