"""``mcap_player``: republish a recording with its original timing, a rate factor,
looping and ``/clock``.

Messages are published serialized in log-time order (each one is checked to deserialize
as its type: one that does not, e.g. truncated, is skipped and named, as replay skips
it), read by the package's one
MCAP reader (:class:`gyro_attitude.io.mcap_reader.McapStreamReader`): streamed chunk by chunk
when the summary says where chunks start, else (a recorder killed with ``kill -9``) every
readable message sorted in memory.  Publishers get the
recorded offered QoS (reliable / transient-local only if every recorded publisher was);
``/tf_static`` is always reliable and transient local, as tf2's listeners take it.

Parameters: :func:`parameter_specs` (``config/mcap_player.yaml`` lists them all). An input
that cannot be read (empty, not MCAP, damaged beyond what the reader recovers) ends the node
with one line naming the file and the problem, exit status 1.
"""

from __future__ import annotations

import struct
import sys
import threading
import time
from pathlib import Path

import rclpy
from mcap.exceptions import McapError
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rclpy.task import Future

from gyro_attitude.io.imu_fast import deserialized
from gyro_attitude.io.mcap_reader import (
    UNFINISHED,
    McapStreamReader,
    bag_files,
    match_topic,
)
from gyro_attitude.io.mcap_records import MAGIC
from gyro_attitude.io.qos import parse_qos_profiles
from gyro_attitude.ros.mcap_recorder_node import message_class
from gyro_attitude.ros.node_main import InputError, run_node
from gyro_attitude.ros.params import ParameterError, ParamSpec, check_update, declare_all
from gyro_attitude.ros.qos import adapted_qos
from gyro_attitude.ros.tf import TF2_MSGS_HOW, TF_STATIC_TOPIC, TF_TYPE, tf_static_qos

NODE_NAME = "mcap_player"
PLAYBACK_QUEUE_DEPTH = 1000


def parameter_specs() -> list[ParamSpec]:
    return [
        ParamSpec("input", "", "recording to play: an MCAP file or a rosbag2 bag directory "
                  "(required)"),
        ParamSpec("rate", 1.0, "playback speed factor (2 = twice as fast)", low=1e-3,
                  high=1e3),
        ParamSpec("loop", False, "start over at the end, until stopped"),
        ParamSpec("publish_clock", True, "publish rosgraph_msgs/Clock on /clock with the bag "
                  "time"),
        ParamSpec("clock_rate_hz", 100.0, "/clock messages per wall-clock second", low=0.1,
                  high=10000.0),
        ParamSpec("topics", ("",), "recorded topics to play ([''] = all)"),
        ParamSpec("namespace_topics", False, "publish recorded names without the leading '/' "
                  "so that the node's namespace applies"),
        ParamSpec("wait_for_subscribers", 0, "before starting, wait until every topic has "
                  "this many subscribers", low=0, high=1000),
        ParamSpec("wait_timeout_s", 10.0, "give up waiting for subscribers after [s]",
                  low=0.0, high=3600.0),
    ]


def check_recording_start(path) -> None:
    """InputError unless ``path`` starts like an MCAP file (checked before any playing, so
    an empty or foreign file is named as such instead of playing nothing)."""
    try:
        with open(path, "rb") as f:
            head = f.read(len(MAGIC))
    except OSError as exc:
        raise InputError(f"{path}: {exc.strerror or exc}") from exc
    if not head:
        raise InputError(f"{path}: empty file")
    if head != MAGIC:
        raise InputError(f"{path}: not an MCAP file (no MCAP magic at the start)")


def iter_log_time_order(paths, topics: list[str] | None, damages: list[str] | None = None):
    """(topic, type_name, offered_qos_yaml, log_time, data) in log-time order within each of
    ``paths`` (a split bag's files, one after the other, as rosbag2 plays them); damage met
    on the way (skipped by the reader) is appended to ``damages`` when given."""
    for path in paths:
        reader = McapStreamReader(path, on_damage="warn")
        wanted = None
        if topics is not None:
            summary = reader.summary()
            recorded = [c.topic for c in (summary.channels if summary else reader.channels)
                        .values()]
            wanted = [match_topic(recorded, t) or t for t in topics]
        for m in reader.iter_messages(wanted, log_time_order=True):
            yield (m.channel.topic, m.channel.type_name,
                   m.channel.metadata.get("offered_qos_profiles", ""), m.log_time, m.data)
        if damages is not None:
            damages.extend(d for d in reader.damages if d not in damages)


def _file_channels(path) -> list[tuple[str, str, str]]:
    reader = McapStreamReader(path, on_damage="warn")
    summary = reader.summary()
    if summary is not None and summary.channels:
        channels = summary.channels
    else:  # no summary: walk the file, channels register as met
        for _ in reader.iter_chunks():
            pass
        channels = reader.channels
    return [(c.topic, c.type_name, c.metadata.get("offered_qos_profiles", ""))
            for c in channels.values()]


