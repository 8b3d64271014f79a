"""Vertical gyro: erection laws against closed forms (rest offset, acceleration, steady turn)."""

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from gyro_attitude.core.earth import OMEGA_IE
from gyro_attitude.core.instruments.vertical_gyro import (
    VerticalGyro,
    VerticalGyroParams,
    vertical_gyro_acceleration_error,
    vertical_gyro_rest_tilt,
    vertical_gyro_turn_indication,
)
from gyro_attitude.core.motion import CoordinatedTurn, ProfileSegment, SegmentProfile, Stationary

K = 0.02  # 1/s, erection time constant 50 s


def test_rest_offset_from_earth_rate():
    """At rest facing north at 30°N the free-axis drift −ω_ie × ẑ is balanced by the erection:
    s_E + i s_N = −Ω cos L / (k + i Ω sin L) (closed form, written out here); the horizon reads
    roll = −s_E (the reference leans west, toward the left wing) and pitch = −s_N."""
    lat = math.radians(30.0)
    out = VerticalGyro(VerticalGyroParams(erection_gain=K)).simulate(
        np.arange(0.0, 1500.0, 10.0), Stationary((0.0, 0.0, math.pi / 2)), lat, max_step=50.0)
    z = -OMEGA_IE * math.cos(lat) / complex(K, OMEGA_IE * math.sin(lat))
    assert vertical_gyro_rest_tilt(lat, K) == pytest.approx((z.real, z.imag), rel=1e-12)
    # 30 time constants: the transient e^{−kt} is gone; rtol 1e-4 resolves the 3e-3 relative
    # Ω sin L term in roll, and the pitch is that term alone
    assert out.roll_indicated[-1] == pytest.approx(-z.real, rel=1e-4)
    assert out.pitch_indicated[-1] == pytest.approx(-z.imag, rel=1e-3)
    assert out.roll_true[-1] == 0.0 and out.pitch_true[-1] == 0.0


def test_constant_rate_erection_closes_at_the_set_rate():
    """At the pole (no horizontal Earth rate) a 5° tilt closes at exactly ε until the linear zone."""
    eps = math.radians(3.0) / 60.0
    params = VerticalGyroParams(erection_law="constant_rate", erection_rate=eps,
                                linear_zone=math.radians(0.25))
    theta0 = math.radians(5.0)
    t = np.arange(0.0, 80.0, 1.0)
    out = VerticalGyro(params).simulate(t, Stationary(), math.pi / 2,
                                        spin_axis0=(math.sin(theta0), 0.0, math.cos(theta0)))
    np.testing.assert_allclose(out.spin_axis_tilt, theta0 - eps * t, rtol=0, atol=1e-9)


def test_linear_acceleration_pitch_error():
    """2 m/s² northward from rest at the equator facing north: the apparent vertical tilts back by
    atan(a/g) and the horizon shows θ(t) nose up, tan((θ_a−θ)/2) = tan(θ_a/2) e^{−kt}.
    Bound 0.5 %: the transport rate of the growing speed (v/(R k) ≤ 4e-4 rad vs 0.2 rad)."""
    a = 2.0
    prof = SegmentProfile([ProfileSegment(60.0, acceleration_enu=(0.0, a, 0.0))],
                          attitude_rad=(0.0, 0.0, math.pi / 2))
    t = np.arange(0.0, 60.0, 0.5)
    out = VerticalGyro(VerticalGyroParams(erection_gain=K)).simulate(t, prof, 0.0)
    assert out.latitude[-1] == pytest.approx(0.5 * a * t[-1] ** 2 / 6.335e6, rel=1e-3)  # R_M at 0°
    g0 = 9.7803253359  # WGS-84 normal gravity at the equator
    expected = vertical_gyro_acceleration_error(a, K, t, gravity=g0)
    theta_a = math.atan(a / g0)
    np.testing.assert_allclose(expected, -(theta_a - 2 * np.arctan(math.tan(theta_a / 2) * np.exp(-K * t))),
                               rtol=1e-12)
    np.testing.assert_allclose(out.pitch_indicated[1:], expected[1:], rtol=5e-3)


