"""Scene simulator against closed forms (docs/equations.md), scipy oracles and conserved quantities."""


import copy

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.spatial.transform import Rotation

from gyro_attitude.core import earth as earth_module
from gyro_attitude.core.gyro.rate_gyro import RateGyroParams, RateGyroTriad
from gyro_attitude.core.scene import MAX_RATE_HZ, MAX_SAMPLES_PER_CALL, SceneSimulator, SceneSpec, simulator

OMEGA_IE = 7.292115e-5
A = 6378137.0
E2 = (1 / 298.257223563) * (2 - 1 / 298.257223563)


def _radii(lat):
    d = 1 - E2 * np.sin(lat) ** 2
    return A * (1 - E2) / d**1.5, A / np.sqrt(d)


def scene(**overrides):
    d = {
        "description": "test scene",
        "seed": 7,
        "earth": {"latitude_deg": 45.0},
        "motion": {"type": "stationary"},
    }
    for k, v in overrides.items():
        d[k] = v
    return d


def run(d, rate_hz=100.0, n=100, blocks=1, seed=None):
    sim = SceneSimulator(SceneSpec.from_dict(d), rate_hz, seed=seed)
    out = [sim.next_block(n) for _ in range(blocks)]
    return sim, out


def cat(blocks, field):
    return np.concatenate([getattr(b, field) for b in blocks])


# --------------------------------------------------------------------------- Earth rate
@pytest.mark.parametrize("lat_deg", [-60.0, 0.0, 33.3, 89.0])
def test_stationary_gyro_sees_earth_rate_in_body_axes(lat_deg):
    att = {"roll_deg": 10.0, "pitch_deg": -20.0, "yaw_deg": 130.0}
    d = scene(earth={"latitude_deg": lat_deg, "height_m": 100.0},
              motion={"type": "stationary", "attitude": att})
    sim, (b,) = run(d, n=50)
    lat = np.radians(lat_deg)
    r_nb = Rotation.from_euler("ZYX", np.radians([130.0, -20.0, 10.0]))
    expect = r_nb.inv().apply([0.0, OMEGA_IE * np.cos(lat), OMEGA_IE * np.sin(lat)])
    assert np.abs(b.omega_ib_b - expect).max() < 1e-15
    assert np.abs(b.truth_omega_ib_b - expect).max() < 1e-15
    assert np.array_equal(b.truth_omega_nb_b, np.zeros((50, 3)))
    assert np.array_equal(b.velocity_enu, np.zeros((50, 3)))
    assert np.allclose(b.position_llh, [lat, 0.0, 100.0], rtol=0, atol=0)
    assert b.specific_force_b is None and b.gimbal is None
    assert sim.effects_run == {"motion.stationary", "earth_rate"}


def test_stationary_truth_repeated_from_one_time_equals_the_per_time_arithmetic():
    """At rest the simulator computes the truth and the specific force once and repeats it:
    the rows must be those the general path gives at every time (here a zero-speed straight
    line with the same attitude, which the shortcut does not take), to the bit."""
    from gyro_attitude.core.motion import ConstantVelocity

    att = {"roll_deg": 3.0, "pitch_deg": -7.0, "yaw_deg": 61.0}
    d = scene(earth={"latitude_deg": -37.5, "height_m": 820.0},
              motion={"type": "stationary", "attitude": att},
              accelerometer={"gravity": True})
    spec = SceneSpec.from_dict(d)
    general = copy.copy(spec)
    object.__setattr__(general, "motion", ConstantVelocity(
        0.0, np.radians([att["roll_deg"], att["pitch_deg"], att["yaw_deg"]])))
    assert not general.motion.moves
    a = SceneSimulator(spec, 100.0, seed=4).next_block(700)
    b = SceneSimulator(general, 100.0, seed=4).next_block(700)
    for name in ("omega_ib_b", "truth_omega_ib_b", "truth_q_nb", "specific_force_b",
                 "position_llh", "velocity_enu"):
        assert getattr(a, name) is not None, name
        assert np.array_equal(getattr(a, name), getattr(b, name)), name


