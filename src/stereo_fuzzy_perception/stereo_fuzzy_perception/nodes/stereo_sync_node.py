"""Pair left and right images with their calibration into StereoPair messages.

Inputs: left/image_raw, left/camera_info, right/image_raw, right/camera_info (a camera driver,
stereo_camera_node, or a bag replay), grouped by header stamp by stamp_pairing.StampSynchronizer
over the four streams (exact, or within `slop_s`), as stereo_image_proc synchronises the same
four inputs with message_filters. The node only pairs topics: capturing devices is
stereo_camera_node's job.

Every set is checked (encoding, image sizes, calibration) before it is published on
pair; a bad set is dropped, counted by reason and reported on /diagnostics.
"""

from __future__ import annotations

import threading
import time
from collections import Counter, deque
from dataclasses import dataclass
from functools import partial
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.event_handler import QoSMessageLostInfo, SubscriptionEventCallbacks
from rclpy.impl.rcutils_logger import RcutilsLogger
from rclpy.node import Node
from rclpy.qos import QoSProfile
from sensor_msgs.msg import CameraInfo, Image
from std_msgs.msg import Header
from stereo_fuzzy_parameters.declaration import declare_settings, run_node

from stereo_fuzzy_msgs.msg import StereoPair
from stereo_fuzzy_perception.core.camera_model import StereoCalibration
from stereo_fuzzy_perception.core.image_encoding import SUPPORTED_ENCODINGS, ImageEncodingError
from stereo_fuzzy_perception.core.stamp_gaps import StampGaps
from stereo_fuzzy_perception.core.stamp_pairing import Evicted, StampSynchronizer, seconds_to_ns
from stereo_fuzzy_perception.nodes import qos, topic_names
from stereo_fuzzy_perception.nodes.conversions import (
    camera_info_to_calibration,
    check_image_layout,
    image_size_problem,
    stamp_to_ns,
)
from stereo_fuzzy_perception.nodes.pair_timing import PairTimingPublisher
from stereo_fuzzy_perception.nodes.stereo_sync_parameters import StereoSyncSettings

# The four synchronised input streams, in StampSynchronizer stream order.
INPUT_TOPICS = topic_names.CAMERA_TOPICS
LEFT_IMAGE, LEFT_INFO, RIGHT_IMAGE, RIGHT_INFO = range(4)
INFO_OF_IMAGE = {LEFT_IMAGE: LEFT_INFO, RIGHT_IMAGE: RIGHT_INFO}

# Why a pair is dropped; every reason is reported on /diagnostics, zero or not.
DROP_REASONS = (
    'unsupported_encoding',   # encoding not in image_encoding.SUPPORTED_ENCODINGS
    'bad_image',              # empty image, step shorter than a row, data shorter than step*h
    'image_too_large',        # more than max_image_pixels, or a side above 32767 px
    'uncalibrated',           # camera_info unusable (CameraCalibration.problem(): any check)
    'size_mismatch',          # left vs right image, or an image vs its camera_info
    'right_tx_not_negative',  # right P[0,3] >= 0: not the right camera of a stereo pair
    'missing_camera_info',    # an image dropped unpaired while no camera_info was queued
)
ERROR_THROTTLE_S = 5.0
DEFAULT_MAX_IMAGE_PIXELS = StereoSyncSettings().max_image_pixels


@dataclass(frozen=True)
class PairProblem:
    """Why a set of two images and two camera_infos cannot be published."""

    reason: str
    detail: str