@pytest.mark.parametrize("turn_deg_s", [3.0, -3.0])
def test_steady_turn_error_matches_closed_form(turn_deg_s):
    """Coordinated 3°/s turn at 120 m/s (bank 32.6°), 50°N, proportional erection.  After 10
    time constants the indication equals the closed-form steady turn error (derived without
    Earth rate) within the Earth-rate terms the closed form neglects: the free-axis drift
    (Ω + V/R)/k and the Coriolis tilt of the apparent vertical 2ΩV/g (0.37° together)."""
    w = math.radians(turn_deg_s)
    v = 120.0
    carrier = CoordinatedTurn(v, w, yaw0=0.3)
    t = np.arange(0.0, 500.0, 1.0)
    out = VerticalGyro(VerticalGyroParams(erection_gain=K)).simulate(t, carrier, math.radians(50.0),
                                                                    max_step=5.0)
    phi = abs(carrier.roll)
    roll_i, pitch_i = vertical_gyro_turn_indication(w, phi, K)
    bound = (OMEGA_IE + v / 6.37e6) / K + 2.0 * OMEGA_IE * v / 9.8
    assert abs(roll_i - carrier.roll) > 5 * bound  # the turn error is well above the bound
    assert abs(pitch_i) > 10 * bound
    np.testing.assert_allclose(out.roll_indicated[-100:], roll_i, rtol=0, atol=bound)
    np.testing.assert_allclose(out.pitch_indicated[-100:], pitch_i, rtol=0, atol=bound)
    np.testing.assert_allclose(out.roll_true, carrier.roll, rtol=0, atol=1e-12)


def test_turn_closed_form_is_a_fixed_point_in_the_turning_frame():
    """Independent check of the derivation: rotate the closed-form body-frame axis back into a
    turning frame with scipy and evaluate k(f̂ − μs) − ω ẑ × s (must vanish); and the limits
    k → 0 (true attitude) and k → ∞ (wings level)."""
    w, phi = math.radians(-4.0), math.radians(25.0)
    for k in (0.003, 0.05, 0.4):
        roll_i, pitch_i = vertical_gyro_turn_indication(w, phi, k)
        roll_true = phi if w < 0 else -phi
        # s in body axes from the indicated angles: the up vector of Ry(pitch)·Rx(roll)
        s_b = Rotation.from_euler("YX", [pitch_i, roll_i]).inv().apply([0.0, 0.0, 1.0])
        body = Rotation.from_euler("ZX", [0.0, roll_true])  # heading 0: along +x (east), level turn
        s = body.apply(s_b)
        f_hat = body.apply([0.0, 0.0, 1.0])
        mu = s @ f_hat
        residual = k * (f_hat - mu * s) - w * np.cross([0.0, 0.0, 1.0], s)
        np.testing.assert_allclose(residual, 0.0, rtol=0, atol=1e-14)
    roll_small, pitch_small = vertical_gyro_turn_indication(w, phi, 1e-7)
    assert roll_small == pytest.approx(phi, rel=1e-9) and abs(pitch_small) < 1e-6
    roll_big, pitch_big = vertical_gyro_turn_indication(w, phi, 1e8)
    assert abs(roll_big) < 1e-6 and abs(pitch_big) < 1e-6


@pytest.mark.parametrize(("field", "value"), [("erection_law", "pid"), ("erection_gain", 0.0),
                                               ("erection_rate", math.nan), ("linear_zone", 2.0),
                                               ("erection_gain", None)])
def test_bad_params_name_the_field(field, value):
    with pytest.raises(ValueError, match=field):
        VerticalGyroParams(**{field: value})


def test_bad_inputs():
    vg = VerticalGyro(VerticalGyroParams())
    with pytest.raises(ValueError, match="spin_axis0"):
        vg.simulate([0.0, 1.0], Stationary(), 0.5, spin_axis0=(0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="latitude"):
        vg.simulate([0.0, 1.0], Stationary(), math.inf)
    with pytest.raises(ValueError, match="bank"):
        vertical_gyro_turn_indication(0.05, 2.0, 0.02)
