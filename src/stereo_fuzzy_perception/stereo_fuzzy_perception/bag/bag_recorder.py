"""Record topics from the ROS graph into a new MCAP bag, as serialized bytes.

What `ros2 bag record` does, for this project's needs: named topics, a regex or all of them
(found as they appear), minus exclusions; each message stamped with its receive time, the
publishers' offered QoS in the metadata (or a QoS override file's), custom types' definitions
in the file; files split by size or duration. Topics whose type is not installed are skipped
with a warning. Stops on Ctrl-C, after N messages or after a duration, and always closes the
bag so it stays readable.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from rclpy.executors import Executor, ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import QoSProfile
from rclpy.subscription import Subscription

from stereo_fuzzy_perception.bag.bag_format import absolute_topic
from stereo_fuzzy_perception.bag.bag_qos import profile_to_bag_qos, recording_profile
from stereo_fuzzy_perception.bag.bag_writer import BagWriter
from stereo_fuzzy_perception.bag.message_types import MessageTypeError, import_message_class
from stereo_fuzzy_perception.bag.topic_selection import select_topics

# Topics `--all` leaves out: every node's log and parameter events.
EXCLUDED_FROM_ALL = ('/rosout', '/parameter_events')


@dataclass(frozen=True)
class RecordOptions:
    """What to record and when to stop.

    Attributes:
        output: Bag directory to create.
        topics: Topics to record (absolute names).
        all_topics: Record every topic that appears, except EXCLUDED_FROM_ALL and hidden ones.
        regex: Also record the topics matching this regular expression.
        exclude_topics: Never record these topics.
        exclude_regex: Never record the topics matching this regular expression.
        qos_overrides: {topic: QoS to subscribe with}, instead of what the publishers offer.
        max_messages: Stop after this many messages in total (None: no limit).
        duration_s: Stop after this long [s] (None: no limit).
        compression: 'zstd' (MCAP chunk compression) or 'none'.
        max_bag_size: Split the bag into files of about this many bytes (0: one file).
        max_bag_duration_s: Split the bag into files of this much time [s] (0: one file).
        discovery_period_s: How often to look for the topics on the graph [s].
    """

    output: Path
    topics: tuple[str, ...] = ()
    all_topics: bool = False
    regex: str | None = None
    exclude_topics: tuple[str, ...] = ()
    exclude_regex: str | None = None
    qos_overrides: dict[str, QoSProfile] = field(default_factory=dict)
    max_messages: int | None = None
    duration_s: float | None = None
    compression: str = 'zstd'
    max_bag_size: int = 0
    max_bag_duration_s: float = 0.0
    discovery_period_s: float = 0.1


class BagRecorder:
    """Subscribes raw to the topics on `node` and writes what arrives into a new bag."""

    def __init__(self, node: Node, options: RecordOptions) -> None:
        """Create the bag directory (nothing is subscribed until discover() finds publishers).

        Raises:
            BagError: When the output exists.
        """
        self.node = node
        self.options = options
        self.wanted = {absolute_topic(name) for name in options.topics}
        self.bag = BagWriter(options.output, compression=options.compression,
                             max_bag_size=options.max_bag_size,
                             max_bag_duration_ns=round(options.max_bag_duration_s * 1e9))
        self.subscriptions: dict[str, Subscription] = {}
        self.skipped: set[str] = set()
        self.counts: dict[str, int] = {}
        self.message_count = 0

    def _wants(self, topic: str) -> bool:
        options = self.options
        if topic in self.skipped:
            return False
        named = topic in self.wanted
        if not named and options.all_topics:
            hidden = any(part.startswith('_') for part in topic.split('/'))
            if topic in EXCLUDED_FROM_ALL or hidden:
                return False
        elif not named and options.regex is None:
            return False
        if options.all_topics:
            return bool(select_topics([topic], None, None, options.exclude_topics,
                                      options.exclude_regex))
        return bool(select_topics([topic], self.wanted, options.regex, options.exclude_topics,
                                  options.exclude_regex))

    def discover(self) -> list[str]:
        """Subscribe to wanted topics that have appeared; return the ones newly subscribed."""
        added = []
        for topic, types in self.node.get_topic_names_and_types():
            if topic in self.subscriptions or not self._wants(topic) or not types:
                continue
            msgtype = types[0]
            if len(types) > 1:
                self.node.get_logger().warning(
                    f'{topic} carries several types {types}; recording {msgtype}')
            publishers = [info.qos_profile
                          for info in self.node.get_publishers_info_by_topic(topic)
                          if info.topic_type == msgtype]
            if not publishers:
                continue
            try:
                message_class = import_message_class(msgtype)
                self.bag.add_topic(topic, msgtype,
                                   offered_qos=[profile_to_bag_qos(p) for p in publishers])
            except MessageTypeError:
                self.skipped.add(topic)
                self.node.get_logger().warning(
                    f'not recording {topic}: its type {msgtype} is not installed here')
                continue
            self.counts[topic] = 0
            qos = self.options.qos_overrides.get(topic) or recording_profile(publishers)
            self.subscriptions[topic] = self.node.create_subscription(
                message_class, topic, self._callback(topic), qos, raw=True)
            self.node.get_logger().info(f'recording {topic} ({msgtype})')
            added.append(topic)
        return added

    def _callback(self, topic: str) -> Callable[[bytes], None]:
        def receive(data: bytes) -> None:
            if self.done():
                return
            self.bag.write(topic, self.node.get_clock().now().nanoseconds, data)
            self.counts[topic] += 1
            self.message_count += 1
        return receive

    def done(self) -> bool:
        """Return True once the message limit is reached."""
        limit = self.options.max_messages
        return limit is not None and self.message_count >= limit

    def run(self, executor: Executor, stop: Callable[[], bool] = lambda: False) -> int:
        """Spin until stopped, the limit or the duration; close the bag; return the count."""
        options = self.options
        started = time.monotonic()
        next_discovery = started
        try:
            while not stop() and not self.done():
                now = time.monotonic()
                if options.duration_s is not None and now - started >= options.duration_s:
                    break
                if now >= next_discovery:
                    self.discover()
                    next_discovery = now + options.discovery_period_s
                executor.spin_once(timeout_sec=min(0.05, options.discovery_period_s))
            self._drain(executor)
        finally:
            self.close()
        return self.message_count

    def _drain(self, executor: Executor) -> None:
        """Handle messages that arrived (and were acknowledged) but are not written yet."""
        while not self.done():
            before = self.message_count
            try:
                executor.spin_once(timeout_sec=0.05)
            except ExternalShutdownException:
                return
            if self.message_count == before:
                return

    def close(self) -> None:
        """Stop receiving and finish the bag (safe to call twice)."""
        for subscription in self.subscriptions.values():
            self.node.destroy_subscription(subscription)
        self.subscriptions.clear()
        self.bag.close()
