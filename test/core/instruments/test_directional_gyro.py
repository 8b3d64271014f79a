"""Directional gyro: cardan error against scipy geometry, drift against ω_ie sin L and the nut."""

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from gyro_attitude.core.earth import OMEGA_IE, radii_of_curvature
from gyro_attitude.core.instruments.cases import CASES, instrument_case
from gyro_attitude.core.instruments.directional_gyro import (
    DirectionalGyro,
    DirectionalGyroParams,
    cardan_error,
    cardan_indicated_heading,
    directional_gyro_drift_rate,
)
from gyro_attitude.core.motion import ConstantVelocity, CoordinatedTurn, Stationary


def _scipy_outer_gimbal(heading, pitch, roll):
    """Geometric definition, independent of the module: rotor along north seen in body axes
    (scipy ZYX = yaw-pitch-roll of q_nb, yaw = 90° − heading), outer gimbal angle about body z."""
    rot = Rotation.from_euler("ZYX", np.stack([np.pi / 2 - heading, pitch, roll], axis=-1))
    r_b = rot.inv().apply([0.0, 1.0, 0.0])
    return np.mod(np.arctan2(r_b[:, 1], r_b[:, 0]), 2 * np.pi)


def test_cardan_closed_form_matches_geometry():
    rng = np.random.default_rng(5)
    n = 2000
    heading = rng.uniform(0, 2 * np.pi, n)
    pitch = rng.uniform(-1.2, 1.2, n)
    roll = rng.uniform(-1.4, 1.4, n)
    got = cardan_indicated_heading(heading, pitch, roll)
    want = _scipy_outer_gimbal(heading, pitch, roll)
    d = np.mod(got - want + np.pi, 2 * np.pi) - np.pi
    np.testing.assert_allclose(d, 0.0, rtol=0, atol=1e-12)


def test_cardan_pure_bank_textbook_form():
    """tan ψ_g = cos φ tan ψ: zero on cardinal headings, −(φ²/4) sin 2ψ for small φ."""
    phi = math.radians(30.0)
    psi = np.radians([0.0, 45.0, 90.0, 135.0, 180.0, 270.0])
    err = cardan_error(psi, 0.0, phi)
    np.testing.assert_allclose(err[[0, 2, 4, 5]], 0.0, rtol=0, atol=1e-15)
    assert err[1] == pytest.approx(math.atan(math.cos(phi)) - math.pi / 4, rel=1e-12)
    assert err[3] == pytest.approx(-(math.atan(math.cos(phi)) - math.pi / 4), rel=1e-12)
    small = cardan_error(math.radians(45.0), 0.0, 0.01)
    assert small == pytest.approx(-(0.01 ** 2) / 4, rel=1e-3)


@pytest.mark.parametrize(("heading", "pitch", "roll"), [(45.0, 0.0, 30.0), (120.0, -10.0, -25.0),
                                                        (300.0, 15.0, 45.0)])
def test_simulated_gimbal_equals_closed_form_at_rest(heading, pitch, roll):
    """At the equator at rest ω_ie lies along the north rotor: no drift, pure cardan error."""
    yaw = math.radians(90.0 - heading)
    att = (math.radians(roll), math.radians(pitch), yaw)
    out = DirectionalGyro(DirectionalGyroParams()).simulate([0.0, 600.0], Stationary(att), 0.0)
    want = cardan_indicated_heading(math.radians(heading), math.radians(pitch), math.radians(roll))
    np.testing.assert_allclose(out.heading_indicated, want, rtol=0, atol=1e-10)
    assert out.heading_true[0] == pytest.approx(math.radians(heading), abs=1e-12)


