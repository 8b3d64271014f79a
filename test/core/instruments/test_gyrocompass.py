"""Gyrocompass: period, speed error, Schuler tuning and ballistic deflection against closed forms."""

import math

import numpy as np
import pytest

from gyro_attitude.core.earth import OMEGA_IE, gravity_enu, radii_of_curvature
from gyro_attitude.core.instruments.gyrocompass import (
    Gyrocompass,
    GyrocompassParams,
    ballistic_throw,
    gyrocompass_equilibrium,
    gyrocompass_period,
    schuler_period,
)
from gyro_attitude.core.motion import ConstantVelocity, ProfileSegment, SegmentProfile, Stationary

H = 10.0  # N·m·s


def _zero_crossing_period(t, x):
    i = np.nonzero(np.sign(x[:-1]) != np.sign(x[1:]))[0]
    tz = t[i] - x[i] * (t[i + 1] - t[i]) / (x[i + 1] - x[i])
    return 2.0 * np.mean(np.diff(tz)), len(tz)


def test_schuler_period_is_84_4_minutes():
    assert schuler_period() / 60.0 == pytest.approx(84.4, abs=0.05)


@pytest.mark.parametrize("lat_deg", [20.0, 60.0, -35.0])
def test_schuler_tuned_params_give_the_schuler_period(lat_deg):
    """m l = H/(R_M Ω cos L) ⇔ T = 2π √(R_M/g(L)) at that latitude (WGS-84 radius and gravity)."""
    lat = math.radians(lat_deg)
    r_m, _ = radii_of_curvature(lat)
    g = float(-gravity_enu(lat)[2])
    params = GyrocompassParams.schuler_tuned(H, lat)
    assert params.period(lat) == pytest.approx(2 * math.pi * math.sqrt(float(r_m) / g), rel=1e-12)


@pytest.mark.parametrize(("lat_deg", "period_min", "heading"), [(45.0, None, 90.0), (20.0, 60.0, 30.0)])
def test_undamped_period_and_settle_point(lat_deg, period_min, heading):
    """2° east offset, undamped: the axis swings about the meridian with T = 2π√(H/(PΩ cos L)).

    The model's period differs from the formula by the ω_N beside P/H (< 0.2 %); 1 % is the bound.
    Latitude 20° separates cos L from sin L.  The compass reads true heading − α."""
    lat = math.radians(lat_deg)
    params = (GyrocompassParams.schuler_tuned(H, lat) if period_min is None
              else GyrocompassParams.with_period(H, period_min * 60.0, lat))
    P = params.pendulosity(lat)
    T = 2.0 * math.pi * math.sqrt(H / (P * OMEGA_IE * math.cos(lat)))  # the textbook formula
    assert params.period(lat) == pytest.approx(T, rel=1e-12)
    if period_min is None:
        assert T == pytest.approx(schuler_period(), rel=3e-3)  # WGS-84 R_M, g(L) vs mean R, g0
    t = np.arange(0.0, 3.2 * T, 20.0)
    yaw = math.radians(90.0 - heading)
    out = Gyrocompass(params).simulate(t, Stationary((0.0, 0.0, yaw)), lat,
                                       azimuth0=math.radians(2.0), max_step=60.0)
    measured, n = _zero_crossing_period(t, out.spin_axis_azimuth)
    assert n >= 5
    assert measured == pytest.approx(T, rel=0.01)
    assert measured == pytest.approx(gyrocompass_period(H, P, lat), rel=0.01)
    # undamped: the swing keeps its 2° amplitude, centred on the meridian (east of it never more)
    assert np.max(out.spin_axis_azimuth) == pytest.approx(math.radians(2.0), rel=1e-3)
    assert np.min(out.spin_axis_azimuth) == pytest.approx(-math.radians(2.0), rel=1e-3)
    err = (out.heading_indicated - math.radians(heading) + math.pi) % (2 * math.pi) - math.pi
    np.testing.assert_allclose(err, -out.spin_axis_azimuth, rtol=0, atol=1e-12)
    # the mean tilt is the static equilibrium β = Ω sin L / (P/H + Ω cos L)
    beta_eq = OMEGA_IE * math.sin(lat) / (P / H + OMEGA_IE * math.cos(lat))
    whole = t < 3.0 * measured  # average over whole periods
    assert np.mean(out.spin_axis_elevation[whole]) == pytest.approx(beta_eq, rel=0.02)


