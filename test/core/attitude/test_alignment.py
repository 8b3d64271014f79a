"""Static alignment against closed forms: levelling error = accel bias / g, gyrocompass error =
bias / (ω_ie cos L), refusal for a MEMS gyro, no rest → ValueError; the stream's aligner stage
gives the kernels' alignment bit for bit."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from sim_static import OMEGA_IE, G, static_imu
from stages import aligned as align

from gyro_attitude.core.attitude.settings import StreamConfig
from gyro_attitude.core.attitude.stream import AttitudeStream

DEG_PER_H = np.radians(1.0) / 3600.0


def _q(heading_deg, pitch_deg, roll_deg):
    # ENU yaw = 90° − heading; q_nb = Rz(ψ) Ry(θ) Rx(φ).
    return Rotation.from_euler("ZYX", [90.0 - heading_deg, pitch_deg, roll_deg], degrees=True).as_quat()


def _tilt_error(q_est, q_true):
    up_est = Rotation.from_quat(q_est).inv().apply([0, 0, 1])
    up_true = Rotation.from_quat(q_true).inv().apply([0, 0, 1])
    return np.arccos(np.clip(up_est @ up_true, -1, 1))



def level(**kw) -> StreamConfig:
    return StreamConfig(initial_attitude_source="level", **kw)


def gyrocompass(lat, sigma, **kw) -> StreamConfig:
    """Gyrocompassing at ``lat`` with the residual gyro bias of 1σ ``sigma`` (the bias given
    is zero: the gyro's own is the residual)."""
    return level(heading_source="gyrocompass", gyro_bias="parameter",
                 gyro_bias_sigma_rad_s=sigma, latitude_rad=lat, **kw)

@pytest.mark.parametrize("accel_bias", [(0.05, 0.0, 0.0), (0.0, -0.1, 0.0), (0.03, 0.04, 0.2)])
def test_levelling_error_equals_horizontal_accel_bias_over_g(accel_bias):
    q = _q(40.0, 0.0, 0.0)  # level: body axes horizontal, so the horizontal bias is (b_x, b_y)
    t, g, a = static_imu(600, 200.0, q, np.radians(45), accel_bias=accel_bias)
    res = align(t, g, a, level(initial_heading_deg=40.0))
    # Exact: tilt = atan(|b_h| / (g + b_z)).
    expected = np.arctan(np.hypot(*accel_bias[:2]) / (G + accel_bias[2]))
    np.testing.assert_allclose(_tilt_error(res.q_nb, q), expected, rtol=1e-6, atol=1e-12)
    np.testing.assert_allclose(res.heading, np.radians(40.0), rtol=0, atol=1e-12)


def test_levelling_recovers_roll_pitch_and_reports_expected_error():
    q = _q(200.0, 12.0, -25.0)
    t, g, a = static_imu(600, 200.0, q, 0.5, accel_noise=0.03, seed=2)
    res = align(t, g, a, level(initial_heading_deg=200.0, accel_bias_sigma=0.02))
    np.testing.assert_allclose(np.degrees([res.roll, res.pitch]), [-25.0, 12.0], atol=0.02)
    # Expected 1σ: √(0.02² + 0.03²/n)/g ≈ 0.02/g.
    np.testing.assert_allclose(res.level_error_expected, np.hypot(0.02, 0.03 / np.sqrt(res.samples)) / G,
                               rtol=0.05)
    # The quaternion is the truth's within the measured noise (~0.03/√n/g ≈ 1e-4 rad).
    assert Rotation.from_quat(res.q_nb).inv() * Rotation.from_quat(q) is not None
    assert (Rotation.from_quat(res.q_nb).inv() * Rotation.from_quat(q)).magnitude() < 5e-4


@pytest.mark.parametrize("grade_deg_h", [1.0, 0.01])
@pytest.mark.parametrize("lat_deg", [0.0, 30.0, 60.0])
@pytest.mark.parametrize("heading_deg", [10.0, 135.0, 290.0])
def test_gyrocompass_heading_error_is_bias_over_horizontal_earth_rate(grade_deg_h, lat_deg, heading_deg):
    lat = np.radians(lat_deg)
    bias_err = grade_deg_h * DEG_PER_H
    q = _q(heading_deg, 3.0, -2.0)
    # Residual bias: east-pointing in the level frame turns the heading by bias / (ω_ie cos L).
    c_nb = Rotation.from_quat(q)
    east_b = c_nb.inv().apply([bias_err, 0.0, 0.0])
    t, g, a = static_imu(2000, 100.0, q, lat, gyro_bias=east_b)
    res = align(t, g, a, gyrocompass(lat, bias_err, accel_bias_sigma=0.0,
                                     heading_error_limit_deg=10.0), lat)
    expected = np.arctan2(bias_err, OMEGA_IE * np.cos(lat))  # exact for a level frame rotation
    err = (res.heading - np.radians(heading_deg) + np.pi) % (2 * np.pi) - np.pi
    # Sign: an east bias adds to sin ψ → ψ grows → heading (= 90° − ψ) shrinks.
    np.testing.assert_allclose(err, -expected, rtol=1e-6, atol=1e-9)
    assert res.heading_source == "gyrocompass"
    # Reported 1σ ≈ σ_b/(ω_ie cos L) (the tilt term is tiny without accel bias/noise).
    np.testing.assert_allclose(res.heading_error_expected, bias_err / (OMEGA_IE * np.cos(lat)), rtol=1e-3)


def test_gyrocompass_refused_for_mems_gyro():
    q = _q(30.0, 0.0, 0.0)
    t, g, a = static_imu(1000, 100.0, q, np.radians(45), gyro_bias=(1e-4, 0, 0))
    with pytest.raises(ValueError, match="gyrocompass refused"):
        align(t, g, a, gyrocompass(np.radians(45), np.radians(0.01)), np.radians(45))
    # A tactical gyro (1 °/h) at 60°N: expected 7.6° > the default 5° limit.
    with pytest.raises(ValueError, match="7.6"):
        align(t, g, a, gyrocompass(np.radians(60), DEG_PER_H), np.radians(60))
    with pytest.raises(ValueError, match="gyro_bias_sigma"):
        align(t, g, a, gyrocompass(np.radians(45), 0.0), np.radians(45))


def test_no_rest_refused_not_identity():
    t = np.arange(1000, dtype=np.int64) * 10_000_000
    s = np.arange(1000) / 100.0
    g = np.column_stack([np.sin(3 * s), np.cos(2 * s), 0.1 * s]) * 0.5
    a = np.tile([0.0, 0.0, G], (1000, 1)) + np.column_stack([3 * np.sin(5 * s), 0 * s, 0 * s])
    with pytest.raises(ValueError, match="no rest"):
        align(t, g, a)
    with pytest.raises(ValueError, match="no rest of at least 1 s followed by motion"):
        AttitudeStream(config=level()).run(t, g, "imu", None, a)


def test_the_streams_aligner_stage_equals_the_kernels_bitwise():
    q = _q(77.0, 4.0, 9.0)
    t, g, a = static_imu(800, 200.0, q, 0.3, gyro_noise=1e-3, accel_noise=0.05, seed=9,
                         t0_ns=10**9)  # (a stamp 0 is no sample to the stream)
    # Motion after the rest ends the alignment.
    g[500:] += 0.5
    a[500:, 0] += 3.0
    res = align(t, g, a, level(initial_heading_deg=77.0))
    rs = AttitudeStream(config=level(initial_heading_deg=77.0)).run(t, g, "imu", None,
                                                                     a).alignment
    np.testing.assert_array_equal(rs.q_nb, res.q_nb)
    assert (rs.samples, rs.rest_start_ns, rs.rest_end_ns) == (res.samples, res.rest_start_ns,
                                                              res.rest_end_ns)
    assert rs.samples > 300 and rs.rest_end_ns < t[500]
