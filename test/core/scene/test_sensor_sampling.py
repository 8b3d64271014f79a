"""Sensors that sample as real ones do: interval mean, Butterworth low-pass, range with saturation counted,
turn-on bias per run, g-sensitivity — each against a closed form, each off unless named."""

import math

import numpy as np
import pytest

from gyro_attitude.core import earth
from gyro_attitude.core.scene import SceneSimulator, SceneSpec

HALF, FREQ, RATE = math.radians(1.0), 10.0, 200.0
OM = 2 * math.pi * FREQ


def coning(gyro=None, **extra):
    d = {"description": "coning", "seed": 3, "rate_hz": RATE, "start_time_ns": 10**9,
         "earth": {"latitude_deg": 45.0, "rotation": False, "transport_rate": False},
         "motion": {"type": "coning", "half_angle_deg": 1.0, "frequency_hz": FREQ}}
    if gyro is not None:
        d["gyro"] = gyro
    d.update(extra)
    return SceneSpec.from_dict(d)


def coning_rate(t):
    """Body rate of classical coning (docs/equations.md)."""
    return np.stack((np.full_like(t, -2 * OM * math.sin(HALF / 2) ** 2),
                     -OM * math.sin(HALF) * np.sin(OM * t), OM * math.sin(HALF) * np.cos(OM * t)), 1)


def coning_interval_mean(t, dt):
    """Exact mean of the coning body rate over (t − dt, t]."""
    s, c = np.sin, np.cos
    my = -OM * math.sin(HALF) * (c(OM * (t - dt)) - c(OM * t)) / (OM * dt)
    mz = OM * math.sin(HALF) * (s(OM * t) - s(OM * (t - dt))) / (OM * dt)
    return np.stack((np.full_like(t, -2 * OM * math.sin(HALF / 2) ** 2), my, mz), 1)


def test_mean_bandwidth_is_the_exact_interval_mean():
    sim = SceneSimulator(coning({"sampling": {"bandwidth": {"filter": "mean"}}}), RATE)
    b = sim.next_block(400)
    t = (b.t_ns - b.t_ns[0]) / 1e9
    ref = coning_interval_mean(t[1:], 1 / RATE)
    assert np.max(np.abs(b.omega_ib_b[1:] - ref)) < 1e-9 * OM
    # and it is not the point sample: the mean attenuates by sinc(ωΔt/2) = 0.9959
    assert np.max(np.abs(b.omega_ib_b[1:] - coning_rate(t[1:]))) > 1e-3 * OM * math.sin(HALF)
    assert "gyro.bandwidth" in sim.effects_run


def _amplitude(t, y, w):
    a = np.column_stack((np.sin(w * t), np.cos(w * t), np.ones_like(t)))
    coef, *_ = np.linalg.lstsq(a, y, rcond=None)
    return math.hypot(coef[0], coef[1])


@pytest.mark.parametrize("order, cutoff", [(1, 15.0), (2, 20.0), (4, 12.0)])
def test_lowpass_bandwidth_has_the_butterworth_gain(order, cutoff):
    spec = coning({"sampling": {"bandwidth": {"filter": "lowpass", "order": order,
                                              "cutoff_hz": cutoff}}})
    b = SceneSimulator(spec, RATE).next_block(2000)
    t = (b.t_ns - b.t_ns[0]) / 1e9
    steady = t > 2.0
    gain = _amplitude(t[steady], b.omega_ib_b[steady, 1], OM) / (OM * math.sin(HALF))
    # bilinear Butterworth: analog |H| at the pre-warped frequencies
    wa = math.tan(OM / RATE / 2)
    wc = math.tan(2 * math.pi * cutoff / RATE / 2)
    assert gain == pytest.approx(1 / math.sqrt(1 + (wa / wc) ** (2 * order)), rel=1e-6)
    # started in steady state: the constant x component passes from the first sample on
    np.testing.assert_allclose(b.omega_ib_b[:50, 0], coning_rate(t[:50])[:, 0], rtol=1e-9)


