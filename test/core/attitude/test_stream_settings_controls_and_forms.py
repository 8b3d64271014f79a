"""Attitude-stream and validation cases: setting bounds that name
the field, the stream state run() leaves, nav time series over skipped samples, the per-sample
result, integrating the samples since the last rest after levelling, the live-node controls
(restart, set_config, set_algorithm, update_nav) and the interval statistics."""

import math
import re

import numpy as np
import pytest
from attitude_truth import nav_rate_written_out
from scipy.spatial.transform import Rotation

from gyro_attitude.core.attitude import NavFrame, chain, integrate_batch
from gyro_attitude.core.attitude import validation as iv
from gyro_attitude.core.attitude.settings import check_gyrocompass_feasible
from gyro_attitude.core.attitude.stream import (
    ALIGNING,
    INTEGRATOR_ERROR,
    INVALID_COVARIANCE,
    RUNNING,
    AttitudeStream,
    StreamConfig,
    bias_summary,
    covariance_rows,
)

MS = 1_000_000
G = 9.80665
OMEGA_IE = 7.292115e-5  # docs/equations.md conventions, written out


def angle(a, b):
    return (Rotation.from_quat(a).inv() * Rotation.from_quat(b)).magnitude()


# ------------------------------------------------------------------------- settings
# (field, lowest, highest) as StreamConfig documents them
BOUNDS = [
    ("initial_attitude_variance", 0.0, 10.0),
    ("gyro_noise_density", 0.0, 1.0),
    ("gyro_bias_sigma_rad_s", 0.0, 10.0),
    ("gyro_bias_rw", 0.0, 1.0),
    ("initial_heading_deg", -360.0, 360.0),
    ("accel_bias_sigma", 0.0, 10.0),
    ("heading_error_limit_deg", 0.0, 180.0),
    ("max_gap_s", 1e-6, 1e6),
    ("min_rest_s", 0.01, 3600.0),
]


@pytest.mark.parametrize("name, lo, hi", BOUNDS)
def test_setting_bounds_are_inclusive_and_refusals_name_the_field(name, lo, hi):
    StreamConfig(**{name: lo})
    StreamConfig(**{name: hi})
    for bad in (hi + 0.5, lo - 0.5, None, True, "1"):
        with pytest.raises(ValueError, match=rf"^{name} must be a (finite )?number"):
            StreamConfig(**{name: bad})


def test_latitude_bounds_are_the_poles():
    for lat in (-math.pi / 2, math.pi / 2, 0.0):
        StreamConfig(latitude_rad=lat)
    for bad in (-math.pi / 2 - 1e-9, math.pi / 2 + 1e-9, math.nan):
        with pytest.raises(ValueError, match="^latitude_rad must be"):
            StreamConfig(latitude_rad=bad)


def test_gyro_bias_vector_must_be_three_bounded_numbers():
    StreamConfig(gyro_bias="parameter", gyro_bias_rad_s=(-1e3, 0.0, 1e3))
    for bad in ((1.0, 2.0), 5, "abc", (1.0, 2.0, 3.0, 4.0)):
        with pytest.raises(ValueError, match=r"^gyro_bias_rad_s must be 3 numbers"):
            StreamConfig(gyro_bias="parameter", gyro_bias_rad_s=bad)
    for bad in ((0.0, 0.0, 1000.5), (-1000.5, 0.0, 0.0), (0.0, math.inf, 0.0)):
        with pytest.raises(ValueError, match=r"^gyro_bias_rad_s must be a finite number"):
            StreamConfig(gyro_bias="parameter", gyro_bias_rad_s=bad)


@pytest.mark.parametrize("name, value", [("gyro_bias", "fixed"), ("initial_attitude_source", "nav"),
                                         ("heading_source", "compass"), ("aiding", "mag")])
def test_choices_name_the_field(name, value):
    with pytest.raises(ValueError, match=rf"^{name} must be one of"):
        StreamConfig(**{name: value})


def test_gyrocompass_settings_name_what_is_missing():
    ok = dict(initial_attitude_source="level", heading_source="gyrocompass", gyro_bias="parameter",
              gyro_bias_sigma_rad_s=1e-7)
    StreamConfig(**ok)
    with pytest.raises(ValueError, match="needs initial_attitude_source 'level'"):
        StreamConfig(**{**ok, "initial_attitude_source": "parameter"})
    # a stated bias with no stated uncertainty, and an estimated bias, are both refused
    for bad in ({"gyro_bias_sigma_rad_s": 0.0}, {"gyro_bias": "auto"}):
        with pytest.raises(ValueError, match="gyro_bias 'parameter' with its 1σ "
                                             "gyro_bias_sigma_rad_s > 0"):
            StreamConfig(**{**ok, **bad})


