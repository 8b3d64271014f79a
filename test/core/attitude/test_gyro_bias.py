"""Gyro bias at rests: pooled mean against the truth, its standard error, Earth rate, stream == batch."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from sim_static import OMEGA_IE, rest_motion_rest, static_imu

from gyro_attitude.core.attitude.gyro_bias import GyroBiasEstimator, estimate_gyro_bias


def test_auto_bias_matches_truth_within_its_standard_error():
    bias = np.array([0.008, -0.004, 0.01])
    sigma = 0.002
    t, g, a, truth = rest_motion_rest(bias=bias, gyro_noise=sigma, seed=5)
    b, rep = estimate_gyro_bias(t, g, a)
    assert rep.rests_used == 3
    # White noise: SE >= σ/√n (closed form, n the rest samples used); the between-rest
    # scatter of 3 rest means (χ² with 2 dof) may raise it, rarely beyond 3×.
    white = sigma / np.sqrt(rep.rest_samples)
    assert np.all(rep.standard_error >= 0.9 * white) and np.all(rep.standard_error <= 3 * white)
    assert np.all(np.abs(rep.bias - bias) < 4 * rep.standard_error)
    # Held during motion, zero before the first rest qualifies (1 s of samples + 0.5 s window).
    assert np.all(b[: int(1.4 * 200)] == 0)
    first_motion = np.flatnonzero(~truth)[0]
    np.testing.assert_allclose(b[first_motion + 100], b[first_motion + 300], rtol=0, atol=0)
    assert rep.earth_rate_removed is False and "absorbed" in rep.note


def test_stream_equals_batch_bitwise_with_attitude():
    t, g, a, _ = rest_motion_rest(seed=6)
    q = Rotation.from_euler("z", np.linspace(0, 1, t.size)[:, None]).as_quat()
    b, rep = estimate_gyro_bias(t, g, a, q, latitude_rad=0.8)
    est = GyroBiasEstimator(latitude_rad=0.8)
    bs = np.array([est.update(t[k], g[k], a[k], q[k]) for k in range(t.size)])
    np.testing.assert_array_equal(bs, b)
    np.testing.assert_array_equal(est.report().standard_error, rep.standard_error)
    assert est.report().rests_used == rep.rests_used


@pytest.mark.parametrize("lat_deg", [0.0, 45.0, 80.0])
def test_earth_rate_removed_when_latitude_and_attitude_known(lat_deg):
    lat = np.radians(lat_deg)
    q = Rotation.from_euler("zyx", [30, 5, -3], degrees=True).as_quat()
    bias = np.array([1e-4, -2e-4, 3e-4])
    t, g, a = static_imu(2000, 200.0, q, lat, gyro_bias=bias, gyro_noise=1e-7, accel_noise=0.01)
    _, with_earth = estimate_gyro_bias(t, g, a, np.tile(q, (t.size, 1)), latitude_rad=lat)
    _, without = estimate_gyro_bias(t, g, a)
    earth_b = Rotation.from_quat(q).inv().apply([0, OMEGA_IE * np.cos(lat), OMEGA_IE * np.sin(lat)])
    # Noise 1e-7 rad/s per sample over ~1900 samples: mean error ~2e-9; Earth rate is 7e-5.
    np.testing.assert_allclose(with_earth.bias, bias, rtol=0, atol=2e-8)
    np.testing.assert_allclose(without.bias, bias + earth_b, rtol=0, atol=2e-8)
    assert with_earth.earth_rate_removed and not without.earth_rate_removed


def test_modes_none_and_parameter_and_bad_input():
    t, g, a, _ = rest_motion_rest(seed=7)
    b, rep = estimate_gyro_bias(t, g, a, mode="none")
    assert np.all(b == 0) and rep.mode == "none"
    b, rep = estimate_gyro_bias(t, g, a, mode="parameter", bias=[1e-3, 2e-3, 3e-3])
    np.testing.assert_array_equal(b[-1], [1e-3, 2e-3, 3e-3])
    with pytest.raises(ValueError, match="mode"):
        GyroBiasEstimator("sometimes")
    with pytest.raises(ValueError, match="needs bias"):
        GyroBiasEstimator("parameter")
    with pytest.raises(ValueError, match="bias"):
        GyroBiasEstimator("parameter", [np.nan, 0, 0])
    with pytest.raises(ValueError, match="min_rest_s"):
        GyroBiasEstimator(min_rest_s=-1)
    with pytest.raises(ValueError, match="latitude"):
        GyroBiasEstimator(latitude_rad=3.0)
    with pytest.raises(ValueError, match="gyro"):
        GyroBiasEstimator().update(0, [1e300, 0, 0])


def test_no_rest_reports_not_estimated():
    t = np.arange(500, dtype=np.int64) * 5_000_000
    g = np.column_stack([np.sin(np.arange(500) / 10.0), np.zeros(500), np.zeros(500)])
    b, rep = estimate_gyro_bias(t, g)
    assert rep.rests_used == 0 and "not estimated" in rep.note and np.all(b == 0)
