"""Gyro bias at rests (the bias stage's kernel, as the chain steps it): pooled mean against the
truth, its standard error, the Earth rate at a given attitude; the stream's stage is it."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from sim_static import OMEGA_IE, rest_motion_rest, static_imu
from stages import bias_rows

from gyro_attitude.core.attitude.gyro_bias import B_BIAS
from gyro_attitude.core.attitude.settings import StreamConfig
from gyro_attitude.core.attitude.stream import AttitudeStream


def test_auto_bias_matches_truth_within_its_standard_error():
    bias = np.array([0.008, -0.004, 0.01])
    sigma = 0.002
    t, g, a, truth = rest_motion_rest(bias=bias, gyro_noise=sigma, seed=5)
    b, rep = bias_rows(t, g, a)
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


def test_the_streams_bias_stage_is_the_kernel_bitwise():
    t, g, a, _ = rest_motion_rest(seed=6)
    t = t + 10**9  # (a stamp 0 is no sample to the stream)
    b, rep = bias_rows(t, g, a)
    s = AttitudeStream("rotvec_cubic")
    bs = np.empty_like(b)
    for k in range(t.size):
        s.push(int(t[k]), g[k], "imu", None, a[k])
        bs[k] = s.state.bias_f[0][B_BIAS:B_BIAS + 3]
    np.testing.assert_array_equal(bs, b)
    np.testing.assert_array_equal(s.bias_report.standard_error, rep.standard_error)
    assert s.bias_report.rests_used == rep.rests_used == 3


@pytest.mark.parametrize("lat_deg", [0.0, 45.0, 80.0])
def test_earth_rate_removed_when_latitude_and_attitude_known(lat_deg):
    lat = np.radians(lat_deg)
    q = Rotation.from_euler("zyx", [30, 5, -3], degrees=True).as_quat()
    bias = np.array([1e-4, -2e-4, 3e-4])
    t, g, a = static_imu(2000, 200.0, q, lat, gyro_bias=bias, gyro_noise=1e-7, accel_noise=0.01)
    _, with_earth = bias_rows(t, g, a, np.tile(q, (t.size, 1)), latitude_rad=lat)
    _, without = bias_rows(t, g, a)
    earth_b = Rotation.from_quat(q).inv().apply([0, OMEGA_IE * np.cos(lat), OMEGA_IE * np.sin(lat)])
    # Noise 1e-7 rad/s per sample over ~1900 samples: mean error ~2e-9; Earth rate is 7e-5.
    np.testing.assert_allclose(with_earth.bias, bias, rtol=0, atol=2e-8)
    np.testing.assert_allclose(without.bias, bias + earth_b, rtol=0, atol=2e-8)
    assert with_earth.earth_rate_removed and not without.earth_rate_removed


def test_modes_none_and_parameter():
    t, g, a, _ = rest_motion_rest(seed=7)
    b, rep = bias_rows(t, g, a, config=StreamConfig(gyro_bias="none"))
    assert np.all(b == 0) and rep.mode == "none"
    b, rep = bias_rows(t, g, a, config=StreamConfig(gyro_bias="parameter",
                                                     gyro_bias_rad_s=[1e-3, 2e-3, 3e-3]))
    np.testing.assert_array_equal(b[-1], [1e-3, 2e-3, 3e-3])
    assert rep.mode == "parameter"


def test_no_rest_reports_not_estimated():
    t = np.arange(500, dtype=np.int64) * 5_000_000
    g = np.column_stack([np.sin(np.arange(500) / 10.0), np.zeros(500), np.zeros(500)])
    b, rep = bias_rows(t, g)
    assert rep.rests_used == 0 and "not estimated" in rep.note and np.all(b == 0)
