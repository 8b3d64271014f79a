"""Array-wide Imu/QuaternionStamped reading, message for message against rclpy."""

from __future__ import annotations

import numpy as np
import pytest
import rclpy.serialization as rclpy_serialization
from geometry_msgs.msg import QuaternionStamped
from sensor_msgs.msg import Imu
from std_msgs.msg import String

from gyro_attitude.io.imu_fast import (
    read_imu_arrays,
    read_quaternion_stamped_arrays,
    read_topic_arrays,
)
from gyro_attitude.io.mcap_writer import Rosbag2McapWriter


def random_unit_quaternions(rng, n):
    q = rng.normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)

def _random_imu(rng, t_ns, frame):
    m = Imu()
    m.header.stamp.sec, m.header.stamp.nanosec = divmod(int(t_ns), 10**9)
    m.header.frame_id = frame
    q = random_unit_quaternions(rng, 1)[0]
    m.orientation.x, m.orientation.y, m.orientation.z, m.orientation.w = map(float, q)
    v = rng.normal(size=15)
    m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z = map(float, v[:3])
    m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z = map(
        float, v[3:6])
    m.orientation_covariance = [float(x) for x in rng.normal(size=9)]
    m.angular_velocity_covariance = [float(x) for x in rng.normal(size=9)]
    m.linear_acceleration_covariance = [float(x) for x in rng.normal(size=9)]
    return m


def _expected(msgs):
    """Field arrays straight from rclpy's deserialization of what was written."""
    des = [rclpy_serialization.deserialize_message(rclpy_serialization.serialize_message(m),
                                                   Imu) for m in msgs]
    return {
        "stamp_ns": np.array([m.header.stamp.sec * 10**9 + m.header.stamp.nanosec
                              for m in des]),
        "orientation": np.array([[m.orientation.x, m.orientation.y, m.orientation.z,
                                  m.orientation.w] for m in des]),
        "angular_velocity": np.array([[m.angular_velocity.x, m.angular_velocity.y,
                                       m.angular_velocity.z] for m in des]),
        "linear_acceleration": np.array([[m.linear_acceleration.x, m.linear_acceleration.y,
                                          m.linear_acceleration.z] for m in des]),
        "orientation_covariance": np.array([list(m.orientation_covariance) for m in des]),
        "angular_velocity_covariance": np.array([list(m.angular_velocity_covariance)
                                                 for m in des]),
        "linear_acceleration_covariance": np.array([list(m.linear_acceleration_covariance)
                                                    for m in des]),
        "frame_ids": [m.header.frame_id for m in des],
    }


def _check(arrays, exp):
    for key, val in exp.items():
        if key == "frame_ids":
            assert arrays.frame_ids == set(val)
        else:
            np.testing.assert_array_equal(getattr(arrays, key), val, err_msg=key)


def _write_messages(path, rng, n, frames, extra_every=None, flush_every=None, abandon=False):
    """Imu via rclpy serialization, a QuaternionStamped after each, optionally a String
    every ``extra_every`` messages (irregular spacing)."""
    msgs = []
    wr = Rosbag2McapWriter(path, chunk_size=5000)
    wr.add_topic("imu/data_raw", "sensor_msgs/msg/Imu")
    wr.add_topic("truth/attitude", "geometry_msgs/msg/QuaternionStamped")
    wr.add_topic("chatter", "std_msgs/msg/String")
    for k in range(n):
        t = 10**9 + k * 1_000_000
        m = _random_imu(rng, t, frames[k % len(frames)])
        msgs.append(m)
        wr.write_message("imu/data_raw", m, t + 17, t + 3)
        qs = QuaternionStamped()
        qs.header.stamp = m.header.stamp
        qs.quaternion = m.orientation
        wr.write_message("truth/attitude", qs, t + 18)
        if extra_every and k % extra_every == 0:
            wr.write_message("chatter", String(data="x" * int(rng.integers(0, 9))), t + 19)
        if flush_every and k % flush_every == flush_every - 1:
            wr.flush()
    if abandon:
        wr.flush()
        wr.abandon()
    else:
        wr.finish()
    return msgs