def test_gyrocompass_refusal_threshold_and_figures():
    # heading error σ_b / (ω_ie cos L) against the limit; at 60° N the horizontal Earth rate
    # is ω_ie/2 ≈ 7.52 °/h
    lat = math.radians(60.0)
    horizontal = OMEGA_IE * math.cos(lat)
    good = StreamConfig(heading_error_limit_deg=5.0,
                        gyro_bias_sigma_rad_s=horizontal * math.radians(4.9))
    check_gyrocompass_feasible(good.gyro_bias_sigma_rad_s, lat, 5.0)
    bad = StreamConfig(heading_error_limit_deg=5.0,
                       gyro_bias_sigma_rad_s=horizontal * math.radians(6.0))
    with pytest.raises(ValueError, match="gyrocompass refused") as exc:
        check_gyrocompass_feasible(bad.gyro_bias_sigma_rad_s, lat, 5.0)
    nums = [float(x) for x in re.findall(r"([0-9.]+(?:e[-+]?\d+)?) ?°", str(exc.value))]
    expected = [math.degrees(bad.gyro_bias_sigma_rad_s) * 3600, math.degrees(horizontal) * 3600,
                6.0, 5.0]
    np.testing.assert_allclose(nums, expected, rtol=2e-3)  # printed to 3 figures


# ------------------------------------------------------------------------- covariance rows
COV_TABLE = [  # row-major 3x3 → (variances or None, invalid)
    ([-1.0] + [0.0] * 8, None, False),  # REP-145 "no estimate"
    ([-1.0, 0, 0, 0, -1.0, 0, 0, 0, math.nan], None, False),  # element 0 = −1 wins
    ([0.0] * 9, None, False),  # all zeros: unknown
    ([0.0, 1e-9, 0, 0, 0, 0, 0, 0, 0], [0.0, 0.0, 0.0], False),  # zero diagonal, not all zero
    ([0.0, 0, 0, 0, 2e-6, 0, 0, 0, 3e-6], [0.0, 2e-6, 3e-6], False),  # a zero variance is known
    ([1e-6, 0, 0, 0, 2e-6, 0, 0, 0, 3e-6], [1e-6, 2e-6, 3e-6], False),
    ([1.0, 0, 0, 0, 1.0, 0, 0, 0, 1.0], [1.0, 1.0, 1.0], False),  # +1 in element 0 is data
    ([math.nan] + [0.0] * 8, None, True),
    ([1.0, 0, 0, 0, -1.0, 0, 0, 0, 1.0], None, True),
    ([1.0, 0, 0, 0, 1.0, 0, 0, 0, math.inf], None, True),
]


def test_covariance_rows_written_out():
    """The offline estimator's rows and the causal step judge a covariance alike (one
    verdict kernel): as the table says, row by row, and for one row repeated as a read-only
    view (what the array reader returns for a constant covariance)."""
    table = np.array([c for c, _, _ in COV_TABLE])
    counts, details = {}, {}
    var, known = covariance_rows(table, np.arange(len(COV_TABLE)), counts, details)
    assert counts[INVALID_COVARIANCE] == sum(bad for _, _, bad in COV_TABLE)
    for k, (cov, expected, bad) in enumerate(COV_TABLE):
        assert bool(known[k]) == (expected is not None), cov
        if expected is not None:
            np.testing.assert_array_equal(var[k], expected)
        # the causal step: a known covariance gives a variance, an invalid one is counted
        s = AttitudeStream("exp_map")
        s.push(MS, [0.0, 0.0, 0.0], "imu", cov)
        s.push(2 * MS, [0.0, 0.0, 0.0], "imu", cov)
        assert (s.counts[INVALID_COVARIANCE] == 2) == bad, cov
        assert (s.variance is not None) == (expected is not None), cov
    for cov, expected, bad in COV_TABLE:
        counts = {}
        var, known = covariance_rows(np.broadcast_to(cov, (5, 9)), np.arange(5), counts, {})
        assert var.shape == (5, 3) and known.shape == (5,)
        assert counts[INVALID_COVARIANCE] == 5 * bad and known.tolist() == [expected is not None] * 5
        if expected is not None:
            np.testing.assert_array_equal(var, [expected] * 5)


