"""Play a bag onto the ROS graph: the recorded CDR bytes, at the recorded pace.

What `ros2 bag play` does, for this project's needs: rate, loop, start offset, topic selection,
remapping, /clock, and waiting for subscribers before the first message.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock

from stereo_fuzzy_perception.bag.bag_io import (
    BagError,
    BagInfo,
    absolute_topic,
    playback_delay_s,
    read_info,
    read_messages,
)
from stereo_fuzzy_perception.bag.bag_qos import playback_profile
from stereo_fuzzy_perception.bag.message_types import import_message_class

# How long to wait, after the last message, for reliable subscribers to acknowledge it.
ACK_TIMEOUT_S = 5.0


@dataclass(frozen=True)
class PlayOptions:
    """How to play a bag.

    Attributes:
        bag: The bag directory.
        rate: Speed relative to the recording [-].
        loop: Start again at the end, until interrupted.
        start_offset_s: Skip the first seconds of the bag [s].
        topics: Only these topics (absolute names); all when None.
        remaps: {recorded topic: published topic}.
        clock_hz: Publish /clock at this rate [Hz] (0: do not publish /clock).
        wait_for_subscribers: Wait until every played topic has a subscriber before starting.
        wait_timeout_s: Give up waiting after this long [s].
        settle_s: After the subscribers appeared, wait this long before the first message [s]:
            a publisher sees a subscriber before that subscriber has matched the publisher,
            and a volatile subscriber drops what arrives in between (`ros2 bag play --delay`).
    """

    bag: Path
    rate: float = 1.0
    loop: bool = False
    start_offset_s: float = 0.0
    topics: tuple[str, ...] | None = None
    remaps: dict[str, str] = field(default_factory=dict)
    clock_hz: float = 0.0
    wait_for_subscribers: bool = False
    wait_timeout_s: float = 30.0
    settle_s: float = 0.5


class BagPlayer:
    """Publishes a bag's messages from `node`; one publisher per played topic."""

    def __init__(self, node: Node, options: PlayOptions) -> None:
        """Read the bag's summary and create the publishers.

        Raises:
            BagError: For an unreadable bag, an unknown topic or a bad rate or offset.
            MessageTypeError: When a message type of the bag cannot be imported.
        """
        if not options.rate > 0.0:
            raise BagError(f'--rate must be positive, got {options.rate}')
        if options.start_offset_s < 0.0:
            raise BagError(f'--start-offset must not be negative, got {options.start_offset_s}')
        self.node = node
        self.options = options
        self.info: BagInfo = read_info(options.bag)
        recorded = {topic.name: topic for topic in self.info.topics}
        selected = options.topics if options.topics is not None else tuple(recorded)
        unknown = [name for name in selected if name not in recorded]
        if unknown:
            raise BagError(f'{options.bag} has no topic(s) {", ".join(unknown)}; it has '
                           + ', '.join(recorded))
        self.topics = tuple(selected)
        self.publishers: dict[str, Publisher] = {}
        for name in self.topics:
            topic = recorded[name]
            message_class = import_message_class(topic.msgtype)
            self.publishers[name] = node.create_publisher(
                message_class, options.remaps.get(name, name), playback_profile(topic.offered_qos))
        self.clock_publisher = None
        if options.clock_hz > 0.0:
            self.clock_publisher = node.create_publisher(
                Clock, '/clock', QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE))
        self.published = 0
        self._last_clock_ns = -1

    def published_topics(self) -> dict[str, str]:
        """Return {recorded topic: topic it is published on}."""
        return {name: self.publishers[name].topic_name for name in self.topics}

    def wait_for_subscribers(self, stop: Callable[[], bool] = lambda: False) -> list[str]:
        """Wait until every publisher has a subscriber; return the topics still without one."""
        deadline = time.monotonic() + self.options.wait_timeout_s
        while True:
            waiting = [publisher.topic_name for publisher in self.publishers.values()
                       if publisher.get_subscription_count() == 0]
            if not waiting or time.monotonic() >= deadline or stop():
                return waiting
            time.sleep(0.02)

    def _publish_clock(self, bag_time_ns: int) -> None:
        """Publish bag time on /clock, never going backwards."""
        if self.clock_publisher is not None and bag_time_ns > self._last_clock_ns:
            self._last_clock_ns = bag_time_ns
            message = Clock()
            message.clock.sec, message.clock.nanosec = divmod(int(bag_time_ns), 1_000_000_000)
            self.clock_publisher.publish(message)

    def play_once(self, stop: Callable[[], bool] = lambda: False) -> int:
        """Publish the selected messages once at the recorded pace; return how many."""
        options = self.options
        offset_ns = round(options.start_offset_s * 1e9)
        first_ns = self.info.start_ns + offset_ns
        clock_period = 1.0 / options.clock_hz if options.clock_hz > 0.0 else None
        self._last_clock_ns = -1
        started: float | None = None
        next_clock = 0.0
        count = 0
        for message in read_messages(options.bag, self.topics, start_offset_ns=offset_ns):
            if started is None:  # bag time first_ns is now (opening the bag took a while)
                started = next_clock = time.monotonic()
            due = started + playback_delay_s(message.timestamp_ns, first_ns, options.rate)
            while True:
                now = time.monotonic()
                if stop():
                    return count
                if clock_period is not None and now >= next_clock:
                    self._publish_clock(first_ns + round((now - started) * options.rate * 1e9))
                    next_clock = now + clock_period
                if now >= due:
                    break
                wake = due if clock_period is None else min(due, next_clock)
                time.sleep(min(max(wake - now, 0.0), 0.1))
            self._publish_clock(message.timestamp_ns)
            self.publishers[message.topic].publish(message.data)
            count += 1
        self.published += count
        return count

    def run(self, stop: Callable[[], bool] = lambda: False) -> int:
        """Wait for subscribers if asked, then play (again and again with loop); return count.

        Raises:
            BagError: When subscribers did not appear within the wait timeout.
        """
        if self.options.wait_for_subscribers:
            waiting = self.wait_for_subscribers(stop)
            if waiting:
                raise BagError(f'no subscriber on {", ".join(waiting)} after '
                               f'{self.options.wait_timeout_s} s')
        settled = time.monotonic() + self.options.settle_s
        while time.monotonic() < settled and not stop():
            time.sleep(0.02)
        while not stop():
            self.play_once(stop)
            if not self.options.loop:
                break
        for publisher in self.publishers.values():
            publisher.wait_for_all_acked(Duration(nanoseconds=round(ACK_TIMEOUT_S * 1e9)))
        return self.published


def topic_selection(names: list[str] | None) -> tuple[str, ...] | None:
    """Return the absolute topic names of a --topics list (None: all topics)."""
    return None if not names else tuple(absolute_topic(name) for name in names)
