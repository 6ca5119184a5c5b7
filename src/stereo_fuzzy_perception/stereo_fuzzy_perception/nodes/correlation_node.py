"""Match stereo pairs by window correlation (Eqs. 7-8) and publish triangulated matches.

Thin adapter around stereo_matching.StereoMatchingPipeline: the subscription only keeps the
newest pair (a depth-1 hand-off); a worker thread rectifies, matches and triangulates it, so the
executor never blocks and latency stays bounded; pairs replaced before the worker took them are
counted as dropped (`superseded`).

It also subscribes the fuzzy stage's decisions (`best_point/decision`) and matches each pair
where the newest decision found the object (core/matching/area_tracker.py, parameters roi.*);
where each pair was matched, and why not in the area, is counted on /diagnostics.
"""

from __future__ import annotations

import threading
import time
import traceback
from collections import Counter, deque
from typing import Any

import cv2
import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.node import Node
from rclpy.qos import QoSProfile
from rclpy.subscription import Subscription
from sensor_msgs.msg import PointCloud2
from stereo_fuzzy_parameters.declaration import declare_settings, run_node
from stereo_msgs.msg import DisparityImage

from stereo_fuzzy_msgs.msg import FuzzyDecision, StereoMatches, StereoPair
from stereo_fuzzy_perception.core.camera_model import CalibrationError, StereoCalibration
from stereo_fuzzy_perception.core.frame_transforms import RigPoseError
from stereo_fuzzy_perception.core.image_encoding import ImageEncodingError
from stereo_fuzzy_perception.core.matching.area_search import REGION_PROBLEMS
from stereo_fuzzy_perception.core.matching.area_tracker import (
    FULL_FRAME_REASONS,
    AreaTracker,
    SearchPlan,
)
from stereo_fuzzy_perception.core.matching.disparity_range import DisparityRangeError
from stereo_fuzzy_perception.core.matching.rectification import RectificationError
from stereo_fuzzy_perception.core.matching.scene_change import block_means
from stereo_fuzzy_perception.core.matching.stereo_matching import StereoMatchingPipeline
from stereo_fuzzy_perception.core.matching.undecided_matches import UndecidedMatches
from stereo_fuzzy_perception.core.matching.window_matcher import MatcherInputError, warm_up
from stereo_fuzzy_perception.core.sequence_gaps import SequenceGaps
from stereo_fuzzy_perception.nodes import qos, topic_names
from stereo_fuzzy_perception.nodes.area_conversions import (
    decision_points,
    decision_to_tracked_area,
    stamp_seconds,
)
from stereo_fuzzy_perception.nodes.conversions import (
    ImageSizeError,
    check_pair_size,
    disparity_image_message,
    matched_points_to_cloud,
    stamp_to_ns,
    stereo_matches_message,
    stereo_pair_with_colour,
)
from stereo_fuzzy_perception.nodes.correlation_parameters import CorrelationSettings
from stereo_fuzzy_perception.nodes.pair_timing import PairTimingPublisher

DROP_REASONS = ('superseded', 'image_too_large', 'calibration', 'size_mismatch', 'encoding',
                'matcher_input', 'opencv', 'internal')
DECISION_TOPIC = topic_names.DECISION
POSE_MISMATCH = 'pose_mismatch'
PERIODIC_SKIPPED = 'periodic_unchanged'
FROM_MATCHES = 'area_from_matches'
FOUND_IN_MATCHES = 'found_in_matches'
POSE_TOLERANCE_M = 0.005
"""Largest distance between a decision's best point in the camera frame and its world point
placed with this node's camera pose; more means the two nodes place the camera differently,
and the area is not tracked [m]."""