def test_earth_rotation_off_means_navigation_frame_is_inertial():
    d = scene(earth={"latitude_deg": 45.0, "rotation": False},
              motion={"type": "coning", "half_angle_deg": 2.0, "frequency_hz": 3.0})
    sim, (b,) = run(d)
    assert np.array_equal(b.omega_ib_b, b.truth_omega_nb_b)
    assert "earth_rate" not in sim.effects_run


# --------------------------------------------------------------------------- moving carrier
def _oracle_position(lat0, lon0, h0, v_enu, t_end, t_eval):
    """Position equations of docs/conventions.md integrated by scipy (DOP853, tight tolerances)."""

    def rhs(_, y):
        r_m, r_n = _radii(y[0])
        return [v_enu[1] / (r_m + y[2]), v_enu[0] / ((r_n + y[2]) * np.cos(y[0])), v_enu[2]]

    sol = solve_ivp(rhs, (0.0, t_end), [lat0, lon0, h0], method="DOP853", rtol=1e-13,
                    atol=1e-15, t_eval=t_eval)
    return sol.y.T


@pytest.mark.parametrize(
    "yaw_deg, pitch_deg", [(0.0, 0.0), (90.0, 0.0), (210.0, 0.0), (30.0, -3.0)],
    ids=["east", "north", "south-west", "climbing"],
)
def test_constant_velocity_position_and_transport_rate(yaw_deg, pitch_deg):
    speed, lat0, lon0, h0 = 250.0, np.radians(40.0), np.radians(-75.0), 1000.0
    d = scene(
        earth={"latitude_deg": 40.0, "longitude_deg": -75.0, "height_m": h0},
        motion={"type": "constant_velocity", "speed_mps": speed,
                "attitude": {"yaw_deg": yaw_deg, "pitch_deg": pitch_deg}},
    )
    rate, n, blocks = 2.0, 500, 4  # 1000 s, 250 km, in resumable blocks
    sim, out = run(d, rate_hz=rate, n=n, blocks=blocks)
    t = cat(out, "t_ns") / 1e9
    r_nb = Rotation.from_euler("ZYX", np.radians([yaw_deg, pitch_deg, 0.0]))
    v = r_nb.apply([speed, 0, 0])
    assert np.allclose(cat(out, "velocity_enu"), v, rtol=0, atol=1e-12)
    llh = cat(out, "position_llh")
    ref = _oracle_position(lat0, lon0, h0, v, t[-1], t)
    assert np.abs(llh[:, :2] - ref[:, :2]).max() < 2e-13  # rad: ~1 mm
    assert np.abs(llh[:, 2] - ref[:, 2]).max() < 1e-8
    # Transport rate of docs/conventions.md at the oracle position, plus Earth rate, in body axes.
    lat, h = ref[:, 0], ref[:, 2]
    r_m, r_n = _radii(lat)
    w_in = np.stack((-v[1] / (r_m + h), OMEGA_IE * np.cos(lat) + v[0] / (r_n + h),
                     OMEGA_IE * np.sin(lat) + v[0] * np.tan(lat) / (r_n + h)), axis=1)
    assert np.abs(cat(out, "omega_ib_b") - r_nb.inv().apply(w_in)).max() < 1e-17
    assert {"position", "transport_rate", "earth_rate"} <= sim.effects_run


