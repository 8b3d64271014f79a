"""``mcap_recorder``: record topics of the live ROS graph into a rosbag2-compatible MCAP.

Subscriptions are serialized (``raw=True``): messages go to the file as received, never
decoded.  A topic is subscribed as soon as a publisher for it appears (the graph is polled
every ``discovery_period_s``); its channel gets the publishers' offered QoS and type hash.
The subscription's QoS adapts to the publishers like rosbag2's: reliable only if every
publisher is reliable, transient-local only if every publisher is.

Output safety: an existing output is refused unless ``force`` is true; the recording is
written under a temporary name beside the output (a hidden ``.<name>.*.partial`` folder,
see :mod:`gyro_attitude.io.safe_output`) and renamed to the output once finished, so a
failed or killed recording never replaces a file under the requested name.  A full disk
ends the recording: it is cut back to its last whole chunk, ended as a valid MCAP, moved
to the output name, and one line says so (exit 1; :mod:`gyro_attitude.io.recording`).

Crash safety: the open chunk is closed and the file flushed every ``flush_period_s``
(default 0.5 s, at most 1 s), so ``kill -9`` loses at most that much and leaves a temporary
file whose complete chunks every reader here recovers.  SIGINT/SIGTERM finish the file
(summary, footer), rename it to the output and lose nothing.

Parameters: :func:`parameter_specs` (``config/mcap_recorder.yaml`` lists them all).
"""

from __future__ import annotations

import importlib
import os
import sys
import time
from pathlib import Path

from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rclpy.validate_full_topic_name import validate_full_topic_name
from rclpy.validate_topic_name import validate_topic_name

from gyro_attitude.io.mcap_writer import COMPRESSIONS, DEFAULT_COMPRESSION
from gyro_attitude.io.qos import qos_profile, qos_profiles_yaml
from gyro_attitude.io.recording import SafeRecording
from gyro_attitude.io.safe_output import check_output_path
from gyro_attitude.ros.node_main import run_node
from gyro_attitude.ros.params import ParameterError, ParamSpec, check_update, declare_all
from gyro_attitude.ros.qos import adapted_qos, offered_profiles

NODE_NAME = "mcap_recorder"
DEFAULT_TOPICS = ("imu/data_raw", "imu/data", "attitude", "truth/attitude")
MAX_FLUSH_PERIOD_S = 1.0  # the crash-safety promise: at most this much is lost to kill -9


def parameter_specs() -> list[ParamSpec]:
    return [
        ParamSpec("topics", DEFAULT_TOPICS,
                  "topics to record (relative names resolve in the node's namespace)"),
        ParamSpec("all_topics", False, "record every topic that has a publisher"),
        ParamSpec("output", "", "MCAP file (or bag directory) to write; "
                  "'' = bags/recording_<UTC time>.mcap"),
        ParamSpec("force", False, "replace an existing output (refused otherwise)"),
        ParamSpec("bag_directory", False,
                  "write a rosbag2 bag directory (MCAP file + metadata.yaml)"),
        ParamSpec("compression", DEFAULT_COMPRESSION,
                  "chunk compression (zstd as rosbag2's MCAP storage; '' = none)",
                  choices=COMPRESSIONS),
        ParamSpec("flush_period_s", 0.5, "close the open chunk and flush the file this often "
                  "[s]: the most a kill -9 loses", low=0.01, high=MAX_FLUSH_PERIOD_S),
        ParamSpec("discovery_period_s", 0.2, "poll the graph for new topics this often [s]",
                  low=0.01, high=10.0),
        ParamSpec("queue_depth", 1000, "subscription queue depth (keep last)", low=1,
                  high=100000),
    ]


def message_class(type_name: str):
    """The Python class of ``pkg/msg/Type`` (ValueError if its package is not installed)."""
    parts = type_name.split("/")
    if len(parts) != 3 or parts[1] != "msg":
        raise ValueError(f"unsupported type name {type_name!r} (expected pkg/msg/Type)")
    try:
        return getattr(importlib.import_module(f"{parts[0]}.msg"), parts[2])
    except (ImportError, AttributeError) as exc:
        raise ValueError(f"message type {type_name} is not installed: {exc}") from exc


def _is_bag_directory(path: Path) -> bool:
    """A rosbag2 bag directory (or an empty one): only ``metadata.yaml`` and ``.mcap`` files.
    Anything else in it is not ours to delete, even with force."""
    if path.is_symlink() or not path.is_dir():
        return False
    return all(e.is_file() and not e.is_symlink()
               and (e.name == "metadata.yaml" or e.suffix == ".mcap") for e in path.iterdir())


def _checked_output(out: str, *, force: bool) -> Path:
    """:func:`check_output_path`, except that with ``force`` an existing bag directory may be
    replaced (the check refuses every directory; :class:`SafeOutput` replaces one on commit)."""
    path = Path(out)
    if force and _is_bag_directory(path):
        parent = path.resolve().parent
        if not os.access(parent, os.W_OK | os.X_OK):
            raise ValueError(f"output directory {parent} is not writable")
        return path
    return check_output_path(path, force=force)