def test_regular_interleave(tmp_path):
    rng = np.random.default_rng(10)
    msgs = _write_messages(tmp_path / "a.mcap", rng, 300, ["imu_link"])
    arrays = read_imu_arrays(tmp_path / "a.mcap")
    assert len(arrays) == 300 and arrays.fast_messages == 300 and arrays.fallback_messages == 0
    _check(arrays, _expected(msgs))
    np.testing.assert_array_equal(arrays.log_time_ns, arrays.stamp_ns + 17)
    np.testing.assert_array_equal(arrays.publish_time_ns, arrays.stamp_ns + 3)
    assert arrays.topic == "/imu/data_raw" and arrays.frame_id == "imu_link"
    truth = read_quaternion_stamped_arrays(tmp_path / "a.mcap")
    np.testing.assert_array_equal(truth.quaternion, arrays.orientation)


def test_irregular_spacing(tmp_path):
    rng = np.random.default_rng(11)
    msgs = _write_messages(tmp_path / "a.mcap", rng, 200, ["imu_link"], extra_every=3)
    arrays = read_imu_arrays(tmp_path / "a.mcap")
    assert arrays.fast_messages == 200 and arrays.fallback_messages == 0
    _check(arrays, _expected(msgs))


def test_mixed_frame_ids_fall_back_per_message(tmp_path):
    rng = np.random.default_rng(12)
    frames = ["imu_link", "imu_link", "imu_link", "a_much_longer_frame_name", ""]
    msgs = _write_messages(tmp_path / "a.mcap", rng, 120, frames)
    arrays = read_imu_arrays(tmp_path / "a.mcap")
    assert arrays.fallback_messages > 0 and arrays.fast_messages > 0
    assert arrays.fast_messages + arrays.fallback_messages == 120
    _check(arrays, _expected(msgs))  # file order kept across the two paths


def test_frame_ids_of_the_same_length_are_told_apart(tmp_path):
    """The fixed CDR layout depends only on the frame_id's length: a different frame_id of the
    same length must still be recognised as different (not decoded as the first one)."""
    rng = np.random.default_rng(13)
    frames = ["imu_link", "imu_link", "imu_lonk"]
    msgs = _write_messages(tmp_path / "a.mcap", rng, 90, frames)
    arrays = read_imu_arrays(tmp_path / "a.mcap")
    assert arrays.frame_ids == {"imu_link", "imu_lonk"}
    assert arrays.fallback_messages > 0
    _check(arrays, _expected(msgs))


def test_file_without_index_or_summary(tmp_path):
    """A crash-truncated recording: chunks closed by flush, no summary; still array-read."""
    rng = np.random.default_rng(13)
    msgs = _write_messages(tmp_path / "a.mcap", rng, 90, ["imu"], flush_every=7, abandon=True)
    with pytest.raises(ValueError, match="without Data End"):
        read_imu_arrays(tmp_path / "a.mcap")
    arrays = read_imu_arrays(tmp_path / "a.mcap", on_damage="warn")
    assert "without Data End" in arrays.damage
    _check(arrays, _expected(msgs))


def test_array_written_round_trip(tmp_path):
    rng = np.random.default_rng(14)
    n = 5000
    t = 5 * 10**9 + np.arange(n, dtype=np.int64) * 1_000_000
    w, a = rng.normal(size=(n, 3)), rng.normal(size=(n, 3))
    q = random_unit_quaternions(rng, n)
    with Rosbag2McapWriter(tmp_path / "a.mcap", compression="zstd", chunk_size=20000) as wr:
        wr.add_topic("imu/data_raw", "sensor_msgs/msg/Imu")
        wr.add_topic("truth/attitude", "geometry_msgs/msg/QuaternionStamped")
        wr.write_imu_array("imu/data_raw", t, w, a, q, frame_id="imu_link")
        wr.write_quaternion_stamped_array("truth/attitude", t, q)
    out = read_topic_arrays(tmp_path / "a.mcap", {"/imu/data_raw": "sensor_msgs/msg/Imu",
                                                  "truth/attitude":
                                                  "geometry_msgs/msg/QuaternionStamped"})
    imu, truth = out["/imu/data_raw"], out["truth/attitude"]
    np.testing.assert_array_equal(imu.stamp_ns, t)
    np.testing.assert_array_equal(imu.angular_velocity, w)
    np.testing.assert_array_equal(imu.linear_acceleration, a)
    np.testing.assert_array_equal(imu.orientation, q)
    np.testing.assert_array_equal(truth.quaternion, q)
    assert imu.fast_messages == n and truth.fast_messages == n


