"""Choose the best point of the correlation area with the fuzzy system (or a baseline).

Subscribes `matches` (StereoMatches; the chain remaps it to `stereo/matches`) and
`/tf_static`, publishes `best_point`
(PointStamped in `world`, stamped with the pair's stamp, only when a point was chosen),
`best_point/decision` (FuzzyDecision, for every input, with the reason when no point was
chosen), `best_point/markers` (MarkerArray in `world`: the correlation area, border points,
numbered area centres and best point, while someone subscribes) and /diagnostics.
The algorithm is point_selectors.BestPointChooser; this node only converts and publishes. The
decision runs in the subscription callback, so every input gets its decision; what it costs per
point count is the "fuzzy decision time" row of the README's benchmark table.

The matches' frame is placed in `world` by, in this order: the pose file `rig_pose_file`, the
transforms on /tf_static (a replayed bag that recorded them needs no rig parameters), or the
chapter's rig.* numbers (core/rig_pose.py). A configured rig.baseline_m (> 0) must agree with
the calibration: with `left_calibration_file` and `right_calibration_file` it is checked at
start and a mismatch ends the node; in any case, the first matches message whose calibration
contradicts it is logged once as an ERROR with both numbers, /diagnostics turns ERROR, and every
decision from then on is refused as `rig_mismatch` with that reason (rig.baseline_m is
read-only: the node must be restarted with the right value).
"""

from __future__ import annotations

import dataclasses
import threading
import time
from collections import Counter
from typing import Any

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PointStamped
from rclpy.node import Node
from std_msgs.msg import Header
from stereo_fuzzy_parameters.declaration import declare_settings, run_node
from visualization_msgs.msg import MarkerArray

from stereo_fuzzy_msgs.msg import FuzzyDecision, StereoMatches
from stereo_fuzzy_perception.core.best_point import four_areas, top_shape_fit
from stereo_fuzzy_perception.core.best_point.correlation_area import (
    DEGENERATE_AREA,
    LOOK_COLOUR_SILHOUETTE,
    NO_OBJECT,
    NO_POINTS,
    NO_RULE_FIRED,
    STATUS_OK,
    TOO_FEW_POINTS,
    UNCERTAIN_TOP,
)
from stereo_fuzzy_perception.core.best_point.point_selectors import (
    OUTPUT_STATUSES,
    BestPointChooser,
    BestPointDecision,
    SelectorError,
    load_selector_files,
)
from stereo_fuzzy_perception.core.best_point.second_look import decide_with_second_look
from stereo_fuzzy_perception.core.best_point.top_shape_fit import TopShapeMemory
from stereo_fuzzy_perception.core.camera_calibration_file import (
    CalibrationFileError,
    read_calibration_yaml,
)
from stereo_fuzzy_perception.core.camera_model import StereoCalibration
from stereo_fuzzy_perception.core.frame_transforms import (
    LEFT_CAMERA_FRAME,
    RigPoseError,
    Transform,
)
from stereo_fuzzy_perception.core.matching.matcher_config import MatcherConfig
from stereo_fuzzy_perception.core.rig_pose import (
    BASELINE_TOLERANCE_M,
    RIG_PARAMETERS,
    CameraPoseSource,
    check_baseline,
)
from stereo_fuzzy_perception.core.sequence_gaps import SequenceGaps
from stereo_fuzzy_perception.nodes import qos, topic_names
from stereo_fuzzy_perception.nodes.conversions import (
    best_point_to_point_stamped,
    camera_info_to_calibration,
    cloud_to_matched_points,
    decision_to_markers,
    decision_to_message,
    stereo_matches_colour,
    stereo_matches_image,
    stereo_matches_matcher,
    tf_message_to_transforms,
)
from stereo_fuzzy_perception.nodes.fuzzy_best_point_parameters import FuzzyBestPointSettings
from stereo_fuzzy_perception.nodes.pair_timing import PairTimer, PairTimingPublisher
from tf2_msgs.msg import TFMessage

MALFORMED_INPUT = 'malformed_input'
RIG_MISMATCH = 'rig_mismatch'
INTERNAL_ERROR = 'internal_error'
REFUSAL_REASONS = (NO_POINTS, NO_OBJECT, TOO_FEW_POINTS, UNCERTAIN_TOP, DEGENERATE_AREA,
                   NO_RULE_FIRED, MALFORMED_INPUT, RIG_MISMATCH, *OUTPUT_STATUSES,
                   INTERNAL_ERROR)