def test_turning_carrier_position_matches_scipy():
    """Time-varying velocity (a 2°/s turn at 200 m/s across the date line): the oracle
    integrates the position equations with the velocity written out in closed form."""
    speed, rate, yaw0 = 200.0, np.radians(2.0), np.radians(10.0)
    d = scene(earth={"latitude_deg": -35.0, "longitude_deg": 179.98, "height_m": 500.0},
              motion={"type": "coordinated_turn", "speed_mps": speed, "turn_rate_deg_s": 2.0,
                      "yaw_deg": 10.0})
    _, out = run(d, rate_hz=5.0, n=700, blocks=3)  # 420 s, crosses the date line
    t = cat(out, "t_ns") / 1e9
    llh = cat(out, "position_llh")

    def rhs(tt, y):
        ve, vn = speed * np.cos(yaw0 + rate * tt), speed * np.sin(yaw0 + rate * tt)
        r_m, r_n = _radii(y[0])
        return [vn / (r_m + y[2]), ve / ((r_n + y[2]) * np.cos(y[0])), 0.0]

    sol = solve_ivp(rhs, (0.0, t[-1]), [np.radians(-35.0), np.radians(179.98), 500.0],
                    method="DOP853", rtol=1e-13, atol=1e-15, t_eval=t)
    ref = sol.y.T
    dlon = (llh[:, 1] - ref[:, 1] + np.pi) % (2 * np.pi) - np.pi  # longitude is wrapped
    assert np.abs(llh[:, 0] - ref[:, 0]).max() < 2e-13  # rad: ~1 mm
    assert np.abs(dlon).max() < 2e-13
    assert llh[:, 1].min() < -3.1 and llh[:, 1].max() > 3.1  # it did cross ±180°
    assert np.all(llh[:, 2] == 500.0)


def test_transport_rate_can_be_switched_off():
    d = scene(earth={"latitude_deg": 10.0, "transport_rate": False},
              motion={"type": "constant_velocity", "speed_mps": 300.0})
    sim, (b,) = run(d)
    lat = b.position_llh[:, 0]
    assert np.abs(b.omega_ib_b - np.stack((0 * lat, OMEGA_IE * np.cos(lat),
                                           OMEGA_IE * np.sin(lat)), 1)).max() < 1e-18
    assert "transport_rate" not in sim.effects_run and "position" in sim.effects_run


# --------------------------------------------------------------------------- closed forms
def test_coning_scene_reproduces_design_closed_form():
    alpha, f = 1.5, 7.0
    d = scene(earth={"latitude_deg": 0.0, "rotation": False, "transport_rate": False},
              motion={"type": "coning", "half_angle_deg": alpha, "frequency_hz": f})
    sim, out = run(d, rate_hz=1000.0, n=250, blocks=3)
    t = cat(out, "t_ns") / 1e9
    a, om = np.radians(alpha), 2 * np.pi * f
    lam = np.stack((np.full_like(t, np.cos(a / 2)), 0 * t, np.sin(a / 2) * np.cos(om * t),
                    np.sin(a / 2) * np.sin(om * t)), 1)
    assert np.abs(cat(out, "truth_q_nb") - lam[:, [1, 2, 3, 0]]).max() < 1e-15
    w = np.stack((np.full_like(t, -2 * om * np.sin(a / 2) ** 2), -om * np.sin(a) * np.sin(om * t),
                  om * np.sin(a) * np.cos(om * t)), 1)
    assert np.abs(cat(out, "omega_ib_b") - w).max() < 1e-13
    assert sim.effects_run == {"motion.coning"}


def test_spinning_projectile_scene_closed_form():
    spin, alpha, fc = 40.0, 2.5, 4.0
    d = scene(earth={"latitude_deg": 0.0, "rotation": False, "transport_rate": False},
              motion={"type": "spinning_projectile", "spin_rate_hz": spin,
                      "half_angle_deg": alpha, "coning_frequency_hz": fc})
    _, (b,) = run(d, rate_hz=2000.0, n=1000)
    t = b.t_ns / 1e9
    a, om, p = np.radians(alpha), 2 * np.pi * fc, 2 * np.pi * spin
    # q = q_cone ⊗ q_spin written out in scalar-first Hamilton algebra.
    c, s = np.cos(a / 2), np.sin(a / 2)
    cone = np.stack((np.full_like(t, c), 0 * t, s * np.cos(om * t), s * np.sin(om * t)), 1)
    spin_q = np.stack((np.cos(p * t / 2), np.sin(p * t / 2), 0 * t, 0 * t), 1)
    w0, x0, y0, z0 = cone.T
    w1, x1, y1, z1 = spin_q.T
    prod = np.stack((w0 * w1 - x0 * x1 - y0 * y1 - z0 * z1, w0 * x1 + x0 * w1 + y0 * z1 - z0 * y1,
                     w0 * y1 - x0 * z1 + y0 * w1 + z0 * x1, w0 * z1 + x0 * y1 - y0 * x1 + z0 * w1), 1)
    assert np.abs(b.truth_q_nb - prod[:, [1, 2, 3, 0]]).max() < 1e-14
    w = np.stack((np.full_like(t, p - 2 * om * s * s), -om * np.sin(a) * np.sin((om - p) * t),
                  om * np.sin(a) * np.cos((om - p) * t)), 1)
    assert np.abs(b.omega_ib_b - w).max() < 1e-12