# ------------------------------------------------------------------------- interval statistics
def test_interval_summary_of_two_intervals_written_out():
    ring, fill = np.zeros(2, np.int64), np.zeros(2, np.int64)
    stats = iv.IntervalStatistics(ring, fill)
    iv.interval_add(ring, fill, 5 * MS)
    one = stats.summary()  # one interval: no figures yet
    assert set(one) == {"rate_hz", "mean_dt_s", "jitter_s", "max_dt_s"}
    assert all(math.isnan(x) for x in one.values())
    for dt in (10 * MS, 20 * MS):
        iv.interval_add(ring, fill, dt)
    # the oldest one left the window
    assert stats.summary() == pytest.approx({"rate_hz": 1 / 0.015, "mean_dt_s": 0.015,
                                             "jitter_s": 0.005, "max_dt_s": 0.020}, rel=1e-12)


# ------------------------------------------------------------------------- run() vs push()
def hostile(n=300):
    """1 kHz, constant rate about z, with two non-finite and two absurd rates, a zero, a
    duplicate and an out-of-order stamp, a changed frame, a 0.5 s gap and a 2 s jump back."""
    t = 10_000_000_000 + np.arange(n, dtype=np.int64) * MS
    w = np.tile([0.0, 0.0, 0.4], (n, 1))
    frames = ["imu"] * n
    w[10], w[11], w[12], w[13] = [np.nan, 0, 0], [0, np.inf, 0], [2e4, 0, 0], [0, 0, -1e200]
    t[20] = 0
    t[30] = t[29]
    t[40] = t[39] - 3 * MS
    frames[50] = "other"
    t[100:] += 500 * MS
    t[200:] -= 2_500 * MS
    return t, w, frames


HOSTILE_COUNTS = {iv.NON_FINITE: 2, iv.IMPLAUSIBLE_RATE: 2, iv.ZERO_STAMP: 1,
                  iv.DUPLICATE_STAMP: 1, iv.OUT_OF_ORDER: 1, iv.FRAME_CHANGED: 1, iv.GAP: 1}


def test_run_leaves_the_stream_where_push_would():
    t, w, frames = hostile()
    cfg = StreamConfig(gyro_bias="none")
    s = AttitudeStream("exp_map", config=cfg)
    s.run(t, w, frames)
    assert {k: s.counts[k] for k in HOSTILE_COUNTS} == HOSTILE_COUNTS
    assert s.counts[INTEGRATOR_ERROR] == 0
    assert s.accepted == t.size - 8 and s.rejected_total == 8  # a gap is no rejection
    assert s.time_jump_resets == 1 and s.last_t_ns == int(t[-1])
    # the frame stays locked: another frame is refused, the locked one integrates on
    verdict, q = s.push(int(t[-1]) + MS, w[-1], "other")
    assert verdict.reason == iv.FRAME_CHANGED and q is None
    q_before = s.quaternion
    verdict, q = s.push(int(t[-1]) + 2 * MS, w[-1], "imu")
    assert verdict.action == iv.ACCEPT
    # exp_map, constant rate: one 2 ms interval about z on top of the held attitude
    expected = (Rotation.from_quat(q_before) * Rotation.from_rotvec([0, 0, 0.4 * 2e-3])).as_quat()
    assert angle(q, expected) < 1e-15


def test_run_slices_nav_time_series_to_the_accepted_samples():
    # A NavFrame whose latitude and velocity are series over the input rows: the batch path
    # integrates each accepted run with the rows of those samples (skipped rows dropped).
    n = 120
    t = 10_000_000_000 + np.arange(n, dtype=np.int64) * 10 * MS
    w = np.tile([0.01, -0.02, 0.03], (n, 1))
    w[30] = np.nan
    w[31] = [0, 0, 2e4]
    lat = np.linspace(0.3, 0.9, n)
    vel = np.column_stack([np.linspace(0, 250, n), np.linspace(100, -100, n), np.zeros(n)])
    nav = NavFrame(lat, velocity_enu=vel)
    res = AttitudeStream("rotvec_cubic", config=StreamConfig(gyro_bias="none"),
                         nav=nav).run(t, w, "imu")
    keep = np.r_[0:30, 32:n]
    expected = integrate_batch(t[keep], w[keep], (0, 0, 0, 1), "rotvec_cubic",
                               nav=NavFrame(lat[keep], velocity_enu=vel[keep]))
    assert res.index.tolist() == keep.tolist()
    assert angle(res.q, expected).max() < 1e-15
    # the nav rate is not the same on every row: a shifted slice would be seen
    assert angle(integrate_batch(t[keep], w[keep], (0, 0, 0, 1), "rotvec_cubic",
                                 nav=NavFrame(lat[:-2], velocity_enu=vel[:-2])),
                 expected).max() > 1e-9


