"""Input checks of the Imu stream (the validation stage of AttitudeStream.push): each bad case
is rejected with its own reason, once."""

import math

import numpy as np
import pytest

from gyro_attitude.core.attitude import validation as iv
from gyro_attitude.core.attitude.stream import AttitudeStream, StreamConfig

MS = 1_000_000


def make(max_gap_ms=100, jump_ms=1000):
    return AttitudeStream("rotvec_cubic", config=StreamConfig(
        gyro_bias="none", max_gap_s=max_gap_ms / 1e3, time_jump_threshold_s=jump_ms / 1e3))


def check(stream, t, w, frame):
    """The verdict of one sample pushed."""
    return stream.push(t, w, frame)[0]


def test_clean_stream_is_accepted():
    v = make()
    actions = [check(v, t * MS, [0.1, 0.2, 0.3], "imu").action for t in range(1, 11)]
    assert actions == [iv.START] + [iv.ACCEPT] * 9
    assert v.accepted == 10 and v.rejected_total == 0
    assert v.last_t_ns == 10 * MS and v.frame_id == "imu"


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_rejected_and_state_untouched(bad):
    v = make()
    check(v, 1 * MS, [0, 0, 0], "imu")
    verdict = check(v, 2 * MS, [0, bad, 0], "imu")
    assert verdict.rejected and verdict.reason == iv.NON_FINITE
    assert v.last_t_ns == 1 * MS
    # the next good sample integrates over (1 ms, 3 ms]: the bad one cost one sample only
    assert check(v, 3 * MS, [0, 0, 0], "imu").action == iv.ACCEPT
    assert v.counts[iv.NON_FINITE] == 1 and v.rejected_total == 1


def test_stamp_problems_each_have_their_reason():
    v = make()
    assert check(v, 0, [0, 0, 0], "imu").reason == iv.ZERO_STAMP
    assert check(v, -5, [0, 0, 0], "imu").reason == iv.ZERO_STAMP
    check(v, 10 * MS, [0, 0, 0], "imu")
    assert check(v, 10 * MS, [0, 0, 0], "imu").reason == iv.DUPLICATE_STAMP
    assert check(v, 9 * MS, [0, 0, 0], "imu").reason == iv.OUT_OF_ORDER
    assert check(v, 11 * MS, [0, 0, 0], "other").reason == iv.FRAME_CHANGED
    assert check(v, 11 * MS, [0, 0, 0], "imu").action == iv.ACCEPT
    expected = {iv.ZERO_STAMP: 2, iv.DUPLICATE_STAMP: 1, iv.OUT_OF_ORDER: 1, iv.FRAME_CHANGED: 1}
    for reason in iv.REJECT_REASONS:
        assert v.counts[reason] == expected.get(reason, 0), reason
    assert v.rejected_total == 5 and v.accepted == 2


def test_gap_restarts_time_base_and_is_counted():
    v = make(max_gap_ms=50)
    check(v, 1 * MS, [0, 0, 0], "imu")
    assert check(v, 51 * MS, [0, 0, 0], "imu").action == iv.ACCEPT  # exactly the limit: fine
    verdict = check(v, 102 * MS, [0, 0, 0], "imu")
    assert verdict.action == iv.RESTART_AFTER_GAP and verdict.reason == iv.GAP
    assert v.last_t_ns == 102 * MS
    assert check(v, 103 * MS, [0, 0, 0], "imu").action == iv.ACCEPT
    assert v.counts[iv.GAP] == 1 and v.rejected_total == 0


def test_backward_jump_beyond_threshold_resets():
    v = make(jump_ms=500)
    check(v, 2000 * MS, [0, 0, 0], "imu")
    assert check(v, 1600 * MS, [0, 0, 0], "imu").reason == iv.OUT_OF_ORDER
    verdict = check(v, 1000 * MS, [0, 0, 0], "imu")
    assert verdict.action == iv.RESET_TIME_JUMP
    assert v.time_jump_resets == 1 and v.last_t_ns == 1000 * MS
    assert check(v, 1001 * MS, [0, 0, 0], "imu").action == iv.ACCEPT


def test_reset_forgets_frame_and_time():
    v = make()
    check(v, 5 * MS, [0, 0, 0], "a")
    v.restart()
    assert check(v, 1 * MS, [0, 0, 0], "b").action == iv.START


@pytest.mark.parametrize("kwargs, named", [
    ({"max_gap_s": 0}, "max_gap_s"), ({"time_jump_threshold_s": -1e-9}, "time_jump_threshold_s"),
    ({"max_gap_s": "0.1"}, "max_gap_s"), ({"time_jump_threshold_s": True}, "time_jump"),
    ({"max_rate_rad_s": 0.0}, "max_rate_rad_s"), ({"max_missing_samples": -1}, "max_missing"),
    ({"max_missing_samples": 1.5}, "max_missing")])
def test_config_refuses_bad_thresholds_naming_the_setting(kwargs, named):
    with pytest.raises(ValueError, match=named):
        StreamConfig(**kwargs)


def test_interval_statistics_against_numpy():
    rng = np.random.default_rng(3)
    dt_ns = (1_000_000 + rng.integers(-20_000, 20_000, size=500)).astype(np.int64)
    ring, fill = np.zeros(200, np.int64), np.zeros(2, np.int64)
    stats = iv.IntervalStatistics(ring, fill)
    assert math.isnan(stats.summary()["rate_hz"])
    for d in dt_ns:
        iv.interval_add(ring, fill, int(d))
    tail = dt_ns[-200:] / 1e9
    s = stats.summary()
    assert s["rate_hz"] == pytest.approx(1.0 / np.mean(tail), rel=1e-12)
    assert s["jitter_s"] == pytest.approx(np.std(tail), rel=1e-9)
    assert s["max_dt_s"] == pytest.approx(tail.max(), rel=1e-12)
    assert len(stats) == 200


def test_random_streams_only_accept_positive_bounded_steps():
    """Any mix of good and bad samples: an ACCEPT always integrates 0 < dt <= max_gap with
    finite values in the locked frame, and every rejection is counted exactly once."""
    from hypothesis import given, settings
    from hypothesis import strategies as st

    sample = st.tuples(
        st.integers(min_value=-5, max_value=3000).map(lambda ms: ms * MS // 2),
        st.sampled_from([0.1, math.nan, math.inf]),
        st.sampled_from(["imu", "imu", "imu", "other"]),
    )

    @settings(max_examples=200, deadline=None)
    @given(st.lists(sample, max_size=60))
    def run(stream):
        v = make(max_gap_ms=100, jump_ms=1000)
        last = None
        rejects = 0
        for t, w, frame in stream:
            verdict = check(v, t, [w, 0.0, 0.0], frame)
            if verdict.rejected:
                rejects += 1
                continue
            assert math.isfinite(w) and t > 0
            assert frame == v.frame_id
            if verdict.action == iv.ACCEPT:
                assert 0 < t - last <= 100 * MS
            elif verdict.action == iv.RESTART_AFTER_GAP:
                assert t - last > 100 * MS
            elif verdict.action == iv.RESET_TIME_JUMP:
                assert last - t > 1000 * MS
            else:
                assert verdict.action == iv.START and last is None
            last = t
        assert v.rejected_total == rejects
        assert v.accepted == len(stream) - rejects

    run()


def test_validation_thresholds_given_as_anything_but_a_stream_config_are_refused():
    with pytest.raises(TypeError, match="StreamConfig"):
        iv.classify(np.arange(1, 4) * 10**7, np.zeros((3, 3)), "imu", {"max_rate_rad_s": 1.0})
