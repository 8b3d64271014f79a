"""What gyro_sim publishes: topic names, types, frames and message fields of SimBlocks (numpy only).

The live node (``ros/gyro_sim_node.py``, rclpy messages) and the offline
``gyro-attitude simulate`` (``offline/simulate.py``, CDR arrays) both take their message
fields from :class:`SimTopics`, so the two produce the same messages for the same scene
and seed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gyro_attitude.core.earth import radii_of_curvature
from gyro_attitude.core.rotation import quat_conjugate, quat_rotate
from gyro_attitude.core.scene import SimBlock

__all__ = [
    "TOPICS",
    "IMU_TOPIC",
    "JOINT_TOPIC",
    "TRUTH_TOPIC",
    "ODOM_TOPIC",
    "MAG_TOPIC",
    "DEFAULT_FRAME_ID",
    "DEFAULT_WORLD_FRAME_ID",
    "TopicFields",
    "SimTopics",
    "local_enu_position",
]

IMU_TOPIC = "imu/data_raw"
JOINT_TOPIC = "gyro/joint_states"
TRUTH_TOPIC = "truth/attitude"
ODOM_TOPIC = "truth/odom"
MAG_TOPIC = "imu/mag"
TOPICS = {
    IMU_TOPIC: "sensor_msgs/msg/Imu",
    JOINT_TOPIC: "sensor_msgs/msg/JointState",
    TRUTH_TOPIC: "geometry_msgs/msg/QuaternionStamped",
    ODOM_TOPIC: "nav_msgs/msg/Odometry",
    MAG_TOPIC: "sensor_msgs/msg/MagneticField",
}
DEFAULT_FRAME_ID = "imu_link"  # Imu header, odometry child frame, joint states
DEFAULT_WORLD_FRAME_ID = "enu"  # truth/attitude and truth/odom header


def local_enu_position(llh: np.ndarray, llh0: np.ndarray) -> np.ndarray:
    """Position (east, north, up) [m] of geodetic ``llh (n,3)`` relative to ``llh0 (3,)`` on
    the tangent plane at the start (first order in the offsets: good to ~1e-6 relative
    for the km-scale paths of the scenes)."""
    r_m, r_n = radii_of_curvature(llh0[0])
    h0 = llh0[2]
    # the longitude difference wrapped to [−π, π): a path across the antimeridian (lon +π to
    # −π) is a few metres east, not the Earth's circumference west
    dlon = np.remainder(llh[:, 1] - llh0[1] + np.pi, 2.0 * np.pi) - np.pi
    east = dlon * (r_n + h0) * np.cos(llh0[0])
    north = (llh[:, 0] - llh0[0]) * (r_m + h0)
    return np.stack([east, north, llh[:, 2] - h0], axis=-1)


@dataclass
class TopicFields:
    """Message fields of ``n`` samples.

    ``t_rel_ns`` stamps relative to the scene's first sample (the publisher adds its own
    start); Imu: ``angular_velocity``, ``specific_force`` (``None``: no accelerometer);
    truth: ``q_nb``; odometry: ``position_enu`` (m, from the first sample), ``q_nb``,
    ``velocity_body`` (child frame), ``omega_nb_b``; joint states (free gyro only):
    ``gimbal_names``, ``gimbal_angles``, ``gimbal_rates`` (else ``None``); magnetometer:
    ``magnetic_field`` (tesla, else ``None``).
    """

    t_rel_ns: np.ndarray
    angular_velocity: np.ndarray
    specific_force: np.ndarray | None
    q_nb: np.ndarray
    position_enu: np.ndarray | None
    velocity_body: np.ndarray | None
    omega_nb_b: np.ndarray
    gimbal_names: tuple[str, ...] | None = None
    gimbal_angles: np.ndarray | None = None
    gimbal_rates: np.ndarray | None = None
    magnetic_field: np.ndarray | None = None


class SimTopics:
    """Turns consecutive :class:`SimBlock` s of one run into :class:`TopicFields`; the
    first sample fixes the ENU origin of the odometry and the zero of the stamps."""

    def __init__(self):
        self.llh0: np.ndarray | None = None
        self.t0_ns: int | None = None

    def fields(self, b: SimBlock, truth: bool = True) -> TopicFields:
        """Fields of the block; ``truth=False`` leaves the odometry fields ``None``."""
        n = int(np.shape(b.t_ns)[0])
        if self.llh0 is None and n:
            self.llh0 = np.asarray(b.position_llh[0], dtype=np.float64).copy()
            self.t0_ns = int(b.t_ns[0])
        q = np.asarray(b.truth_q_nb, dtype=np.float64)
        pos = v_body = None
        if truth:
            llh = np.asarray(b.position_llh, dtype=np.float64)
            pos = local_enu_position(llh, self.llh0) if n else np.zeros((0, 3))
            v_body = quat_rotate(quat_conjugate(q), np.asarray(b.velocity_enu, dtype=np.float64))
        g = b.gimbal
        return TopicFields(
            t_rel_ns=np.asarray(b.t_ns, dtype=np.int64) - (self.t0_ns or 0),
            angular_velocity=np.asarray(b.omega_ib_b, dtype=np.float64),
            specific_force=(None if b.specific_force_b is None
                            else np.asarray(b.specific_force_b, dtype=np.float64)),
            q_nb=q,
            position_enu=pos,
            velocity_body=v_body,
            omega_nb_b=np.asarray(b.truth_omega_nb_b, dtype=np.float64),
            gimbal_names=None if g is None else tuple(str(x) for x in g.names),
            gimbal_angles=None if g is None else np.asarray(g.positions, dtype=np.float64),
            gimbal_rates=None if g is None else np.asarray(g.velocities, dtype=np.float64),
            magnetic_field=(None if b.magnetic_field_b is None
                            else np.asarray(b.magnetic_field_b, dtype=np.float64)),
        )
