"""correlation_node in-process with real rclpy: matches, bad pairs dropped, parameters.

Each test has a ROS context and domain of its own (ros_context) and waits on graph conditions
and messages, never on fixed sleeps.
"""

from __future__ import annotations

import numpy as np
import pytest
from correlation_harness import (
    BASELINE,
    FOCAL,
    HEIGHT,
    OVERHEAD_RIG,
    SHIFT,
    TIMEOUT,
    WIDTH,
    Harness,
    camera,
    stereo_pair,
    textured_pair,
)
from ros_waiting import wait_until

pytestmark = pytest.mark.ros

@pytest.fixture
def harness(ros_context):
    created = []

    def make(**overrides):
        created.append(Harness(ros_context, **overrides))
        return created[-1]

    yield make
    for item in created:
        item.close()


def test_known_shift_gives_points_at_f_b_over_d(harness):
    from stereo_fuzzy_perception.nodes.conversions import (
        cloud_to_matched_points,
        stereo_matches_image,
    )

    rig = harness(window_size=9, disparity_range=32)
    rig.publish_and_wait_processed(stereo_pair(stamp_sec=7))
    wait_until(lambda: rig.matches, TIMEOUT, 'a StereoMatches message', rig.executor)
    message = rig.matches[-1]
    assert message.header.stamp.sec == 7
    assert message.header.frame_id == 'left_camera_optical_frame'
    assert (message.method, message.window_size, message.disparity_range) == ('zncc', 9, 32)
    assert list(message.left_info.d) == [0.0] * 5
    assert message.right_info.p[3] == pytest.approx(-FOCAL * BASELINE)
    points = cloud_to_matched_points(message.points)
    assert len(points) > 0.8 * HEIGHT * (WIDTH - SHIFT - 2 * 4)
    depth = FOCAL * BASELINE / SHIFT
    assert np.median(points.xyz[:, 2]) == pytest.approx(depth, rel=1e-3)
    assert np.mean(np.abs(points.xyz[:, 2] - depth) < 0.02 * depth) > 0.98
    expected_x = (points.u_left - WIDTH / 2) * points.xyz[:, 2] / FOCAL
    assert np.allclose(points.xyz[:, 0], expected_x, atol=1e-4)
    assert np.mean(np.abs(points.u_left - points.u_right - SHIFT) < 0.5) > 0.98
    # both rectified images the matcher read come along (the fuzzy stage's outline and a
    # plain top's height): the right one is the left one SHIFT columns to the left
    left_image = stereo_matches_image(message)
    right_image = stereo_matches_image(message, 'right')
    assert left_image is not None and right_image is not None
    assert left_image.pixels.shape == right_image.pixels.shape == (HEIGHT, WIDTH)
    assert left_image.window_size == right_image.window_size == 9
    inner = slice(SHIFT + 10, WIDTH - 10)
    left_part = left_image.pixels[20:-20, inner].astype(int)
    right_part = right_image.pixels[20:-20, 10:WIDTH - 10 - SHIFT].astype(int)
    assert np.mean(np.abs(left_part - right_part) <= 2) > 0.95


@pytest.mark.parametrize(('bad', 'reason', 'words'), [
    ({'left_k_zero': True}, 'calibration', 'not calibrated'),
    ({'right_tx': 5.0}, 'calibration', 'must be negative'),
    ({'right_width': WIDTH - 16}, 'calibration', 'calibration is'),
    ({'encoding': 'yuv422'}, 'encoding', 'yuv422'),
], ids=['uncalibrated', 'right-tx-positive', 'size-mismatch', 'unsupported-encoding'])
def test_bad_pair_is_dropped_reported_and_a_good_pair_still_matches(harness, bad, reason, words):
    rig = harness(window_size=7, disparity_range=16)
    rig.publish_and_wait_processed(stereo_pair(**bad))
    assert rig.node.dropped[reason] == 1
    assert rig.node.processed == 0
    assert words in rig.node.last_error
    wait_until(lambda: rig.diagnostics and rig.latest_values()[f'dropped {reason}'] == '1',
               TIMEOUT, f'/diagnostics reporting the {reason} drop', rig.executor)
    assert rig.diagnostics[-1].status[0].level == rig.diagnostics[-1].status[0].WARN
    assert words in rig.diagnostics[-1].status[0].message
    assert rig.diagnostics[-1].status[0].hardware_id == 'correlation_node', (
        'hardware_id names the node (it drives no device)')

    rig.publish_and_wait_processed(stereo_pair(stamp_sec=2))
    wait_until(lambda: rig.matches, TIMEOUT, 'matches of the good pair', rig.executor)
    assert rig.node.processed == 1
    assert rig.matches[-1].header.stamp.sec == 2


