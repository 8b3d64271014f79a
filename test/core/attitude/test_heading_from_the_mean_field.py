"""Heading from the field after levelling (aiding magnetometer, initial_attitude_source level):
the static alignment takes the heading from the mean field over the rest, tilt-compensated with
the levelled attitude, so its error is the closed form σ/√N, not one sample's noise."""

import math

import numpy as np
from scipy.spatial.transform import Rotation

from gyro_attitude.core.attitude.settings import StreamConfig
from gyro_attitude.core.attitude.stream import AttitudeStream

G = 9.81
RATE = 200.0
ROLL, PITCH, HEADING = 0.1, -0.05, math.radians(40.0)
DECL, INCL, B = math.radians(5.0), math.radians(65.0), 50e-6  # east, down, tesla
SIGMA_M, SIGMA_F = 0.5e-6, 0.02  # per axis: tesla, m/s²


def still_then_turning(seed, rest_s=3.0, turn_s=1.0):
    """A still IMU at ROLL, PITCH, HEADING (ENU, q_nb = Rz(π/2 − heading) Ry(pitch) Rx(roll),
    written with scipy), then a turn about the vertical; noisy gyro, accelerometer and field."""
    rng = np.random.default_rng(seed)
    n_rest, n_turn = int(rest_s * RATE), int(turn_s * RATE)
    n = n_rest + n_turn
    c_bn = Rotation.from_euler("ZYX", [math.pi / 2 - HEADING, PITCH, ROLL]).inv().as_matrix()
    m_n = B * np.array([math.cos(INCL) * math.sin(DECL), math.cos(INCL) * math.cos(DECL),
                        -math.sin(INCL)])
    f = c_bn @ [0.0, 0.0, G] + SIGMA_F * rng.standard_normal((n, 3))
    m = c_bn @ m_n + SIGMA_M * rng.standard_normal((n, 3))
    w = 0.002 * rng.standard_normal((n, 3))
    w[n_rest:] += c_bn @ [0.0, 0.0, 0.5]
    t = np.round((1 + np.arange(n)) * 1e9 / RATE).astype(np.int64)
    return t, w, f, m


def test_the_levelled_heading_is_the_mean_fields_within_sigma_over_root_n():
    cfg = StreamConfig(aiding="magnetometer", initial_attitude_source="level",
                       initial_heading_deg=0.0, magnetic_declination_deg=math.degrees(DECL),
                       accel_bias_sigma=0.0)
    errors, expected, reported = [], [], []
    for seed in range(30):
        t, w, f, m = still_then_turning(seed)
        res = AttitudeStream(config=cfg).run(t, w, "imu", None, f, m)
        al = res.alignment
        assert al.heading_source == "magnetometer" and al.mag_samples == al.samples
        errors.append(math.remainder(al.heading - HEADING, 2 * math.pi))
        # closed form: the horizontal field's noise across it over N samples, and the levelling
        # noise σ_f/(g√N) turned into heading by tan(inclination)
        n = al.samples
        expected.append(math.sqrt(SIGMA_M ** 2 / (n * (B * math.cos(INCL)) ** 2)
                                  + (math.tan(INCL) * SIGMA_F / (G * math.sqrt(n))) ** 2))
        reported.append(al.heading_error_expected)
        # the attitude handed out starts from that heading (the levelled q_nb, read by scipy)
        yaw = Rotation.from_quat(al.q_nb).as_euler("ZYX")[0]
        assert abs(math.remainder(math.pi / 2 - yaw - al.heading, 2 * math.pi)) < 1e-9
    sigma = float(np.mean(expected))
    rms = math.sqrt(float(np.mean(np.square(errors))))
    # one sample's field would leave ~√N (here ~20×) this error
    assert 0.6 * sigma <= rms <= 1.5 * sigma, (rms, sigma)
    assert max(abs(e) for e in errors) <= 4 * sigma
    # the alignment's own figure is the closed form (from the measured scatter)
    np.testing.assert_allclose(reported, expected, rtol=0.35)
