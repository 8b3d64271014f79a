"""The causal AHRS filter (core/attitude/ahrs.py) against closed forms and an independent rotation
oracle (scipy): tilt and heading convergence, sustained acceleration, magnetic disturbances,
bad magnetometer samples, reference recovery, hard iron."""

import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from gyro_attitude.core.attitude.ahrs import A_LP_OUT, AhrsFilter, _butterworth2
from gyro_attitude.core.attitude.settings import StreamConfig
from gyro_attitude.core.attitude.stream import AttitudeStream

FS = 200.0
G = 9.81
# a Berlin-like field in ENU (tesla): 16 µT north, 41 µT down
B_ENU = np.array([0.0, 16e-6, -41e-6])


def tilt_deg(q, q_true):
    u = Rotation.from_quat(q).apply([0.0, 0.0, 1.0], inverse=True)
    v = Rotation.from_quat(q_true).apply([0.0, 0.0, 1.0], inverse=True)
    return np.degrees(np.arccos(np.clip(np.sum(u * v, axis=-1), -1.0, 1.0)))


def heading_deg(q, q_true):
    """Rotation about the vertical of the error q ⊗ q_true⁻¹ (twist about z), degrees."""
    e = (Rotation.from_quat(q) * Rotation.from_quat(q_true).inv()).as_quat()
    return np.degrees(np.abs((2 * np.arctan2(e[..., 2], e[..., 3]) + np.pi) % (2 * np.pi) - np.pi))


def aided_run(t_ns, gyro, accel, q0, mag=None, *, config=None):
    """Attitudes (N, 4) of the causal estimator with the AHRS aiding alone (no bias stage) over
    bias-free rates from ``q0``, integrated with the exponential map, and its AHRS stage (for
    the counters).  The stamps are moved 1 s on (a zero stamp is refused)."""
    cfg = config if config is not None else StreamConfig()
    aiding = "magnetometer" if mag is not None else "tilt"
    s = AttitudeStream("exp_map", q0=q0, config=replace(cfg, aiding=aiding, gyro_bias="none"))
    res = s.run(np.asarray(t_ns) + 10**9, gyro, "imu", None, accel, mag)
    assert res.index.size == len(t_ns)
    return res.q, s.aiding


def static(rot: Rotation, seconds: float, rng=None, b_enu=B_ENU, hard_iron=(0.0, 0.0, 0.0)):
    """A still body at ``rot`` (body→ENU): stamps, gyro, accel, mag, truth."""
    n = int(seconds * FS)
    t = (np.arange(n) * (1e9 / FS)).astype(np.int64)
    f = np.tile(rot.apply([0.0, 0.0, G], inverse=True), (n, 1))
    m = np.tile(rot.apply(b_enu, inverse=True) + np.asarray(hard_iron), (n, 1))
    w = np.zeros((n, 3))
    if rng is not None:
        w += rng.normal(0, 0.002, w.shape)
        f += rng.normal(0, 0.02, f.shape)
        m += rng.normal(0, 0.1e-6, m.shape)
    return t, w, f, m, np.tile(rot.as_quat(), (n, 1))


def test_butterworth_has_unit_dc_gain_and_half_power_at_its_cutoff():
    tau, dt = 3.0, 0.005
    b0, b1, b2, a1, a2 = _butterworth2(tau, dt)
    assert (b0 + b1 + b2) / (1 + a1 + a2) == pytest.approx(1.0, rel=1e-8)  # 1+a1+a2 ~ 1e-5
    fc = math.sqrt(2) / (2 * math.pi * tau)
    z = np.exp(-2j * math.pi * fc * dt)
    h = (b0 + b1 * z + b2 * z * z) / (1 + a1 * z + a2 * z * z)
    assert abs(h) ** 2 == pytest.approx(0.5, rel=1e-6)


