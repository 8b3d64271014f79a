"""Odometry and JointState message batches (simulate's array encoders) against rclpy's own serialization."""

from __future__ import annotations

import numpy as np
import pytest

rclpy_serialization = pytest.importorskip("rclpy.serialization")
from nav_msgs.msg import Odometry  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402

from gyro_attitude.io.cdr_arrays import joint_state_batch, odometry_batch  # noqa: E402
from gyro_attitude.ros import convert  # noqa: E402

STAMPS = np.array([0, 1, 10**9 + 5, 123_456_789_012, 2**31 * 10**9 - 1], dtype=np.int64)


@pytest.mark.parametrize("frame,child", [("enu", "imu_link"), ("", "b"), ("wörld", "x" * 13)])
def test_odometry_matches_rclpy(frame, child):
    rng = np.random.default_rng(1)
    n = STAMPS.size
    pos, q, v, w = (rng.normal(size=(n, k)) for k in (3, 4, 3, 3))
    rows = odometry_batch("truth/odom", STAMPS, pos, q, v, w, frame_id=frame,
                          child_frame_id=child).payloads()
    for k in range(n):
        ref = convert.odometry_msg(int(STAMPS[k]), frame, child, pos[k], q[k], v[k], w[k])
        raw = rclpy_serialization.serialize_message(ref)
        assert rows.shape[1] == len(raw)
        assert rclpy_serialization.deserialize_message(rows[k].tobytes(), Odometry) == ref


@pytest.mark.parametrize("names", [["outer_gimbal", "inner_gimbal"], ["a"], ["x", "yy", "zzz"],
                                   ["spin_axis_azimuth", "spin_axis_elevation", "äöü", "k"]])
def test_joint_state_matches_rclpy(names):
    rng = np.random.default_rng(2)
    n, k = STAMPS.size, len(names)
    p, r = rng.normal(size=(n, k)), rng.normal(size=(n, k))
    rows = joint_state_batch("gyro/joint_states", STAMPS, names, p, r,
                             frame_id="imu_link").payloads()
    for i in range(n):
        ref = convert.joint_state_msg(int(STAMPS[i]), names, p[i], r[i])
        ref.header.frame_id = "imu_link"
        raw = rclpy_serialization.serialize_message(ref)
        assert rows.shape[1] == len(raw)
        assert rclpy_serialization.deserialize_message(rows[i].tobytes(), JointState) == ref


def test_bad_input_refused():
    with pytest.raises(ValueError, match="position"):
        odometry_batch("o", STAMPS, np.zeros((2, 3)), np.zeros((5, 4)), np.zeros((5, 3)),
                       np.zeros((5, 3)))
    with pytest.raises(ValueError, match="NUL"):
        joint_state_batch("j", STAMPS[:1], ["j"], [[0.0]], [[0.0]], frame_id="a\x00b")
    with pytest.raises(ValueError, match="NUL"):
        joint_state_batch("j", STAMPS[:1], ["j\x00"], [[0.0]], [[0.0]])
    with pytest.raises(ValueError, match="int32"):
        joint_state_batch("j", np.array([2**31 * 10**9]), ["j"], [[0.0]], [[0.0]])
    with pytest.raises(ValueError, match="at least one joint"):
        joint_state_batch("j", STAMPS[:1], [], np.zeros((1, 0)), np.zeros((1, 0)))
    with pytest.raises(ValueError, match="str"):
        joint_state_batch("j", STAMPS[:1], "abc", [[0.0]], [[0.0]])
    with pytest.raises(ValueError, match="velocities"):
        joint_state_batch("j", STAMPS[:2], ["a", "b"], np.zeros((2, 2)), np.zeros((2, 3)))


@pytest.mark.parametrize("frame", ["imu_link", "", "sensör"])
def test_magnetic_field_matches_rclpy(frame):
    from sensor_msgs.msg import MagneticField

    from gyro_attitude.io.cdr_arrays import magnetic_field_batch

    rng = np.random.default_rng(3)
    n = STAMPS.size
    b, cov = rng.normal(size=(n, 3)) * 1e-5, rng.normal(size=(n, 9)) * 1e-12
    rows = magnetic_field_batch("imu/mag", STAMPS, b, frame_id=frame,
                                magnetic_field_covariance=cov).payloads()
    for k in range(n):
        ref = convert.magnetic_field_msg(int(STAMPS[k]), frame, b[k], cov[k])
        raw = rclpy_serialization.serialize_message(ref)
        assert rows.shape[1] == len(raw)
        assert rclpy_serialization.deserialize_message(rows[k].tobytes(), MagneticField) == ref