def test_size_mismatch_between_images_and_their_calibration_is_named(harness):
    from stereo_fuzzy_perception.nodes.conversions import array_to_image

    rig = harness()
    pair = stereo_pair()
    left, _ = textured_pair(width=WIDTH - 20)
    pair.left_image = array_to_image(left, 'mono8', pair.header)  # info still says WIDTH
    rig.publish_and_wait_processed(pair)
    assert rig.node.dropped['size_mismatch'] == 1, rig.node.last_error
    assert f'{WIDTH - 20}x{HEIGHT}' in rig.node.last_error


def test_matcher_parameters_change_at_run_time_and_invalid_values_are_refused(harness):
    from rclpy.parameter import Parameter

    rig = harness()
    refused = rig.node.set_parameters([Parameter('window_size', value=8)])[0]
    assert not refused.successful
    assert 'odd' in refused.reason
    assert rig.node.pipeline.config.window_size == 9
    refused = rig.node.set_parameters([Parameter('preprocess', value='sobel')])[0]
    assert not refused.successful and 'preprocess' in refused.reason

    accepted = rig.node.set_parameters([Parameter('window_size', value=11),
                                        Parameter('method', value='plain')])[0]
    assert accepted.successful, accepted.reason
    assert rig.node.pipeline.config.window_size == 11
    rig.publish_and_wait_processed(stereo_pair())
    wait_until(lambda: rig.matches, TIMEOUT, 'matches with the new settings', rig.executor)
    assert (rig.matches[-1].method, rig.matches[-1].window_size) == ('plain', 11)


def test_disparity_image_is_published_to_a_subscriber(harness):
    from stereo_fuzzy_perception.nodes import qos
    from stereo_msgs.msg import DisparityImage

    rig = harness(disparity_range=32)
    images: list = []
    rig.probe.create_subscription(DisparityImage, 'disparity', images.append,
                                  qos.RESULTS)
    wait_until(lambda: rig.node.disparity_publisher.get_subscription_count() > 0, TIMEOUT,
               'the node to see the disparity subscriber', rig.executor)
    rig.publish_and_wait_processed(stereo_pair())
    wait_until(lambda: images, TIMEOUT, 'a DisparityImage', rig.executor)
    message = images[-1]
    assert (message.f, message.t) == (pytest.approx(FOCAL), pytest.approx(BASELINE))
    assert (message.min_disparity, message.max_disparity) == (0.0, 31.0)
    data = np.frombuffer(bytes(message.image.data), np.float32).reshape(HEIGHT, WIDTH)
    valid = data >= message.min_disparity
    assert valid.mean() > 0.7
    assert np.median(data[valid]) == pytest.approx(SHIFT, abs=0.05)


def _publish_burst_after_one_processed(h, stamps: range) -> None:
    """Publish one pair, wait until it is matched, then publish `stamps` at once."""
    h.publish_and_wait_processed(stereo_pair(stamp_sec=stamps.start - 1))
    for stamp in stamps:
        h.publisher.publish(stereo_pair(stamp_sec=stamp))
    wait_until(lambda: h.node.received == len(stamps) + 1, TIMEOUT,
               'the node to receive the burst', h.executor)


def test_busy_node_works_on_the_newest_pair_and_counts_the_superseded(harness):
    # max_rate_hz holds the worker 2 s after each pair, so the burst arrives while it is busy.
    h = harness(max_rate_hz=0.5, input_queue_depth=1)
    _publish_burst_after_one_processed(h, range(2, 6))
    wait_until(lambda: h.node.processed + h.node.dropped['superseded'] == 5, TIMEOUT,
               'every pair to be matched or counted as superseded', h.executor)
    wait_until(lambda: len(h.matches) == h.node.processed, TIMEOUT,
               'the matches of every processed pair', h.executor)
    stamps = [message.header.stamp.sec for message in h.matches]
    assert stamps[0] == 1 and stamps[-1] == 5, stamps  # the newest pair is never the one dropped
    assert stamps == sorted(stamps)
    assert h.node.dropped['superseded'] >= 1