class CorrelationNode(Node):
    """Match stereo pairs by window correlation and publish triangulated matches."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__('correlation_node', **kwargs)
        self.settings = declare_settings(self, CorrelationSettings, apply=self._apply_settings)
        self.pipeline = StereoMatchingPipeline(self.settings.matcher_config(),
                                               self.settings.point_stride)
        self.tracker = AreaTracker(self.settings.roi.tracking_config())
        # The camera pose in world for the last calibration seen (None: unknown), to place the
        # decisions' areas in the image.
        self._pose: tuple[StereoCalibration, np.ndarray | None] | None = None
        self.searched: Counter[str] = Counter(dict.fromkeys(
            ('area', *FULL_FRAME_REASONS, *REGION_PROBLEMS, POSE_MISMATCH, PERIODIC_SKIPPED,
             FROM_MATCHES, FOUND_IN_MATCHES),
            0))
        # After a failed region, the next pair waits for that pair's decision (roi.*)
        self.decision_waits: Counter[str] = Counter({'arrived': 0, 'timed out': 0})
        # disparity_range 0: the range derived for the last calibration seen
        self._derived_for: StereoCalibration | None = None
        input_qos = QoSProfile(depth=qos.RESULTS.depth, history=qos.RESULTS.history,
                               durability=qos.RESULTS.durability,
                               reliability=qos.reliability_from_name(
                                   self.settings.input_reliability))
        self.matches_publisher = self.create_publisher(StereoMatches, topic_names.MATCHES,
                                                       qos.RESULTS)
        # Created once the matching kernel is ready (a pair before it could not be matched).
        self.pair_subscription: Subscription | None = None
        self.points_publisher = self.create_publisher(PointCloud2, topic_names.POINTS, qos.RESULTS)
        self.disparity_publisher = self.create_publisher(DisparityImage, topic_names.DISPARITY,
                                                         qos.RESULTS)
        self.diagnostics_publisher = self.create_publisher(
            DiagnosticArray, topic_names.DIAGNOSTICS, qos.DIAGNOSTICS)
        self._input_qos = input_qos
        # Per-pair timing, only while someone subscribes (a benchmark).
        self.pair_timing = PairTimingPublisher(self, topic_names.MATCHES_TIMING)

        self._condition = threading.Condition()
        self._pending: deque[tuple[StereoPair, int]] = deque()  # and its arrival [ns]
        self._stopping = False
        self.received = 0
        self.processed = 0
        # Matches without a decision yet; the next pair waits while max_undecided_matches are.
        self.undecided = UndecidedMatches()
        self.held_for_decisions = 0
        self.waiting_for_decisions = False  # the worker holds a pair until a decision comes
        self.pair_sequence = SequenceGaps()
        self.dropped: Counter[str] = Counter({reason: 0 for reason in DROP_REASONS})
        self.last_error = ''
        self.last_timings_ms: dict[str, float] = {}
        self.last_points = 0
        self._total_ms = 0.0
        self._error_loggers = {reason: self.get_logger().get_child(reason)
                               for reason in DROP_REASONS}
        self._worker = threading.Thread(target=self._work, name='correlation_worker',
                                        daemon=True)
        self._worker.start()
        self.decision_subscription = self.create_subscription(
            FuzzyDecision, DECISION_TOPIC, self._on_decision, qos.RESULTS)
        self.create_timer(self.settings.diagnostics_period_s, self._publish_diagnostics)
        self.get_logger().info(
            f'correlation_node started: {self.pipeline.config.method}, window '
            f'{self.pipeline.config.window_size}, disparities '
            + ('from the calibration, rig pose and workspace box'
               if self.settings.derives_disparities else
               f'{self.pipeline.config.min_disparity}..{self.pipeline.config.max_disparity}'))

    # --- parameters and input -----------------------------------------------------------------

    def _apply_settings(self, settings: CorrelationSettings) -> None:
        self.settings = settings
        self._derived_for = None
        self._pose = None
        self.tracker.config = settings.roi.tracking_config()
        self.pipeline.config = settings.matcher_config()
        self.pipeline.point_stride = settings.point_stride
        with self._condition:
            self._condition.notify_all()  # the worker re-reads max_rate_hz
        self.get_logger().info(f'matcher settings now {self.pipeline.config}')

    def _on_pair(self, pair: StereoPair) -> None:
        arrived_ns = time.time_ns()
        with self._condition:
            self.received += 1
            self.pair_sequence.observe(int(pair.sequence))
            if len(self._pending) >= self.settings.input_queue_depth:
                self._pending.popleft()
                self.dropped['superseded'] += 1
                self.get_logger().warning(
                    'dropped a pair that waited while the previous one was matched '
                    f"({self.dropped['superseded']} so far): input faster than matching",
                    throttle_duration_sec=5.0)
            self._pending.append((pair, arrived_ns))
            self._condition.notify()

    def _on_decision(self, msg: FuzzyDecision) -> None:
        """Track the decision's correlation area (or search everywhere when it found none)."""
        with self._condition:
            self.undecided.decided(stamp_to_ns(msg.header.stamp))
            self._condition.notify_all()  # the worker may wait for this decision
        try:
            area = decision_to_tracked_area(msg)
            known = self._pose
            if area is not None and known is not None and known[1] is not None:
                world, camera = decision_points(msg)
                placed = np.linalg.inv(known[1]) @ np.append(world, 1.0)
                if float(np.linalg.norm(placed[:3] - camera)) > POSE_TOLERANCE_M:
                    area = None
                    with self._condition:
                        self.searched[POSE_MISMATCH] += 1
                    self.get_logger().warning(
                        "a decision places its best point elsewhere than this node's camera "
                        'pose (rig_pose_file / rig.*) does: not tracking its area (give both '
                        'nodes the same pose)', throttle_duration_sec=60.0)
            self.tracker.observe(area, stamp_seconds(msg.header.stamp))
        except Exception as error:  # a bad decision must not stop the node: search everywhere
            self.tracker.observe(None)
            self.get_logger().error(f'decision not tracked: {error!r}',
                                    throttle_duration_sec=self.settings.error_log_period_s)

    def _plan(self, pair: StereoPair, left: np.ndarray,
              calibration: StereoCalibration) -> SearchPlan:
        """Return where this pair is matched (the tracked area's region or the whole image)."""
        known = self._pose
        if known is None or not (known[0].left.same_as(calibration.left)
                                 and known[0].right.same_as(calibration.right)):
            try:
                pose: np.ndarray | None = self.settings.pose_source().world_from_camera(
                    calibration)
            except RigPoseError:
                pose = None
            known = self._pose = (calibration, pose)
        waited = self.tracker.wait_for_decision()
        if waited is not None:
            with self._condition:
                self.decision_waits['arrived' if waited else 'timed out'] += 1
        config = self.pipeline.config
        detect = self.tracker.config.detect_scene_change
        rectifier = self.pipeline.rectifier
        return self.tracker.plan(
            stamp_seconds(pair.header.stamp), calibration, known[1],
            (config.min_disparity, config.disparity_range),
            blocks=block_means(left) if detect else None,
            raw_box=lambda roi: rectifier.raw_box(calibration, roi))

    # --- worker -------------------------------------------------------------------------------

    def _work(self) -> None:
        seconds = warm_up()
        # Subscribe only once the matcher has run (its kernel loaded, its working memory
        # faulted in), so that upstream publishers (or `bag play --wait-for-subscribers`) can
        # see on the graph when it is ready.
        self.pair_subscription = self.create_subscription(StereoPair, topic_names.PAIR,
                                                          self._on_pair, self._input_qos)
        self.get_logger().info(f'matching kernel ready in {seconds:.2f} s; subscribed to '
                               f'{self.pair_subscription.topic_name}')
        last_start = -float('inf')
        while True:
            with self._condition:
                while not self._pending and not self._stopping:
                    self._condition.wait()
                # max_rate_hz is re-read on every wake-up (a change notifies), so lowering or
                # clearing it takes effect at once, not at the deadline of the old rate.
                while not self._stopping:
                    rate = self.settings.max_rate_hz
                    remaining = (last_start + 1.0 / rate - time.monotonic()) if rate > 0.0 \
                        else 0.0
                    if remaining <= 0.0:
                        break
                    self._condition.wait(remaining)
                held = False
                while not self._stopping and (wait := self._undecided_wait()) > 0.0:
                    held = self.waiting_for_decisions = True  # newer pairs replace this one
                    self._condition.wait(wait)
                self.waiting_for_decisions = False
                self.held_for_decisions += int(held)
                if self._stopping:
                    return
                pending = self._pending.popleft() if self._pending else None
            if pending is None:
                continue
            last_start = time.monotonic()
            self._process(*pending)

    def _undecided_wait(self) -> float:
        """Return how long the next pair must wait for decisions [s] (0: match it now)."""
        settings = self.settings
        limit = (settings.max_undecided_matches
                 if self.decision_subscription.get_publisher_count() > 0 else 0)
        return self.undecided.wait_s(time.monotonic(), limit, settings.undecided_timeout_s)

    def _process(self, pair: StereoPair, arrived_ns: int = 0) -> None:
        timer = self.pair_timing.start(arrived_ns)
        try:
            check_pair_size(pair, self.settings.max_image_pixels)
            left, right, calibration, colour = stereo_pair_with_colour(pair)
            calibration.require_valid()
            self._derive_disparities(calibration)
            if left.shape != right.shape:
                raise RectificationError(
                    f'left image is {left.shape[1]}x{left.shape[0]} but right image is '
                    f'{right.shape[1]}x{right.shape[0]}')
            if timer is not None:
                timer.step('decode')
            plan = self._plan(pair, left, calibration)
            if timer is not None:
                timer.step('plan')
            # A disparity subscriber gets every row; otherwise only the rows that
            # point_stride publishes are matched.
            result = self.pipeline.process(
                left, right, calibration,
                full_disparity=self.disparity_publisher.get_subscription_count() > 0,
                region=plan.region)
            if colour[0] is not None:
                # the fuzzy stage looks for the object's silhouette in colour first
                self.pipeline.colour_parts(*colour, calibration, result.points)
            if timer is not None:
                timer.step('pipeline')
                timer.steps(result.timings_ms)
            stamp_s = stamp_seconds(pair.header.stamp)
            if result.region_problem:
                self.tracker.region_failed(result.region_problem, stamp_s)
            found = result.region is None and self.tracker.matched_whole(
                result.disparity_map, stamp_s, result.rectified, self.pipeline.point_stride,
                (result.disparity_map.config.min_disparity,
                 result.disparity_map.config.disparity_range)) is not None
            if timer is not None:
                timer.step('regions from matches')
        except ImageSizeError as error:
            self._drop('image_too_large', str(error))
            return
        except ImageEncodingError as error:
            self._drop('encoding', str(error))
            return
        except (CalibrationError, DisparityRangeError, RigPoseError) as error:
            self._drop('calibration', str(error))
            return
        except RectificationError as error:
            self._drop('size_mismatch', str(error))
            return
        except MatcherInputError as error:
            self._drop('matcher_input', str(error))
            return
        except cv2.error as error:  # odd shapes or values OpenCV refuses (remap, cvtColor)
            self._drop('opencv', ' '.join(str(error).split()))
            return
        except Exception as error:  # keep matching whatever one pair does
            self._drop('internal', f'{error!r}\n{traceback.format_exc()}')
            return
        start = time.perf_counter()
        header = pair.header
        try:
            matches = stereo_matches_message(
                header, result.rectified, result.points, result.disparity_map.config,
                result.point_stride)
            matches.sequence = self.processed + 1
            matches.pair_sequence = pair.sequence
            if timer is not None:
                timer.step('pack')
            with self._condition:  # before publishing: its decision may come back at once
                self.undecided.published(stamp_to_ns(header.stamp), time.monotonic())
            self.matches_publisher.publish(matches)
            if timer is not None:
                timer.step('publish matches')
                timer.event('matches out')
            if self.points_publisher.get_subscription_count() > 0:
                self.points_publisher.publish(matched_points_to_cloud(result.points, header))
            if self.disparity_publisher.get_subscription_count() > 0:
                self.disparity_publisher.publish(
                    disparity_image_message(result.disparity_map, result.rectified, header))
        except Exception as error:
            if not self.context.ok():
                return  # shutting down: nothing left to publish to
            self._drop('internal', f'{error!r}\n{traceback.format_exc()}')
            return
        timings = dict(result.timings_ms, publish=1e3 * (time.perf_counter() - start))
        if timer is not None:
            timer.note('matched', 'area' if result.region is not None
                       else f'whole: {result.region_problem or plan.reason}')
            timer.note('points', str(len(result.points)))
            self.pair_timing.publish(timer, pair.header.stamp)
        with self._condition:
            self.searched[result.region_problem or plan.reason or 'area'] += 1
            if plan.periodic_skipped and result.region is not None:
                self.searched[PERIODIC_SKIPPED] += 1
            if plan.from_matches and result.region is not None:
                self.searched[FROM_MATCHES] += 1
            self.searched[FOUND_IN_MATCHES] += int(found)
            self.processed += 1
            self.last_timings_ms = timings
            self.last_points = len(result.points)
            self._total_ms += sum(timings.values())
        where = (f'in the tracked area {result.region.roi}, disparities '
                 f'{result.region.min_disparity}+{result.region.disparity_range}'
                 if result.region is not None else
                 f'on the whole image ({result.region_problem or plan.reason})')
        self.get_logger().debug(
            f'pair matched {where}: {len(result.points)} points, '
            + ', '.join(f'{name} {ms:.1f} ms' for name, ms in timings.items()))

    def _derive_disparities(self, calibration: StereoCalibration) -> None:
        """With disparity_range 0, search the workspace box's disparities for this calibration.

        Raises:
            DisparityRangeError: When the box is not in view of both cameras.
        """
        settings = self.settings
        if not settings.derives_disparities or (
                self._derived_for is not None
                and self._derived_for.left.same_as(calibration.left)
                and self._derived_for.right.same_as(calibration.right)):
            return
        config = settings.with_derived_disparities(calibration)
        self.pipeline.config = config
        self._derived_for = calibration
        self.get_logger().info(
            f'disparities {config.min_disparity}..{config.max_disparity} px derived from the '
            'calibration, the rig pose and the workspace box')

    def _drop(self, reason: str, text: str) -> None:
        with self._condition:
            self.dropped[reason] += 1
            self.last_error = f'{reason}: {text.splitlines()[0]}'
        self._error_loggers[reason].error(
            f'stereo pair dropped ({reason}): {text}',
            throttle_duration_sec=self.settings.error_log_period_s)
        self._publish_diagnostics()

    # --- diagnostics and shutdown -------------------------------------------------------------

    def _publish_diagnostics(self) -> None:
        with self._condition:
            values = {
                'pairs received': self.received,
                'pairs processed': self.processed,
                'pairs waiting': len(self._pending),
                'pairs matched in the tracked area': self.searched['area'],
                **{f'pairs matched whole: {reason}': self.searched[reason]
                   for reason in (*FULL_FRAME_REASONS, *REGION_PROBLEMS)},
                f'decisions not tracked: {POSE_MISMATCH}': self.searched[POSE_MISMATCH],
                'periodic whole images skipped, image unchanged outside the area':
                    self.searched[PERIODIC_SKIPPED],
                'regions found in whole-image matches': self.searched[FOUND_IN_MATCHES],
                'pairs matched in a region found in whole-image matches':
                    self.searched[FROM_MATCHES],
                **{f'decisions waited for after a failed region: {outcome}': count
                   for outcome, count in self.decision_waits.items()},
                'pairs held while max_undecided_matches were undecided':
                    self.held_for_decisions,
                'undecided matches': len(self.undecided),
                'undecided matches expired (no decision within undecided_timeout_s)':
                    self.undecided.expired,
                **self.pair_sequence.report(topic_names.PAIR),
                **{f'dropped {reason}': count for reason, count in self.dropped.items()},
                'last valid points': self.last_points,
                **{f'last {name} time [ms]': round(ms, 2)
                   for name, ms in self.last_timings_ms.items()},
                'mean processing time [ms]': round(self._total_ms / self.processed, 2)
                if self.processed else 0.0,
                # Readers DDS has matched to the matches writer, and writers to the pair
                # reader (none before the kernel is ready): what is published reaches them.
                f'{topic_names.MATCHES} subscribers':
                    self.matches_publisher.get_subscription_count(),
                f'{topic_names.PAIR} publishers': (self.pair_subscription.get_publisher_count()
                                                   if self.pair_subscription else 0),
            }
            last_error = self.last_error
            errors = sum(count for reason, count in self.dropped.items()
                         if reason != 'superseded')
        status = DiagnosticStatus(
            level=DiagnosticStatus.WARN if errors else DiagnosticStatus.OK,
            name=f'{self.get_name()}: correlation', hardware_id=self.get_name(),
            message=f'last error: {last_error}' if last_error else 'matching',
            values=[KeyValue(key=key, value=str(value)) for key, value in values.items()])
        array = DiagnosticArray(status=[status])
        array.header.stamp = self.get_clock().now().to_msg()
        self.diagnostics_publisher.publish(array)

    def destroy_node(self) -> None:
        """Stop the worker thread, then destroy the node."""
        with self._condition:
            self._stopping = True
            self._condition.notify_all()
        self._worker.join(timeout=30.0)
        super().destroy_node()


def main(args: list[str] | None = None) -> None:
    """Run the node until shutdown; a bad parameter ends it with one line."""
    run_node(CorrelationNode, args)


if __name__ == '__main__':
    main()
