"""numpy <-> message conversion: stamps, quaternion order, covariance conventions."""

import math

import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from scipy.spatial.transform import Rotation
from sensor_msgs.msg import Imu

from gyro_attitude.io.cdr_arrays import ImuCdr, QuaternionStampedCdr
from gyro_attitude.ros import convert


@pytest.mark.parametrize("t_ns", [1, 999_999_999, 1_000_000_000, 1_763_700_000_123_456_789])
def test_stamp_round_trip(t_ns):
    stamp = convert.ns_to_stamp(t_ns)
    assert stamp.sec == t_ns // 1_000_000_000 and stamp.nanosec == t_ns % 1_000_000_000
    assert convert.stamp_to_ns(stamp) == t_ns


@pytest.mark.parametrize("bad", [-1, 2**31 * 1_000_000_000])
def test_stamp_refuses_out_of_range(bad):
    with pytest.raises(ValueError, match="time"):
        convert.ns_to_stamp(bad)


def test_quaternion_fields_are_scalar_last_like_scipy():
    rot = Rotation.from_rotvec([0.3, -0.2, 1.1])
    q = rot.as_quat()  # scipy: scalar-last (x, y, z, w)
    msg = convert.quat_to_msg(q)
    assert (msg.x, msg.y, msg.z, msg.w) == tuple(q.tolist())
    np.testing.assert_array_equal(convert.quat_from_msg(msg), q)
    # rotation angle is 1.1... rad: w is the cosine of half of it, in the w field
    assert msg.w == pytest.approx(math.cos(np.linalg.norm([0.3, -0.2, 1.1]) / 2))
    with pytest.raises(ValueError, match="quaternion"):
        convert.quat_to_msg([0, 0, 1])


def test_covariance_conventions():
    assert convert.covariance_from_variances(None) == [-1.0] + [0.0] * 8
    cov = convert.covariance_from_variances([1e-6, 2e-6, 3e-6])
    assert np.array_equal(np.reshape(cov, (3, 3)), np.diag([1e-6, 2e-6, 3e-6]))
    assert convert.covariance_from_variances(4.0)[8] == 4.0
    np.testing.assert_array_equal(convert.variances_from_covariance(cov), [1e-6, 2e-6, 3e-6])
    assert convert.variances_from_covariance(convert.NO_ESTIMATE_COVARIANCE) is None
    assert convert.variances_from_covariance(convert.UNKNOWN_COVARIANCE) is None
    with pytest.raises(ValueError, match="variances"):
        convert.covariance_from_variances([1.0, -1.0, 0.0])
    with pytest.raises(ValueError, match="variances"):
        convert.covariance_from_variances([1.0, 2.0])


def test_imu_message_rep145_fields_survive_serialization():
    omega = [0.01, -0.02, 0.5]
    f = [0.1, 0.2, 9.8]
    msg = convert.imu_msg(
        1_500_000_123, "imu_link", omega, f, gyro_variances=[1e-8] * 3, accel_variances=None
    )
    back = deserialize_message(serialize_message(msg), Imu)
    t_ns, frame, w, sf = convert.imu_arrays(back)
    assert t_ns == 1_500_000_123 and frame == "imu_link"
    np.testing.assert_array_equal(w, omega)
    np.testing.assert_array_equal(sf, f)
    assert back.orientation_covariance[0] == -1.0  # no orientation estimate from a raw gyro
    assert list(back.angular_velocity_covariance) == convert.covariance_from_variances([1e-8] * 3)
    assert not any(back.linear_acceleration_covariance)  # value present, covariance unknown


def test_imu_without_accelerometer_marks_field_as_no_estimate():
    msg = convert.imu_msg(5, "imu_link", [0, 0, 0], None, gyro_variances=None)
    assert msg.linear_acceleration_covariance[0] == -1.0
    assert not any(msg.angular_velocity_covariance)
    msg2 = convert.imu_msg(5, "imu_link", [0, 0, 0], orientation=[0, 0, 0, 1],
                           orientation_covariance=[2.0] + [0.0] * 8)
    assert msg2.orientation.w == 1.0 and msg2.orientation_covariance[0] == 2.0


def test_odometry_and_joint_state():
    odom = convert.odometry_msg(7, "enu", "imu_link", [1, 2, 3], [0, 0, 0, 1], [4, 5, 6],
                                [0.1, 0.2, 0.3])
    assert odom.header.frame_id == "enu" and odom.child_frame_id == "imu_link"
    assert odom.pose.pose.position.z == 3.0 and odom.twist.twist.linear.y == 5.0
    assert odom.twist.twist.angular.z == 0.3
    js = convert.joint_state_msg(7, ["outer_gimbal", "inner_gimbal"], [0.1, 0.2], [1.0, 2.0])
    assert list(js.name) == ["outer_gimbal", "inner_gimbal"] and list(js.velocity) == [1.0, 2.0]
    with pytest.raises(ValueError, match="names"):
        convert.joint_state_msg(7, ["a"], [0.1, 0.2], [1.0, 2.0])


