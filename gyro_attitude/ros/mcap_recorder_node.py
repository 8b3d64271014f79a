"""``mcap_recorder``: record topics of the live ROS graph into a rosbag2-compatible MCAP.

Subscriptions are serialized (``raw=True``): messages go to the file as received, never
decoded.  A topic is subscribed as soon as a publisher for it appears (the graph is polled
every ``discovery_period_s``); its channel gets the publishers' offered QoS and type hash.
The subscription's QoS adapts to the publishers like rosbag2's: reliable only if every
publisher is reliable, transient-local only if every publisher is.

Crash safety: the open chunk is closed and the file flushed every ``flush_period_s``
(default 0.5 s, at most 1 s), so ``kill -9`` loses at most that much and leaves a file
whose complete chunks every reader here recovers.  SIGINT/SIGTERM finish the file
(summary, footer) and lose nothing.

Parameters: ``topics`` (string array; relative names resolve in the node's namespace),
``all_topics`` (record everything published), ``output`` (file; default
``bags/recording_<UTC time>.mcap``), ``bag_directory``, ``compression`` ('', zstd, lz4),
``flush_period_s``, ``discovery_period_s``, ``queue_depth``.
"""

from __future__ import annotations

import importlib
import sys
import time
from pathlib import Path

from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from gyro_attitude.io.mcap_writer import COMPRESSIONS, Rosbag2McapWriter
from gyro_attitude.io.qos import qos_profile, qos_profiles_yaml
from gyro_attitude.ros.node_main import run_node
from gyro_attitude.ros.params import ParameterError

DEFAULT_TOPICS = ["imu/data_raw", "imu/data", "attitude", "truth/attitude"]
MAX_FLUSH_PERIOD_S = 1.0


def message_class(type_name: str):
    """The Python class of ``pkg/msg/Type`` (ValueError if its package is not installed)."""
    parts = type_name.split("/")
    if len(parts) != 3 or parts[1] != "msg":
        raise ValueError(f"unsupported type name {type_name!r} (expected pkg/msg/Type)")
    try:
        return getattr(importlib.import_module(f"{parts[0]}.msg"), parts[2])
    except (ImportError, AttributeError) as exc:
        raise ValueError(f"message type {type_name} is not installed: {exc}") from exc


def _split_ns(duration) -> tuple[int, int]:
    ns = int(duration.nanoseconds)
    return divmod(ns, 1_000_000_000)


def offered_qos_yaml(endpoint_infos) -> str:
    """rosbag2 ``offered_qos_profiles`` YAML from ``get_publishers_info_by_topic``."""
    profiles = []
    for info in endpoint_infos:
        q = info.qos_profile
        profiles.append(qos_profile(
            history=int(q.history), depth=int(q.depth), reliability=int(q.reliability),
            durability=int(q.durability), deadline=_split_ns(q.deadline),
            lifespan=_split_ns(q.lifespan), liveliness=int(q.liveliness),
            liveliness_lease_duration=_split_ns(q.liveliness_lease_duration),
            avoid_ros_namespace_conventions=bool(q.avoid_ros_namespace_conventions)))
    return qos_profiles_yaml(profiles) if profiles else qos_profiles_yaml([qos_profile()])


def adapted_qos(endpoint_infos, depth: int) -> QoSProfile:
    """Subscription QoS compatible with every publisher (rosbag2's adaptation rule)."""
    infos = list(endpoint_infos)
    reliable = bool(infos) and all(
        i.qos_profile.reliability == ReliabilityPolicy.RELIABLE for i in infos)
    transient = bool(infos) and all(
        i.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL for i in infos)
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST, depth=depth,
        reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if transient else DurabilityPolicy.VOLATILE)


