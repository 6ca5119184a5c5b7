"""Record topics from the ROS graph into a new MCAP bag, as serialized bytes.

What `ros2 bag record` does, for this project's needs: named topics or all of them (found as they
appear), each message stamped with its receive time, the publishers' offered QoS in the
metadata, custom types' definitions in the file. Stops on Ctrl-C, after N messages or after a
duration, and always closes the bag so it stays readable.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from rclpy.executors import Executor, ExternalShutdownException
from rclpy.node import Node
from rclpy.subscription import Subscription

from stereo_fuzzy_perception.bag.bag_io import BagWriter, absolute_topic
from stereo_fuzzy_perception.bag.bag_qos import profile_to_bag_qos, recording_profile
from stereo_fuzzy_perception.bag.message_types import import_message_class

# Topics `--all` leaves out: every node's log and parameter events.
EXCLUDED_FROM_ALL = ('/rosout', '/parameter_events')


@dataclass(frozen=True)
class RecordOptions:
    """What to record and when to stop.

    Attributes:
        output: Bag directory to create.
        topics: Topics to record (absolute names); ignored with all_topics.
        all_topics: Record every topic that appears, except EXCLUDED_FROM_ALL and hidden ones.
        max_messages: Stop after this many messages in total (None: no limit).
        duration_s: Stop after this long [s] (None: no limit).
        compression: 'zstd' (MCAP chunk compression) or 'none'.
        discovery_period_s: How often to look for the topics on the graph [s].
    """

    output: Path
    topics: tuple[str, ...] = ()
    all_topics: bool = False
    max_messages: int | None = None
    duration_s: float | None = None
    compression: str = 'zstd'
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
        self.bag = BagWriter(options.output, compression=options.compression)
        self.subscriptions: dict[str, Subscription] = {}
        self.counts: dict[str, int] = {}
        self.message_count = 0

    def _wants(self, topic: str) -> bool:
        if self.options.all_topics:
            hidden = any(part.startswith('_') for part in topic.split('/'))
            return topic not in EXCLUDED_FROM_ALL and not hidden
        return topic in self.wanted

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
            message_class = import_message_class(msgtype)
            self.bag.add_topic(topic, msgtype,
                               offered_qos=[profile_to_bag_qos(p) for p in publishers])
            self.counts[topic] = 0
            self.subscriptions[topic] = self.node.create_subscription(
                message_class, topic, self._callback(topic), recording_profile(publishers),
                raw=True)
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