# --------------------------------------------------------------------------- specific force
def test_specific_force_at_rest_on_the_equator_is_normal_gravity():
    d = scene(earth={"latitude_deg": 0.0}, accelerometer={"gravity": True})
    sim, (b,) = run(d, n=10)
    assert np.allclose(b.specific_force_b, [0.0, 0.0, 9.7803253359], rtol=0, atol=1e-9)
    assert {"gravity", "specific_force"} <= sim.effects_run and "coriolis" not in sim.effects_run


def test_eotvos_effect_moving_east_on_the_equator():
    v = 200.0
    d = scene(earth={"latitude_deg": 0.0},
              motion={"type": "constant_velocity", "speed_mps": v}, accelerometer={})
    _, (b,) = run(d, rate_hz=10.0, n=5)
    # f_z = g − (2ω_ie + v/a)·v: Coriolis plus the centripetal term of the transport rate.
    expect = 9.7803253359 - (2 * OMEGA_IE + v / A) * v
    assert b.specific_force_b[0] == pytest.approx([0.0, 0.0, expect], abs=1e-9)


def test_gravity_switched_off_leaves_kinematic_acceleration():
    d = scene(earth={"latitude_deg": 20.0, "rotation": False, "transport_rate": False},
              motion={"type": "coordinated_turn", "speed_mps": 100.0, "turn_rate_deg_s": 5.0},
              accelerometer={"gravity": False})
    sim, (b,) = run(d, n=200)
    a = 100.0 * np.radians(5.0)
    assert np.allclose(np.linalg.norm(b.specific_force_b, axis=1), a, rtol=1e-13)
    assert "gravity" not in sim.effects_run


# --------------------------------------------------------------------------- effects
def test_unnamed_effects_are_never_evaluated(monkeypatch):
    def forbidden(*_a, **_k):
        raise AssertionError("evaluated an effect the scene did not call for")

    monkeypatch.setattr(earth_module, "gravity_enu", forbidden)
    monkeypatch.setattr(earth_module, "transport_rate_enu", forbidden)
    sim, _ = run(scene(), n=100, blocks=3)
    assert sim.effects_run == {"motion.stationary", "earth_rate"}
    # The same scene with accelerometers does evaluate gravity (the patch would catch it).
    with pytest.raises(AssertionError, match="did not call for"):
        run(scene(accelerometer={}), n=10)


def test_effects_run_lists_instrument_errors():
    d = scene(gyro={"errors": {"arw_rad_sqrt_s": 1e-4, "bias_rad_s": [1e-5, 0, 0]}},
              accelerometer={"errors": {"quantization_m_s": 1e-4}})
    sim, _ = run(d)
    assert sim.effects_run == {
        "motion.stationary", "earth_rate", "gyro.white_noise", "gyro.bias", "specific_force",
        "gravity", "accelerometer.quantization",
    }


