"""The replay pipeline as a library: ReplayResult, and the attitude-stream policy deciding what
is written (skipped samples never reach the output; the rest is integrate_batch)."""

from __future__ import annotations

import json
import os
import sys

import numpy as np
import pytest

from gyro_attitude.core.attitude import integrate_batch
from gyro_attitude.io.imu_fast import read_imu_arrays, read_quaternion_stamped_arrays
from gyro_attitude.io.mcap_writer import Rosbag2McapWriter
from gyro_attitude.offline.replay import ReplayResult, replay_file

os.environ.setdefault("AMENT_PREFIX_PATH", sys.prefix)


def _input(path, n=300):
    t = 5 * 10**9 + np.arange(n, dtype=np.int64) * 2_000_000
    tt = (t - t[0]) * 1e-9
    w = np.stack([0.2 * np.sin(tt), 0.1 + 0 * tt, 0.3 * np.cos(2 * tt)], axis=1)
    with Rosbag2McapWriter(path) as wr:
        wr.add_topic("imu/data_raw", "sensor_msgs/msg/Imu")
        wr.write_imu_array("imu/data_raw", t, w)
    return t, w


def test_result_is_a_dataclass_with_a_json_summary(tmp_path):
    t, w = _input(tmp_path / "in.mcap")
    r = replay_file(tmp_path / "in.mcap", tmp_path / "out.mcap", algorithm="rotvec_cubic")
    assert isinstance(r, ReplayResult)
    s = r.summary()
    assert not [k for k in s if k.startswith("_")]
    assert not {"index", "t_ns", "q", "error_t_ns", "error_rad"} & set(s)
    json.dumps(s)  # plain JSON types only
    assert s["messages"] == s["attitude_messages"] == 300 and s["compression"] == "zstd"
    np.testing.assert_array_equal(r.t_ns, t)
    np.testing.assert_allclose(r.q, integrate_batch(t, w), rtol=0, atol=1e-15)
    assert r.index.tolist() == list(range(300)) and r.error_rad.size == 0
    assert sum(s["skipped"].values()) == 0 and s["gaps"] == 0 and s["time_jump_resets"] == 0


def test_skipped_samples_are_not_written_and_the_rest_is_integrated_around_them(tmp_path):
    """One NaN and one absurd (1e155 rad/s) sample are skipped, counted, never written;
    the output is integrate_batch over the remaining samples (the interval closes over the
    skipped sample, as in the node)."""
    n = 300
    t = 5 * 10**9 + np.arange(n, dtype=np.int64) * 2_000_000
    tt = (t - t[0]) * 1e-9
    w = np.stack([0.2 * np.sin(tt), 0.1 + 0 * tt, 0.3 * np.cos(2 * tt)], axis=1)
    w[10] = [np.nan, 0, 0]
    w[20] = [1e155, 0, 0]
    with Rosbag2McapWriter(tmp_path / "in.mcap") as wr:
        wr.add_topic("imu/data_raw", "sensor_msgs/msg/Imu")
        wr.write_imu_array("imu/data_raw", t, w)
    r = replay_file(tmp_path / "in.mcap", tmp_path / "out.mcap", algorithm="exp_map")
    keep = np.r_[0:10, 11:20, 21:300]
    assert r.messages == 300 and r.attitude_messages == 298
    assert r.skipped["non_finite"] == 1 and r.skipped["implausible_rate"] == 1
    att = read_quaternion_stamped_arrays(tmp_path / "out.mcap", "attitude")
    imu = read_imu_arrays(tmp_path / "out.mcap", "imu/data")
    np.testing.assert_array_equal(att.stamp_ns, t[keep])
    np.testing.assert_array_equal(imu.stamp_ns, t[keep])
    assert np.isfinite(att.quaternion).all()
    np.testing.assert_allclose(att.quaternion, integrate_batch(t[keep], w[keep],
                                                               algorithm="exp_map"),
                               rtol=0, atol=1e-15)