def test_ship_speed_error_damped_settles_within_6h():
    """Damped (ζ = 0.5), 10 m/s due north from 45°N: after 6 h the compass reads +δ,
    δ = atan(v_N / (R Ω cos L + v_E)) at the latitude reached (2 % bound; model differences:
    WGS-84 R_M vs R, the Coriolis specific force on the pendulum, order 1e-3)."""
    lat0 = math.radians(45.0)
    params = GyrocompassParams.schuler_tuned(H, lat0, damping_ratio=0.5)
    t = np.arange(0.0, 6 * 3600.0 + 1.0, 60.0)
    out = Gyrocompass(params).simulate(t, ConstantVelocity(10.0, (0.0, 0.0, math.pi / 2)), lat0,
                                       max_step=60.0)
    lat = out.latitude[-1]
    r_m, _ = radii_of_curvature(lat)
    assert lat == pytest.approx(lat0 + 6 * 3600.0 * 10.0 / float(r_m), rel=1e-3)
    delta = math.atan(10.0 / (float(r_m) * OMEGA_IE * math.cos(lat) + 0.0))
    err = (out.heading_indicated + math.pi) % (2 * math.pi) - math.pi
    assert err[-1] == pytest.approx(delta, rel=0.02)
    assert out.spin_axis_azimuth[-1] == pytest.approx(-delta, rel=0.02)  # west of north
    # settled: the last hour stays within 2 % of δ (moving with the latitude)
    assert np.all(np.abs(err[t >= 5 * 3600] - delta) < 0.02 * delta)


def test_undamped_equilibrium_formula_on_a_ship():
    """The closed-form settle point agrees with DESIGN's δ formula (and −δ west)."""
    lat = math.radians(30.0)
    params = GyrocompassParams.with_period(H, 3600.0, lat)
    alpha, _ = gyrocompass_equilibrium(params, lat, (3.0, 8.0, 0.0))
    r_m, r_n = (float(r) for r in radii_of_curvature(lat))
    assert -alpha == pytest.approx(math.atan((8.0 / r_m) / (OMEGA_IE * math.cos(lat) + 3.0 / r_n)),
                                   rel=1e-3)


def _course_change(params, lat, v=10.0, turn=60.0, after=5400.0):
    """Settled on a northerly course, then a 90° turn to east in ``turn`` s (constant ENU
    acceleration), then ``after`` s straight."""
    alpha0, beta0 = gyrocompass_equilibrium(params, lat, (0.0, v, 0.0),
                                            (-2 * OMEGA_IE * math.sin(lat) * v, 0.0))
    profile = SegmentProfile(
        [ProfileSegment(300.0),
         ProfileSegment(turn, (0.0, 0.0, -(math.pi / 2) / turn), (v / turn, -v / turn, 0.0)),
         ProfileSegment(after)],
        attitude_rad=(0.0, 0.0, math.pi / 2), velocity_enu=(0.0, v, 0.0))
    t = np.arange(0.0, 300.0 + turn + after, 5.0)
    out = Gyrocompass(params).simulate(t, profile, lat, azimuth0=alpha0, elevation0=beta0,
                                       max_step=10.0)
    swing = out.spin_axis_azimuth[t >= 300.0 + turn]
    return 0.5 * (swing.max() - swing.min()), 0.5 * (swing.max() + swing.min())


