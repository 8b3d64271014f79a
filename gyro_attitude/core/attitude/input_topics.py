"""The estimator's inputs each on their own topic (the rule replay and the node share).

A recording's reader keeps one message type per topic, and a node subscribing to one topic
with two types takes one type's messages for the other's; so the Imu, the truth, the odometry
and the magnetometer must be named apart.  A node's input must not be one of its own outputs
either: it would take every message it publishes back as input (``-r imu/data_raw:=imu/data``
integrates its own results; ``mag_topic:=imu/data`` reads Imu messages as fields).  The callers
give the names as they resolve them (replay: the name without its leading slash; the node:
namespace and remappings applied).
"""

from __future__ import annotations

from collections.abc import Iterable

__all__ = ["input_on_output", "input_on_output_message", "shared_output_message",
           "shared_topic", "shared_topic_message"]


def shared_topic(inputs: Iterable[tuple[str, str]]) -> tuple[str, str, str] | None:
    """``(role, earlier role, topic)`` for the first ``(role, topic)`` of ``inputs`` whose
    topic an earlier one has, else None."""
    seen: dict[str, str] = {}
    for role, topic in inputs:
        if topic in seen:
            return role, seen[topic], topic
        seen[topic] = role
    return None


def shared_topic_message(role: str, earlier: str, topic: str) -> str:
    return (f"{role}: topic {topic!r} is also the {earlier}; the Imu, truth, odometry and "
            f"magnetometer inputs each need their own topic")


def input_on_output(inputs: Iterable[tuple[str, str]],
                    outputs: Iterable[tuple[str, str]]) -> tuple[str, str, str] | None:
    """``(input role, output name, topic)`` for the first input whose topic is one of the
    ``outputs`` (``(name, topic)`` pairs), else None."""
    out = {topic: name for name, topic in outputs}
    for role, topic in inputs:
        if topic in out:
            return role, out[topic], topic
    return None


def input_on_output_message(role: str, output: str, topic: str) -> str:
    return (f"{role}: topic {topic!r} is the node's own output {output!r}; it would take "
            f"every message it publishes back as input")


def shared_output_message(output: str, earlier: str, topic: str) -> str:
    return (f"output {output!r}: topic {topic!r} is also the output {earlier!r}; a node's "
            f"outputs each need their own topic")