def test_library_arguments_of_the_wrong_type_are_value_errors(tmp_path):
    """Library callers get ValueError naming the argument, never TypeError/AttributeError."""
    import pytest

    from gyro_attitude.core.attitude.stream import AttitudeStream

    _input(tmp_path / "in.mcap")
    good = {"input_path": tmp_path / "in.mcap", "output_path": tmp_path / "o.mcap"}
    for bad, name in (({"input_path": None}, "input_path"), ({"output_path": 5}, "output_path"),
                      ({"imu_topic": None}, "imu_topic"), ({"truth_topic": b"x"}, "truth_topic"),
                      ({"nav": "abc", "frame": "enu"}, "nav"), ({"config": "abc"}, "config"),
                      ({"chunk_size": 1e300}, "chunk_size")):
        args = {**good, **bad}
        with pytest.raises(ValueError, match=name):
            replay_file(args.pop("input_path"), args.pop("output_path"), **args)
    assert not (tmp_path / "o.mcap").exists()
    with pytest.raises(ValueError, match="frame_id"):
        AttitudeStream().run(np.array([1, 2]), np.zeros((2, 3)), frame_id=5)
    with pytest.raises(ValueError, match="t_ns"):
        AttitudeStream().push(1.5, [0.0, 0.0, 0.0])
    q = AttitudeStream(q0=(1e300, 0.0, 0.0, 1.0)).quaternion  # scaled, not overflowed
    np.testing.assert_allclose(q, [1.0, 0.0, 0.0, 0.0], rtol=0, atol=1e-15)


def _turning_about_z(t_ns, rate):
    """x, y, z, w of a constant-rate turn about z (closed form)."""
    half = 0.5 * rate * (t_ns - t_ns[0]) * 1e-9
    return np.stack([0 * half, 0 * half, np.sin(half), np.cos(half)], axis=1)


def test_error_figures_hold_a_block_of_temporaries_not_the_recording():
    """The truth comparison's working memory is per TRUTH_BLOCK, not per message: 200 k
    truth stamps against 200 k attitudes, the truth tilted 0.01 rad about x from the
    estimate (the error is 0.01 everywhere, closed form) and stamped half a sample later
    (every stamp slerped, across block boundaries)."""
    import tracemalloc
    from types import SimpleNamespace

    from gyro_attitude.offline import replay as rp

    n = 200_000
    t = 10**9 + np.arange(n, dtype=np.int64) * 1_000_000
    q = _turning_about_z(t, 0.7)
    ts = t[:-1] + 500_000
    tilt = np.array([np.sin(0.005), 0.0, 0.0, np.cos(0.005)])
    half = _turning_about_z(np.r_[t[0], ts], 0.7)[1:]
    from gyro_attitude.core.rotation import _qmul
    truth = SimpleNamespace(topic="truth/attitude", stamp_ns=ts,
                            quaternion=_qmul(half, np.broadcast_to(tilt, half.shape)))
    tracemalloc.start()
    try:
        result = SimpleNamespace(**rp._truth_figures(truth, t, q))
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert result.truth_matched == n - 1
    np.testing.assert_array_equal(result.error_t_ns, ts)
    np.testing.assert_allclose(result.error_rad, 0.01, rtol=0, atol=1e-9)
    assert result.max_error_rad == pytest.approx(0.01, abs=1e-9)
    # kept: the error series and its squares (the RMS of np.mean(err**2), bit for bit: 8 B a
    # stamp each) and two flags a stamp; the rest is one block's (whole-recording temporaries
    # were > 250 B a stamp: 50 MB here)
    assert peak < 18 * n + 500 * rp.TRUTH_BLOCK, f"peak {peak / 1e6:.0f} MB"


def test_a_step_back_in_any_block_of_stamps_is_sorted_out(monkeypatch):
    """_strictly_increasing checks the stamps TRUTH_BLOCK intervals at a time (no temporary of
    the recording's length): a repeated or earlier stamp in any block, its last interval
    included, is found and sorted as the whole-array rule sorts it."""
    import gyro_attitude.offline.replay as rp

    monkeypatch.setattr(rp, "TRUTH_BLOCK", 7)
    t = np.arange(50, dtype=np.int64) * 10
    q = np.arange(200.0).reshape(50, 4)
    same_t, same_q = rp._strictly_increasing(t, q)
    assert same_t is t and same_q is q
    for k in range(1, 50):
        tk = t.copy()
        tk[k] = tk[k - 1]  # a repeated stamp: the first recorded is kept
        got_t, got_q = rp._strictly_increasing(tk, q)
        assert got_t.size == 49 and (np.diff(got_t) > 0).all(), k
        np.testing.assert_array_equal(got_q, np.delete(q, k, axis=0))