def offered_qos_yaml(endpoint_infos) -> str:
    """rosbag2 ``offered_qos_profiles`` YAML from ``get_publishers_info_by_topic``."""
    profiles = offered_profiles(endpoint_infos)
    return qos_profiles_yaml(profiles) if profiles else qos_profiles_yaml([qos_profile()])


class McapRecorderNode(Node):
    """Records serialized messages of the chosen topics into one MCAP file."""

    def __init__(self, **kwargs):
        super().__init__(NODE_NAME, **kwargs)
        specs = parameter_specs()
        self._specs = {s.name: s for s in specs}
        p = declare_all(self, specs)  # raises ParameterError naming a bad parameter
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self._topics = [self._resolved_topic(t) for t in p["topics"] if t]
        self._all = bool(p["all_topics"])
        if not self._topics and not self._all:
            raise ParameterError("parameter 'topics': empty list and all_topics is false")
        out = p["output"] or str(Path("bags") / time.strftime(
            "recording_%Y%m%d_%H%M%S.mcap", time.gmtime()))
        self._depth = int(p["queue_depth"])
        self._recording: SafeRecording | None = None
        try:
            self.output = _checked_output(out, force=bool(p["force"]))
            # Written under a temporary name beside the output and renamed by close(): a
            # failed or killed recording never replaces what the output name holds; a full
            # disk ends it readable under its name (OutputWriteError: one line, exit 1).
            self._recording = SafeRecording(
                self.output, force=p["force"], bag_directory=bool(p["bag_directory"]),
                compression=p["compression"], max_chunk_interval_s=float(p["flush_period_s"]))
        except (OSError, ValueError) as exc:
            raise ParameterError(f"parameter 'output': {exc}") from exc
        self.partial_path = self._recording.partial_path  # the file being written until close()
        self._subs: dict[str, object] = {}
        self._discover()
        self.create_timer(float(p["discovery_period_s"]), self._discover)
        self.create_timer(float(p["flush_period_s"]), self._flush)
        self.get_logger().info(
            f"recording {'all topics' if self._all else ', '.join(self._topics)} "
            f"to {self.output} (until finished: {self.partial_path})")

    def _resolved_topic(self, name: str) -> str:
        """The fully qualified name of ``name``; ParameterError naming it when invalid (rcl
        would otherwise fail later with a C source location)."""
        try:
            validate_topic_name(name)
            full = self.resolve_topic_name(name)
            validate_full_topic_name(full)
        except Exception as exc:  # rclpy's InvalidTopicNameException, or rcl's ValueError
            reason = str(exc).splitlines()[0].split(", at /")[0]
            raise ParameterError(f"parameter 'topics': {name!r} is not a valid topic name "
                                 f"({reason})") from None
        return full

    def _on_set_parameters(self, params) -> SetParametersResult:
        reason = check_update(self._specs, params)
        return SetParametersResult(successful=reason is None, reason=reason or "")

    def _discover(self) -> None:
        if self._recording.closed:
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
                self._recording.add_topic(name, type_name, offered_qos_yaml(infos))
            except ValueError as exc:
                self.get_logger().warning(f"not recording {name}: {exc}")
                self._subs[name] = None
                continue

            def callback(raw: bytes, info, topic=name) -> None:
                self._on_message(topic, raw, info)

            self._subs[name] = self.create_subscription(
                cls, name, callback, adapted_qos(offered_profiles(infos), self._depth),
                raw=True)
            self.get_logger().info(f"subscribed to {name} [{type_name}]")

    def _on_message(self, topic: str, raw: bytes, info) -> None:
        if self._recording.closed:
            return
        recv = time.time_ns()
        pub = None
        if isinstance(info, dict):
            pub = info.get("source_timestamp") or None
            recv = info.get("received_timestamp") or recv
        self._recording.write(topic, raw, recv, pub)

    def _flush(self) -> None:
        self._recording.flush()

    @property
    def message_count(self) -> int:
        return self._recording.message_count

    def close(self) -> None:
        """Finish the file (last chunk, metadata, summary, footer) and move it to the output
        name (idempotent)."""
        if self._recording is not None:
            self._recording.close()


def _close_and_report(node: McapRecorderNode) -> None:
    count = node.message_count
    node.close()
    print(f"mcap_recorder: wrote {count} messages to {node.output}", flush=True)


def main(args=None) -> int:
    """Record until SIGINT/SIGTERM (the file is finished with its summary and renamed to the
    output); exit 0, 2 on an invalid parameter or an existing output without force, 1 when
    the disk fills (the recording so far kept, readable, under the output name)."""
    return run_node(NODE_NAME, McapRecorderNode, args, finish=_close_and_report)



if __name__ == "__main__":
    sys.exit(main())