def test_banked_turn_cardan_error():
    """A full 3°/s coordinated turn at 120 m/s at the equator (bank 32.6°): the indication
    follows the closed-form cardan error; bound: the rotor's tilt by the transport rate V t/R."""
    turn = CoordinatedTurn(120.0, math.radians(3.0), yaw0=0.0)
    t = np.arange(0.0, 120.0, 0.5)
    out = DirectionalGyro(DirectionalGyroParams()).simulate(t, turn, 0.0, max_step=0.5)
    want = cardan_indicated_heading(out.heading_true, 0.0, turn.roll)
    d = np.mod(out.heading_indicated - want + np.pi, 2 * np.pi) - np.pi
    bound = 120.0 * t[-1] / 6.37e6
    assert np.max(np.abs(cardan_error(out.heading_true, 0.0, turn.roll))) > 20 * bound
    np.testing.assert_allclose(d, 0.0, rtol=0, atol=bound)


def _slope(t, heading):
    return np.polyfit(t, np.unwrap(heading), 1)[0]


@pytest.mark.parametrize(("lat_deg", "nut_deg"), [(30.0, None), (-50.0, None), (30.0, 30.0), (30.0, 40.0)])
def test_drift_is_earth_rate_sin_latitude(lat_deg, nut_deg):
    """Level at rest: the card falls at ω_ie sin L (rises in the south); the nut set to the
    latitude cancels it; a mis-set nut leaves ω_ie (sin L − sin L_nut).  Leveling k_l = 0.05/s;
    bound: its drift error Ω² cos² L / (2 k_l) (module docstring), ≤ 1.1e-3 of Ω sin L here."""
    lat = math.radians(lat_deg)
    nut = None if nut_deg is None else math.radians(nut_deg)
    t = np.arange(0.0, 7200.0, 60.0)
    k_l = 0.05
    out = DirectionalGyro(DirectionalGyroParams(nut, k_l)).simulate(
        t, Stationary((0.0, 0.0, math.radians(30.0))), lat, max_step=600.0)
    expected = -OMEGA_IE * math.sin(lat) + (0.0 if nut is None else OMEGA_IE * math.sin(nut))
    assert directional_gyro_drift_rate(lat, 0.0, nut) == pytest.approx(expected, rel=1e-12, abs=1e-20)
    slope = _slope(t, out.heading_indicated)
    assert slope == pytest.approx(expected, rel=0, abs=(OMEGA_IE * math.cos(lat)) ** 2 / (2 * k_l))


def test_drift_adds_transport_rate_moving_east():
    """200 m/s due east at 40°N: drift ω_ie sin L + v_E tan L / R_N."""
    lat = math.radians(40.0)
    t = np.arange(0.0, 3600.0, 60.0)
    k_l = 0.05
    out = DirectionalGyro(DirectionalGyroParams(None, k_l)).simulate(t, ConstantVelocity(200.0), lat,
                                                                     max_step=600.0)
    _, r_n = radii_of_curvature(lat)
    expected = -(OMEGA_IE * math.sin(lat) + 200.0 * math.tan(lat) / float(r_n))
    assert _slope(t, out.heading_indicated) == pytest.approx(
        expected, rel=0, abs=(OMEGA_IE * math.cos(lat) + 200.0 / float(r_n)) ** 2 / (2 * k_l))
    assert directional_gyro_drift_rate(lat, 200.0) == pytest.approx(expected, rel=1e-12)


def test_bad_inputs():
    with pytest.raises(ValueError, match="latitude_nut"):
        DirectionalGyroParams(latitude_nut=2.0)
    with pytest.raises(ValueError, match="leveling_gain"):
        DirectionalGyroParams(leveling_gain=-1.0)
    with pytest.raises(ValueError, match="heading"):
        cardan_indicated_heading(math.nan, 0.0, 0.0)
    with pytest.raises(ValueError, match="t_grid"):
        DirectionalGyro(DirectionalGyroParams()).simulate([], Stationary(), 0.0)


def test_named_cases_build_and_run_briefly():
    for name in CASES:
        case = instrument_case(name)
        assert case.name == name and case.description
        out = case.instrument.simulate(case.t_grid[:3], case.carrier, case.latitude, **case.options)
        assert np.all(np.isfinite(out.heading_indicated if hasattr(out, "heading_indicated")
                                  else out.roll_indicated))
    with pytest.raises(ValueError, match="unknown instrument case"):
        instrument_case("nope")