class McapRecorderNode(Node):
    """Records serialized messages of the chosen topics into one MCAP file."""

    def __init__(self, **kwargs):
        super().__init__("mcap_recorder", **kwargs)
        p = {
            "topics": self.declare_parameter("topics", list(DEFAULT_TOPICS)).value,
            "all_topics": self.declare_parameter("all_topics", False).value,
            "output": self.declare_parameter("output", "").value,
            "bag_directory": self.declare_parameter("bag_directory", False).value,
            "compression": self.declare_parameter("compression", "").value,
            "flush_period_s": self.declare_parameter("flush_period_s", 0.5).value,
            "discovery_period_s": self.declare_parameter("discovery_period_s", 0.2).value,
            "queue_depth": self.declare_parameter("queue_depth", 1000).value,
        }
        if p["compression"] not in COMPRESSIONS:
            raise ParameterError(f"parameter 'compression': {p['compression']!r} is not one "
                                 f"of {COMPRESSIONS}")
        if not 0.01 <= float(p["flush_period_s"]) <= MAX_FLUSH_PERIOD_S:
            raise ParameterError(f"parameter 'flush_period_s': {p['flush_period_s']} is not "
                                 f"in [0.01, {MAX_FLUSH_PERIOD_S}] s")
        if not 0.01 <= float(p["discovery_period_s"]) <= 10.0:
            raise ParameterError(f"parameter 'discovery_period_s': {p['discovery_period_s']} "
                                 "is not in [0.01, 10] s")
        if not 1 <= int(p["queue_depth"]) <= 100000:
            raise ParameterError(f"parameter 'queue_depth': {p['queue_depth']} is not in "
                                 "[1, 100000]")
        self._topics = [self.resolve_topic_name(t) for t in p["topics"] if t]
        self._all = bool(p["all_topics"])
        if not self._topics and not self._all:
            raise ParameterError("parameter 'topics': empty list and all_topics is false")
        out = p["output"] or str(Path("bags") / time.strftime(
            "recording_%Y%m%d_%H%M%S.mcap", time.gmtime()))
        self._depth = int(p["queue_depth"])
        try:
            self._writer = Rosbag2McapWriter(
                out, bag_directory=bool(p["bag_directory"]), compression=p["compression"],
                max_chunk_interval_s=float(p["flush_period_s"]))
        except (OSError, ValueError) as exc:
            raise ParameterError(f"parameter 'output': {exc}") from exc
        self.output = self._writer.path
        self._subs: dict[str, object] = {}
        self._discover()
        self.create_timer(float(p["discovery_period_s"]), self._discover)
        self.create_timer(float(p["flush_period_s"]), self._flush)
        self.get_logger().info(
            f"recording {'all topics' if self._all else ', '.join(self._topics)} "
            f"to {self.output}")

    def _discover(self) -> None:
        if self._writer is None:
            return
        for name, types in self.get_topic_names_and_types():
            if name in self._subs or not types:
                continue
            if not self._all and name not in self._topics:
                continue
            infos = self.get_publishers_info_by_topic(name)
            if not infos:
                continue  # only subscribers so far: the type's offered QoS is unknown
            type_name = types[0]
            try:
                cls = message_class(type_name)
                self._writer.add_topic(name, type_name, offered_qos_yaml(infos))
            except ValueError as exc:
                self.get_logger().warning(f"not recording {name}: {exc}")
                self._subs[name] = None
                continue

            def callback(raw: bytes, info, topic=name) -> None:
                self._on_message(topic, raw, info)

            self._subs[name] = self.create_subscription(
                cls, name, callback, adapted_qos(infos, self._depth), raw=True)
            self.get_logger().info(f"subscribed to {name} [{type_name}]")

    def _on_message(self, topic: str, raw: bytes, info) -> None:
        if self._writer is None:
            return
        recv = time.time_ns()
        pub = None
        if isinstance(info, dict):
            pub = info.get("source_timestamp") or None
            recv = info.get("received_timestamp") or recv
        self._writer.write(topic, raw, recv, pub)

    def _flush(self) -> None:
        if self._writer is not None:
            self._writer.flush()

    @property
    def message_count(self) -> int:
        return 0 if self._writer is None else self._writer.message_count

    def close(self) -> None:
        """Finish the file: last chunk, metadata, summary, footer (idempotent)."""
        if self._writer is not None:
            self._writer.finish()
            self._writer = None


def _close_and_report(node: McapRecorderNode) -> None:
    count = node.message_count
    node.close()
    print(f"mcap_recorder: wrote {count} messages to {node.output}", flush=True)


def main(args=None) -> int:
    """Record until SIGINT/SIGTERM (the file is finished with its summary); exit 0, or 2 on
    an invalid parameter."""
    return run_node("mcap_recorder", McapRecorderNode, args, finish=_close_and_report)



if __name__ == "__main__":
    sys.exit(main())