ERROR_THROTTLE_S = 5.0
HINT_THROTTLE_S = 60.0


def build_chooser(settings: FuzzyBestPointSettings) -> BestPointChooser:
    """Return the chooser the settings describe.

    Raises:
        SelectorError: Unknown selector or an unusable rule base / weights file; the message
            names the parameter and its value.
    """
    try:
        chooser = BestPointChooser.create(
            settings.selector, settings.area_config(), settings.rig.stereo_rig(),
            rule_base_file=settings.rule_base_file, weights_file=settings.network_file)
        # a camera sees a standing object for many pairs: its top is fitted on the first
        return dataclasses.replace(chooser, top_shape_memory=TopShapeMemory())
    except SelectorError as error:
        # Name the file parameter the selector read, so the reason says what to change.
        if settings.selector == 'neural_network' and settings.network_file:
            raise SelectorError(f'network_file={settings.network_file!r}: {error}') from None
        if settings.selector.startswith('fuzzy') and settings.rule_base_file:
            raise SelectorError(f'rule_base_file={settings.rule_base_file!r}: {error}') from None
        raise


def build_pose_source(settings: FuzzyBestPointSettings) -> CameraPoseSource:
    """Return where the camera pose comes from (pose file or rig.* numbers).

    Raises:
        RigPoseError: An unusable pose file.
    """
    return CameraPoseSource.from_settings(settings.rig.stereo_rig(), settings.rig_pose_file,
                                          settings.world.world_frame)


def calibration_files_problem(settings: FuzzyBestPointSettings) -> str | None:
    """Return why the calibration files are unusable or contradict rig.baseline_m, or None.

    Nothing is checked when neither file is given (the first matches message is checked then).
    """
    left_file, right_file = settings.left_calibration_file, settings.right_calibration_file
    if not left_file and not right_file:
        return None
    if not left_file or not right_file:
        return ('left_calibration_file and right_calibration_file go together; got '
                f'{left_file!r} and {right_file!r}')
    calibrations = []
    for name, path in (('left_calibration_file', left_file),
                       ('right_calibration_file', right_file)):
        try:
            calibrations.append(read_calibration_yaml(path))
        except CalibrationFileError as error:
            return f'{name}: {error}'
    calibration = StereoCalibration(*calibrations)
    problem = calibration.problem()
    if problem:
        return (f'left_calibration_file={left_file!r}, right_calibration_file={right_file!r}: '
                f'{problem}')
    if settings.rig.baseline_m > 0.0:
        try:
            check_baseline(settings.rig.baseline_m, calibration)
        except RigPoseError as error:
            return (f'{error} (calibration {right_file}; allowed: 0, or within '
                    f'{BASELINE_TOLERANCE_M} m of the calibration)')
    return None


def chooser_problem(settings: FuzzyBestPointSettings) -> str | None:
    """Return why the settings cannot work (a bad rule base, pose or calibration file), or None.

    Both selector files are loaded and checked whichever selector is active, so a bad
    network_file is refused when it is set, not when neural_network is selected later. Never
    raises.
    """
    try:
        for name, rule_base_file, weights_file in (
                ('rule_base_file', settings.rule_base_file, ''),
                ('network_file', '', settings.network_file)):
            try:
                load_selector_files(rule_base_file, weights_file)
            except SelectorError as error:
                return f'{name}={rule_base_file or weights_file!r}: {error}'
        build_chooser(settings)
        build_pose_source(settings)
        return calibration_files_problem(settings)
    except (SelectorError, RigPoseError) as error:
        return str(error)
    except Exception as error:  # a loader bug must refuse the change, not kill the node
        return f'cannot check the settings ({type(error).__name__}: {error})'