def test_constant_velocity_of_three_samples_is_not_a_series():
    # velocity_enu (3,) on a recording of 3 samples is still one constant velocity
    t = np.array([1, 2, 3], dtype=np.int64) * 10 * MS
    w = np.tile([0.0, 0.0, 0.1], (3, 1))
    w[1] = np.nan
    v = (200.0, -50.0, 0.0)
    res = AttitudeStream("exp_map", config=StreamConfig(gyro_bias="none"),
                         nav=NavFrame(0.8, velocity_enu=v)).run(t, w, "imu")
    rate_n = nav_rate_written_out(0.8, 0.0, v)
    h = 20e-3
    expected = (Rotation.from_rotvec(-rate_n * h) * Rotation.from_rotvec([0, 0, 0.1 * h]))
    assert res.index.tolist() == [0, 2]
    assert angle(res.q[1], expected.as_quat()) < 1e-15


def test_per_sample_run_result_fields():
    # auto bias on a recording that rests, hostile samples inside: run() on arrays
    t, w, frames = hostile()
    # at rest (with the noise every real gyro shows): the auto bias has rests to act on
    w[:] = 1e-6 * np.random.default_rng(1).normal(size=w.shape)
    w[10], w[11], w[12], w[13] = [np.nan, 0, 0], [0, np.inf, 0], [2e4, 0, 0], [0, 0, -1e200]
    cov = np.tile(np.diag([1e-6, 1e-6, 1e-6]).reshape(9), (t.size, 1))
    cov[:5] = 0.0  # no estimate on the first rows
    s = AttitudeStream("exp_map", config=StreamConfig(min_rest_s=0.05, rest_window_s=0.02))
    res = s.run(t, w, frames, cov)
    assert res.index.dtype == np.int64 and res.q.shape == (res.index.size, 4)
    assert {k: res.counts[k] for k in HOSTILE_COUNTS} == HOSTILE_COUNTS
    assert res.time_jump_resets == 1 and res.skipped == 8
    assert set(res.details) >= {iv.NON_FINITE, iv.FRAME_CHANGED, iv.GAP, "time_jump"}
    # rows before the first covariance have no variance estimate (zeros), later ones do
    first = int(np.flatnonzero(res.index >= 5)[0])
    assert not res.variance_known[:first].any() and res.variance_known[first:].all()
    np.testing.assert_array_equal(res.variance[:first], 0.0)
    assert (res.variance[first + 1:] >= 0).all() and (res.variance[first + 1] > 0).all()