def test_the_low_pass_goes_on_from_its_output_when_its_time_constant_switches():
    """At a rest the low-pass runs with the short rest time constant, in motion with the long
    one: a constant specific force must come out unchanged across the switch (a second-order
    state kept as it was swells the output ~4x for seconds after a 0.5 s -> 3 s switch)."""
    f = np.array([0.0, 0.0, 9.8])  # level: no correction rotates the filter's state
    s = AttitudeStream(config=StreamConfig(ahrs_rest_accel_tau_s=0.5, ahrs_accel_tau_s=3.0,
                                           aiding="tilt", gyro_bias="none"))
    aid = s.aiding
    seen = []
    for k in range(2000):  # 10 s at 200 Hz: 4 s still (a rest from 1 s on), then a turn
        rate = (0.0, 0.0, 0.0) if k < 800 else (0.0, 0.0, 0.2)  # about the vertical: f stays
        s.push(10**9 + k * 5_000_000, rate, "imu", None, f)
        if k >= 700:
            seen.append(aid.af[A_LP_OUT:A_LP_OUT + 3].copy())
    assert aid.at_rest is False
    np.testing.assert_allclose(np.array(seen), np.tile(f, (len(seen), 1)), rtol=1e-9)


def test_tilt_converges_to_the_static_tilt_from_a_level_start():
    truth = Rotation.from_euler("xyz", [12.0, -7.0, 30.0], degrees=True)
    t, w, f, m, qt = static(truth, 20.0, np.random.default_rng(1))
    q, aid = aided_run(t, w, f, [0, 0, 0, 1.0], m)
    assert tilt_deg(q[-1], qt[-1]) < 0.05
    assert aid.aided_samples > 0 and aid.at_rest


def test_a_wrong_start_takes_the_mean_vertical_of_the_first_samples_at_once():
    """From a start 14° off, the tilt is the accelerometer's vertical averaged over the samples
    so far (as VQF), not a low-pass moving over accel_tau_s (which leaves most of the 14° after
    0.5 s): within 0.2° after 0.5 s at rest, 0.1° after 1 s."""
    truth = Rotation.from_euler("xyz", [12.0, -7.0, 30.0], degrees=True)
    t, w, f, m, qt = static(truth, 1.0, np.random.default_rng(2))
    q, _ = aided_run(t, w, f, [0, 0, 0, 1.0])
    assert tilt_deg(q[0], qt[0]) > 13.0  # the first sample has no interval to correct over
    assert tilt_deg(q[int(0.5 * FS):], qt[int(0.5 * FS):]).max() < 0.2
    assert tilt_deg(q[-1], qt[-1]) < 0.1


def test_heading_is_taken_from_the_field_and_points_to_magnetic_north():
    truth = Rotation.from_euler("xyz", [5.0, 3.0, 123.0], degrees=True)
    t, w, f, m, qt = static(truth, 15.0, np.random.default_rng(2))
    q, aid = aided_run(t, w, f, [0, 0, 0, 1.0], m)
    assert heading_deg(q[-1], qt[-1]) < 0.2
    assert aid.heading_initialized and aid.mag_used > 0


def test_declination_turns_the_heading_to_true_north():
    # a field 10° east of true north; with declination 10° the estimate is the true heading,
    # without it the estimate is off by the declination
    decl = 10.0
    b = np.array([16e-6 * math.sin(math.radians(decl)), 16e-6 * math.cos(math.radians(decl)),
                  -41e-6])
    truth = Rotation.from_euler("z", 40.0, degrees=True)
    t, w, f, m, qt = static(truth, 10.0, b_enu=b)
    q_true_north, _ = aided_run(t, w, f, [0, 0, 0, 1.0], m,
                                    config=StreamConfig(magnetic_declination_deg=decl))
    q_magnetic, _ = aided_run(t, w, f, [0, 0, 0, 1.0], m)
    assert heading_deg(q_true_north[-1], qt[-1]) < 0.05
    assert heading_deg(q_magnetic[-1], qt[-1]) == pytest.approx(decl, abs=0.05)