def test_wrong_type_and_missing_topic(tmp_path):
    with Rosbag2McapWriter(tmp_path / "a.mcap") as wr:
        wr.add_topic("imu/data_raw", "std_msgs/msg/String")
        wr.write_message("imu/data_raw", String(data="not an imu"), 1)
    with pytest.raises(ValueError, match="holds std_msgs/msg/String messages, expected "
                                         "sensor_msgs/msg/Imu"):
        read_imu_arrays(tmp_path / "a.mcap")
    with pytest.raises(ValueError, match="no topic 'imu/other'"):
        read_imu_arrays(tmp_path / "a.mcap", topic="imu/other")
    with pytest.raises(ValueError, match="no array reader"):
        read_topic_arrays(tmp_path / "a.mcap", {"imu/data_raw": "std_msgs/msg/String"})


def test_summary_counts_match_mcap_and_wrong_counts_are_harmless(tmp_path, monkeypatch):
    from mcap.reader import make_reader

    from gyro_attitude.io.mcap_reader import McapStreamReader

    rng = np.random.default_rng(15)
    msgs = _write_messages(tmp_path / "a.mcap", rng, 150, ["imu_link", "imu_link", "x"],
                           extra_every=4)
    with open(tmp_path / "a.mcap", "rb") as f:
        s = make_reader(f).get_summary()
    summary = McapStreamReader(tmp_path / "a.mcap").summary()
    assert summary.message_counts == dict(s.statistics.channel_message_counts)
    real_summary = McapStreamReader.summary
    for wrong in (0, 1, 149, 151, 10_000, 2**40):  # the pre-sizing hint may lie
        def forged(self, w=wrong):
            out = real_summary(self)
            out.message_counts = {cid: w for cid in out.message_counts}
            return out

        monkeypatch.setattr(McapStreamReader, "summary", forged)
        _check(read_imu_arrays(tmp_path / "a.mcap"), _expected(msgs))


def test_field_subset(tmp_path):
    rng = np.random.default_rng(16)
    msgs = _write_messages(tmp_path / "a.mcap", rng, 40, ["imu_link"])
    out = read_topic_arrays(tmp_path / "a.mcap", {"imu/data_raw": "sensor_msgs/msg/Imu"},
                            fields={"imu/data_raw": ("angular_velocity",)})["imu/data_raw"]
    assert out.orientation is None and out.linear_acceleration is None
    np.testing.assert_array_equal(out.angular_velocity, _expected(msgs)["angular_velocity"])
    with pytest.raises(ValueError, match="no array fields"):
        read_topic_arrays(tmp_path / "a.mcap", {"imu/data_raw": "sensor_msgs/msg/Imu"},
                          fields={"imu/data_raw": ("angular_rate",)})


def test_relative_topic_matches_a_namespace_once(tmp_path):
    with Rosbag2McapWriter(tmp_path / "a.mcap") as wr:
        for ns in ("/robot1", "/robot2"):
            wr.add_topic(f"{ns}/imu/data_raw", "sensor_msgs/msg/Imu")
            wr.write_imu_array(f"{ns}/imu/data_raw", np.arange(3), np.zeros((3, 3)))
    with pytest.raises(ValueError, match="ambiguous"):
        read_imu_arrays(tmp_path / "a.mcap")
    assert len(read_imu_arrays(tmp_path / "a.mcap", "/robot2/imu/data_raw")) == 3
    assert len(read_imu_arrays(tmp_path / "a.mcap", "robot1/imu/data_raw")) == 3