def pair_problem(left_image: Image, left_info: CameraInfo, right_image: Image,
                 right_info: CameraInfo,
                 max_pixels: int = DEFAULT_MAX_IMAGE_PIXELS) -> PairProblem | None:
    """Return the first reason the set cannot be used (checks in DROP_REASONS order), or None."""
    sides = (('left', left_image, left_info), ('right', right_image, right_info))
    for side, image, _ in sides:
        try:
            check_image_layout(image)
        except ImageEncodingError as error:
            reason = ('unsupported_encoding' if image.encoding not in SUPPORTED_ENCODINGS
                      else 'bad_image')
            return PairProblem(reason, f'{side} image: {error}')
    for side, image, info in sides:
        for what, size in (('image', image), ('camera_info', info)):
            problem = image_size_problem(int(size.width), int(size.height), max_pixels)
            if problem:
                return PairProblem('image_too_large', f'{side} {what}: {problem}')
    calibrations = {}
    for side, _, info in sides:
        calibration = camera_info_to_calibration(info)
        problem = calibration.problem()
        if problem:
            return PairProblem('uncalibrated', f'{side} camera_info: {problem}')
        calibrations[side] = calibration
    for side, image, info in sides:
        if (image.width, image.height) != (info.width, info.height):
            return PairProblem('size_mismatch', (
                f'{side} image is {image.width}x{image.height} but its camera_info is '
                f'{info.width}x{info.height}'))
    if (left_image.width, left_image.height) != (right_image.width, right_image.height):
        return PairProblem('size_mismatch', (
            f'left image is {left_image.width}x{left_image.height} but right image is '
            f'{right_image.width}x{right_image.height}'))
    problem = StereoCalibration(calibrations['left'], calibrations['right']).problem()
    if problem:
        return PairProblem('right_tx_not_negative', problem)
    return None


