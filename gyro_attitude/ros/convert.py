"""numpy <-> ROS 2 message conversion (the only module that builds/reads message fields).

Conventions (docs/conventions.md, REP-103, REP-145):

* Times are int nanoseconds; ``builtin_interfaces/Time`` holds ``sec`` (int32) and
  ``nanosec`` (uint32, < 1e9). Negative times and times past 2038 (int32 sec) are refused.
* Quaternions are numpy scalar-last ``(x, y, z, w)``, the field order of
  ``geometry_msgs/Quaternion``; no reordering anywhere.
* ``sensor_msgs/Imu``: ``angular_velocity`` in rad/s (ω_ib^b, sensor frame against
  inertial space), ``linear_acceleration`` = specific force in m/s². A 3x3 covariance
  (row-major, 9 floats) has element 0 = −1 when the field carries no estimate; all zeros
  means "estimate present, covariance unknown"; otherwise the diagonal holds per-axis
  variances.
"""

from __future__ import annotations

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import Quaternion, QuaternionStamped, Vector3
from nav_msgs.msg import Odometry
from sensor_msgs.msg import Imu, JointState, MagneticField

from gyro_attitude.core.attitude.nav_frame import odometry_velocity
from gyro_attitude.core.attitude.validation import NO_ESTIMATE, no_estimate
from gyro_attitude.core.rotation import as_quat_array, as_vector_array

__all__ = [
    "NO_ESTIMATE_COVARIANCE",
    "UNKNOWN_COVARIANCE",
    "ns_to_stamp",
    "stamp_to_ns",
    "quat_to_msg",
    "quat_from_msg",
    "vector3_to_msg",
    "vector3_from_msg",
    "covariance_from_variances",
    "variances_from_covariance",
    "imu_msg",
    "imu_arrays",
    "quaternion_stamped_msg",
    "odometry_msg",
    "odometry_velocity_parent",
    "joint_state_msg",
]

_NS = 1_000_000_000
_INT32_MAX = 2**31 - 1
_INF = float("inf")

# Element 0 = -1: "this field has no estimate" (REP-145 / sensor_msgs/Imu comments).
NO_ESTIMATE_COVARIANCE: tuple[float, ...] = (NO_ESTIMATE,) + (0.0,) * 8
# All zeros: "covariance unknown".
UNKNOWN_COVARIANCE: tuple[float, ...] = (0.0,) * 9


def ns_to_stamp(t_ns: int) -> Time:
    """``builtin_interfaces/Time`` of an int ns time (>= 0, sec within int32)."""
    t_ns = int(t_ns)
    if t_ns < 0:
        raise ValueError(f"time must be >= 0 ns for a ROS stamp, got {t_ns}")
    sec, nanosec = divmod(t_ns, _NS)
    if sec > _INT32_MAX:
        raise ValueError(f"time {t_ns} ns overflows the int32 seconds of a ROS stamp")
    return Time(sec=sec, nanosec=nanosec)


def stamp_to_ns(stamp) -> int:
    """Int ns of a ``builtin_interfaces/Time`` (or anything with ``sec``/``nanosec``)."""
    return int(stamp.sec) * _NS + int(stamp.nanosec)


def quat_to_msg(q) -> Quaternion:
    """``geometry_msgs/Quaternion`` of a scalar-last ``(4,)`` array (copied as is)."""
    x, y, z, w = as_quat_array(q).reshape(4).tolist()
    return Quaternion(x=x, y=y, z=z, w=w)


def quat_from_msg(msg) -> np.ndarray:
    """Scalar-last ``(4,)`` float array of a ``geometry_msgs/Quaternion``."""
    return np.array([msg.x, msg.y, msg.z, msg.w], dtype=np.float64)


def vector3_to_msg(v) -> Vector3:
    x, y, z = as_vector_array(v).reshape(3).tolist()
    return Vector3(x=x, y=y, z=z)


def vector3_from_msg(msg) -> np.ndarray:
    return np.array([msg.x, msg.y, msg.z], dtype=np.float64)


