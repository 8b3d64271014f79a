"""TF: an attitude as a tf2 transform on ``/tf``, where RViz and ``tf2_echo`` look for it.

The nodes' ``publish_tf`` sends, per published attitude, one ``tf2_msgs/TFMessage`` holding a
``geometry_msgs/TransformStamped`` from a world frame to the sensor frame (rotation = the
attitude q_nb, translation zero, stamp = the attitude's), as imu_tools' filters do and with
the QoS of tf2's ``TransformBroadcaster`` (reliable, volatile, keep last 100).

``tf2_msgs`` is not among the Jazzy wheels the pip-only set-up installs: ``dev.sh`` builds it
into the virtual environment from ``interfaces/tf2_msgs`` (needs a C/C++ compiler and CMake),
a system ROS provides it. Without it ``publish_tf`` is refused in one line
(:data:`TF2_MSGS_MISSING`) and everything else runs.
"""

from __future__ import annotations

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from gyro_attitude.io.cdr_arrays import TransformCdr
from gyro_attitude.ros.params import ParameterError

__all__ = ["TF_TOPIC", "TF_STATIC_TOPIC", "TF_TYPE", "TF2_MSGS_HOW", "TF2_MSGS_MISSING", "tf_message_class",
           "tf_qos", "tf_static_qos", "TfBroadcaster"]

TF_TOPIC = "/tf"
TF_STATIC_TOPIC = "/tf_static"
TF_TYPE = "tf2_msgs/msg/TFMessage"
TF2_MSGS_HOW = ("source a ROS 2 install, or run `bash dev.sh` (builds it into the venv; needs "
                "a C/C++ compiler, CMake and the Python headers)")
TF2_MSGS_MISSING = f"parameter 'publish_tf': the ROS package tf2_msgs is not installed: {TF2_MSGS_HOW}"


def tf_message_class():
    """``tf2_msgs.msg.TFMessage``, or None when tf2_msgs is not installed."""
    try:
        from tf2_msgs.msg import TFMessage
    except ImportError:
        return None
    return TFMessage


def tf_qos() -> QoSProfile:
    """tf2_ros' ``DynamicBroadcasterQoS``: reliable, volatile, keep last 100."""
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100,
                      reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.VOLATILE)


def tf_static_qos(depth: int) -> QoSProfile:
    """``/tf_static`` as tf2's static broadcaster and listeners have it: reliable and
    transient local (a listener joining later still gets the transforms)."""
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=int(depth),
                      reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL)


class TfBroadcaster:
    """Sends rotations from ``parent`` to a child frame on ``/tf``, serialized in place
    (:class:`~gyro_attitude.io.cdr_arrays.TransformCdr`) rather than built as Python messages
    at the sample rate. Raises :class:`ParameterError` (:data:`TF2_MSGS_MISSING`) when
    tf2_msgs is not installed, or naming the frame that cannot be one (``child``, when
    known at start: not the parent)."""

    def __init__(self, node, parent: str, child: str | None = None):
        cls = tf_message_class()
        if cls is None:
            raise ParameterError(TF2_MSGS_MISSING)
        if not parent:
            raise ParameterError("parameter 'world_frame_id': empty, the TF parent frame")
        if child is not None and child == parent:  # tf2 refuses a frame's transform to itself
            raise ParameterError(f"parameter 'publish_tf': the child frame {child!r} is the "
                                 "parent frame (world_frame_id)")
        self._cdr = TransformCdr(parent)
        self._pub = node.create_publisher(cls, TF_TOPIC, tf_qos())

    def send(self, stamp_cdr: bytes, child: str, x: float, y: float, z: float,
             w: float) -> bool:
        """Publish one transform (``stamp_cdr``: the 8 serialized stamp bytes) when somebody
        listens; whether it went out."""
        if not self._pub.get_subscription_count():
            return False
        self._pub.publish(self._cdr.encode(stamp_cdr, child, x, y, z, w))
        return True

    def encode(self, stamp_cdr: bytes, child: str, x: float, y: float, z: float,
               w: float) -> bytes:
        """The serialized message :meth:`send` publishes (e.g. for a recording too)."""
        return self._cdr.encode(stamp_cdr, child, x, y, z, w)

    def publish(self, raw: bytes) -> bool:
        """Publish a message from :meth:`encode` when somebody listens; whether it went out."""
        if not self._pub.get_subscription_count():
            return False
        self._pub.publish(raw)
        return True