def test_instrument_errors_act_on_the_true_rate_and_force():
    b_g, s_g = np.array([1e-4, -2e-4, 3e-4]), np.array([1e-3, 0.0, -2e-3])
    b_a = np.array([0.01, -0.02, 0.03])
    d = scene(motion={"type": "coning", "half_angle_deg": 3.0, "frequency_hz": 2.0},
              gyro={"errors": {"bias_rad_s": b_g.tolist(), "scale_factor": s_g.tolist()}},
              accelerometer={"errors": {"bias_m_s2": b_a.tolist()}})
    _, (b,) = run(d, n=300)
    assert np.abs(b.omega_ib_b - ((1 + s_g) * b.truth_omega_ib_b + b_g)).max() < 1e-15
    # Specific force of a body at rest in n: gravity only, in body axes, plus the bias.
    g = 9.7803253359 * (1 + 0.00193185265241 * 0.5) / np.sqrt(1 - E2 * 0.5)  # 45°, h = 0
    f_true = Rotation.from_quat(b.truth_q_nb).inv().apply([0.0, 0.0, g])
    assert np.abs(b.specific_force_b - (f_true + b_a)).max() < 1e-12


def test_truth_is_consistent_with_the_design_navigation_update():
    """Integrating the scene's true ω_ib^b with the ENU update of docs/conventions.md (the attitude
    integrator, Earth and transport rate removed) must follow the scene's own q_nb; a wrong
    sign or frame in ω_ib^b = C_bn ω_in^n + ω_nb^b would leave ~|ω_in|·t ≈ 1e-3 rad."""
    from gyro_attitude.core import attitude as integrate

    d = scene(earth={"latitude_deg": 60.0},
              motion={"type": "ship", "speed_mps": 150.0, "yaw_deg": 30.0,
                      "roll": {"amplitude_deg": 4.0, "period_s": 9.0},
                      "pitch": {"amplitude_deg": 2.0, "period_s": 7.0},
                      "heave": {"amplitude_m": 2.0, "period_s": 8.0}})
    _, (b,) = run(d, rate_hz=200.0, n=12_000)
    nav = integrate.NavFrame(latitude_rad=b.position_llh[:, 0], longitude_rad=b.position_llh[:, 1],
                             height_m=b.position_llh[:, 2], velocity_enu=b.velocity_enu)
    q = integrate.integrate_batch(b.t_ns, b.truth_omega_ib_b, q0=b.truth_q_nb[0],
                                  algorithm="rotvec_cubic", nav=nav)
    err = (Rotation.from_quat(q).inv() * Rotation.from_quat(b.truth_q_nb)).magnitude()
    assert err.max() < 1e-8


# --------------------------------------------------------------------------- reproducibility
NOISY = scene(
    earth={"latitude_deg": 30.0},
    motion={"type": "ship", "speed_mps": 8.0, "yaw_deg": 20.0,
            "roll": {"amplitude_deg": 5.0, "period_s": 7.0},
            "heave": {"amplitude_m": 0.5, "period_s": 6.0}},
    gyro={"errors": {"arw_rad_sqrt_s": 1e-4, "bias_instability_rad_s": 1e-5,
                     "bias_instability_tau_s": 5.0, "quantization_rad": 1e-6}},
    accelerometer={"errors": {"vrw_m_s_sqrt_s": 1e-3}},
)


def test_same_seed_same_output_and_block_split_invariance():
    _, a = run(NOISY, n=600)
    _, b = run(NOISY, n=600)
    for field in ("t_ns", "omega_ib_b", "specific_force_b", "truth_q_nb", "position_llh"):
        assert np.array_equal(cat(a, field), cat(b, field))
    sim = SceneSimulator(SceneSpec.from_dict(NOISY), 100.0)
    c = [sim.next_block(k) for k in (1, 0, 250, 349)]
    for field in ("omega_ib_b", "specific_force_b", "truth_q_nb", "truth_omega_ib_b"):
        assert np.allclose(cat(a, field), cat(c, field), rtol=1e-13, atol=1e-15)
    assert np.array_equal(cat(a, "t_ns"), cat(c, "t_ns"))
    assert np.abs(cat(a, "position_llh") - cat(c, "position_llh")).max() < 1e-12
    _, other = run(NOISY, n=600, seed=123)
    assert not np.allclose(cat(a, "omega_ib_b"), cat(other, "omega_ib_b"))
    assert np.array_equal(cat(a, "truth_q_nb"), cat(other, "truth_q_nb"))