def covariance_from_variances(variances) -> list[float]:
    """Row-major 3x3 covariance with the given per-axis variances on the diagonal.

    ``None`` gives :data:`NO_ESTIMATE_COVARIANCE` (element 0 = −1). Negative or
    non-finite variances raise ``ValueError``.
    """
    if variances is None:
        return list(NO_ESTIMATE_COVARIANCE)
    var = np.asarray(variances, dtype=np.float64)
    if var.shape == ():
        var = np.full(3, float(var))
    if var.shape != (3,):
        raise ValueError(f"variances must be a scalar or shape (3,), got {var.shape}")
    a, b, c = var.tolist()  # scalar checks: numpy reductions cost more for three numbers
    if not (0.0 <= a < _INF and 0.0 <= b < _INF and 0.0 <= c < _INF):  # NaN fails too
        raise ValueError(f"variances must be finite and >= 0, got {[a, b, c]}")
    return [a, 0.0, 0.0, 0.0, b, 0.0, 0.0, 0.0, c]


def variances_from_covariance(cov) -> np.ndarray | None:
    """Diagonal of a 9-element covariance; ``None`` when element 0 is −1 (no estimate)
    or the matrix is all zeros (unknown)."""
    c = np.asarray(cov, dtype=np.float64).reshape(9)
    if no_estimate(c) or not np.any(c):
        return None
    return c[[0, 4, 8]].copy()


def imu_msg(
    t_ns: int,
    frame_id: str,
    angular_velocity,
    specific_force=None,
    gyro_variances=None,
    accel_variances=None,
    orientation=None,
    orientation_covariance=None,
) -> Imu:
    """``sensor_msgs/Imu`` of one sample.

    angular_velocity: ω_ib^b (3,) rad/s. specific_force: (3,) m/s² or ``None`` (the field
    is then zero with covariance element 0 = −1). gyro_variances / accel_variances: (3,)
    per-axis variances or ``None`` (no estimate of the covariance: all zeros for a field
    that has a value). orientation: scalar-last (4,) or ``None`` (no estimate: element 0 of
    the orientation covariance = −1). orientation_covariance: 9 floats, used with
    ``orientation``.
    """
    msg = Imu()
    msg.header.stamp = ns_to_stamp(t_ns)
    msg.header.frame_id = frame_id
    msg.angular_velocity = vector3_to_msg(angular_velocity)
    msg.angular_velocity_covariance = (
        covariance_from_variances(gyro_variances)
        if gyro_variances is not None
        else list(UNKNOWN_COVARIANCE)
    )
    if specific_force is None:
        msg.linear_acceleration_covariance = list(NO_ESTIMATE_COVARIANCE)
    else:
        msg.linear_acceleration = vector3_to_msg(specific_force)
        msg.linear_acceleration_covariance = (
            covariance_from_variances(accel_variances)
            if accel_variances is not None
            else list(UNKNOWN_COVARIANCE)
        )
    if orientation is None:
        msg.orientation_covariance = list(NO_ESTIMATE_COVARIANCE)
    else:
        msg.orientation = quat_to_msg(orientation)
        msg.orientation_covariance = (
            list(UNKNOWN_COVARIANCE)
            if orientation_covariance is None
            else [float(c) for c in orientation_covariance]
        )
    return msg


def magnetic_field_msg(t_ns: int, frame_id: str, field, covariance) -> MagneticField:
    """``sensor_msgs/MagneticField`` of one sample: ``field`` (3,) tesla, ``covariance`` 9
    floats (row-major, T²; all zeros: unknown, REP-145)."""
    msg = MagneticField()
    msg.header.stamp = ns_to_stamp(t_ns)
    msg.header.frame_id = frame_id
    msg.magnetic_field = vector3_to_msg(field)
    msg.magnetic_field_covariance = [float(c) for c in covariance]
    return msg