class FuzzyBestPointNode(Node):
    """Choose the best point of the correlation area with the fuzzy system."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__('fuzzy_best_point_node', **kwargs)
        self._lock = threading.Lock()
        self.settings = declare_settings(self, FuzzyBestPointSettings,
                                         apply=self._apply_settings, check=chooser_problem)
        self._chooser = build_chooser(self.settings)
        self._pose_source = build_pose_source(self.settings)
        self._static_transforms: dict[str, Transform] = {}
        self._pose_origin = ''
        # Set by the first matches message whose calibration contradicts rig.baseline_m.
        self.rig_mismatch = ''
        # Compile (first run) or load the numba point kernel now, not on the first input.
        started = time.monotonic()
        four_areas.warm_up()
        top_shape_fit.warm_up()
        self.get_logger().info(
            f'point kernels ready in {time.monotonic() - started:.2f} s (numba compile or cache)')
        self.decisions: Counter[str] = Counter({STATUS_OK: 0, **dict.fromkeys(
            REFUSAL_REASONS, 0)})
        self._last_status = 'waiting for input'
        # Pairs matched again at point stride 1 (second_look_stride_one), and how many of them
        # gave a point.
        self.second_looks: Counter[str] = Counter(looked=0, found=0)
        # Matches that came with colour images, and the points the colour silhouette gave.
        self.colour_looks: Counter[str] = Counter(matches=0, points=0)
        self.matches_sequence = SequenceGaps()
        self.best_point_publisher = self.create_publisher(
            PointStamped, topic_names.BEST_POINT, qos.RESULTS)
        self.decision_publisher = self.create_publisher(
            FuzzyDecision, topic_names.DECISION, qos.RESULTS)
        self.markers_publisher = self.create_publisher(MarkerArray, topic_names.MARKERS,
                                                       qos.RESULTS)
        self.diagnostics_publisher = self.create_publisher(
            DiagnosticArray, topic_names.DIAGNOSTICS, qos.DIAGNOSTICS)
        # Per-pair timing, only while someone subscribes (a benchmark).
        self.pair_timing = PairTimingPublisher(self, topic_names.DECISION_TIMING)
        self.matches_subscription = self.create_subscription(
            StereoMatches, topic_names.MATCHES, self._on_matches, qos.RESULTS)
        self.create_subscription(TFMessage, topic_names.TF_STATIC, self._on_tf_static,
                                 qos.TF_STATIC)
        self.create_timer(self.settings.diagnostics_period_s, self._publish_diagnostics)
        self.get_logger().info(
            f'choosing best points with {self._describe()} from '
            f'{self.matches_subscription.topic_name}')

    def _describe(self) -> str:
        chooser = self._chooser
        if chooser.rule_base is not None:
            return f'{chooser.selector} (rule base {chooser.rule_base.name!r})'
        return chooser.selector

    def _apply_settings(self, settings: FuzzyBestPointSettings) -> None:
        chooser = build_chooser(settings)  # validated already
        with self._lock:
            self.settings = settings
            self._chooser = chooser
        self.get_logger().info(f'now choosing with {self._describe()}')

    def _on_matches(self, msg: StereoMatches) -> None:
        timer = self.pair_timing.start(time.time_ns())
        header = Header(stamp=msg.header.stamp, frame_id=self.settings.world.world_frame)
        with self._lock:
            chooser = self._chooser
            second_look = self.settings.second_look_stride_one
            self.matches_sequence.observe(int(msg.sequence))
        try:
            points = cloud_to_matched_points(msg.points)
            points.left_image = stereo_matches_image(msg)
            points.right_image = stereo_matches_image(msg, 'right')
            points.left_colour = stereo_matches_colour(msg)
            points.right_colour = stereo_matches_colour(msg, 'right')
            left = camera_info_to_calibration(msg.left_info)
            right = camera_info_to_calibration(msg.right_info)
            problem = StereoCalibration(left, right).problem()
            if problem:
                raise ValueError(f'rectified calibration: {problem}')
        except (ValueError, KeyError, TypeError) as error:
            self.get_logger().error(
                f'malformed StereoMatches (stamp {msg.header.stamp.sec}.'
                f'{msg.header.stamp.nanosec:09d}): {error}',
                throttle_duration_sec=ERROR_THROTTLE_S)
            decision = BestPointDecision(chooser.selector, status=MALFORMED_INPUT,
                                         reason=str(error))
            self._publish(decision, header, msg.header.frame_id, timer)
            return
        mismatch = self._baseline_mismatch(StereoCalibration(left, right))
        if mismatch:
            self._publish(BestPointDecision(chooser.selector, status=RIG_MISMATCH,
                                            reason=mismatch), header, msg.header.frame_id, timer)
            return
        try:
            chooser = dataclasses.replace(chooser, world_from_camera=self._world_from_camera(
                StereoCalibration(left, right), msg.header.frame_id or LEFT_CAMERA_FRAME))
        except RigPoseError as error:
            self.get_logger().error(f'camera pose: {error}',
                                    throttle_duration_sec=ERROR_THROTTLE_S)
            self._publish(BestPointDecision(chooser.selector, status=RIG_MISMATCH,
                                            reason=str(error)), header, msg.header.frame_id,
                          timer)
            return
        if timer is not None:
            timer.step('decode')
        matcher = self._matcher_for_second_look(msg) if second_look else None
        try:
            looked = decide_with_second_look(chooser, points, left, right, matcher,
                                             int(msg.point_stride))
            decision = looked.decision
            if looked.looked:
                self.second_looks['looked'] += 1
                self.second_looks['found'] += looked.found
            if points.left_colour is not None:
                self.colour_looks['matches'] += 1
                self.colour_looks['points'] += int(decision.has_best_point
                                                   and decision.look == LOOK_COLOUR_SILHOUETTE)
        except Exception as error:  # no input may stop the node; say what happened instead
            self.get_logger().error(f'choosing failed: {error!r}',
                                    throttle_duration_sec=ERROR_THROTTLE_S)
            decision = BestPointDecision(chooser.selector, status=INTERNAL_ERROR,
                                         reason=f'{type(error).__name__}: {error}')
        if (decision.status == NO_POINTS and decision.points_in > 0
                and not self._pose_source.transforms and self._pose_origin == RIG_PARAMETERS):
            self.get_logger().warning(
                f'none of {decision.points_in} points lands in the workspace with the camera '
                'pose of the rig.* parameters: if they do not describe this rig, give its pose '
                'file (rig_pose_file, written by rig_calibration) or publish it on /tf_static',
                throttle_duration_sec=HINT_THROTTLE_S)
        if timer is not None:
            timer.step('decide')
        self._publish(decision, header, msg.header.frame_id, timer)

    def _matcher_for_second_look(self, msg: StereoMatches) -> MatcherConfig | None:
        """Return the matcher settings the matches came with, or None (with a warning) when
        they are unusable: the pair is then decided at its own stride only."""
        if int(msg.point_stride) <= 1:
            return None
        try:
            return stereo_matches_matcher(msg)
        except ValueError as error:
            self.get_logger().warning(
                f'StereoMatches (stamp {msg.header.stamp.sec}.{msg.header.stamp.nanosec:09d}) '
                f'carry matcher settings that cannot be used again ({error}): no second look '
                'at point stride 1 for them', throttle_duration_sec=ERROR_THROTTLE_S)
            return None

    def _baseline_mismatch(self, calibration: StereoCalibration) -> str:
        """Return why every decision is refused (rig.baseline_m vs calibration), or ''.

        The first contradiction is kept for the node's life and logged once.
        """
        configured = self.settings.rig.baseline_m
        if not self.rig_mismatch and configured > 0.0:
            try:
                check_baseline(configured, calibration)
            except RigPoseError as error:
                self.rig_mismatch = str(error)
                self.get_logger().error(
                    f'{error}; refusing every decision as {RIG_MISMATCH} until the node is '
                    'restarted with a rig.baseline_m that agrees (allowed: 0, or within '
                    f'{BASELINE_TOLERANCE_M} m of the calibration)')
        return self.rig_mismatch

    def _on_tf_static(self, msg: TFMessage) -> None:
        transforms = tf_message_to_transforms(msg)
        with self._lock:
            for transform in transforms:
                self._static_transforms[transform.child_frame_id] = transform

    def _world_from_camera(self, calibration: StereoCalibration,
                           camera_frame: str) -> np.ndarray:
        """Return world <- camera from the pose file, /tf_static or the rig.* numbers.

        Raises:
            RigPoseError: A configured baseline disagrees with the calibration, or the pose
                file does not place `camera_frame`.
        """
        source = self._pose_source
        if not source.transforms:
            with self._lock:
                static = list(self._static_transforms.values())
            from_tf = source.with_transforms(static, topic_names.TF_STATIC)
            if static and from_tf.connects(camera_frame):
                source = from_tf
        if source.origin != self._pose_origin:
            self._pose_origin = source.origin
            self.get_logger().info(f'{camera_frame} placed in {source.world_frame} by '
                                   f'{source.origin}')
        return source.world_from_camera(calibration, camera_frame)

    def _publish(self, decision: BestPointDecision, header: Header, camera_frame: str,
                 timer: PairTimer | None = None) -> None:
        self.decisions[decision.status] += 1
        self._last_status = decision.status_text()
        if decision.has_best_point:
            self.best_point_publisher.publish(best_point_to_point_stamped(decision, header))
            point = decision.best_point_world
            self.get_logger().debug(
                f'best point ({point[0]:.4f}, {point[1]:.4f}, {point[2]:.4f}) m from '
                f'{decision.points_used} of {decision.points_in} points')
        else:
            self.get_logger().debug(f'no best point: {decision.status_text()}')
        self.decision_publisher.publish(decision_to_message(decision, header, camera_frame))
        if self.markers_publisher.get_subscription_count() > 0:
            self.markers_publisher.publish(decision_to_markers(decision, header))
        if timer is not None:
            timer.step('publish')
            timer.note('status', decision.status)
            timer.note('points', str(decision.points_in))
            self.pair_timing.publish(timer, header.stamp)

    def _publish_diagnostics(self) -> None:
        made = self.decisions[STATUS_OK]
        refused = {reason: self.decisions[reason] for reason in REFUSAL_REASONS}
        status = DiagnosticStatus(name=f'{self.get_name()}: best point',
                                  hardware_id=self.get_name())
        if self.rig_mismatch:
            status.level = DiagnosticStatus.ERROR
            status.message = f'{RIG_MISMATCH}: {self.rig_mismatch}'
        elif made == 0 and not any(refused.values()):
            status.level, status.message = DiagnosticStatus.OK, 'waiting for input'
        elif self._last_status == STATUS_OK:
            status.level, status.message = DiagnosticStatus.OK, 'choosing best points'
        else:
            status.level, status.message = DiagnosticStatus.WARN, self._last_status
        values: list[tuple[str, object]] = [('selector', self._describe()),
                                            ('camera pose from', self._pose_origin or
                                             self._pose_source.origin),
                                            ('decisions made', made),
                                            ('decisions refused', sum(refused.values()))]
        values += [(f'refused {reason}', count) for reason, count in refused.items()]
        values += [('matched again at point stride 1', self.second_looks['looked']),
                   ('points from matching again', self.second_looks['found']),
                   ('matches with colour images', self.colour_looks['matches']),
                   ('points from the colour silhouette', self.colour_looks['points'])]
        with self._lock:
            memory = self._chooser.top_shape_memory
            if memory is not None and self._chooser.area_config.fit_top_shape:
                values += [('top shapes fitted', memory.counts['fitted']),
                           ('top shapes reused for the same object', memory.counts['recalled']),
                           ('points moved toward a fitted top', memory.counts['moved']),
                           ('faces in pieces given their fitted top',
                            memory.counts['pieces']),
                           ('faces too small in the image given their fitted top',
                            memory.counts['small'])]
            values += list(self.matches_sequence.report(topic_names.MATCHES).items())
        # Whether DDS has matched a writer to this reader: 0 while matches are published means
        # discovery has not connected the two nodes (nothing can arrive, nothing counts as lost).
        values.append((f'{topic_names.MATCHES} publishers',
                       self.matches_subscription.get_publisher_count()))
        values.append((f'{topic_names.BEST_POINT} subscribers',
                       self.best_point_publisher.get_subscription_count()))
        status.values = [KeyValue(key=key, value=str(value)) for key, value in values]
        array = DiagnosticArray(status=[status])
        array.header.stamp = self.get_clock().now().to_msg()
        self.diagnostics_publisher.publish(array)


def main(args: list[str] | None = None) -> None:
    """Run the node until shutdown; a bad parameter or file ends it with one line."""
    run_node(FuzzyBestPointNode, args)


if __name__ == '__main__':
    main()