def _imu(frame_id: str, t_ns: int, rng) -> Imu:
    m = convert.imu_msg(t_ns, frame_id, rng.normal(size=3), rng.normal(size=3),
                        rng.uniform(1e-8, 1e-6, 3), rng.uniform(1e-5, 1e-3, 3))
    m.orientation_covariance = list(rng.normal(size=9))
    return m


@pytest.mark.parametrize("frame_id", ["", "a", "imu", "imu_link", "imu_link_1", "ö/base"])
def test_serialized_imu_is_read_and_filled_in_as_rclpy_serializes_it(frame_id):
    """ImuCdr reads every field rclpy wrote, and with_orientation gives the bytes rclpy
    serializes for the message with that orientation (every frame_id length, so every
    alignment of the float64 body)."""
    from geometry_msgs.msg import QuaternionStamped

    rng = np.random.default_rng(len(frame_id))
    for t_ns in (1, 1_763_700_000_123_456_789):
        m = _imu(frame_id, t_ns, rng)
        s = ImuCdr.parse(serialize_message(m))
        assert s is not None and s.t_ns == t_ns and s.frame_id == frame_id
        assert s.angular_velocity.tolist() == [m.angular_velocity.x, m.angular_velocity.y,
                                               m.angular_velocity.z]
        assert s.linear_acceleration.tolist() == [m.linear_acceleration.x,
                                                  m.linear_acceleration.y,
                                                  m.linear_acceleration.z]
        assert s.angular_velocity_covariance.tolist() == list(m.angular_velocity_covariance)
        assert (s.linear_acceleration_covariance.tolist()
                == list(m.linear_acceleration_covariance))
        q, cov = rng.normal(size=4).tolist(), rng.normal(size=9).tolist()
        m.orientation.x, m.orientation.y, m.orientation.z, m.orientation.w = q
        m.orientation_covariance = cov
        assert s.with_orientation(*q, cov) == serialize_message(m)
        att = QuaternionStamped()
        att.header.stamp = m.header.stamp
        att.header.frame_id = frame_id + "_world"
        att.quaternion.x, att.quaternion.y, att.quaternion.z, att.quaternion.w = q
        enc = QuaternionStampedCdr(frame_id + "_world").encode(s.stamp_cdr, *q)
        ref = serialize_message(att)
        # equal but for the alignment padding after frame_id (rclpy leaves it unset)
        pad = slice(16 + len((frame_id + "_world").encode()) + 1, len(ref) - 32)
        assert len(enc) == len(ref) and enc[pad] == bytes(len(ref[pad]))
        assert enc[:pad.start] + enc[pad.stop:] == ref[:pad.start] + ref[pad.stop:]
        assert deserialize_message(enc, QuaternionStamped) == att
        assert QuaternionStampedCdr.parse(ref) == (t_ns, tuple(q))


def test_serialized_quaternion_stamped_other_than_plain_little_endian_is_refused():
    from geometry_msgs.msg import QuaternionStamped

    m = QuaternionStamped()
    m.header.frame_id = "map"
    raw = serialize_message(m)
    assert QuaternionStampedCdr.parse(raw) == (0, (0.0, 0.0, 0.0, 1.0))
    assert QuaternionStampedCdr.parse(b"\x00\x00" + raw[2:]) is None  # big-endian
    assert QuaternionStampedCdr.parse(raw[:-1]) is None  # truncated
    assert QuaternionStampedCdr.parse(raw + b"\x00" * 8) is None
    assert QuaternionStampedCdr.parse(raw[:12] + (200).to_bytes(4, "little") + raw[16:]) is None
    assert QuaternionStampedCdr.parse(b"") is None


def test_serialized_imu_other_than_plain_little_endian_is_left_to_rclpy():
    raw = serialize_message(_imu("imu_link", 5, np.random.default_rng(0)))
    assert ImuCdr.parse(raw) is not None
    assert ImuCdr.parse(b"\x00\x00" + raw[2:]) is None  # big-endian encapsulation
    assert ImuCdr.parse(raw[:-1]) is None  # truncated
    assert ImuCdr.parse(raw + b"\x00" * 8) is None  # longer than the layout
    assert ImuCdr.parse(raw[:12] + (200).to_bytes(4, "little") + raw[16:]) is None
    assert ImuCdr.parse(b"") is None
