"""Topics of a recording copied unchanged into an output MCAP (``replay`` passes ``/tf`` and
``/tf_static`` through).

Every message of the chosen topics keeps its bytes, log and publish time; its channel keeps
the recorded schema, offered QoS and type hash, so the message package need not be installed.
Messages come in log-time order (:meth:`McapStreamReader.iter_messages`); :meth:`TopicCopy.write_until`
interleaves them with the output's own messages so that the output stays in log-time order.
A recording whose summary lists none of the topics is not read a second time.
"""

from __future__ import annotations

from collections.abc import Iterator

from gyro_attitude.io.mcap_reader import McapStreamReader, RawMessage, bag_files, topic_matches

__all__ = ["PASSED_THROUGH_TOPICS", "TopicCopy"]

#: What ``replay`` copies from its input: where RViz and tf2 look for the frames.
PASSED_THROUGH_TOPICS = ("/tf", "/tf_static")


class TopicCopy:
    """Copy ``topics`` of the recording ``path`` (an MCAP file or bag directory) into a
    :class:`~gyro_attitude.io.mcap_writer.Rosbag2McapWriter`: call :meth:`write_until` with
    a log time before writing the output's messages up to it, and :meth:`write_rest` at the
    end. ``copied``: messages copied per topic."""

    def __init__(self, path, topics=PASSED_THROUGH_TOPICS, *, on_damage: str = "warn"):
        self._files = bag_files(path)
        self._topics = list(topics)
        self._on_damage = on_damage
        self._messages: Iterator[RawMessage] | None = None
        self._pending: RawMessage | None = None
        self._done = not self._topics or not self._recorded_anywhere()
        self.copied: dict[str, int] = {}

    def _recorded_anywhere(self) -> bool:
        """False only when every file's intact summary lists none of the topics."""
        for f in self._files:
            summary = McapStreamReader(f, on_damage="warn").summary()
            if summary is None or any(topic_matches(c.topic, t)
                                      for c in summary.channels.values() for t in self._topics):
                return True
        return False

    def _iter(self) -> Iterator[RawMessage]:
        for f in self._files:  # a split bag: file after file, as rosbag2 plays it
            reader = McapStreamReader(f, on_damage=self._on_damage)
            yield from reader.iter_messages(self._topics, log_time_order=True)

    def write_until(self, writer, log_time_ns: int | None) -> None:
        """Copy the messages logged at or before ``log_time_ns`` (None: all the rest)."""
        if self._done:
            return
        if self._messages is None:
            self._messages = self._iter()
        while True:
            m = self._pending
            if m is None:
                m = next(self._messages, None)
                if m is None:
                    self._done = True
                    return
            if log_time_ns is not None and m.log_time > log_time_ns:
                self._pending = m
                return
            self._pending = None
            self._copy(writer, m)

    def write_rest(self, writer) -> None:
        self.write_until(writer, None)

    def _copy(self, writer, m: RawMessage) -> None:
        ch = m.channel
        if ch.topic not in self.copied:
            schema = ch.schema
            if schema is None:  # a channel without schema cannot be a rosbag2 topic
                return
            writer.add_topic(ch.topic, schema.name, ch.metadata.get("offered_qos_profiles"),
                             recorded_schema=(schema.encoding, schema.data,
                                              ch.metadata.get("topic_type_hash", "")))
            self.copied[ch.topic] = 0
        writer.write(ch.topic, m.data, m.log_time, m.publish_time)
        self.copied[ch.topic] += 1