def test_course_change_ballistic_deflection_schuler_vs_not():
    """North → east at 10 m/s.  Not tuned (T = 60 min): the first throw is
    Δv_N (P/(gH) − 1/(R Ω cos L)) ≈ 1.7° off the new settle point and the axis swings that much.
    Schuler-tuned: no ballistic throw; what swing remains comes only from the change of the
    equilibrium tilt (transport-rate vertical and Coriolis on the pendulum, order Ω v/g: 0.07°),
    so it must be < 5 % of the untuned swing and match that closed form."""
    lat = math.radians(45.0)
    v = 10.0
    untuned = GyrocompassParams.with_period(H, 3600.0, lat)
    tuned = GyrocompassParams.schuler_tuned(H, lat)
    r_m, _ = radii_of_curvature(lat)
    P = untuned.pendulosity(lat)
    g = P / untuned.pendulous_moment
    textbook_throw = v * (P / (g * H) - 1.0 / (float(r_m) * OMEGA_IE * math.cos(lat)))
    bt = ballistic_throw(untuned, lat, (0.0, v, 0.0), (v, 0.0, 0.0))
    assert bt["throw"] == pytest.approx(textbook_throw, rel=1e-3)
    amp_untuned, centre_untuned = _course_change(untuned, lat)
    assert amp_untuned == pytest.approx(bt["amplitude"], rel=0.02)
    assert amp_untuned == pytest.approx(abs(textbook_throw), rel=0.03)
    bt_tuned = ballistic_throw(tuned, lat, (0.0, v, 0.0), (v, 0.0, 0.0))
    assert abs(bt_tuned["throw"]) < 1e-12
    amp_tuned, centre_tuned = _course_change(tuned, lat)
    assert amp_tuned < 0.05 * amp_untuned
    assert amp_tuned == pytest.approx(bt_tuned["amplitude"], rel=0.03)
    # both swing about the new meridian settle point (east course: no speed error)
    assert abs(centre_tuned) < 1e-5 and abs(centre_untuned) < 1e-4


@pytest.mark.parametrize(("field", "value"), [("angular_momentum", 0.0), ("pendulous_moment", math.nan),
                                               ("damping", -1.0), ("angular_momentum", "10"),
                                               ("damping", math.inf), ("latitude_correction", 1)])
def test_bad_params_name_the_field(field, value):
    kwargs = {"angular_momentum": 10.0, "pendulous_moment": 0.03, "damping": 0.0}
    kwargs[field] = value
    with pytest.raises(ValueError, match=field):
        GyrocompassParams(**kwargs)


def test_bad_inputs():
    gc = Gyrocompass(GyrocompassParams(10.0, 0.03))
    with pytest.raises(ValueError, match="latitude"):
        gc.simulate([0.0, 1.0], Stationary(), math.radians(90.0))
    with pytest.raises(ValueError, match="t_grid"):
        gc.simulate([0.0, math.nan], Stationary(), 0.5)
    with pytest.raises(ValueError, match="increasing"):
        gc.simulate([1.0, 0.0], Stationary(), 0.5)
    with pytest.raises(ValueError, match="carrier"):
        gc.simulate([0.0, 1.0], "ship", 0.5)
    with pytest.raises(ValueError, match="azimuth0"):
        gc.simulate([0.0, 1.0], Stationary(), 0.5, azimuth0=math.inf)


def test_chunks_equal_one_piece():
    params = GyrocompassParams.schuler_tuned(H, 0.7, damping_ratio=0.3)
    t = np.arange(0.0, 2000.0, 10.0)
    gc = Gyrocompass(params)
    whole = gc.simulate(t, Stationary(), 0.7, azimuth0=0.03, chunk=10_000)
    parts = list(gc.iter_chunks(t, Stationary(), 0.7, azimuth0=0.03, chunk=37))
    assert max(len(p.t) for p in parts) <= 37
    joined = np.concatenate([p.spin_axis_azimuth for p in parts])
    np.testing.assert_allclose(joined, whole.spin_axis_azimuth, rtol=0, atol=1e-9)