def recorded_channels(paths, topics: list[str] | None) -> list[tuple[str, str, str]]:
    """(topic, type_name, offered_qos_yaml) of the channels recorded in ``paths``
    (optionally a subset; the first file that records a topic gives its type and QoS);
    InputError naming the recorded topics when a requested topic is not among them."""
    chans = []
    for path in paths:
        known = {c[0] for c in chans}
        chans += [c for c in _file_channels(path) if c[0] not in known]
    recorded = [c[0] for c in chans]
    if topics is None:
        return chans
    missing = [t for t in topics if match_topic(recorded, t) is None]
    if missing:
        raise InputError(f"parameter 'topics': {', '.join(missing)} not in the recording; "
                         f"it has: {', '.join(sorted(recorded)) or 'no topics'}")
    wanted = {match_topic(recorded, t) for t in topics}
    return [c for c in chans if c[0] in wanted]


class McapPlayerNode(Node):
    """Republishes the messages of one recording with their recorded timing."""

    def __init__(self, **kwargs):
        super().__init__(NODE_NAME, **kwargs)
        specs = parameter_specs()
        self._specs = {s.name: s for s in specs}
        p = declare_all(self, specs)  # raises ParameterError naming a bad parameter
        self.add_on_set_parameters_callback(self._on_set_parameters)
        if not p["input"]:
            raise ParameterError("parameter 'input': the recording to play is required")
        try:
            self.paths = bag_files(p["input"])  # a split bag: its files in rosbag2's order
        except ValueError as exc:
            raise ParameterError(f"parameter 'input': {exc}") from exc
        self.path = self.paths[0] if len(self.paths) == 1 else Path(p["input"])
        for path in self.paths:
            check_recording_start(path)
        self.rate = p["rate"]
        self.loop = p["loop"]
        self.clock_period = 1.0 / p["clock_rate_hz"]
        self.topics = [t for t in p["topics"] if t] or None
        self.namespace_topics = p["namespace_topics"]
        self.wait_for_subscribers = p["wait_for_subscribers"]
        self.wait_timeout_s = p["wait_timeout_s"]
        self._pubs: dict[str, object] = {}
        self._classes: dict[str, type] = {}  # message class per played topic
        self._clock_pub = None
        if p["publish_clock"]:
            from rosgraph_msgs.msg import Clock

            self._clock_cls = Clock
            self._clock_pub = self.create_publisher(Clock, "/clock", 10)
        self.published = 0
        self.damages: list[str] = []  # damage the reader met and skipped, in file order
        self.undecodable: dict[str, int] = {}  # topic -> messages skipped as undecodable
        self.damage_reported = False

    def _on_set_parameters(self, params) -> SetParametersResult:
        reason = check_update(self._specs, params)
        return SetParametersResult(successful=reason is None, reason=reason or "")

    def _publisher(self, topic: str, type_name: str, qos_yaml: str):
        if topic not in self._pubs:
            name = topic.lstrip("/") if self.namespace_topics else topic
            try:
                cls = message_class(type_name)
            except ValueError as exc:
                how = f" ({TF2_MSGS_HOW})" if type_name == TF_TYPE else ""
                self.get_logger().warning(f"not playing {topic}: {exc}{how}")
                self._pubs[topic] = None
                return None
            self._classes[topic] = cls
            try:
                profiles = parse_qos_profiles(qos_yaml)
            except ValueError:
                profiles = []  # unreadable offered QoS: the rule's safe default
            # /tf_static as tf2 has it whatever the recording says (transient local: a
            # listener started later still gets the static transforms); /tf as recorded
            qos = (tf_static_qos(PLAYBACK_QUEUE_DEPTH) if topic == TF_STATIC_TOPIC
                   else adapted_qos(profiles, PLAYBACK_QUEUE_DEPTH))
            self._pubs[topic] = self.create_publisher(cls, name, qos)
        return self._pubs[topic]

    def _decodes(self, topic: str, type_name: str, log_time: int, data) -> bool:
        """Whether ``data`` deserializes as its type: a message that does not (truncated)
        is skipped and named, as replay skips it, instead of reaching subscribers that
        cannot read it."""
        _, problem = deserialized(data, self._classes[topic], topic, type_name, log_time)
        if problem is None:
            return True
        n = self.undecodable[topic] = self.undecodable.get(topic, 0) + 1
        if n == 1:  # the first per topic is named; the count is in the final report
            self.get_logger().warning(f"{problem}: skipped")
            self.damages.append(problem)
        return False

    def _publish_clock(self, bag_ns: int) -> None:
        msg = self._clock_cls()
        msg.clock.sec, msg.clock.nanosec = divmod(int(bag_ns), 1_000_000_000)
        self._clock_pub.publish(msg)

    def _wait_for_subscribers(self, topics) -> None:
        if self.wait_for_subscribers <= 0:
            return
        end = time.monotonic() + self.wait_timeout_s
        while rclpy.ok() and time.monotonic() < end:
            pubs = [self._pubs[t] for t in topics if self._pubs.get(t) is not None]
            if all(p.get_subscription_count() >= self.wait_for_subscribers for p in pubs):
                # Discovery is two-sided: our writers see the readers, but a reader may not
                # have matched a writer yet and would drop the first samples. Settle briefly
                # (the same 0.25 s as gyro_sim).
                time.sleep(0.25)
                return
            time.sleep(0.02)
        self.get_logger().warning("starting without all subscribers")

    def play_once(self) -> int:
        """Publish the whole recording once with its timing; returns messages published."""
        # Publishers for every channel before the clock starts (discovery takes time).
        for topic, type_name, qos_yaml in recorded_channels(self.paths, self.topics):
            self._publisher(topic, type_name, qos_yaml)
        self._wait_for_subscribers(list(self._pubs))
        msgs = iter_log_time_order(self.paths, self.topics, self.damages)
        first = next(msgs, None)
        if first is None:
            return 0
        t0 = first[3]
        wall0 = time.monotonic()
        next_clock = wall0
        count = 0

        def all_msgs():
            yield first
            yield from msgs

        for topic, type_name, qos_yaml, log_time, data in all_msgs():
            if not rclpy.ok():
                break
            target = wall0 + (log_time - t0) * 1e-9 / self.rate
            while True:
                now = time.monotonic()
                if self._clock_pub is not None and now >= next_clock:
                    self._publish_clock(t0 + int((now - wall0) * self.rate * 1e9))
                    next_clock += self.clock_period
                if now >= target:
                    break
                wake = target if self._clock_pub is None else min(target, next_clock)
                time.sleep(max(0.0, min(wake - now, 0.05)))
            pub = self._publisher(topic, type_name, qos_yaml)
            if pub is not None and self._decodes(topic, type_name, log_time, data):
                pub.publish(data)
                count += 1
                self.published += 1  # counted at once: an interrupted pass reports it too
        return count