# ------------------------------------------------------------------------- level alignment
def test_level_then_turn_integrates_from_the_last_rest_sample():
    # Noise-free: level at rest (pitch 5°, roll −3°, heading 30°), then a constant turn r about
    # body z from sample m on, with a stated gyro bias b on every sample.  With the trapezoid
    # (exp_map) the turn angle at sample k ≥ m is r h (k − m + ½) whatever zero-rate intervals
    # come before, so q_k = q_level ⊗ exp(r h (k − m + ½) z) exactly — provided the samples
    # since the last rest sample are integrated, with ω − b, from the levelled attitude.
    # The variance right after levelling: level error² on x, y; given heading variance plus
    # sin²θ · level error² on z (module comment); plus σ² h² per integrated interval.
    rate_hz, m, r = 100.0, 300, 0.5
    h = 1 / rate_hz
    n = 400
    q_true = Rotation.from_euler("ZYX", [60.0, 5.0, -3.0], degrees=True)  # ENU yaw 60° = 30° hdg
    b = np.array([0.003, -0.002, 0.001])
    t = np.arange(1, n + 1, dtype=np.int64) * 10 * MS
    g = np.tile(b, (n, 1))
    g[m:, 2] += r
    f = np.tile(q_true.inv().apply([0.0, 0.0, G]), (n, 1))
    sigma2 = 4e-8
    cov = np.tile(np.diag([sigma2] * 3).reshape(9), (n, 1))
    cfg = StreamConfig(initial_attitude_source="level", initial_heading_deg=30.0, gyro_bias="parameter",
                       gyro_bias_rad_s=tuple(b), initial_attitude_variance=1e-4, min_rest_s=1.0,
                       aiding="none")
    s = AttitudeStream("exp_map", config=cfg)
    first = None
    for k in range(n):
        _, q = s.push(int(t[k]), g[k], "imu", cov[k], f[k])
        if q is None:
            assert s.phase == ALIGNING and first is None
            continue
        if first is None:
            first = k
            assert k >= m  # the rest ends with the turn
            al = s.alignment
            assert al.rest_end_ns <= t[m - 1]
            intervals = k - int(np.flatnonzero(t == al.rest_end_ns)[0])
            lv = al.level_error_expected ** 2
            expected_var = np.array([lv, lv, 1e-4 + math.sin(al.pitch) ** 2 * lv])
            np.testing.assert_allclose(s.variance, expected_var + intervals * sigma2 * h * h,
                                       rtol=1e-12, atol=0)
            q_level = Rotation.from_quat(al.q_nb)
            assert q_level.magnitude() > 0.5  # the levelled attitude is far from q0
        expected = q_level * Rotation.from_rotvec([0.0, 0.0, r * h * (k - m + 0.5)])
        assert angle(q, expected.as_quat()) < 1e-12, k  # rounding of ≤ 100 products
    assert first is not None and s.phase == RUNNING


def test_level_without_accelerometer_says_so_and_failure_is_kept():
    s = AttitudeStream(config=StreamConfig(initial_attitude_source="level"))
    _, q = s.push(MS, [0.0, 0.0, 0.0], "imu", None, None)
    assert q is None and "needs the accelerometer" in s.alignment_error
    # a usable sample clears the message
    s.push(2 * MS, [0.0, 0.0, 0.0], "imu", None, [0.0, 0.0, G])
    assert s.alignment_error is None
    s.state.phase[0] = chain.FAILED  # as after a refused alignment: nothing more is attempted
    assert s.push(3 * MS, [0.0, 0.0, 0.0], "imu", None, [0.0, 0.0, G])[1] is None


# ------------------------------------------------------------------------- live-node controls
def test_restart_forgets_time_base_and_frame_and_starts_from_q0():
    t = np.arange(1, 11, dtype=np.int64) * 10 * MS
    s = AttitudeStream("exp_map", config=StreamConfig(gyro_bias="none"))
    for k in range(10):
        s.push(int(t[k]), [0.0, 0.0, 1.0], "imu")
    q_new = Rotation.from_euler("x", 0.4).as_quat()
    s.restart(q_new)
    # an earlier stamp and another frame now start the stream afresh, from q_new
    verdict, q = s.push(5 * MS, [0.0, 0.0, 1.0], "other")
    assert verdict.action == iv.START
    np.testing.assert_allclose(q, q_new, rtol=0, atol=1e-15)
    assert angle(s.q_initial, q_new) < 1e-15
    s.restart()
    verdict, q = s.push(MS, [0.0, 0.0, 1.0], "imu")
    assert verdict.action == iv.START and angle(q, q_new) < 1e-15  # the new initial attitude


def test_set_config_takes_the_new_thresholds_and_keeps_the_rest():
    s = AttitudeStream(config=StreamConfig(gyro_bias="none", initial_attitude_variance=0.5))
    s.push(10 * MS, [1.0, 0.0, 0.0], "imu")
    s.set_config(StreamConfig(max_rate_rad_s=0.5, max_gap_s=5e-3, time_jump_threshold_s=7e-3,
                              initial_attitude_variance=0.1))
    assert (s.config.max_rate_rad_s, s.config.max_gap_ns, s.config.time_jump_ns,
            s.config.initial_attitude_variance) == (0.5, 5 * MS, 7 * MS, 0.5)
    assert s.push(11 * MS, [1.0, 0.0, 0.0], "imu")[0].reason == iv.IMPLAUSIBLE_RATE
    assert s.push(20 * MS, [0.1, 0.0, 0.0], "imu")[0].reason == iv.GAP
    assert s.push(12 * MS, [0.1, 0.0, 0.0], "imu")[0].action == iv.RESET_TIME_JUMP


