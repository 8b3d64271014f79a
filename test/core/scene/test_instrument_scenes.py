"""The instrument scenes of config/scenes: each loaded, simulated through SceneSimulator (shortened
where long) and checked against its closed form; block splitting; schema errors."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from gyro_attitude.core.earth import OMEGA_IE
from gyro_attitude.core.instruments.common import heading_from_quat, wrap_pi
from gyro_attitude.core.instruments.directional_gyro import cardan_indicated_heading
from gyro_attitude.core.instruments.gyrocompass import speed_error
from gyro_attitude.core.instruments.stability import shell_nutation_ratio, simulate_shell
from gyro_attitude.core.instruments.vertical_gyro import vertical_gyro_turn_indication
from gyro_attitude.core.scene import SceneSimulator, SceneSpec
from gyro_attitude.io.scene_file import load_scene


def _run(name: str, rate_hz: float, duration_s: float, **changes):
    spec = load_scene(name)
    if changes:
        d = copy.deepcopy(spec.source)
        for path, value in changes.items():
            node = d
            *head, last = path.split(".")
            for k in head:
                node = node[k]
            node[last] = value
        spec = SceneSpec.from_dict(d, name)
    sim = SceneSimulator(spec, rate_hz)
    block = sim.next_block(int(round(duration_s * rate_hz)) + 1)
    t = (block.t_ns - block.t_ns[0]) / 1e9
    joints = dict(zip(block.gimbal.names, block.gimbal.positions.T, strict=True))
    rates = dict(zip(block.gimbal.names, block.gimbal.velocities.T, strict=True))
    return spec, sim, block, t, joints, rates


def _heading_true(q_nb):
    return heading_from_quat(q_nb)


def test_gyrocompass_settling_swings_with_schuler_period_about_the_meridian():
    """Undamped, at rest, started 2° east: indicated − true heading = −2° cos(2πt/T) with
    T = 2π√(H/(P Ω cos L)) (= 84.4 min, Schuler-tuned); its rate is the derivative of that.
    Tolerance: the small-angle model's neglected terms (ω_N beside P/H, < 0.2 % of the period;
    cubic terms of 2°) — measured 1.3e-4 rad over 1.5 periods; bound 4e-4 rad."""
    spec, sim, block, t, j, r = _run("gyrocompass_settling", 0.1, 7600.0)
    ins = spec.instrument.instrument
    lat = spec.earth.latitude_rad
    T = ins.params.period(lat)
    assert T / 60.0 == pytest.approx(84.4, abs=0.3)
    a0 = math.radians(2.0)
    err = wrap_pi(j["heading_indicated"] - _heading_true(block.truth_q_nb))
    w = 2 * math.pi / T
    np.testing.assert_allclose(err, -a0 * np.cos(w * t), rtol=0, atol=4e-4)
    np.testing.assert_allclose(r["heading_indicated"], a0 * w * np.sin(w * t), rtol=0,
                               atol=4e-4 * w)
    assert "instrument.gyrocompass" in sim.effects_run and "free_gyro" not in sim.effects_run


def test_gyrocompass_ship_settles_on_speed_error_within_6h():
    """Damped ζ = 0.5 on a ship at 10 m/s north: after 5 h (> 6 time constants) the reading is
    high by the speed error δ at the latitude reached, within 2 % of δ (latitude drift of the
    settle point during the run)."""
    spec, sim, block, t, j, r = _run("gyrocompass_ship", 1 / 60.0, 6 * 3600.0)
    err = wrap_pi(j["heading_indicated"] - _heading_true(block.truth_q_nb))
    lat = block.position_llh[:, 0]
    delta = np.array([speed_error(10.0, 0.0, float(L)) for L in lat])
    assert math.degrees(delta[-1]) == pytest.approx(1.8, abs=0.1)
    late = t >= 5 * 3600.0
    np.testing.assert_allclose(err[late], delta[late], rtol=0.02, atol=0)
    assert abs(err[0]) < 1e-12  # started on the meridian: the settling is real
    # started at rest on the equilibrium tilt, α answers the step to −δ like a second-order
    # system: overshoot exp(−πζ/√(1−ζ²)) = 16.3 % at ζ = 0.5 (10 % slack: the settle point
    # drifts with latitude, and the sampling is 1 min)
    zeta = 0.5
    assert np.max(err) / delta[np.argmax(err)] - 1.0 == pytest.approx(
        math.exp(-math.pi * zeta / math.sqrt(1 - zeta * zeta)), rel=0.1)


def test_gyrocompass_course_change_schuler_tuned_has_no_ballistic_deflection():
    """Settled north at 10 m/s, turn east in 60 s.  Schuler-tuned: the axis goes straight to the
    new settle point (east course: on the meridian), the residual swing is only the tilt-
    equilibrium shift of order Ω v/g (0.07°, see the phase-1 closed form).  With a 60-min
    period instead it swings by the ballistic throw Δv_N (P/(gH) − 1/(R Ω cos L)) ≈ 1.7°."""
    _, _, block, t, j, _ = _run("gyrocompass_course_change", 0.2, 360.0 + 5400.0)
    after = t >= 360.0
    alpha = j["spin_axis_azimuth"][after]
    assert abs(alpha[0]) < math.radians(0.1)
    assert np.max(np.abs(alpha)) < math.radians(0.1)
    before = t < 300.0
    delta = speed_error(10.0, 0.0, block.position_llh[0, 0])
    # started on the (small-angle) settle point, which the exact speed error matches to 3e-4;
    # the settle point then moves with the latitude reached (measured 1.1e-3 after 300 s)
    np.testing.assert_allclose(j["spin_axis_azimuth"][before], -delta, rtol=2e-3, atol=0)
    _, _, _, t2, j2, _ = _run("gyrocompass_course_change", 0.2, 360.0 + 5400.0,
                              **{"instrument.schuler_tuned": None, "instrument.period_s": 3600.0})
    swing = j2["spin_axis_azimuth"][t2 >= 360.0]
    assert 0.5 * (swing.max() - swing.min()) == pytest.approx(math.radians(1.7), rel=0.05)


def test_vertical_gyro_turn_reaches_closed_form_turn_error():
    """After 10 erection time constants the indicated roll/pitch equal the steady turn error of
    the proportional law; bound: the Earth-rate terms the closed form neglects (phase 1)."""
    spec, _, block, t, j, r = _run("vertical_gyro_turn", 2.0, 500.0)
    motion = spec.motion
    k = spec.instrument.instrument.params.erection_gain
    roll_i, pitch_i = vertical_gyro_turn_indication(motion.turn_rate, abs(motion.roll), k)
    bound = (OMEGA_IE + 120.0 / 6.37e6) / k + 2.0 * OMEGA_IE * 120.0 / 9.8
    assert abs(roll_i - motion.roll) > 5 * bound
    np.testing.assert_allclose(j["roll_indicated"][-100:], roll_i, rtol=0, atol=bound)
    np.testing.assert_allclose(j["pitch_indicated"][-100:], pitch_i, rtol=0, atol=bound)
    # steady: what the joints still move is the Earth-rate part (size ≤ bound), which turns
    # with the aircraft at the turn rate: rates ≤ bound·|ω|
    for name in ("roll_indicated", "pitch_indicated"):
        assert np.max(np.abs(r[name][-100:])) < bound * abs(motion.turn_rate)


def test_directional_gyro_bank_shows_cardan_error():
    """Over a full 3°/s turn the card follows tan ψ_g = cos φ tan ψ (pitch 0), drift nulled by
    the latitude nut except the transport rate; bound V t tan L / R."""
    spec, _, block, t, j, r = _run("directional_gyro_bank", 4.0, 119.0)
    roll = spec.motion.roll
    heading = _heading_true(block.truth_q_nb)
    want = cardan_indicated_heading(heading, 0.0, roll)
    bound = 120.0 * t[-1] * math.tan(spec.earth.latitude_rad) / 6.37e6
    d = wrap_pi(j["heading_indicated"] - want)
    assert np.max(np.abs(wrap_pi(want - heading))) > 20 * bound
    np.testing.assert_allclose(d, 0.0, rtol=0, atol=bound)
    # the card turns at the turn rate times d ψ_g/d ψ of the closed form
    h = 1e-6
    dpsi = wrap_pi(cardan_indicated_heading(heading + h, 0.0, roll)
                   - cardan_indicated_heading(heading - h, 0.0, roll)) / (2 * h)
    np.testing.assert_allclose(r["heading_indicated"], -spec.motion.turn_rate * dpsi, rtol=0,
                               atol=2e-3 * abs(spec.motion.turn_rate))


@pytest.mark.parametrize("name", ["gyrocompass_course_change", "vertical_gyro_turn",
                                  "directional_gyro_bank"])
def test_block_by_block_equals_one_long_run(name):
    """gyro_sim steps the instrument in short blocks: the result equals one long call to within
    the solver tolerance (each block restarts DOP853 from the last state)."""
    spec = load_scene(name)
    rate = 2.0
    n = 400
    whole = SceneSimulator(spec, rate).next_block(n)
    sim = SceneSimulator(spec, rate)
    sizes = [1, 7, 50, 3, 139, 200]
    pieces = [sim.next_block(m) for m in sizes]
    pos = np.concatenate([p.gimbal.positions for p in pieces])
    vel = np.concatenate([p.gimbal.velocities for p in pieces])
    np.testing.assert_allclose(wrap_pi(pos - whole.gimbal.positions), 0.0, rtol=0, atol=1e-8)
    np.testing.assert_allclose(vel, whole.gimbal.velocities, rtol=0, atol=1e-8)


def _base(**instrument):
    return {"description": "x", "seed": 1, "earth": {"latitude_deg": 45.0},
            "motion": {"type": "stationary"}, "instrument": instrument}


@pytest.mark.parametrize(("instrument", "match"), [
    ({"type": "sextant"}, r"instrument\.type: must be one of"),
    ({"type": "gyrocompass", "angular_momentum": 10.0, "schuler_tuned": True, "wobble": 1},
     r"instrument\.wobble: unknown key"),
    ({"type": "gyrocompass", "angular_momentum": 10.0}, r"instrument: give exactly one"),
    ({"type": "gyrocompass", "angular_momentum": 10.0, "period_s": 3600, "pendulous_moment": 1},
     r"instrument: give exactly one"),
    ({"type": "gyrocompass", "angular_momentum": math.nan, "schuler_tuned": True},
     r"instrument\.angular_momentum: must be finite"),
    ({"type": "gyrocompass", "angular_momentum": 10.0, "schuler_tuned": True,
      "azimuth0_deg": 1e300}, r"instrument\.azimuth0_deg: must be <= 180"),
    ({"type": "vertical_gyro", "erection_gain": -1.0}, r"instrument\.erection_gain: must be >"),
    ({"type": "vertical_gyro", "spin_axis0": [0, 1, -1]}, r"instrument\.spin_axis0: must point"),
    ({"type": "vertical_gyro", "spin_axis0": [0, 1]}, r"instrument\.spin_axis0: must have shape"),
    ({"type": "directional_gyro", "latitude_nut_deg": "north"},
     r"instrument\.latitude_nut_deg: must be a number"),
    ({"type": "directional_gyro", "max_step_s": 0.0}, r"instrument\.max_step_s: must be >="),
])
def test_bad_instrument_sections_name_the_key(instrument, match):
    with pytest.raises(ValueError, match=match):
        SceneSpec.from_dict(_base(**instrument))


def test_instrument_refuses_a_gyrocompass_at_the_pole_and_a_second_gimballed_instrument():
    d = _base(type="gyrocompass", angular_momentum=10.0, schuler_tuned=True)
    d["earth"]["latitude_deg"] = 89.5
    with pytest.raises(ValueError, match=r"instrument\.schuler_tuned: latitude must lie within"):
        SceneSpec.from_dict(d)
    d = _base(type="directional_gyro")
    d["free_gyro"] = {"spin_inertia": 1e-4, "transverse_inertia": 6e-5, "spin_rate": 2000.0}
    with pytest.raises(ValueError, match="one gimballed instrument"):
        SceneSpec.from_dict(d)
    d = _base(type="directional_gyro")
    d["earth"]["rotation"] = False
    with pytest.raises(ValueError, match="always see the Earth"):
        SceneSpec.from_dict(d)


def test_only_the_instrument_is_evaluated(monkeypatch):
    """A scene with an instrument and no accelerometer evaluates no specific force, no rate gyro
    and no free gyro (each replaced by a function that raises)."""
    from gyro_attitude.core.scene import simulator as simmod

    def boom(*a, **k):
        raise AssertionError("unrequested effect evaluated")

    monkeypatch.setattr(simmod.SceneSimulator, "_specific_force", boom)
    monkeypatch.setattr(simmod, "FreeGyroSimulator", boom)
    monkeypatch.setattr(simmod, "RateGyroTriad", boom)
    sim = SceneSimulator(load_scene("directional_gyro_bank"), 5.0)
    b = sim.next_block(10)
    assert b.gimbal.names == ("heading_indicated", "outer_gimbal", "inner_gimbal")
    assert sim.effects_run >= {"instrument.directional_gyro"}
    assert "specific_force" not in sim.effects_run


def test_spinning_shell_stays_up_for_s_above_1_and_tumbles_below():
    """s = 1.2: θ nutates between θ₀ and ≈ θ₀/√(1 − 1/s) (linear theory, 2 % at 2°) and matches
    the phase-1 implicit-midpoint run of the same equations (independent integrator; its
    O((n dt)²) phase error at dt = 1e-4 s leaves ~1e-5 rad after 5 s, measured).  s = 0.8: θ grows
    as e^{σt} (σ = 2.5/s) past 45° within 2 s — over 20 θ₀ — before the nonlinear terms
    turn it back (the shell has tumbled)."""
    spec, sim, block, t, j, r = _run("spinning_shell", 100.0, 5.0)
    theta = j["angle_of_attack"]
    p = spec.instrument.instrument.params
    assert p.stability_factor == pytest.approx(1.2, rel=1e-12)
    th0 = math.radians(2.0)
    assert np.max(theta) == pytest.approx(th0 * shell_nutation_ratio(1.2), rel=0.02)
    ref = simulate_shell(p, th0, 5.0, dt=1e-4, record_every=100)
    np.testing.assert_allclose(theta, ref.theta, rtol=0, atol=2e-5)
    _, _, _, t2, j2, _ = _run("spinning_shell", 100.0, 2.0, **{"instrument.stability_factor": 0.8})
    assert np.max(j2["angle_of_attack"]) > math.radians(45.0)


def test_g_sensitive_drift_scene_turns_at_ml_f_over_h():
    """Level rotor at rest (Earth rotation off): the outer gimbal turns about the vertical at
    m·l·|f|/H with f the scene's own accelerometer truth (closed form, §5-3)."""
    spec, sim, block, t, j, r = _run("g_sensitive_drift", 1.0, 600.0)
    p = spec.free_gyro_params
    f = np.linalg.norm(block.specific_force_b[0])
    rate = p.mass_unbalance * f / p.spin_momentum
    np.testing.assert_allclose(j["outer_gimbal"], rate * t, rtol=1e-9, atol=0)
    np.testing.assert_allclose(r["outer_gimbal"], rate, rtol=1e-12, atol=0)
    assert "g_sensitive_drift" in sim.effects_run


