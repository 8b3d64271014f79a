"""Schemas and type hashes against real rosbag2 output (reference/rosbag2/only_topics.mcap)."""

from __future__ import annotations

import pytest
from mcap.reader import make_reader

from gyro_attitude.io.ros2_schema import full_msg_definition, normalize_type_name, type_hash

DELIM = "\n" + "=" * 80 + "\nMSG: "


def _sections(text: str) -> list[tuple[str, str]]:
    """[(name, text)], the root named '' — rosbag2's concatenation split apart."""
    parts = text.split(DELIM)
    out = [("", parts[0])]
    for p in parts[1:]:
        name, _, body = p.partition("\n")
        out.append((name, body))
    return out


def _reference_schemas(reference_dir):
    with open(reference_dir / "only_topics.mcap", "rb") as f:
        summary = make_reader(f).get_summary()
    return summary


def test_schema_structure_matches_rosbag2(reference_dir):
    summary = _reference_schemas(reference_dir)
    checked = 0
    for schema in summary.schemas.values():
        if schema.name.startswith("rosbag2_interfaces/"):
            continue  # rosbag2_interfaces has no wheel here
        assert schema.encoding == "ros2msg"
        ours = _sections(full_msg_definition(schema.name))
        ref = _sections(schema.data.decode())
        assert [n for n, _ in ours] == [n for n, _ in ref], schema.name
        for (name, a), (_, b) in zip(ours, ref, strict=True):
            if name == "builtin_interfaces/Time":
                # The reference was written on rolling, whose Time.msg has longer comments
                # than the Jazzy wheel's; the field lines must agree.
                def fields(t):
                    return [ln for ln in t.splitlines() if ln and not ln.startswith("#")]
                assert fields(a) == fields(b)
            else:
                assert a == b, (schema.name, name)
        checked += 1
    assert checked == 2  # Log and ParameterEvent


def test_type_hashes_match_rosbag2(reference_dir):
    summary = _reference_schemas(reference_dir)
    for ch in summary.channels.values():
        name = summary.schemas[ch.schema_id].name
        if name.startswith("rosbag2_interfaces/"):
            continue
        assert type_hash(name) == ch.metadata["topic_type_hash"]


def test_imu_schema_dependency_order():
    # rosbag2: the root's dependencies in sorted order, depth first, each once.
    names = [n for n, _ in _sections(full_msg_definition("sensor_msgs/msg/Imu"))]
    assert names == ["", "geometry_msgs/Quaternion", "geometry_msgs/Vector3", "std_msgs/Header",
                     "builtin_interfaces/Time"]
    names = [n for n, _ in _sections(full_msg_definition("geometry_msgs/QuaternionStamped"))]
    assert names == ["", "geometry_msgs/Quaternion", "std_msgs/Header",
                     "builtin_interfaces/Time"]


def test_type_hash_format():
    h = type_hash("sensor_msgs/msg/Imu")
    assert h.startswith("RIHS01_") and len(h) == 7 + 64


@pytest.mark.parametrize("bad", ["Imu", "sensor_msgs/msg/", "a/b/c/d", "", "sensor msgs/Imu"])
def test_bad_type_names(bad):
    with pytest.raises(ValueError, match="not of the form"):
        normalize_type_name(bad)


def test_unknown_package_and_type():
    with pytest.raises(ValueError, match="no_such_pkg"):
        full_msg_definition("no_such_pkg/msg/Foo")
    with pytest.raises(ValueError, match="NoSuchType"):
        type_hash("sensor_msgs/msg/NoSuchType")