def test_range_clips_and_counts_the_saturated_samples():
    d = {"description": "spin-up", "seed": 1, "rate_hz": 100.0, "start_time_ns": 10**9,
         "earth": {"latitude_deg": 0.0, "rotation": False, "transport_rate": False},
         "motion": {"type": "profile", "segments": [{"duration_s": 2.0,
                                                     "angular_rate_deg_s": [0.0, 0.0, 3000.0]}]},
         "gyro": {"sampling": {"range_rad_s": math.radians(2000.0)}}}
    sim = SceneSimulator(SceneSpec.from_dict(d), 100.0)
    b = sim.next_block(150)
    assert np.all(b.omega_ib_b[:, 2] == math.radians(2000.0))  # pinned at full scale
    assert np.all(b.truth_omega_ib_b[:, 2] > math.radians(2000.0))
    assert sim.saturated == {"gyro": 150}
    assert "gyro.saturation" in sim.effects_run


def test_turn_on_bias_is_drawn_per_run_and_constant_within_it():
    sigma = 0.01
    biases = []
    for seed in range(300):
        spec = coning({"sampling": {"turn_on_bias_rad_s": sigma}})
        b = SceneSimulator(spec, RATE, seed=seed).next_block(20)
        err = b.omega_ib_b - b.truth_omega_ib_b
        assert np.ptp(err, axis=0).max() < 1e-15  # constant during the run
        biases.append(err[0])
    biases = np.array(biases)
    assert np.std(biases) == pytest.approx(sigma, rel=0.1)
    assert abs(np.mean(biases)) < 4 * sigma / math.sqrt(biases.size)
    same = SceneSimulator(coning({"sampling": {"turn_on_bias_rad_s": sigma}}), RATE, seed=7)
    again = SceneSimulator(coning({"sampling": {"turn_on_bias_rad_s": sigma}}), RATE, seed=7)
    assert np.array_equal(same.next_block(5).omega_ib_b, again.next_block(5).omega_ib_b)


def test_g_sensitivity_adds_g_times_the_specific_force():
    d = {"description": "level", "seed": 1, "rate_hz": 100.0, "start_time_ns": 10**9,
         "earth": {"latitude_deg": 30.0, "height_m": 100.0}, "motion": {"type": "stationary"},
         "gyro": {"sampling": {"g_sensitivity_rad_s_per_m_s2": [[0, 0, 2e-4], [0, 0, 0], [0, 0, 5e-4]]}}}
    b = SceneSimulator(SceneSpec.from_dict(d), 100.0).next_block(10)
    g = -earth.gravity_enu(math.radians(30.0), 100.0)[2]
    err = b.omega_ib_b - b.truth_omega_ib_b
    np.testing.assert_allclose(err, np.tile([2e-4 * g, 0.0, 5e-4 * g], (10, 1)), atol=1e-15)


def test_nothing_is_evaluated_unless_named():
    sim = SceneSimulator(coning(), RATE)
    sim.next_block(10)
    named = {"gyro.bandwidth", "gyro.saturation", "gyro.turn_on_bias", "gyro.g_sensitivity"}
    assert not (named & sim.effects_run) and sim.saturated == {}
    sim = SceneSimulator(coning({"sampling": {"range_rad_s": 100.0}}), RATE)
    sim.next_block(10)
    assert named & sim.effects_run == {"gyro.saturation"} and sim.saturated == {"gyro": 0}


@pytest.mark.parametrize("sampling, message", [
    ({"bandwidth": {"filter": "boxcar"}}, r"gyro\.sampling\.bandwidth\.filter: must be one of"),
    ({"bandwidth": {"filter": "lowpass", "order": 9, "cutoff_hz": 10.0}},
     r"gyro\.sampling\.bandwidth\.order: must be <= 8"),
    ({"bandwidth": {"filter": "mean", "cutoff_hz": 10.0}}, r"order and cutoff_hz are for filter: lowpass"),
    ({"range_rad_s": 1e300}, r"gyro\.sampling\.range_rad_s: must be <= 1000"),
    ({"turn_on_bias_rad_s": -1.0}, r"gyro\.sampling\.turn_on_bias_rad_s: must be >= 0"),
    ({"g_sensitivity_rad_s_per_m_s2": 1.0}, r"g_sensitivity_rad_s_per_m_s2: must lie in"),
])
def test_bad_sampling_values_are_refused_naming_the_key(sampling, message):
    with pytest.raises(ValueError, match=message):
        coning({"sampling": sampling})


def test_lowpass_cutoff_above_nyquist_is_refused():
    spec = coning({"sampling": {"bandwidth": {"filter": "lowpass", "cutoff_hz": 150.0}}})
    with pytest.raises(ValueError, match=r"cutoff_hz 150 Hz must be below the Nyquist frequency 100 Hz"):
        SceneSimulator(spec, RATE)