def test_messages_that_are_not_what_the_schema_says(tmp_path):
    """A channel declared Imu carrying String CDR: the fast path rejects every record and
    the per-message decode fails with a clear error."""
    with Rosbag2McapWriter(tmp_path / "a.mcap") as wr:
        wr.add_topic("imu/data_raw", "sensor_msgs/msg/Imu")
        wr.write("imu/data_raw", rclpy_serialization.serialize_message(String(data="hi")), 1)
    with pytest.raises(ValueError, match="does not deserialize as sensor_msgs/msg/Imu"):
        read_imu_arrays(tmp_path / "a.mcap")


def _write_with_covariances(path, rng, n, cov_of, frames=("imu_link",)):
    """Imu messages whose three covariances are ``cov_of(k)`` (9 floats each)."""
    msgs = []
    with Rosbag2McapWriter(path, chunk_size=4000) as wr:  # ~10 messages a chunk
        wr.add_topic("imu/data_raw", "sensor_msgs/msg/Imu")
        for k in range(n):
            t = 10**9 + k * 1_000_000
            m = _random_imu(rng, t, frames[k % len(frames)])
            m.orientation_covariance = [float(x) for x in cov_of(k)]
            m.angular_velocity_covariance = [float(x) for x in cov_of(k)]
            m.linear_acceleration_covariance = [float(x) for x in cov_of(k)]
            msgs.append(m)
            wr.write_message("imu/data_raw", m, t)
    return msgs


CONSTANT = [1e-6, 0, 0, 0, 2e-6, 0, 0, 0, 3e-6]
NEGATIVE_ZERO = [1e-6, -0.0, 0, 0, 2e-6, 0, 0, 0, 3e-6]  # equal as numbers, not as bits


@pytest.mark.parametrize(("name", "cov_of", "held"), [
    ("constant", lambda k: CONSTANT, True),
    ("unknown (-1)", lambda k: [-1.0] + [0.0] * 8, True),
    ("NaN throughout", lambda k: [float("nan")] * 9, True),
    ("changes in a later chunk", lambda k: CONSTANT if k < 57 else [4e-6] * 9, False),
    ("changes in the first chunk", lambda k: CONSTANT if k != 3 else [5e-6] * 9, False),
    ("only the sign of a zero changes", lambda k: CONSTANT if k < 80 else NEGATIVE_ZERO, False),
    ("changes back and forth", lambda k: CONSTANT if (k // 25) % 2 else [7e-6] * 9, False),
])
@pytest.mark.parametrize("frames", [("imu_link",), ("imu_link", "imu_link", "other")],
                         ids=["array path", "with per-message fallback"])
@pytest.mark.parametrize("count", [None, 0, 50, 2**40], ids=lambda c: f"summary={c}")
def test_repeated_covariances_are_held_as_one_row(tmp_path, monkeypatch, name, cov_of, held,
                                                  frames, count):
    """Covariances every message repeats come back as a read-only view of one row; any
    change (even of a zero's sign) gives the per-message values, bit for bit, whichever
    path (array, per-message fallback, right/wrong/absent summary count) read them."""
    from gyro_attitude.io.mcap_reader import McapStreamReader

    rng = np.random.default_rng(21)
    msgs = _write_with_covariances(tmp_path / "a.mcap", rng, 160, cov_of, frames)
    if count is not None:
        real_summary = McapStreamReader.summary

        def forged(self):
            out = real_summary(self)
            out.message_counts = {cid: count for cid in out.message_counts}
            return out

        monkeypatch.setattr(McapStreamReader, "summary", forged)
    arrays = read_imu_arrays(tmp_path / "a.mcap")
    exp = _expected(msgs)
    for key in ("orientation_covariance", "angular_velocity_covariance",
                "linear_acceleration_covariance"):
        got = getattr(arrays, key)
        assert got.shape == (160, 9)
        # bit-exact: the sign of zero and NaN payloads included
        np.testing.assert_array_equal(got.view(np.uint64), exp[key].view(np.uint64), err_msg=key)
        assert (got.strides[0] == 0) == held, key
        assert got.flags.writeable != held
    _check(arrays, {k: v for k, v in exp.items() if not k.endswith("_covariance")})
