"""Rest detection: stream == batch bit for bit, finds the true rests, ignores a constant bias."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from sim_static import rest_motion_rest
from stages import bias_rows, rest_rows

from gyro_attitude.core.attitude import rest
from gyro_attitude.core.attitude.rest import (
    ACCEL_CHANGED,
    NOT_INCREASING,
    detect_rest,
    rest_segments,
    rest_start,
    rest_update,
)
from gyro_attitude.core.attitude.settings import StreamConfig


def test_stream_equals_batch_bitwise():
    t, g, a, _ = rest_motion_rest(seed=3)
    batch = detect_rest(t, g, a)
    got, _ = rest_rows(t, g, a)
    np.testing.assert_array_equal([r[0] for r in got], batch.at_rest)
    np.testing.assert_array_equal([r[1] for r in got], batch.oldest)


def test_a_window_that_outgrows_its_ring_mid_stream_keeps_its_samples_in_order():
    """The streaming window is a ring that doubles when a window holds more samples than it
    has room for.  Here the rate goes up tenfold after 3 s (the window then needs ten times
    the entries, while its oldest entry sits mid-ring): decisions, window starts and
    statistics stay the batch detector's, bit for bit."""
    rng = np.random.default_rng(7)
    t = np.concatenate([np.arange(150) * 20_000_000,  # 50 Hz for 3 s, then 2 kHz
                        3_000_000_000 + np.arange(8000) * 500_000]) + 1_000_000_000
    g = 0.002 * rng.standard_normal((t.size, 3))
    g[4000:6000, 2] += 0.8  # a turn in the fast part
    a = np.array([0.0, 0.0, 9.81]) + 0.02 * rng.standard_normal((t.size, 3))
    batch = detect_rest(t, g, a)
    got, ring_sizes = rest_rows(t, g, a)
    got = np.array(got)
    assert len(ring_sizes) >= 3  # it grew at least twice
    np.testing.assert_array_equal(got[:, 0].astype(bool), batch.at_rest)
    np.testing.assert_array_equal(got[:, 1], batch.oldest)
    np.testing.assert_array_equal(got[:, 2], batch.gyro_std)
    assert batch.at_rest.any()


@pytest.mark.parametrize("chunk", [5, 37, 1000])  # below, near and above a window's rows
def test_batch_equals_the_stream_bitwise_and_marks_every_rest_windows_samples(monkeypatch, chunk):
    """The batch loop gives the streaming detector's numbers sample by sample (window
    statistics and decisions); ``covered`` marks the samples of every rest window, a chunk of
    rest rows at a time, whatever the chunk."""
    monkeypatch.setattr(rest, "_COVER_CHUNK", chunk)
    t, g, a, _ = rest_motion_rest(seed=5)
    batch = detect_rest(t, g, a)
    got = np.array(rest_rows(t, g, a)[0])
    np.testing.assert_array_equal(got[:, 0].astype(bool), batch.at_rest)
    np.testing.assert_array_equal(got[:, 1], batch.oldest)
    np.testing.assert_array_equal(got[:, 2], batch.gyro_std)
    np.testing.assert_array_equal(got[:, 3], batch.accel_std)
    assert batch.at_rest.any() and not batch.at_rest.all()
    covered = np.zeros(t.size, bool)
    for k in np.flatnonzero(batch.at_rest):
        covered[batch.oldest[k]:k + 1] = True
    np.testing.assert_array_equal(batch.covered, covered)


@pytest.mark.parametrize("use_accel", [True, False])
def test_finds_the_true_rests_despite_a_large_bias(use_accel):
    # 0.01 rad/s (0.57 °/s, near the largest consumer MEMS bias) on z, inside the mean-rate
    # bound: the deviation test must not mind it.
    t, g, a, truth = rest_motion_rest(bias=(0.006, -0.004, 0.01), seed=4)
    r = detect_rest(t, g, a if use_accel else None)
    segs = rest_segments(r.covered)
    true_segs = rest_segments(truth)
    assert len(segs) == len(true_segs) == 3
    for (s, e), (ts, te) in zip(segs, true_segs, strict=True):
        # Motion starts/stops smoothly (sin); edges agree within 0.3 s at 200 Hz.
        assert abs(s - ts) <= 60 and abs(e - te) <= 60
    # No motion sample is vouched for by a rest window far inside the motion.
    assert not np.any(r.covered & ~truth & ~np.isin(np.arange(t.size), _near_edges(truth, 60)))


def _near_edges(mask, width):
    edges = np.flatnonzero(np.diff(mask.astype(int)) != 0)
    return np.unique(np.clip((edges[:, None] + np.arange(-width, width + 1)).ravel(), 0, mask.size - 1))


