"""Play a bag onto the ROS graph: the recorded CDR bytes, at the recorded pace.

What `ros2 bag play` does, for this project's needs: rate, loop, start offset, playback
duration, topic selection (names, regex, exclusions), remapping, QoS overrides, /clock, waiting
for subscribers, starting paused with pause / resume / step services, a progress line, and a
check that every message the bag's metadata promises was played.

Topics whose message type is not installed are skipped with a warning, as rosbag2 does. The
services are std_srvs/Trigger under the player's name (`/bag_player/pause`, `resume`,
`toggle_paused`, `is_paused`, `play_next`): rosbag2's own (rosbag2_interfaces) are not in the
PyPI distribution of Jazzy.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock

from stereo_fuzzy_perception.bag.bag_format import BagError, absolute_topic
from stereo_fuzzy_perception.bag.bag_qos import playback_profile
from stereo_fuzzy_perception.bag.bag_reader import read_info, read_messages
from stereo_fuzzy_perception.bag.bag_summary import BagInfo
from stereo_fuzzy_perception.bag.message_types import MessageTypeError, import_message_class
from stereo_fuzzy_perception.bag.playback_clock import PlaybackClock
from stereo_fuzzy_perception.bag.topic_selection import select_topics

# How long to wait, after the last message, for reliable subscribers to acknowledge it.
ACK_TIMEOUT_S = 5.0
PROGRESS_PERIOD_S = 0.1


@dataclass(frozen=True)
class PlayOptions:
    """How to play a bag.

    Attributes:
        bag: The bag directory or .mcap file.
        rate: Speed relative to the recording [-].
        loop: Start again at the end, until interrupted.
        start_offset_s: Skip the first seconds of the bag [s].
        topics: Only these topics (absolute names); all when None (and no regex).
        regex: Also (or only, without topics) the topics matching this regular expression.
        exclude_topics: Never these topics.
        exclude_regex: Never the topics matching this regular expression.
        remaps: {recorded topic: published topic}.
        qos_overrides: {recorded topic: QoS to publish it with}, instead of the recorded QoS.
        clock_hz: Publish /clock at this rate [Hz] (0: do not publish /clock).
        wait_for_subscribers: Wait until every played topic has a subscriber before starting.
        wait_timeout_s: Give up waiting after this long [s].
        settle_s: After the subscribers appeared, wait this long before the first message [s]:
            a publisher sees a subscriber before that subscriber has matched the publisher,
            and a volatile subscriber drops what arrives in between (`ros2 bag play --delay`).
        start_paused: Start with the clock paused (resume or step through the services).
        duration_s: Play only this much bag time from the start (offset) [s]; None: all.
    """

    bag: Path
    rate: float = 1.0
    loop: bool = False
    start_offset_s: float = 0.0
    topics: tuple[str, ...] | None = None
    regex: str | None = None
    exclude_topics: tuple[str, ...] = ()
    exclude_regex: str | None = None
    remaps: dict[str, str] = field(default_factory=dict)
    qos_overrides: dict[str, QoSProfile] = field(default_factory=dict)
    clock_hz: float = 0.0
    wait_for_subscribers: bool = False
    wait_timeout_s: float = 30.0
    settle_s: float = 0.5
    start_paused: bool = False
    duration_s: float | None = None


class BagPlayer:
    """Publishes a bag's messages from `node`; one publisher per played topic."""

    def __init__(self, node: Node, options: PlayOptions,
                 progress: Callable[[str], None] | None = None) -> None:
        """Read the bag's summary, create the publishers and the pause services.

        Args:
            node: The node to publish from.
            options: What to play and how.
            progress: Called about ten times a second with a one-line progress report.

        Raises:
            BagError: For an unreadable bag, an unknown topic, nothing left to play or a bad
                rate, offset or duration.
        """
        if not options.rate > 0.0:
            raise BagError(f'--rate must be positive, got {options.rate}')
        if options.start_offset_s < 0.0:
            raise BagError(f'--start-offset must not be negative, got {options.start_offset_s}')
        if options.duration_s is not None and not options.duration_s > 0.0:
            raise BagError(f'--playback-duration must be positive, got {options.duration_s}')
        self.node = node
        self.options = options
        self.progress = progress
        self.info: BagInfo = read_info(options.bag)
        recorded = {topic.name: topic for topic in self.info.topics}
        unknown = [name for name in options.topics or () if name not in recorded]
        if unknown:
            raise BagError(f'{options.bag} has no topic(s) {", ".join(unknown)}; it has '
                           + ', '.join(recorded))
        selected = select_topics(recorded, options.topics, options.regex,
                                 options.exclude_topics, options.exclude_regex)
        self.publishers: dict[str, Publisher] = {}
        self.skipped: dict[str, str] = {}
        for name in selected:
            topic = recorded[name]
            try:
                message_class = import_message_class(topic.msgtype)
            except MessageTypeError as error:
                self.skipped[name] = str(error)
                node.get_logger().warning(
                    f'skipping {name}: its type {topic.msgtype or "(none recorded)"} is not '
                    'installed here')
                continue
            qos = options.qos_overrides.get(name) or playback_profile(topic.offered_qos)
            self.publishers[name] = node.create_publisher(
                message_class, options.remaps.get(name, name), qos)
        if not self.publishers:
            raise BagError(f'nothing to play from {options.bag}: ' + (
                'the selection keeps no topic' if not selected
                else 'no selected topic has an installed type'))
        self.topics = tuple(self.publishers)
        self.clock_publisher = None
        if options.clock_hz > 0.0:
            self.clock_publisher = node.create_publisher(
                Clock, '/clock', QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE))
        self.published = 0
        self._last_clock_ns = -1
        self._lock = threading.Lock()
        self._paused = options.start_paused
        self._steps = 0
        self._clock: PlaybackClock | None = None
        self._create_services()

    # --- pause / resume / step ---------------------------------------------------------------

    def _create_services(self) -> None:
        from std_srvs.srv import Trigger

        def service(name: str, act: Callable[[], str]) -> None:
            def callback(request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
                response.message = act()
                response.success = True
                return response
            self.node.create_service(Trigger, f'~/{name}', callback)

        service('pause', self.pause)
        service('resume', self.resume)
        service('toggle_paused', lambda: self.resume() if self.is_paused() else self.pause())
        service('is_paused', lambda: 'paused' if self.is_paused() else 'playing')
        service('play_next', self.play_next)

    def is_paused(self) -> bool:
        """Return True while playback is paused."""
        with self._lock:
            return self._paused

    def pause(self) -> str:
        """Pause playback; return what happened, in words."""
        with self._lock:
            self._paused = True
            if self._clock is not None:
                self._clock.pause()
        return 'paused'

    def resume(self) -> str:
        """Resume playback; return what happened, in words."""
        with self._lock:
            self._paused = False
            if self._clock is not None:
                self._clock.resume()
        return 'playing'

    def play_next(self) -> str:
        """While paused, publish the next message at once; return what happened, in words."""
        with self._lock:
            if not self._paused:
                return 'not paused: play_next only steps a paused player'
            self._steps += 1
        return 'stepping to the next message'

    def _take_step(self) -> bool:
        with self._lock:
            if self._steps > 0:
                self._steps -= 1
                return True
            return False

    # --- playback ----------------------------------------------------------------------------

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

    def expected_count(self) -> int:
        """Return how many messages one whole pass publishes, by the bag's own counts."""
        return sum(topic.message_count for topic in self.info.topics
                   if topic.name in self.publishers)

    def _report(self, clock: PlaybackClock, count: int, first_ns: int) -> None:
        if self.progress is None:
            return
        elapsed = max(0, clock.bag_time_ns() - first_ns) / 1e9
        total = self.info.duration_ns / 1e9 - self.options.start_offset_s
        if self.options.duration_s is not None:
            total = min(total, self.options.duration_s)
        state = 'paused' if clock.paused else f'x{self.options.rate:g}'
        self.progress(f'bag time {clock.bag_time_ns() / 1e9:.3f}  {elapsed:.2f} / '
                      f'{max(total, 0.0):.2f} s  {count} messages  [{state}]')

    def play_once(self, stop: Callable[[], bool] = lambda: False) -> int:
        """Publish the selected messages once at the recorded pace; return how many."""
        options = self.options
        offset_ns = round(options.start_offset_s * 1e9)
        first_ns = self.info.start_ns + offset_ns
        end_ns = None if options.duration_s is None else first_ns + round(
            options.duration_s * 1e9)
        clock_period = 1.0 / options.clock_hz if options.clock_hz > 0.0 else None
        self._last_clock_ns = -1
        next_clock = next_report = 0.0
        count = 0
        clock: PlaybackClock | None = None
        for message in read_messages(options.bag, self.topics, start_offset_ns=offset_ns):
            if end_ns is not None and message.timestamp_ns > end_ns:
                break
            if clock is None:  # bag time first_ns is now (opening the bag took a while)
                with self._lock:
                    clock = self._clock = PlaybackClock(first_ns, options.rate, self._paused)
            while True:
                now = time.monotonic()
                if stop():
                    self.published += count
                    return count
                if self._take_step():
                    with self._lock:
                        clock.jump_to(message.timestamp_ns)
                    break
                if clock_period is not None and now >= next_clock and not clock.paused:
                    self._publish_clock(clock.bag_time_ns())
                    next_clock = now + clock_period
                if now >= next_report:
                    self._report(clock, count, first_ns)
                    next_report = now + PROGRESS_PERIOD_S
                with self._lock:
                    wait = clock.seconds_until(message.timestamp_ns)
                if wait <= 0.0:
                    break
                if clock_period is not None:
                    wait = min(wait, max(next_clock - now, 0.0))
                time.sleep(min(wait, PROGRESS_PERIOD_S, 0.02 if clock.paused else wait))
            self._publish_clock(message.timestamp_ns)
            self.publishers[message.topic].publish(message.data)
            count += 1
        if clock is not None:
            self._report(clock, count, first_ns)
        self.published += count
        return count

    def run(self, stop: Callable[[], bool] = lambda: False) -> int:
        """Wait for subscribers if asked, then play (again and again with loop); return count.

        Raises:
            BagError: When subscribers did not appear within the wait timeout, or a whole pass
                published fewer messages than the bag's metadata promises (a damaged file, or
                one this reader cannot decode).
        """
        if self.options.wait_for_subscribers:
            waiting = self.wait_for_subscribers(stop)
            if waiting:
                raise BagError(f'no subscriber on {", ".join(waiting)} after '
                               f'{self.options.wait_timeout_s} s')
        settled = time.monotonic() + self.options.settle_s
        while time.monotonic() < settled and not stop():
            time.sleep(0.02)
        whole = self.options.start_offset_s == 0.0 and self.options.duration_s is None
        while not stop():
            count = self.play_once(stop)
            if whole and not stop() and count < self.expected_count():
                raise BagError(
                    f'{self.options.bag} promises {self.expected_count()} messages on the '
                    f'played topics but only {count} could be read and published')
            if not self.options.loop:
                break
        for publisher in self.publishers.values():
            publisher.wait_for_all_acked(Duration(nanoseconds=round(ACK_TIMEOUT_S * 1e9)))
        return self.published


def topic_selection(names: list[str] | None) -> tuple[str, ...] | None:
    """Return the absolute topic names of a --topics list (None: all topics)."""
    return None if not names else tuple(absolute_topic(name) for name in names)