def test_input_queue_depth_keeps_a_burst_that_fits(harness):
    h = harness(max_rate_hz=0.5, input_queue_depth=4)
    _publish_burst_after_one_processed(h, range(2, 6))
    wait_until(lambda: len(h.matches) == 5, TIMEOUT, 'all five pairs matched', h.executor)
    assert [message.header.stamp.sec for message in h.matches] == [1, 2, 3, 4, 5]
    assert h.node.dropped['superseded'] == 0


def test_disparity_range_0_derives_the_search_from_the_rig_and_the_workspace(harness):
    from stereo_fuzzy_perception.core.camera_model import StereoCalibration
    from stereo_fuzzy_perception.core.matching.disparity_range import (
        workspace_disparity_range,
    )
    from stereo_fuzzy_perception.core.rig_geometry import StereoRig
    from stereo_fuzzy_perception.nodes.conversions import cloud_to_matched_points

    rig = harness(window_size=9, **OVERHEAD_RIG)  # disparity_range: the default, 0
    assert rig.node.get_parameter('disparity_range').value == 0
    rig.publish_and_wait_processed(stereo_pair(stamp_sec=3))
    wait_until(lambda: rig.matches, TIMEOUT, 'a StereoMatches message', rig.executor)
    pose = StereoRig(baseline_m=BASELINE, alpha_deg=0.0, x0_m=0.2, y0_m=0.15,
                     z0_m=FOCAL * BASELINE / SHIFT, vergence_deg=0.0).world_from_left_camera()
    expected = workspace_disparity_range(
        StereoCalibration(camera(tx=0.0), camera()), pose, (0.0, 0.0, 0.0), (0.4, 0.3, 0.2))
    message = rig.matches[-1]
    assert (message.min_disparity, message.disparity_range) == (
        expected.min_disparity, expected.disparity_range)
    assert expected.min_disparity < SHIFT < expected.max_disparity < 2 * SHIFT
    points = cloud_to_matched_points(message.points)
    assert np.median(points.xyz[:, 2]) == pytest.approx(FOCAL * BASELINE / SHIFT, rel=1e-3)


def test_a_workspace_out_of_view_drops_the_pair_with_the_reason(harness):
    rig = harness(window_size=9, **dict(OVERHEAD_RIG, **{'rig.x0_m': 9.0}))
    rig.publish_and_wait_processed(stereo_pair())
    assert rig.node.dropped['calibration'] == 1
    assert 'workspace box' in rig.node.last_error


def _decision_publisher(h):
    from stereo_fuzzy_perception.nodes import qos, topic_names

    from stereo_fuzzy_msgs.msg import FuzzyDecision

    publisher = h.probe.create_publisher(FuzzyDecision, topic_names.DECISION, qos.RESULTS)
    wait_until(lambda: h.node.decision_subscription.get_publisher_count() > 0, TIMEOUT,
               'the node to see the decision publisher', h.executor)
    return publisher


def test_next_pair_waits_for_the_decision_of_undecided_matches(harness):
    from stereo_fuzzy_msgs.msg import FuzzyDecision

    h = harness(max_undecided_matches=1, undecided_timeout_s=10.0)
    decisions = _decision_publisher(h)
    h.publish_and_wait_processed(stereo_pair(stamp_sec=1))
    h.publisher.publish(stereo_pair(stamp_sec=2))
    wait_until(lambda: h.node.waiting_for_decisions, TIMEOUT,
               'the worker to hold pair 2 until the decision of pair 1', h.executor)
    assert h.node.processed == 1 and len(h.node.undecided) == 1
    h.publisher.publish(stereo_pair(stamp_sec=3))  # replaces the held pair: the newest wins
    wait_until(lambda: h.node.received == 3, TIMEOUT, 'pair 3 to arrive', h.executor)
    decision = FuzzyDecision()
    decision.header.stamp.sec = 1
    decisions.publish(decision)
    wait_until(lambda: h.node.processed == 2, TIMEOUT, 'the held pair to be matched',
               h.executor)
    wait_until(lambda: len(h.matches) == 2, TIMEOUT, 'its matches', h.executor)
    assert [message.header.stamp.sec for message in h.matches] == [1, 3]
    assert h.node.dropped['superseded'] == 1
    assert h.node.held_for_decisions == 1
    wait_until(lambda: h.diagnostics and h.latest_values().get(
        'pairs held while max_undecided_matches were undecided') == '1', TIMEOUT,
        'the held pair on /diagnostics', h.executor)