def test_constant_fast_rotation_is_not_rest():
    t = np.arange(400, dtype=np.int64) * 5_000_000
    g = np.tile([0.0, 0.0, 0.2], (400, 1))  # smooth 11 °/s spin: zero deviation, large mean
    assert not detect_rest(t, g).at_rest.any()
    assert detect_rest(t, g, cfg=StreamConfig(rest_gyro_mean_max=0.3)).at_rest.any()


def test_bad_input_is_refused():
    rf, ri = rest_start(StreamConfig())
    wt, wx, wc = np.zeros(4, np.int64), np.zeros(4, np.int64), np.zeros((4, 12))
    assert rest_update(rf, ri, wt, wx, wc, 10, 0.0, 0.0, 0.0, True, 0.0, 0.0, 9.8) == 0
    before = rf.copy(), ri.copy()
    # refused with nothing changed: a stamp that does not increase, the accelerometer gone
    assert rest_update(rf, ri, wt, wx, wc, 10, 0.0, 0.0, 0.0, True, 0.0, 0.0, 9.8) == \
        NOT_INCREASING
    assert rest_update(rf, ri, wt, wx, wc, 20, 0.0, 0.0, 0.0, False, 0.0, 0.0, 0.0) == \
        ACCEL_CHANGED
    np.testing.assert_array_equal(rf, before[0])
    np.testing.assert_array_equal(ri, before[1])
    with pytest.raises(ValueError, match="rest_window_s"):
        StreamConfig(rest_window_s=float("inf"))
    with pytest.raises(ValueError, match="strictly increasing"):
        detect_rest([0, 0], np.zeros((2, 3)))
    with pytest.raises(ValueError, match="shape"):
        detect_rest([0, 1], np.zeros((3, 3)))
    with pytest.raises(ValueError, match="empty"):
        detect_rest([], np.zeros((0, 3)))
    with pytest.raises(ValueError, match="numeric"):
        detect_rest([0, 1], [["a", "b", "c"]] * 2)


@pytest.mark.parametrize("floor", [-1.0, float("nan"), 0.01, 1.0, "x", True])
def test_a_noise_floor_outside_zero_to_the_std_bound_is_refused_in_one_line(floor):
    t, g = np.arange(10) * 10**7, np.zeros((10, 3))
    with pytest.raises(ValueError, match="gyro_std_min"):
        detect_rest(t, g, gyro_std_min=floor)
    with pytest.raises(ValueError, match="gyro_std_min"):
        rest_start(StreamConfig(), floor)


def test_thresholds_given_as_anything_but_a_stream_config_are_refused():
    with pytest.raises(TypeError, match="StreamConfig"):
        detect_rest(np.arange(10) * 10**7, np.zeros((10, 3)), None, 1.0)
    with pytest.raises(TypeError, match="StreamConfig"):
        rest_start({"rest_window_s": 1.0})


@pytest.mark.parametrize("rate", [0.02, 0.05])
@pytest.mark.parametrize("axis", [(0, 0, 1), (1, 0, 0), (1, 1, 1), (0.3, -0.8, 1.0)])
def test_a_slow_steady_turn_is_never_a_rest_and_leaves_the_bias(rate, axis):
    # A turntable at a constant 0.02 or 0.05 rad/s (1.1, 2.9 °/s) with consumer MEMS noise
    # (1e-4 rad/s/√Hz gyro, 0.02 m/s² accelerometer) and a 0.3 °/s bias: about the vertical the
    # specific force does not change, so only the mean-rate bound can refuse it — per axis, a
    # turn of rate |ω| has a component ≥ |ω|/√3 ≥ 0.0115 rad/s > 0.011 whatever its axis.
    rng = np.random.default_rng(7)
    n, hz = 4000, 200.0
    t = (1 + np.arange(n, dtype=np.int64)) * int(1e9 / hz)
    u = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    bias = np.array([0.004, -0.003, 0.005])
    g = rate * u + bias + 1e-4 * np.sqrt(hz) * rng.standard_normal((n, 3))
    # the specific force in the body turns with the body (exactly, as the body turns about u)
    angle = rate * (t - t[0]) * 1e-9
    f = Rotation.from_rotvec(np.outer(angle, u)).inv().apply([0.0, 0.0, 9.80665])
    a = f + 0.02 * rng.standard_normal((n, 3))
    assert not detect_rest(t, g, a).at_rest.any()
    assert not detect_rest(t, g).at_rest.any()  # gyro only
    b, rep = bias_rows(t, g, a)
    assert rep.rests_used == 0 and np.all(b == 0.0)
    # the same sensor still: a rest, and the bias it estimates
    still = bias + 1e-4 * np.sqrt(hz) * rng.standard_normal((n, 3))
    a_still = np.array([0.0, 0.0, 9.80665]) + 0.02 * rng.standard_normal((n, 3))
    b, rep = bias_rows(t, still, a_still)
    assert rep.rests_used == 1 and np.allclose(rep.bias, bias, atol=1e-4)