def test_gimbal_stop_scene_bounces_with_restitution():
    """The inner gimbal stays between its stops; each impact reverses its rate times e."""
    spec, sim, block, t, j, r = _run("gimbal_stop_bounce", 500.0, 1.0)
    lo, hi = spec.free_gyro_params.inner_gimbal_stops
    e = spec.free_gyro_params.stop_restitution
    assert np.all((j["inner_gimbal"] >= lo - 1e-12) & (j["inner_gimbal"] <= hi + 1e-12))
    impacts = sim._free_gyro.stop_impacts
    assert len(impacts) >= 3
    for _, _, before, after in impacts:
        assert after == pytest.approx(-e * before, rel=1e-14, abs=0)


@pytest.mark.parametrize(("instrument", "match"), [
    ({"type": "spinning_shell", "spin_inertia": 0.02, "transverse_inertia": 0.2,
      "spin_rate": 100.0}, r"instrument: give exactly one of overturning_moment"),
    ({"type": "spinning_shell", "spin_inertia": 0.02, "transverse_inertia": 0.2,
      "spin_rate": 100.0, "stability_factor": 1.2, "spin": 3}, r"instrument\.spin: unknown key"),
    ({"type": "spinning_shell", "spin_inertia": -1, "transverse_inertia": 0.2,
      "spin_rate": 100.0, "stability_factor": 1.2}, r"instrument\.spin_inertia: must be >"),
])
def test_bad_shell_sections_name_the_key(instrument, match):
    with pytest.raises(ValueError, match=match):
        SceneSpec.from_dict(_base(**instrument))