def test_a_decision_that_never_comes_stops_counting_after_the_timeout(harness):
    h = harness(max_undecided_matches=1, undecided_timeout_s=0.05)
    _decision_publisher(h)  # present, but it never decides
    for stamp in (1, 2, 3):
        h.publish_and_wait_processed(stereo_pair(stamp_sec=stamp))
    assert h.node.processed == 3
    assert h.node.undecided.expired >= 2
    wait_until(lambda: h.diagnostics and int(h.latest_values().get(
        'undecided matches expired (no decision within undecided_timeout_s)', 0)) >= 2,
        TIMEOUT, 'the expired matches on /diagnostics', h.executor)


def test_pair_timing_is_sent_only_to_a_subscriber(harness):
    from diagnostic_msgs.msg import DiagnosticArray
    from stereo_fuzzy_perception.nodes import qos

    h = harness()
    h.publish_and_wait_processed(stereo_pair(stamp_sec=1))
    assert h.node.pair_timing.start(0) is None  # nobody listens: nothing measured or sent
    timings: list = []
    h.probe.create_subscription(DiagnosticArray, 'matches/timing',
                                timings.append, qos.RESULTS)
    wait_until(lambda: h.node.pair_timing.publisher.get_subscription_count() > 0, TIMEOUT,
               'the node to see the timing subscriber', h.executor)
    h.publish_and_wait_processed(stereo_pair(stamp_sec=2))
    wait_until(lambda: timings, TIMEOUT, 'the timing of pair 2', h.executor)
    assert timings[0].header.stamp.sec == 2
    values = {item.key: item.value for item in timings[0].status[0].values}
    events = [int(values[f'{event} [ns]']) for event in ('in', 'start', 'matches out', 'out')]
    assert events == sorted(events), values
    assert float(values['match [ms]']) > 0.0 and float(values['cpu [ms]']) > 0.0
    assert values['matched'].startswith('whole'), values


def test_colour_cameras_send_both_rectified_images_in_colour_too(harness):
    """bgr8 cameras: the grey pair is matched, and the parts of both images the matcher read
    travel in colour (rgb8) for the fuzzy stage's colour silhouette; grey cameras send none."""
    from std_msgs.msg import Header
    from stereo_fuzzy_perception.nodes.conversions import (
        array_to_image,
        stereo_matches_colour,
        stereo_matches_image,
    )

    rig = harness(window_size=9, disparity_range=32)
    rig.publish_and_wait_processed(stereo_pair(stamp_sec=3))
    wait_until(lambda: rig.matches, TIMEOUT, 'the grey pair matched', rig.executor)
    assert stereo_matches_colour(rig.matches[-1]) is None
    assert stereo_matches_colour(rig.matches[-1], 'right') is None
    pair = stereo_pair(stamp_sec=4)
    left, right = textured_pair()
    header = Header(frame_id='left_camera_optical_frame')
    # blue, green, red: a reddish surface, each channel the texture at its own scale
    tint = np.array([0.5, 0.75, 1.0])
    for side, grey in (('left', left), ('right', right)):
        bgr = np.clip(grey[..., None] * tint, 0, 255).astype(np.uint8)
        setattr(pair, f'{side}_image', array_to_image(bgr, 'bgr8', header))
    rig.publish_and_wait_processed(pair)
    wait_until(lambda: rig.matches and rig.matches[-1].header.stamp.sec == 4, TIMEOUT,
               'the colour pair matched', rig.executor)
    message = rig.matches[-1]
    for side in ('left', 'right'):
        colour = stereo_matches_colour(message, side)
        grey = stereo_matches_image(message, side)
        assert colour is not None and grey is not None, side
        assert colour.pixels.shape == grey.pixels.shape + (3,)
        assert (colour.x, colour.y) == (grey.x, grey.y)
        lit = colour.pixels[..., 0] > 40
        red_over_blue = colour.pixels[lit, 0].astype(float) / np.maximum(colour.pixels[lit, 2], 1)
        assert np.median(red_over_blue) == pytest.approx(2.0, rel=0.05), 'RGB order, not BGR'