def test_stamps_are_integer_nanoseconds_on_the_sample_grid():
    d = scene(start_time_ns=1_700_000_000_123_456_789)
    sim = SceneSimulator(SceneSpec.from_dict(d), 300.0)
    t = np.concatenate([sim.next_block(k).t_ns for k in (7, 400)])
    assert t.dtype == np.int64
    k = np.arange(407)
    assert np.array_equal(t - d["start_time_ns"], (k * 10**9) // 300)
    sim = SceneSimulator(SceneSpec.from_dict(d), 123.4)
    t = sim.next_block(1000).t_ns - d["start_time_ns"]
    assert np.abs(t - np.arange(1000) * 1e9 / 123.4).max() <= 0.5


def test_stamps_stay_exact_past_int64_overflow_of_k_times_1e9():
    # k·10⁹ overflows int64 after 9.2e9 samples: 2.6 h at 1 MHz. Stamps there must still be
    # start + k·10⁹/r exactly (Python integers are the oracle).
    d = scene(start_time_ns=123)
    sim = SceneSimulator(SceneSpec.from_dict(d), 1.0e6)
    k0 = 9_300_000_000
    sim._k = k0  # jump ahead instead of simulating 2.6 h
    t = sim.next_block(3).t_ns
    assert t.tolist() == [123 + (k * 10**9) // 10**6 for k in range(k0, k0 + 3)]
    sim = SceneSimulator(SceneSpec.from_dict(d), 3.0)
    sim._k = 10**10 + 1
    assert sim.next_block(2).t_ns.tolist() == [123 + (k * 10**9) // 3
                                               for k in (10**10 + 1, 10**10 + 2)]


def test_large_request_is_generated_in_bounded_pieces(monkeypatch):
    """Working memory is bounded by the piece size: a request above BLOCK_SAMPLES is made of
    pieces of at most that size, and equals the same samples asked for piece by piece."""
    monkeypatch.setattr(simulator, "BLOCK_SAMPLES", 64)
    d = copy.deepcopy(NOISY)
    d["free_gyro"] = {"spin_inertia": 1e-4, "transverse_inertia": 6e-5, "spin_rate": 2500.0}
    sim = SceneSimulator(SceneSpec.from_dict(d), 100.0)
    sizes = []
    generate = sim._generate
    monkeypatch.setattr(sim, "_generate", lambda n: sizes.append(n) or generate(n))
    whole = sim.next_block(300)
    assert sizes == [64, 64, 64, 64, 44]
    ref_sim = SceneSimulator(SceneSpec.from_dict(d), 100.0)
    pieces = [ref_sim.next_block(k) for k in (64, 64, 64, 64, 44)]
    for field in ("t_ns", "omega_ib_b", "specific_force_b", "truth_q_nb", "position_llh"):
        assert np.array_equal(getattr(whole, field), cat(pieces, field)), field
    assert np.array_equal(whole.gimbal.angles, np.concatenate([b.gimbal.angles for b in pieces]))
    assert whole.gimbal.rates.shape == (300, 2)


def test_rate_and_request_size_are_bounded():
    spec = SceneSpec.from_dict(scene())
    with pytest.raises(ValueError, match=r"rate_hz must be a number in \(0, 1e\+06\] Hz"):
        SceneSimulator(spec, 1.0e12)
    sim = SceneSimulator(spec, MAX_RATE_HZ)
    with pytest.raises(ValueError, match="more than one call returns"):
        sim.next_block(MAX_SAMPLES_PER_CALL + 1)
    assert sim.next_block(5).t_ns.tolist() == [0, 1000, 2000, 3000, 4000]


def test_imu_variances():
    sim, _ = run(scene())
    g, a = sim.imu_variances()
    assert np.array_equal(g, np.zeros(3)) and a is None
    d = scene(gyro={"errors": {"arw_rad_sqrt_s": 2e-4, "bias_instability_rad_s": 1e-5}},
              accelerometer={})
    sim = SceneSimulator(SceneSpec.from_dict(d), 200.0)
    g, a = sim.imu_variances()
    assert g == pytest.approx(np.full(3, (2e-4) ** 2 * 200.0 + 1e-10), rel=1e-14)
    assert np.array_equal(a, np.zeros(3))


# --------------------------------------------------------------------------- instruments
def test_rate_gyro_scene_composes_the_rate_gyro_triad():
    d = scene(earth={"latitude_deg": 45.0, "rotation": False},
              motion={"type": "profile", "segments": [
                  {"duration_s": 0.5}, {"duration_s": 1.5, "angular_rate_deg_s": [0, 0, 30.0]}]},
              gyro={"model": "rate_gyro",
                    "rate_gyro": {"natural_frequency_hz": 25.0, "damping_ratio": 0.7}})
    sim, out = run(d, rate_hz=1000.0, n=1000, blocks=2)
    triad = RateGyroTriad(RateGyroParams(natural_frequency_hz=25.0, damping_ratio=0.7), 1e-3)
    ref = triad.step_block(cat(out, "truth_omega_ib_b"))
    assert np.allclose(cat(out, "omega_ib_b"), ref, rtol=0, atol=1e-15)
    # Steady state long after the step: x = ω cos(β), β = (H/K) x with the default H/K = 0.01 s
    # (the tilted input axis; unit gain as β → 0).
    x = cat(out, "omega_ib_b")[-1, 2]
    assert x == pytest.approx(np.radians(30.0) * np.cos(0.01 * x), rel=1e-9)
    assert "rate_gyro" in sim.effects_run


def test_free_gyro_on_the_earth_keeps_its_inertial_direction():
    lat_deg = 45.0
    d = scene(earth={"latitude_deg": lat_deg},
              motion={"type": "stationary", "attitude": {"yaw_deg": 90.0}},
              free_gyro={"spin_inertia": 1e-4, "transverse_inertia": 6e-5, "spin_rate": 2500.0})
    sim, out = run(d, rate_hz=10.0, n=100, blocks=2)
    t = cat(out, "t_ns") / 1e9
    lat = np.radians(lat_deg)
    # Spin axis fixed in inertial space: in ENU it turns about the Earth axis at −ω_ie.
    axis = np.array([0.0, np.cos(lat), np.sin(lat)])
    s_n = Rotation.from_rotvec(-OMEGA_IE * np.outer(t, axis)).apply([0.0, 1.0, 0.0])
    s_c = Rotation.from_euler("Z", 90.0, degrees=True).inv().apply(s_n)  # case = body
    alpha = np.arctan2(s_c[:, 1], s_c[:, 0])
    beta = np.arctan2(-s_c[:, 2], np.hypot(s_c[:, 0], s_c[:, 1]))
    g = np.concatenate([b.gimbal.angles for b in out])
    assert out[0].gimbal.names == ("outer_gimbal", "inner_gimbal")
    assert np.abs(g[:, 0] - alpha).max() < 1e-10
    assert np.abs(g[:, 1] - beta).max() < 1e-10
    # Apparent drift about the vertical at ω_ie sin L (seed §2-3).
    assert (g[-1, 0] - g[0, 0]) / (t[-1] - t[0]) == pytest.approx(-OMEGA_IE * np.sin(lat),
                                                                   rel=1e-6)
    assert "free_gyro" in sim.effects_run


def test_simulator_arguments_are_checked():
    spec = SceneSpec.from_dict(scene())
    for bad in (0.0, -10.0, float("nan")):
        with pytest.raises(ValueError, match="rate_hz"):
            SceneSimulator(spec, bad)
    with pytest.raises(ValueError, match="n must be"):
        SceneSimulator(spec, 10.0).next_block(-1)