def test_set_algorithm_keeps_attitude_and_time_base():
    s = AttitudeStream("rotvec_cubic", config=StreamConfig(gyro_bias="none"))
    for k in range(1, 6):
        s.push(k * 10 * MS, [0.0, 0.0, 1.0], "imu")
    q5 = s.quaternion
    s.set_algorithm("exp_map")
    assert s.algorithm == "exp_map"
    _, q = s.push(70 * MS, [0.0, 0.0, 1.0], "imu")
    # exp_map, constant rate: exactly 20 ms about z from the kept attitude and time
    expected = Rotation.from_quat(q5) * Rotation.from_rotvec([0.0, 0.0, 0.02])
    assert angle(q, expected.as_quat()) < 1e-15


def test_update_nav_takes_the_new_nav_rate():
    # at rest in ENU at 45°: the gyro measures ω_ie^n; after update_nav to a carrier at 250 m/s
    # east the body measuring ω_in^n of the new frame stays put in it
    lat = math.radians(45.0)
    v = (250.0, 0.0, 0.0)
    final = {}
    for switch in (True, False):
        s = AttitudeStream("exp_map", config=StreamConfig(gyro_bias="none"), nav=NavFrame(lat))
        s.push(10 * MS, nav_rate_written_out(lat, 0.0, (0, 0, 0)), "imu")
        if switch:
            s.update_nav(NavFrame(lat, velocity_enu=v))
            assert s.nav.velocity_enu == v
        for k in range(2, 12):
            _, q = s.push(k * 10 * MS, nav_rate_written_out(lat, 0.0, v), "imu")
        final[switch] = angle(q, (0, 0, 0, 1))
    # the first interval after the switch averages the old and new nav rates (documented), as
    # the trapezoid averages the old and new body rates: they cancel to rounding
    assert final[True] < 1e-15
    # with the old frame kept, 0.1 s of the transport rate (v/R ≈ 3.9e-5 rad/s, plus its
    # vertical part v tan L/R) turns the body ≈ 5e-6 rad
    assert final[False] > 3e-6



def test_bias_summary_line():
    s = AttitudeStream(config=StreamConfig(gyro_bias="parameter",
                                           gyro_bias_rad_s=(0.0123456789, 0.0, -0.5)))
    line = bias_summary(s.bias_report)
    assert line.startswith("gyro bias parameter: [0.012346, 0.0, -0.5] rad/s (")
    t = np.arange(1, 401, dtype=np.int64) * 10 * MS
    w = np.tile([0.005, -0.002, 0.003], (400, 1)) + 1e-4 * np.random.default_rng(0).normal(
        size=(400, 3))
    s = AttitudeStream(config=StreamConfig(min_rest_s=1.0))
    s.run(t, w, "imu")
    rep = s.bias_report
    assert rep.rests_used >= 1
    line = bias_summary(rep)
    assert line.startswith(f"gyro bias auto: {np.round(rep.bias, 6).tolist()} rad/s (± "
                           f"{np.round(rep.standard_error, 7).tolist()}, {rep.rests_used} "
                           f"rest(s), {rep.rest_samples} samples); ")


