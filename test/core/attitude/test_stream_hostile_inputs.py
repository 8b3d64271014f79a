"""What a hostile caller of push()/run() met after the estimator became one step (a review):
each a clear refusal or a counted rejection, and the first rest's estimate never applied back
across a jump of the clock."""

import math

import numpy as np
import pytest

from gyro_attitude.core.attitude.stream import AttitudeStream, StreamConfig

MS = 1_000_000
T0 = 200_000_000_000


def test_a_stamp_beyond_int64_is_refused_in_one_line_not_a_hang():
    for t in (2**63, 2**64, -2**63 - 1, np.uint64(2**64 - 1)):
        with pytest.raises(ValueError, match="int64"):
            AttitudeStream().push(t, (0.1, 0.0, 0.0))
    with pytest.raises(ValueError, match="int64"):
        AttitudeStream().run(np.array([1, 2**63 + 5], np.uint64), np.zeros((2, 3)))


@pytest.mark.parametrize("omega", ["123", b"abc", {"x": 1, "y": 2, "z": 3}, ("1", "2", "3"),
                                   (10**400, 0, 0)])
def test_text_and_numbers_beyond_float64_are_no_rates(omega):
    s = AttitudeStream()
    verdict, q = s.push(T0, omega)
    assert q is None and verdict.reason == "non_finite" and s.counts["non_finite"] == 1


@pytest.mark.parametrize("accel", ["981", (10**400, 0.0, 9.8)])
def test_text_or_huge_accelerometer_samples_are_counted(accel):
    s = AttitudeStream()
    s.push(T0, (0.0, 0.0, 0.0), "imu", None, accel)
    assert s.counts["invalid_accel"] == 1


@pytest.mark.parametrize("nan_row", [[math.nan] * 3, (math.nan,) * 3, np.full(3, math.nan)])
def test_a_row_of_nan_is_a_missing_field_in_any_container(nan_row):
    s = AttitudeStream(config=StreamConfig(aiding="magnetometer"))
    for k in range(3):
        s.push(T0 + k * 5 * MS, (0.0, 0.0, 0.0), "imu", None, (0.0, 0.0, 9.81), nan_row)
    counts = s.counts
    assert counts["mag_missing"] == 3 and counts["invalid_mag"] == 0


def test_run_after_rejected_pushes_is_refused():
    s = AttitudeStream()
    s.push(T0, (math.nan, 0.0, 0.0))
    with pytest.raises(ValueError, match="fresh"):
        s.run(np.array([T0 + MS]), np.zeros((1, 3)))


@pytest.mark.parametrize("jump_s", [5, 100])
def test_the_first_rest_is_not_applied_back_across_a_jump_of_the_clock(jump_s):
    # still throughout, a 0.004 rad/s bias: the attitude must stay put; a jump back at 0.3 s
    # starts the attitude again from the initial one, and the first rest's estimate applies
    # back to that new start only (it applied -elapsed across the jump: 22.8° for 100 s)
    n = 800
    t = T0 + np.arange(n, dtype=np.int64) * 5 * MS
    t[60:] -= jump_s * 1_000_000_000
    w = np.array([0.004, 0.0, 0.0]) + 1e-4 * np.random.default_rng(0).standard_normal((n, 3))
    a = np.tile([0.0, 0.0, 9.81], (n, 1))
    res = AttitudeStream(config=StreamConfig(aiding="none")).run(t, w, "imu", None, a)
    assert res.time_jump_resets == 1
    angle = math.degrees(2 * math.asin(min(1.0, np.linalg.norm(res.q[-1, :3]))))
    assert angle < 0.01, angle


def test_with_tilt_aiding_the_first_rest_takes_back_the_heading_and_leaves_the_tilt_to_the_filter():
    # still, level, a bias about the vertical (heading drift) and one about x (tilt drift): the
    # first rest takes the heading drift back to the start exactly (the filter cannot see it);
    # the tilt drift, which the filter had partly taken out already, is left to the filter
    n = 1600
    t = T0 + np.arange(n, dtype=np.int64) * 5 * MS
    w = np.array([0.004, 0.0, 0.006]) + 1e-5 * np.random.default_rng(1).standard_normal((n, 3))
    a = np.tile([0.0, 0.0, 9.81], (n, 1))
    res = AttitudeStream(config=StreamConfig(aiding="tilt")).run(t, w, "imu", None, a)
    x, y, z, u = res.q[-1]
    heading = math.degrees(2 * math.atan2(z, u))
    tilt = math.degrees(2 * math.asin(min(1.0, math.hypot(x, y))))
    assert abs(heading) < 0.005, heading  # 0.006 rad/s over ~1.5 s: 0.5° without it
    assert tilt < 0.05, tilt  # the filter's, a few time constants after the rest