class PairStatistics:
    """Counts for /diagnostics; thread-safe, so a report never sees a half-made update."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self.pairs_in = 0
        self.pairs_out = 0
        self.sequence = 0
        self.dropped: Counter[str] = Counter({reason: 0 for reason in DROP_REASONS})
        self.unpaired: Counter[str] = Counter()
        self.lost: Counter[str] = Counter()
        self.received: Counter[str] = Counter()
        # Frames missing between received stamps, per input topic: queue overwrites included.
        self.stamp_gaps = {topic: StampGaps() for topic in INPUT_TOPICS}
        self._drop_times: deque[float] = deque(maxlen=1000)
        self._last_report = (time.monotonic(), 0, 0)

    def count_received(self, topic: str, stamp_ns: int) -> int:
        """Count one message received on an input topic; return the frames its stamp shows
        missing since the previous one (an estimate)."""
        with self._lock:
            self.received[topic] += 1
            return self.stamp_gaps[topic].observe(stamp_ns)

    def count_in(self) -> None:
        """Count one set of four entering the checks."""
        with self._lock:
            self.pairs_in += 1

    def count_out(self) -> None:
        """Count one StereoPair published."""
        with self._lock:
            self.pairs_out += 1

    def next_sequence(self) -> int:
        """Return the sequence number of the next StereoPair: 1, 2, 3, ..."""
        with self._lock:
            self.sequence += 1
            return self.sequence

    def count_lost(self, topic: str, count: int) -> None:
        """Count `count` messages DDS reported lost on an input topic before delivery."""
        with self._lock:
            self.lost[topic] += count

    def count_drop(self, reason: str) -> None:
        """Count one pair dropped for `reason` (one of DROP_REASONS)."""
        with self._lock:
            self.dropped[reason] += 1
            self._drop_times.append(time.monotonic())

    def count_unpaired(self, topic: str) -> None:
        """Count one message evicted unpaired from the queue of `topic`."""
        with self._lock:
            self.unpaired[topic] += 1

    def report(self, warn_window_s: float) -> dict[str, Any]:
        """Return the counts, the rates since the last report [Hz] and the recent drops."""
        with self._lock:
            now = time.monotonic()
            last_time, last_in, last_out = self._last_report
            elapsed = max(now - last_time, 1e-9)
            self._last_report = (now, self.pairs_in, self.pairs_out)
            return {
                'pairs_in': self.pairs_in,
                'pairs_out': self.pairs_out,
                'dropped': dict(self.dropped),
                'unpaired': dict(self.unpaired),
                'lost': dict(self.lost),
                'received': dict(self.received),
                'stamp_gaps': {topic: gaps.report(topic)
                               for topic, gaps in self.stamp_gaps.items()},
                'input_rate_hz': (self.pairs_in - last_in) / elapsed,
                'output_rate_hz': (self.pairs_out - last_out) / elapsed,
                'recent_drops': sum(1 for stamp in self._drop_times
                                    if now - stamp <= warn_window_s),
            }


class StereoSyncNode(Node):
    """Pair left and right images with their calibration into StereoPair messages."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__('stereo_sync_node', **kwargs)
        self.settings = declare_settings(self, StereoSyncSettings, apply=self._apply_settings)
        self.statistics = PairStatistics()
        self._reason_loggers: dict[str, RcutilsLogger] = {}
        self.pair_publisher = self.create_publisher(StereoPair, topic_names.PAIR, qos.RESULTS)
        self.diagnostics_publisher = self.create_publisher(
            DiagnosticArray, topic_names.DIAGNOSTICS, qos.DIAGNOSTICS)
        # Per-pair timing, only while someone subscribes (a benchmark).
        self.pair_timing = PairTimingPublisher(self, topic_names.PAIR_TIMING)
        self.create_timer(self.settings.diagnostics_period_s, self._publish_diagnostics)
        self._start_topics()

    # --- parameters ----------------------------------------------------------------------

    def _apply_settings(self, settings: StereoSyncSettings) -> None:
        self.settings = settings
        synchronizer = getattr(self, '_synchronizer', None)
        if synchronizer is not None:
            synchronizer.slop_ns = seconds_to_ns(settings.slop_s)
            synchronizer.queue_size = settings.queue_size

    # --- inputs -------------------------------------------------------------------------

    def _start_topics(self) -> None:
        self._synchronizer: StampSynchronizer[Image | CameraInfo] = StampSynchronizer(
            len(INPUT_TOPICS), seconds_to_ns(self.settings.slop_s), self.settings.queue_size)
        base = qos.CAMERA_INPUT
        input_qos = QoSProfile(
            history=base.history, depth=base.depth, durability=base.durability,
            reliability=qos.reliability_from_name(self.settings.input_reliability))
        for stream, topic in enumerate(INPUT_TOPICS):
            message_type = Image if stream in (LEFT_IMAGE, RIGHT_IMAGE) else CameraInfo
            self.create_subscription(
                message_type, topic, partial(self._on_input, stream), input_qos,
                event_callbacks=SubscriptionEventCallbacks(
                    message_lost=partial(self._on_message_lost, topic)))
        self.get_logger().info(
            f'pairing {", ".join(INPUT_TOPICS)} by stamp (slop {self.settings.slop_s} s, '
            f'queue {self.settings.queue_size}, {self.settings.input_reliability})')

    def _on_input(self, stream: int, msg: Image | CameraInfo) -> None:
        arrived_ns = time.time_ns()
        stamp_ns = stamp_to_ns(msg.header.stamp)
        if self.statistics.count_received(INPUT_TOPICS[stream], stamp_ns):
            self.get_logger().warning(
                f'{INPUT_TOPICS[stream]}: frames missing before stamp {stamp_ns * 1e-9:.6f} s '
                '(stamp gap; estimated lost in all: see /diagnostics)',
                throttle_duration_sec=ERROR_THROTTLE_S)
        result = self._synchronizer.add(stream, stamp_ns, msg)
        for evicted in result.evicted:
            self._on_evicted(evicted)
        if result.matched is not None:
            left_image, left_info, right_image, right_info = result.matched.items
            self._publish_pair(left_image, left_info, right_image, right_info, arrived_ns)

    def _on_message_lost(self, topic: str, info: QoSMessageLostInfo) -> None:
        self.statistics.count_lost(topic, int(info.total_count_change))
        self.get_logger().warning(
            f'{topic}: {info.total_count} message(s) lost before delivery (DDS sample lost)',
            throttle_duration_sec=ERROR_THROTTLE_S)

    def _on_evicted(self, evicted: Evicted[Image | CameraInfo]) -> None:
        topic = INPUT_TOPICS[evicted.stream]
        self.statistics.count_unpaired(topic)
        info_stream = INFO_OF_IMAGE.get(evicted.stream)
        if info_stream is None or self._synchronizer.queue_lengths()[info_stream] > 0:
            self.get_logger().warn(
                f'{topic} message at stamp {evicted.stamp_ns * 1e-9:.6f} s dropped unpaired: '
                f'no set of all four inputs within slop_s {self.settings.slop_s} s '
                f'(queue_size {self.settings.queue_size})',
                throttle_duration_sec=ERROR_THROTTLE_S)
            return
        info_topic = INPUT_TOPICS[info_stream]
        self._drop('missing_camera_info', (
            f'{topic} image at stamp {evicted.stamp_ns * 1e-9:.6f} s had no camera_info: '
            f'none queued on {info_topic} ({self.statistics.received[info_topic]} received); '
            f'it must be published with the stamps of its images'))

    # --- checks and output ---------------------------------------------------------------

    def _publish_pair(self, left_image: Image, left_info: CameraInfo, right_image: Image,
                      right_info: CameraInfo, arrived_ns: int = 0) -> None:
        timer = self.pair_timing.start(arrived_ns)
        self.statistics.count_in()
        problem = pair_problem(left_image, left_info, right_image, right_info,
                               self.settings.max_image_pixels)
        if problem is not None:
            stamp_s = stamp_to_ns(left_image.header.stamp) * 1e-9
            self._drop(problem.reason, f'pair at stamp {stamp_s:.6f} s: {problem.detail}')
            return
        pair = StereoPair(
            header=Header(stamp=left_image.header.stamp, frame_id=left_image.header.frame_id),
            left_image=left_image, right_image=right_image,
            left_info=left_info, right_info=right_info,
            sequence=self.statistics.next_sequence())
        self.pair_publisher.publish(pair)
        self.statistics.count_out()
        self.pair_timing.publish(timer, pair.header.stamp)

    def _drop(self, reason: str, detail: str) -> None:
        self.statistics.count_drop(reason)
        # One logger per reason: rclpy throttles per logger and call site, so one reason
        # repeating every frame cannot hide another.
        logger = self._reason_loggers.get(reason)
        if logger is None:
            logger = self._reason_loggers[reason] = self.get_logger().get_child(reason)
        logger.error(f'dropped ({reason}): {detail}', throttle_duration_sec=ERROR_THROTTLE_S)

    def _publish_diagnostics(self) -> None:
        settings = self.settings
        window = settings.drop_warn_window_s
        report = self.statistics.report(window)
        status = DiagnosticStatus(name=f'{self.get_name()}: stereo pairing',
                                  hardware_id=self.get_name())
        dropped = {reason: count for reason, count in report['dropped'].items() if count}
        if report['recent_drops']:
            status.level = DiagnosticStatus.WARN
            status.message = (f'{report["recent_drops"]} pairs dropped in the last {window} s ('
                              + ', '.join(f'{r}: {c}' for r, c in dropped.items()) + ' in all)')
        elif report['pairs_out'] == 0:
            status.level = DiagnosticStatus.OK
            status.message = 'waiting for input'
        else:
            status.level = DiagnosticStatus.OK
            status.message = 'pairing'
        values = [
            ('pairs in', report['pairs_in']),
            ('pairs out', report['pairs_out']),
            ('pairs dropped', sum(report['dropped'].values())),
            ('input rate [Hz]', f'{report["input_rate_hz"]:.2f}'),
            ('output rate [Hz]', f'{report["output_rate_hz"]:.2f}'),
        ]
        values += [(f'dropped {reason}', count) for reason, count in report['dropped'].items()]
        values.append(('slop [s]', settings.slop_s))
        # Readers DDS has matched to the pair writer: what is published reaches them.
        values.append((f'{topic_names.PAIR} subscribers',
                       self.pair_publisher.get_subscription_count()))
        values += [(f'received {topic}', report['received'].get(topic, 0))
                   for topic in INPUT_TOPICS]
        values += [(f'unpaired {topic}', report['unpaired'].get(topic, 0))
                   for topic in INPUT_TOPICS]
        values += [(f'lost before delivery {topic}', report['lost'].get(topic, 0))
                   for topic in INPUT_TOPICS]
        values += [item for gaps in report['stamp_gaps'].values() for item in gaps.items()]
        status.values = [KeyValue(key=key, value=str(value)) for key, value in values]
        array = DiagnosticArray(status=[status])
        array.header.stamp = self.get_clock().now().to_msg()
        self.diagnostics_publisher.publish(array)


def main(args: list[str] | None = None) -> None:
    """Run the node until shutdown; a bad parameter ends it with one line."""
    run_node(StereoSyncNode, args)


if __name__ == '__main__':
    main()