def _serve(executor, stop: Future) -> None:
    """Spin ``executor`` (the player's parameter services) until ``stop`` is done or a
    signal shuts the context down."""
    try:
        executor.spin_until_future_complete(stop)
    except Exception:  # a signal shut the context down under it: the play loop ends too
        if rclpy.ok():
            raise


def _play(node: McapPlayerNode, executor) -> None:
    node.get_logger().info(f"playing {node.path} at rate {node.rate:g}"
                           + (" (loop)" if node.loop else ""))
    # The play loop keeps this thread (it sleeps to the next message's time); parameter
    # services (set/get/describe/list) are answered meanwhile by the node's executor on a
    # thread of its own. Publishing from one thread while another spins is safe in rclpy.
    # That thread is stopped (``stop`` wakes its wait) and joined before this returns:
    # run_node shuts the executor down and destroys the node only after, so no thread is
    # inside the executor's wait when its guard conditions and the node's handles go.
    stop = Future()
    services = threading.Thread(target=_serve, args=(executor, stop),
                                name="mcap_player_services", daemon=True)
    services.start()
    try:
        _play_passes(node)
    finally:
        stop.set_result(None)  # its done callback wakes the executor's wait set
        services.join()


def _play_passes(node: McapPlayerNode) -> None:
    try:
        while rclpy.ok():
            n = node.play_once()
            if node.damages and not node.damage_reported:
                node.damage_reported = True
                node.get_logger().warning(f"{node.damages[0]} (skipped; "
                                          f"{len(node.damages)} damaged place(s) in all)")
            if n == 0 or not node.loop:
                break
    except InputError:
        raise
    except (ValueError, OSError, EOFError, struct.error, McapError) as exc:
        # whatever reading the recording raises (the mcap package's own errors included)
        raise InputError(f"{node.path}: {exc}") from exc
    damaged = [d for d in node.damages if not d.endswith(UNFINISHED)]
    if node.published == 0 and not damaged and rclpy.ok():
        # e.g. a file holding only the MCAP magic: playing nothing is not success
        raise InputError(f"{node.path}: no messages"
                         + (f" on {', '.join(node.topics)}" if node.topics else ""))
    if damaged:
        # everything readable was played; the exit status still says the input was damaged
        # (an unfinished recording -- a killed recorder's leftover -- is only warned about)
        raise InputError(f"{damaged[0]} (played the {node.published} readable messages)")


def _report(node: McapPlayerNode) -> None:
    skipped = "".join(f"; skipped {n} on {t} that did not deserialize"
                      for t, n in node.undecodable.items())
    print(f"mcap_player: published {node.published} messages{skipped}", flush=True)


def main(args=None) -> int:
    """Play the recording (once, or looping until SIGINT/SIGTERM); exit 0, 2 on an invalid
    parameter, 1 on a recording that cannot be read."""
    return run_node(NODE_NAME, McapPlayerNode, args, spin=_play, finish=_report)



if __name__ == "__main__":
    sys.exit(main())