def magnetic_field_arrays(msg: MagneticField) -> tuple[int, np.ndarray]:
    """``(t_ns, field (3,) tesla)`` of a MagneticField message."""
    f = msg.magnetic_field
    return stamp_to_ns(msg.header.stamp), np.array([f.x, f.y, f.z], dtype=np.float64)


def imu_arrays(msg: Imu) -> tuple[int, str, np.ndarray, np.ndarray]:
    """``(t_ns, frame_id, angular_velocity (3,), specific_force (3,))`` of an Imu message."""
    av = msg.angular_velocity
    la = msg.linear_acceleration
    return (
        stamp_to_ns(msg.header.stamp),
        msg.header.frame_id,
        np.array([av.x, av.y, av.z], dtype=np.float64),
        np.array([la.x, la.y, la.z], dtype=np.float64),
    )


def quaternion_stamped_msg(t_ns: int, frame_id: str, q) -> QuaternionStamped:
    """``geometry_msgs/QuaternionStamped``; ``frame_id`` is the reference frame (e.g. the
    ENU nav frame for q_nb)."""
    msg = QuaternionStamped()
    msg.header.stamp = ns_to_stamp(t_ns)
    msg.header.frame_id = frame_id
    msg.quaternion = quat_to_msg(q)
    return msg


def odometry_msg(
    t_ns: int,
    frame_id: str,
    child_frame_id: str,
    position,
    q,
    linear_velocity_child,
    angular_velocity_child,
) -> Odometry:
    """``nav_msgs/Odometry``: pose (position, q) in ``frame_id``; twist in ``child_frame_id``
    (nav_msgs convention), i.e. body-frame linear velocity and ω_nb^b. Covariances stay
    zero (this is the truth)."""
    msg = Odometry()
    msg.header.stamp = ns_to_stamp(t_ns)
    msg.header.frame_id = frame_id
    msg.child_frame_id = child_frame_id
    px, py, pz = as_vector_array(position, "position").reshape(3).tolist()
    msg.pose.pose.position.x = px
    msg.pose.pose.position.y = py
    msg.pose.pose.position.z = pz
    msg.pose.pose.orientation = quat_to_msg(q)
    msg.twist.twist.linear = vector3_to_msg(linear_velocity_child)
    msg.twist.twist.angular = vector3_to_msg(angular_velocity_child)
    return msg


def odometry_velocity_parent(msg: Odometry) -> np.ndarray:
    """Linear velocity (3,) of a ``nav_msgs/Odometry`` expressed in its ``header.frame_id``.

    nav_msgs (REP-105) gives ``twist`` in ``child_frame_id``; when that is set and differs
    from ``header.frame_id`` the velocity is rotated into the parent frame with the pose
    orientation (which maps child vectors into the parent: ``v_parent = C(q) v_child``, as
    :func:`odometry_msg` and gyro_sim's ``truth/odom`` fill it with q_nb and the body
    velocity). An empty or equal ``child_frame_id`` means the twist is already in the
    parent frame. Raises ``ValueError`` on a non-finite velocity or a zero/non-finite
    orientation that would be needed."""
    return odometry_velocity(vector3_from_msg(msg.twist.twist.linear),
                             quat_from_msg(msg.pose.pose.orientation), msg.child_frame_id,
                             msg.header.frame_id)


def joint_state_msg(t_ns: int, names, positions, velocities) -> JointState:
    """``sensor_msgs/JointState`` of gimbal angles [rad] and rates [rad/s]."""
    names = [str(n) for n in names]
    pos = np.asarray(positions, dtype=np.float64).reshape(-1)
    vel = np.asarray(velocities, dtype=np.float64).reshape(-1)
    if pos.shape != (len(names),) or vel.shape != (len(names),):
        raise ValueError(
            f"joint positions {pos.shape} and velocities {vel.shape} must match "
            f"{len(names)} names"
        )
    msg = JointState()
    msg.header.stamp = ns_to_stamp(t_ns)
    msg.name = names
    msg.position = pos.tolist()
    msg.velocity = vel.tolist()
    return msg