# ------------------------------------------------------------------------- stamp boundaries
def test_stamp_boundaries_array_wide_and_per_sample():
    # max_gap 50 ms, time jump 1 s; stamps chosen on each boundary, verdicts written out
    cfg = StreamConfig(max_gap_s=0.05, time_jump_threshold_s=1.0)
    base = 5_000 * MS
    steps = [  # (stamp, action, reason)
        (base, iv.START, None),
        (base + 1, iv.ACCEPT, None),  # 1 ns step
        (base + 1 + 50 * MS, iv.ACCEPT, None),  # exactly the gap limit
        (base + 2 + 100 * MS, iv.RESTART_AFTER_GAP, iv.GAP),  # 1 ns beyond it
        (base + 2 + 100 * MS, iv.REJECT, iv.DUPLICATE_STAMP),
        (base + 2 + 100 * MS - 1000 * MS, iv.REJECT, iv.OUT_OF_ORDER),  # exactly the jump
        (base + 1 + 100 * MS - 1000 * MS, iv.RESET_TIME_JUMP, None),  # 1 ns beyond it
        (base + 2 + 100 * MS - 1000 * MS, iv.ACCEPT, None),
        (base - 3000 * MS, iv.RESET_TIME_JUMP, None),  # a second jump
    ]
    t = np.array([s for s, _, _ in steps], dtype=np.int64)
    w = np.zeros((t.size, 3))
    cls = iv.classify(t, w, "imu", cfg)
    codes = {c: a for a, c in iv.ACTION_CODES.items()}
    assert [codes[int(c)] for c in cls.action] == [a for _, a, _ in steps]
    assert cls.time_jump_resets == 2
    assert cls.details[iv.GAP] == "gap of 50.000 ms"
    assert cls.details["time_jump"] == "time jumped back by 1.000 s"
    assert cls.details[iv.DUPLICATE_STAMP] == (f"stamp {base + 2 + 100 * MS} ns repeats the "
                                               "previous one")
    assert cls.details[iv.OUT_OF_ORDER] == (f"stamp {base + 2 - 900 * MS} ns is 1000.000 ms "
                                            "before the previous")
    val = AttitudeStream("rotvec_cubic", config=cfg.replace(gyro_bias="none"))
    for s, action, reason in steps:
        verdict = val.push(s, [0.0, 0.0, 0.0], "imu")[0]
        assert verdict.action == action and (reason is None or verdict.reason == reason), s
    assert val.time_jump_resets == 2


# ------------------------------------------------------------------------- counted details
def test_counted_problems_keep_their_first_detail():
    s = AttitudeStream("exp_map", config=StreamConfig(gyro_bias="none"))
    s.push(MS, [0.0, 0.0, 0.1], "imu", [1.0, 0, 0, 0, -1.0, 0, 0, 0, 1.0])
    s.push(2 * MS, [0.0, 0.0, 0.1], "imu", None, [math.nan, 0.0, 0.0])
    assert s.details["invalid_covariance"].startswith(
        "angular_velocity_covariance [1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 1.0] has a "
        "non-finite, negative or absurd diagonal")
    assert s.details["invalid_accel"].startswith("accelerometer sample [nan, 0.0, 0.0] is not")


def test_integrator_error_verdict():
    s = AttitudeStream("exp_map", config=StreamConfig(gyro_bias="none"))
    s.push(MS, [0.0, 0.0, 1.0], "imu")
    s.state.cubic_f[0][:4] = math.nan  # the integrator's attitude lost: the next step is not finite
    verdict, q = s.push(2 * MS, [0.0, 0.0, 1.0], "imu")
    assert q is None and verdict.rejected and verdict.reason == INTEGRATOR_ERROR
    assert verdict.detail == "non-finite attitude: last good one restored"
    assert s.details[INTEGRATOR_ERROR] == verdict.detail
    assert s.last_t_ns is None  # the next sample starts a fresh time base


# ------------------------------------------------------------------------- aligner settings
def test_gyrocompass_levelling_finds_north_with_the_stated_bias():
    # Static at 45° N, heading 30° (ENU yaw 60°), pitch 4°, roll −2°; the gyro measures
    # C_bn ω_ie^n + b (b stated), noise 1e-7 rad/s; then a turn about body z ends the rest.
    lat = math.radians(45.0)
    q_true = Rotation.from_euler("ZYX", [60.0, 4.0, -2.0], degrees=True)
    b = np.array([2e-5, -1e-5, 3e-5])
    n, m = 400, 300
    rng = np.random.default_rng(4)
    t = np.arange(1, n + 1, dtype=np.int64) * 10 * MS
    g = q_true.inv().apply([0.0, OMEGA_IE * math.cos(lat), OMEGA_IE * math.sin(lat)]) + b
    g = np.tile(g, (n, 1)) + 1e-7 * rng.normal(size=(n, 3))
    g[m:, 2] += 0.5
    f = np.tile(q_true.inv().apply([0.0, 0.0, G]), (n, 1))
    cfg = StreamConfig(initial_attitude_source="level", heading_source="gyrocompass",
                       gyro_bias="parameter", gyro_bias_rad_s=tuple(b), gyro_bias_sigma_rad_s=1e-7,
                       initial_heading_deg=123.0, latitude_rad=lat)
    s = AttitudeStream(config=cfg)
    for k in range(n):
        s.push(int(t[k]), g[k], "imu", None, f[k])
    al = s.alignment
    assert s.phase == RUNNING and al.heading_source == "gyrocompass"
    # σ_noise/(ω_ie cos L)/√samples ≈ 1e-7/5.2e-5/17 ≈ 1e-4 rad; an ignored bias (3.6e-5 rad/s
    # horizontal) would cost ~0.6 rad, the given 123° instead ~1.6 rad
    assert abs(al.heading - math.radians(30.0)) < 1e-3