def test_bad_gyro_options_name_the_key():
    d = _base(type="directional_gyro")
    del d["instrument"]
    d["free_gyro"] = {"spin_inertia": 1e-4, "transverse_inertia": 6e-5, "spin_rate": 2000.0,
                      "inner_gimbal_stops": [-1, 1]}
    with pytest.raises(ValueError, match=r"free_gyro: inner_gimbal_stops need model='full'"):
        SceneSpec.from_dict(d)
    d = _base(type="directional_gyro")
    del d["instrument"]
    d["gyro"] = {"model": "integrating_gyro", "integrating_gyro": {"time_constant_s": 0.01,
                                                                   "wobble": 1}}
    with pytest.raises(ValueError, match=r"gyro\.integrating_gyro\.wobble: unknown key"):
        SceneSpec.from_dict(d)


def test_integrating_gyro_scene_reports_the_mean_rate_over_each_sample():
    """A delta-angle output: the mean of the indicated rate over each interval; with a constant
    rate started steady it is that rate times cos β (β = (H/D)θ grows: 0.5 rad/s for 2 s)."""
    d = _base(type="directional_gyro")
    del d["instrument"]
    d["earth"]["rotation"] = False
    d["motion"] = {"type": "profile", "segments": [{"duration_s": 2.0,
                                                    "angular_rate_deg_s": [0.0, 0.0, 10.0]}]}
    d["gyro"] = {"model": "integrating_gyro",
                 "integrating_gyro": {"time_constant_s": 1e-3, "gimbal_gain": 1e-9}}
    sim = SceneSimulator(SceneSpec.from_dict(d), 100.0)
    out = np.concatenate([sim.next_block(m).omega_ib_b for m in (1, 50, 149)])
    np.testing.assert_allclose(out[:, 2], math.radians(10.0), rtol=1e-12, atol=0)
    assert "integrating_gyro" in sim.effects_run