def _sustained_acceleration(accel_x):
    """Level, still in rotation, 20 s at rest, then ``accel_x`` m/s² along x for 20 s."""
    n = int(40 * FS)
    t = (np.arange(n) * (1e9 / FS)).astype(np.int64)
    f = np.zeros((n, 3))
    f[:, 2] = G
    f[n // 2:, 0] = accel_x
    return t, np.zeros((n, 3)), f


def test_sustained_acceleration_pulls_the_tilt_by_the_rejection_angle_only():
    t, w, f = _sustained_acceleration(2.0)  # the apparent vertical tilts by atan(2/9.81)=11.5°
    q, aid = aided_run(t, w, f, [0, 0, 0, 1.0])
    tilt = tilt_deg(q, np.array([0, 0, 0, 1.0]))
    assert tilt.max() < 4.0
    assert aid.accel_rejected > 0
    # without the rejection the filter follows the apparent vertical
    q_free, _ = aided_run(t, w, f, [0, 0, 0, 1.0],
                              config=StreamConfig(ahrs_accel_reject_deg=180.0,
                                                                 ahrs_accel_norm_tol=1e3))
    assert tilt_deg(q_free, np.array([0, 0, 0, 1.0])).max() > 10.0


def test_a_rest_after_a_real_tilt_error_is_corrected_by_the_recovery():
    # started 8° off: the first seconds (a new low-pass) trust the accelerometer in full
    truth = Rotation.from_euler("x", 8.0, degrees=True)
    t, w, f, m, qt = static(truth, 30.0)
    q, aid = aided_run(t, w, f, [0, 0, 0, 1.0])
    assert tilt_deg(q[-1], qt[-1]) < 0.05


def _turning(seconds=60.0, rate=(0.0, 0.0, 0.3), b_enu=B_ENU, hard_iron=(0.0, 0.0, 0.0)):
    """A level body turning at a constant body rate: exact truth by composition."""
    n = int(seconds * FS)
    t = (np.arange(n) * (1e9 / FS)).astype(np.int64)
    w = np.tile(np.asarray(rate, float), (n, 1))
    rot = Rotation.from_rotvec(w * (np.arange(n) / FS)[:, None])
    f = rot.apply([0.0, 0.0, G], inverse=True)
    m = rot.apply(b_enu, inverse=True) + np.asarray(hard_iron)
    return t, w, f, m, rot.as_quat()


def test_a_magnet_brought_near_does_not_turn_the_heading():
    t, w, f, m, qt = _turning()
    disturbed = (t > 20e9) & (t < 35e9)
    magnet = np.array([30e-6, -20e-6, 10e-6])  # fixed to the body, like a magnet carried along
    m_bad = m.copy()
    m_bad[disturbed] += magnet
    q, aid = aided_run(t, w, f, [0, 0, 0, 1.0], m_bad)
    err = heading_deg(q, qt)
    # exact gyro, so the gyro-only drift over the disturbance is ~0
    assert err[disturbed].max() < 0.05
    assert aid.mag_disturbed > 0.9 * np.count_nonzero(disturbed)
    assert aid.mag_reference_changes == 0


def test_a_steady_new_field_becomes_the_reference_after_the_recovery_time():
    t, w, f, m, qt = _turning(60.0)
    later = t > 20e9
    m2 = m.copy()
    m2[later] *= 1.3  # a steady 30 % stronger field from 20 s (another building)
    _, aid = aided_run(t, w, f, [0, 0, 0, 1.0], m2, config=StreamConfig(mag_recovery_s=15.0))
    assert aid.mag_reference_changes == 1
    assert aid.mag_ref_norm == pytest.approx(1.3 * np.linalg.norm(B_ENU), rel=0.01)


@pytest.mark.parametrize("bad", ["nan", "huge", "zero", "flip", "inf"])
def test_bad_field_samples_are_counted_and_the_heading_holds(bad):
    t, w, f, m, qt = _turning(40.0)
    sel = (t > 15e9) & (t < 38e9)
    mb = m.copy()
    mb[sel] = {"huge": 1e300, "zero": 0.0, "inf": np.inf}.get(bad, 0.0) \
        if bad != "flip" else -m[sel]
    if bad == "nan":  # NaN on one axis (a row of NaN is no field at all: mag_missing)
        mb[sel] = m[sel]
        mb[sel, 0] = np.nan
    q, aid = aided_run(t, w, f, [0, 0, 0, 1.0], mb)
    assert np.isfinite(q).all()
    assert heading_deg(q, qt)[sel].max() < 0.05
    counted = aid.mag_disturbed if bad == "flip" else aid.mag_invalid
    assert counted >= np.count_nonzero(sel) - 1
    assert aid.mag_reference_changes == 0  # a flipped field is never taken for a new reference


def test_hard_iron_given_is_taken_out():
    hi = (20e-6, -10e-6, 5e-6)
    truth = Rotation.from_euler("z", 70.0, degrees=True)
    t, w, f, m, qt = static(truth, 10.0, hard_iron=hi)
    q_given, _ = aided_run(t, w, f, [0, 0, 0, 1.0], m, config=StreamConfig(mag_hard_iron_t=tuple(hi)))
    q_ignored, _ = aided_run(t, w, f, [0, 0, 0, 1.0], m)
    assert heading_deg(q_given[-1], qt[-1]) < 0.05
    assert heading_deg(q_ignored[-1], qt[-1]) > 5.0


def test_hard_iron_is_estimated_by_the_sphere_fit_when_the_body_turns_about_two_axes():
    hi = np.array([20e-6, -10e-6, 5e-6])
    parts = [_turning(21.0, (0.3, 0.0, 0.0), hard_iron=hi), _turning(21.0, (0.0, 0.3, 0.0),
                                                                     hard_iron=hi)]
    m = np.concatenate([p[3] for p in parts])
    f = np.concatenate([p[2] for p in parts])
    w = np.concatenate([p[1] for p in parts])
    t = (np.arange(m.shape[0]) * (1e9 / FS)).astype(np.int64)
    _, aid = aided_run(t, w, f, [0, 0, 0, 1.0], m,
                           config=StreamConfig(mag_hard_iron_estimate=True))
    assert aid.hard_iron_fits > 0
    np.testing.assert_allclose(aid.hard_iron, hi, atol=0.2e-6)
    assert aid.mag_ref_norm == pytest.approx(np.linalg.norm(B_ENU), rel=1e-3)


def test_hard_iron_fit_refuses_a_field_seen_from_one_direction_only():
    t, w, f, m, qt = static(Rotation.identity(), 10.0, np.random.default_rng(3),
                            hard_iron=(20e-6, 0, 0))
    _, aid = aided_run(t, w, f, qt[0], m, config=StreamConfig(mag_hard_iron_estimate=True))
    assert aid.hard_iron_fits == 0 and aid.hard_iron == [0.0, 0.0, 0.0]


def _fit_sums(points_ut):
    """The sphere-fit sums of field samples (µT) as AhrsFilter accumulates them."""
    x, y, z = points_ut.T
    r = x * x + y * y + z * z
    return [np.sum(v) for v in (x * x, x * y, x * z, y * y, y * z, z * z, x, y, z,
                                np.ones_like(x), r * x, r * y, r * z, r)]


@pytest.mark.parametrize("seed", range(40))
def test_hard_iron_solve_agrees_with_numpy_least_squares_and_eigenvalues(seed):
    # Oracle: numpy's lstsq of the same sphere fit and eigvalsh of the field's scatter.  The
    # field directions span a cap of random width about a random axis, stretched along a
    # random direction: some fits are accepted, others refused for too little spread.
    import gyro_attitude.core.attitude.ahrs as ahrs

    rng = np.random.default_rng(seed)
    b = rng.uniform(-30.0, 30.0, 3)
    u = rng.standard_normal((400, 3))
    u *= rng.uniform(0.05, 1.0, 3)  # less spread along some axes
    u += rng.uniform(0.0, 2.0) * rng.standard_normal(3)  # toward one direction
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    pts = b + 45.0 * (Rotation.random(random_state=seed).apply(u)) + 0.05 * rng.standard_normal(
        (400, 3))
    aid = AhrsFilter(StreamConfig(mag_hard_iron_estimate=True))
    aid.af[ahrs.A_HI_SUMS:ahrs.A_HI_SUMS + 14] = _fit_sums(pts)
    ahrs._solve_hard_iron(aid.pa, aid.af, aid.ai)
    design = np.column_stack([2.0 * pts, np.ones(len(pts))])
    sol = np.linalg.lstsq(design, np.sum(pts * pts, axis=1), rcond=None)[0]
    r = math.sqrt(sol[3] + sol[:3] @ sol[:3])
    spread = np.linalg.eigvalsh(np.cov(pts.T, bias=True))[0]
    expected = 5.0 <= r <= 1000.0 and spread >= (r / 3.0) ** 2 / 3.0
    assert aid.hard_iron_fits == int(expected)
    if expected:
        np.testing.assert_allclose(np.array(aid.hard_iron) * 1e6, sol[:3], rtol=1e-7, atol=1e-7)


@pytest.mark.parametrize("name,value", [
    ("ahrs_accel_tau_s", 0.0), ("ahrs_mag_tau_s", math.nan), ("magnetic_declination_deg", 400.0),
    ("mag_hard_iron_t", (1, 2)), ("mag_reference_enu_t", (0.0, 0.0, 1.0)),
    ("mag_hard_iron_estimate", "yes"), ("ahrs_accel_reject_deg", True),
    ("ahrs_rest_min_s", -1.0), ("ahrs_rest_accel_tau_s", 0.0), ("mag_hard_iron_window_s", 0.5)])
def test_bad_settings_are_refused_naming_the_setting(name, value):
    with pytest.raises(ValueError, match=name):
        AhrsFilter(StreamConfig(**{name: value}))


def test_a_field_reference_too_weak_to_be_a_field_is_refused_naming_the_setting():
    with pytest.raises(ValueError, match="mag_reference_enu_t"):
        AhrsFilter(StreamConfig(mag_reference_enu_t=(0.0, 0.0, -1e-9)))


def test_latest_sample_rule_is_the_same_for_arrays_and_the_live_buffer():
    from gyro_attitude.core.attitude.sample_alignment import LatestSamples, latest_at

    t = np.array([10, 20, 30, 40, 50, 200], dtype=np.int64)
    src = np.array([5, 20, 21, 35, 35], dtype=np.int64)  # equal stamps: the later one wins
    vals = np.arange(15, dtype=float).reshape(5, 3)
    rows = latest_at(t, src, vals, max_age_ns=15)
    expect = [vals[0], vals[1], vals[2], vals[4], vals[4], None]
    live = LatestSamples(15)
    for k, tk in enumerate(t):
        for j in np.flatnonzero(src <= tk):
            if all(j_ != j for j_ in getattr(live, "_seen", [])):
                live.add(int(src[j]), vals[j])
                live._seen = [*getattr(live, "_seen", []), j]
        got = live.at(int(tk))
        if expect[k] is None:
            assert np.isnan(rows[k]).all() and got is None
        else:
            np.testing.assert_array_equal(rows[k], expect[k])
            np.testing.assert_array_equal(got, expect[k])


@pytest.mark.parametrize("world,axes", [
    ("enu", np.eye(3)),
    ("ned", np.array([[0, 1, 0], [1, 0, 0], [0, 0, -1.0]])),  # rows: ENU axes in NED
    ("nwu", np.array([[0, -1, 0], [1, 0, 0], [0, 0, 1.0]])),
])
def test_world_frame_expresses_the_same_body_axes_in_the_chosen_world(world, axes):
    from gyro_attitude.core.attitude.modes import WorldFrame
    from gyro_attitude.core.attitude.world_frame import from_enu, from_enu_one

    rng = np.random.default_rng(7)
    q = Rotation.random(20, random_state=rng).as_quat()
    r_enu = Rotation.from_quat(q).as_matrix()  # body -> ENU
    # world coordinates of a vector = (ENU -> world) of its ENU coordinates
    enu_to_world = axes.T
    expect = enu_to_world @ r_enu
    got = Rotation.from_quat(from_enu(q, WorldFrame(world))).as_matrix()
    np.testing.assert_allclose(got, expect, atol=1e-12)
    one = np.array([from_enu_one(tuple(qk), WorldFrame(world)) for qk in q])
    np.testing.assert_allclose(one, from_enu(q, WorldFrame(world)), atol=1e-15)
    # a level body facing north has zero yaw in NED and NWU (x north)
    if world != "enu":
        north = Rotation.from_euler("z", 90, degrees=True).as_quat()
        yaw = Rotation.from_quat(from_enu(north, WorldFrame(world))).as_euler("zyx")[0]
        assert abs(yaw) < 1e-12