def test_levelling_honours_the_configured_rest_thresholds():
    # gyro noise 1e-3 rad/s: a rest for the default thresholds, none for rest_gyro_std_max 1e-4
    n = 300
    rng = np.random.default_rng(5)
    t = np.arange(1, n + 1, dtype=np.int64) * 10 * MS
    g = 1e-3 * rng.normal(size=(n, 3))
    g[250:, 2] += 0.5
    f = np.tile([0.0, 0.0, G], (n, 1))
    for std_max, aligned in ((0.01, True), (1e-4, False)):
        s = AttitudeStream(config=StreamConfig(initial_attitude_source="level", rest_gyro_std_max=std_max))
        for k in range(n):
            s.push(int(t[k]), g[k], "imu", None, f[k])
        assert (s.phase == RUNNING) == aligned, std_max


# ------------------------------------------------------------------------- gravity aiding
def _tilt(q_est, q_true):
    u = Rotation.from_quat(q_est).inv().apply([0, 0, 1])
    v = Rotation.from_quat(q_true).inv().apply([0, 0, 1])
    return np.arccos(np.clip(np.sum(u * v, axis=-1), -1, 1))


def test_classify_reasons_counts_details_and_locked_frame_written_out():
    t = np.array([5, 0, -3, 1, 7, 8, 9, 10], dtype=np.int64)
    w = np.zeros((8, 3))
    w[0] = [np.nan, 0.0, 0.0]  # non-finite (and its frame "x" is not locked)
    w[1] = [0.0, 2e4, 0.0]  # implausible at a zero stamp: the value is named, not the stamp
    w[5] = [0.0, 0.0, 3e4]
    frames = ["x", "imu", "imu", "imu", "imu", "imu", "other", "imu"]
    cls = iv.classify(t, w, frames)  # default thresholds (1e4 rad/s)
    codes = {r: iv.REASON_NAMES.index(r) for r in iv.REJECT_REASONS}
    assert cls.reason.tolist() == [codes[iv.NON_FINITE], codes[iv.IMPLAUSIBLE_RATE],
                                   codes[iv.ZERO_STAMP], 0, 0, codes[iv.IMPLAUSIBLE_RATE],
                                   codes[iv.FRAME_CHANGED], 0]
    a = iv.ACTION_CODES
    assert cls.action.tolist() == [0, 0, 0, a[iv.START], a[iv.ACCEPT], 0, 0, a[iv.ACCEPT]]
    assert cls.frame_id == "imu" and cls.accepted == 3
    assert {r: cls.counts[r] for r in iv.REJECT_REASONS} == {
        iv.NON_FINITE: 1, iv.IMPLAUSIBLE_RATE: 2, iv.ZERO_STAMP: 1, iv.DUPLICATE_STAMP: 0,
        iv.OUT_OF_ORDER: 0, iv.FRAME_CHANGED: 1, iv.GAP: 0}
    assert cls.details == {
        iv.NON_FINITE: "non-finite value(s) [nan, 0.0, 0.0]",
        iv.IMPLAUSIBLE_RATE: "rate [0.0, 20000.0, 0.0] rad/s beyond max_rate_rad_s = 10000",
        iv.ZERO_STAMP: "stamp -3 ns is not positive (0: unset)",
        iv.FRAME_CHANGED: "frame_id 'other' differs from 'imu'"}
    # one frame for all, or None (no frame: ""), is what gets locked
    assert iv.classify(t[3:], w[3:] * 0, "imu").frame_id == "imu"
    assert iv.classify(t[3:], w[3:] * 0, None).frame_id == ""


def test_classify_refuses_float_stamps_but_takes_an_empty_recording():
    with pytest.raises(ValueError, match="integer array of nanoseconds"):
        iv.classify(np.array([1.5]), np.zeros((1, 3)))
    cls = iv.classify(np.array([]), np.zeros((0, 3)))
    assert cls.accepted == 0 and cls.frame_id is None and not any(cls.counts.values())
