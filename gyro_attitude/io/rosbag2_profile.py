"""The rosbag2 (Jazzy) MCAP profile: schema and channel records, the ``rosbag2`` metadata
record, and a bag directory's ``metadata.yaml`` (version 9).

What ``ros2 bag record -s mcap`` writes (compared against real rosbag2 output in the tests):
header profile ``ros2``; one Schema per message type, encoding ``ros2msg``, data built from
the installed ``.msg`` files (:mod:`.ros2_schema`); one Channel per topic, message encoding
``cdr``, metadata ``offered_qos_profiles`` (:mod:`.qos`) and ``topic_type_hash``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from gyro_attitude.io.mcap_records import channel_record, metadata_record, schema_record
from gyro_attitude.io.qos import DEFAULT_QOS_YAML, parse_qos_profiles
from gyro_attitude.io.ros2_schema import full_msg_definition, normalize_type_name, type_hash
from gyro_attitude.io.strict_yaml import dump_yaml

__all__ = [
    "PROFILE",
    "MESSAGE_ENCODING",
    "Rosbag2Topic",
    "normalize_topic",
    "ros2_schema_record",
    "rosbag2_metadata",
    "rosbag2_metadata_record",
    "write_bag_metadata_yaml",
    "bag_directory_file",
]

PROFILE = "ros2"
MESSAGE_ENCODING = "cdr"
SCHEMA_ENCODING = "ros2msg"


def normalize_topic(topic: str) -> str:
    """Fully qualified topic name as rosbag2 stores it (leading ``/``)."""
    if not isinstance(topic, str) or not topic.strip("/"):
        raise ValueError(f"topic name must be a non-empty string, got {topic!r}")
    return topic if topic.startswith("/") else "/" + topic


def full_type_name(type_name: str) -> str:
    """``pkg/msg/Type`` for ``pkg/Type`` or ``pkg/msg/Type`` (ValueError otherwise)."""
    pkg, name = normalize_type_name(type_name)
    return f"{pkg}/msg/{name}"


def ros2_schema_record(schema_id: int, type_name: str) -> bytes:
    return schema_record(schema_id, type_name, SCHEMA_ENCODING,
                         full_msg_definition(type_name).encode("utf-8"))


@dataclass
class Rosbag2Topic:
    """One recorded topic: its channel, QoS and message count."""

    id: int
    topic: str
    type_name: str
    schema_id: int
    qos_yaml: str
    type_hash: str
    count: int = 0
    sequence: int = 0

    @classmethod
    def create(cls, channel_id: int, topic: str, type_name: str, schema_id: int,
               qos_profiles_yaml: str | None) -> Rosbag2Topic:
        qos = DEFAULT_QOS_YAML if qos_profiles_yaml is None else qos_profiles_yaml
        parse_qos_profiles(qos)  # validate before anything reaches the file
        return cls(channel_id, topic, type_name, schema_id, qos, type_hash(type_name))

    @classmethod
    def recorded(cls, channel_id: int, topic: str, type_name: str, schema_id: int,
                 qos_profiles_yaml: str | None, type_hash_: str) -> Rosbag2Topic:
        """A topic copied from a recording: its recorded QoS (the default profile when
        there is none or it does not parse) and type hash, no installed package looked up."""
        qos = qos_profiles_yaml or DEFAULT_QOS_YAML
        try:
            parse_qos_profiles(qos)
        except ValueError:
            qos = DEFAULT_QOS_YAML
        return cls(channel_id, topic, type_name, schema_id, qos, type_hash_)

    def channel_record(self) -> bytes:
        return channel_record(self.id, self.schema_id, self.topic, MESSAGE_ENCODING,
                              {"offered_qos_profiles": self.qos_yaml,
                               "topic_type_hash": self.type_hash})


def rosbag2_metadata(topics: list[Rosbag2Topic], file_name: str, message_count: int,
                     start_ns: int, end_ns: int, ros_distro: str) -> dict:
    """rosbag2's metadata (version 9) as a dict: the ``serialized_metadata`` of the
    ``rosbag2`` metadata record and the content of ``metadata.yaml``."""
    start = 0 if message_count == 0 else start_ns
    duration = 0 if message_count == 0 else end_ns - start_ns
    entries = [{
        "topic_metadata": {
            "name": t.topic,
            "type": t.type_name,
            "serialization_format": MESSAGE_ENCODING,
            "offered_qos_profiles": parse_qos_profiles(t.qos_yaml),
            "type_description_hash": t.type_hash,
        },
        "message_count": t.count,
    } for t in sorted(topics, key=lambda t: t.topic)]
    return {
        "version": 9,
        "storage_identifier": "mcap",
        "duration": {"nanoseconds": duration},
        "starting_time": {"nanoseconds_since_epoch": start},
        "message_count": message_count,
        "topics_with_message_count": entries,
        "compression_format": "",
        "compression_mode": "",
        "relative_file_paths": [file_name],
        "files": [{
            "path": file_name,
            "starting_time": {"nanoseconds_since_epoch": start},
            "duration": {"nanoseconds": duration},
            "message_count": message_count,
        }],
        "custom_data": None,
        "ros_distro": ros_distro,
    }


def rosbag2_metadata_record(meta: dict) -> bytes:
    text = dump_yaml(meta, default_flow_style=False).strip()
    return metadata_record("rosbag2", {"serialized_metadata": text})


def bag_directory_file(directory: Path) -> Path:
    """Create (or accept an empty) bag directory; the path of its one ``.mcap`` file."""
    directory = Path(directory)
    if directory.exists() and (not directory.is_dir() or any(directory.iterdir())):
        raise ValueError(f"bag directory {directory} exists and is not an empty directory")
    directory.mkdir(parents=True, exist_ok=True)
    return directory / f"{directory.name}_0.mcap"


def write_bag_metadata_yaml(directory: Path, meta: dict) -> None:
    with open(Path(directory) / "metadata.yaml", "w", encoding="utf-8") as f:
        f.write(dump_yaml({"rosbag2_bagfile_information": meta}, default_flow_style=False))
