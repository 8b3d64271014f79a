"""The estimator's inputs each on their own topic (the rule replay and the node share).

A recording's reader keeps one message type per topic, and a node subscribing to one topic
with two types takes one type's messages for the other's; so the Imu, the truth, the odometry
and the magnetometer must be named apart.  The callers give the names as they resolve them
(replay: the name without its leading slash; the node: namespace and remappings applied).
"""

from __future__ import annotations

from collections.abc import Iterable

__all__ = ["shared_topic", "shared_topic_message"]


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
