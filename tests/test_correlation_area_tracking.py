"""correlation_node matching where the previous decision found the object (roi.track).

A rig 2.5 m straight above a textured floor (test_correlation_node's OVERHEAD_RIG) sees the floor
at 8 px; a block whose top face is at 10 px stands 0.5 m out of it. The probe publishes a
FuzzyDecision for the block (as fuzzy_best_point_node would), then a pair: with the block in
it the pair is matched in the block's region only; without it (the object left) the region's
check sends the pair to the whole image, with the same points as a node that does not track.
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
)
from ros_waiting import wait_until

pytestmark = pytest.mark.ros

BLOCK = (60, 40, 40, 40)  # u, v, width, height [px] of the block's top face, left image
BLOCK_DISPARITY = 10  # [px]
TRACKING = dict(OVERHEAD_RIG, window_size=9, **{'roi.margin_object_sizes': 0.25})


def block_pair(stamp_sec: int, block: tuple[int, int, int, int] = BLOCK):
    """The floor pair with the block's top face in it (left x matches right x - 10 there)."""
    from stereo_fuzzy_perception.nodes.conversions import array_to_image

    pair = stereo_pair(stamp_sec=stamp_sec)
    left = np.frombuffer(bytes(pair.left_image.data), np.uint8).reshape(HEIGHT, WIDTH).copy()
    right = np.frombuffer(bytes(pair.right_image.data), np.uint8).reshape(HEIGHT, WIDTH).copy()
    u, v, width, height = block
    texture = np.random.default_rng(5).integers(40, 216, (height, width), dtype=np.uint8)
    left[v:v + height, u:u + width] = texture
    right[v:v + height, u - BLOCK_DISPARITY:u - BLOCK_DISPARITY + width] = texture
    pair.left_image = array_to_image(left, 'mono8', pair.header)
    pair.right_image = array_to_image(right, 'mono8', pair.header)
    return pair


def block_decision(node, stamp_sec: int, camera_offset_m: float = 0.0):
    """A decision that found the block's top face, placed with the node's own camera pose."""
    from geometry_msgs.msg import Point, Vector3
    from stereo_fuzzy_perception.core.camera_model import StereoCalibration

    from stereo_fuzzy_msgs.msg import FuzzyDecision

    pose = node.settings.pose_source().world_from_camera(
        StereoCalibration(camera(tx=0.0), camera()))
    depth = FOCAL * BASELINE / BLOCK_DISPARITY
    u, v, width, height = BLOCK

    def world(column: float, row: float) -> np.ndarray:
        point = np.array([(column - WIDTH / 2) * depth / FOCAL,
                          (row - HEIGHT / 2) * depth / FOCAL, depth, 1.0])
        return (pose @ point)[:3]

    msg = FuzzyDecision(has_best_point=True, status=FuzzyDecision.STATUS_OK)
    msg.header.stamp.sec = stamp_sec
    msg.header.frame_id = 'world'
    border = [world(u, v + height / 2), world(u + width - 1, v + height / 2),
              world(u + width / 2, v), world(u + width / 2, v + height - 1)]
    msg.border_points = [Point(x=p[0], y=p[1], z=p[2]) for p in border]
    centre = world(u + width / 2, v + height / 2)
    msg.best_point_world = Point(x=centre[0], y=centre[1], z=centre[2])
    camera_point = np.linalg.inv(pose) @ np.append(centre, 1.0)
    msg.best_point_camera = Point(x=camera_point[0] + camera_offset_m, y=camera_point[1],
                                  z=camera_point[2])
    floor_depth = FOCAL * BASELINE / SHIFT
    msg.top_height = floor_depth - depth
    msg.surface_offset_m = 0.0
    msg.surface_normal = Vector3(x=0.0, y=0.0, z=1.0)
    msg.disparity_sigma_px = 0.05
    return msg


class TrackingHarness(Harness):
    """The correlation node's harness with a decision publisher."""

    def __init__(self, context, **overrides):
        super().__init__(context, **overrides)
        from stereo_fuzzy_perception.nodes import qos

        from stereo_fuzzy_msgs.msg import FuzzyDecision

        self.decisions = self.probe.create_publisher(FuzzyDecision, 'best_point/decision',
                                                     qos.RESULTS)
        wait_until(lambda: self.decisions.get_subscription_count() > 0, TIMEOUT,
                   'the node to subscribe best_point/decision', self.executor)

    def decide(self, msg) -> None:
        """Publish a decision and wait until the node holds its area (or refused it)."""
        before = self.node.searched['pose_mismatch']
        self.decisions.publish(msg)
        wait_until(lambda: self.node.tracker._area is not None
                   or self.node.searched['pose_mismatch'] > before, TIMEOUT,
                   'the node to take the decision', self.executor)


@pytest.fixture
def tracking(ros_context):
    created = []

    def make(**overrides):
        created.append(TrackingHarness(ros_context, **dict(TRACKING, **overrides)))
        return created[-1]

    yield make
    for item in created:
        item.close()


def test_a_pair_is_matched_in_the_region_of_the_decided_block(tracking):
    from stereo_fuzzy_perception.nodes.conversions import cloud_to_matched_points

    h = tracking()
    h.publish_and_wait_processed(block_pair(stamp_sec=1))
    assert h.node.searched['no_area'] == 1
    wait_until(lambda: h.matches, TIMEOUT, 'the first matches', h.executor)
    whole = cloud_to_matched_points(h.matches[-1].points)
    h.decide(block_decision(h.node, stamp_sec=1))
    h.publish_and_wait_processed(block_pair(stamp_sec=1))
    assert h.node.searched['area'] == 1, dict(h.node.searched)
    wait_until(lambda: len(h.matches) == 2, TIMEOUT, 'the second matches', h.executor)
    tracked = cloud_to_matched_points(h.matches[-1].points)
    assert 0 < len(tracked) < len(whole) / 2  # only the region was matched
    u, v, width, height = BLOCK
    on_top = ((tracked.u_left >= u + 5) & (tracked.u_left < u + width - 5)
              & (tracked.v_left >= v + 5) & (tracked.v_left < v + height - 5))
    assert np.count_nonzero(on_top) > 0.8 * (width - 10) * (height - 10)
    assert np.median(tracked.u_left[on_top] - tracked.u_right[on_top]) == pytest.approx(
        BLOCK_DISPARITY, abs=0.1)
    # the same pixels as the whole image's matches, at the same disparities
    whole_top = {(int(a), int(b)): c for a, b, c in zip(whole.u_left, whole.v_left,
                                                        whole.u_right, strict=True)}
    assert all(whole_top.get((int(a), int(b))) == pytest.approx(c, abs=1e-3)
               for a, b, c in zip(tracked.u_left[on_top], tracked.v_left[on_top],
                                  tracked.u_right[on_top], strict=True))


def test_an_object_that_left_its_region_is_matched_on_the_whole_image(tracking):
    from stereo_fuzzy_perception.nodes.conversions import cloud_to_matched_points

    h = tracking()
    h.decide(block_decision(h.node, stamp_sec=2))
    h.publish_and_wait_processed(stereo_pair(stamp_sec=2))  # the floor only: the block left
    assert h.node.searched['object_lost'] == 1, dict(h.node.searched)
    assert h.node.tracker._area is None  # forgotten: the next pair searches everywhere
    wait_until(lambda: h.matches, TIMEOUT, 'the matches', h.executor)
    plain = tracking(**{'roi.track': False})
    plain.publish_and_wait_processed(stereo_pair(stamp_sec=2))
    wait_until(lambda: plain.matches, TIMEOUT, 'the untracked matches', plain.executor)
    assert plain.node.searched['tracking_off'] == 1
    tracked, untracked = (cloud_to_matched_points(m.matches[-1].points) for m in (h, plain))
    assert np.array_equal(tracked.xyz, untracked.xyz)
    wait_until(lambda: h.diagnostics and 'pairs matched whole: object_lost' in
               h.latest_values(), TIMEOUT, 'diagnostics', h.executor)
    assert h.latest_values()['pairs matched whole: object_lost'] == '1'


def test_the_pair_after_a_failed_region_is_matched_in_the_area_its_decision_found(tracking):
    # pairs 1 s apart; the block comes back into its region between the pairs, which the
    # block means would see as a scene change (test_a_region_whose_image_changed_...)
    h = tracking(**{'roi.max_age_s': 5.0, 'roi.detect_scene_change': False})
    h.decide(block_decision(h.node, stamp_sec=2))
    h.publish_and_wait_processed(stereo_pair(stamp_sec=2))  # the block left: whole image
    assert h.node.searched['object_lost'] == 1, dict(h.node.searched)
    h.decide(block_decision(h.node, stamp_sec=2))  # that pair's decision finds it again
    h.publish_and_wait_processed(block_pair(stamp_sec=3))
    assert h.node.decision_waits == {'arrived': 1, 'timed out': 0}
    assert h.node.searched['area'] == 1, dict(h.node.searched)
    h.node.tracker.region_failed('object_lost', 3.0)  # no decision on it will come
    h.publish_and_wait_processed(block_pair(stamp_sec=4))
    assert h.node.decision_waits == {'arrived': 1, 'timed out': 1}
    assert h.node.searched['no_area'] == 1, dict(h.node.searched)
    wait_until(lambda: h.diagnostics and h.latest_values().get(
        'decisions waited for after a failed region: timed out') == '1', TIMEOUT,
        'diagnostics with the waits', h.executor)


def test_a_decision_placed_with_another_camera_pose_is_not_tracked(tracking):
    h = tracking()
    h.publish_and_wait_processed(block_pair(stamp_sec=1))  # the node learns its pose
    h.decide(block_decision(h.node, stamp_sec=1, camera_offset_m=0.05))
    assert h.node.searched['pose_mismatch'] == 1
    h.publish_and_wait_processed(block_pair(stamp_sec=1))
    assert h.node.searched['no_area'] == 2 and h.node.searched['area'] == 0


@pytest.mark.parametrize(('overrides', 'pair_stamp', 'reason'), [
    ({'roi.full_frame_every': 1}, 1, 'periodic'),
    ({'roi.max_age_s': 0.5}, 2, 'stale_area'),  # the pair 1 s after the decision
], ids=['every-pair-whole', 'stale-decision'])
def test_whole_image_when_asked_every_pair_or_when_the_decision_is_stale(
        tracking, overrides, pair_stamp, reason):
    h = tracking(**overrides)
    h.decide(block_decision(h.node, stamp_sec=1))
    h.publish_and_wait_processed(block_pair(stamp_sec=pair_stamp))
    assert h.node.searched[reason] == 1, dict(h.node.searched)
    assert h.node.searched['area'] == 0


@pytest.mark.parametrize('spoil', ['nan_border', 'no_point', 'zero_normal', 'negative_top'])
def test_a_malformed_or_pointless_decision_is_not_tracked_and_the_node_keeps_matching(
        tracking, spoil):
    from geometry_msgs.msg import Point, Vector3

    h = tracking()
    h.decide(block_decision(h.node, stamp_sec=1))
    msg = block_decision(h.node, stamp_sec=1)
    if spoil == 'nan_border':
        msg.border_points[2] = Point(x=float('nan'), y=0.0, z=0.0)
    elif spoil == 'no_point':
        msg.has_best_point, msg.status = False, 'no_object'
    elif spoil == 'zero_normal':
        msg.surface_normal = Vector3(x=0.0, y=0.0, z=0.0)
    else:
        msg.top_height = -0.1
    h.decisions.publish(msg)
    wait_until(lambda: h.node.tracker._area is None, TIMEOUT,
               'the node to drop the tracked area', h.executor)
    h.publish_and_wait_processed(block_pair(stamp_sec=1))
    assert h.node.searched['no_area'] == 1 and h.node.searched['area'] == 0


MOVED_BLOCK = (108, 64, 40, 40)  # the block put down elsewhere, outside the first one's region


def whole_after_region(node) -> int:
    """Pairs matched again on the whole image after their region failed its check."""
    from stereo_fuzzy_perception.core.matching.area_search import REGION_PROBLEMS

    return sum(node.searched[problem] for problem in REGION_PROBLEMS)


@pytest.mark.parametrize('from_matches', [True, False], ids=['found', 'not-looked-for'])
def test_after_a_failed_region_the_next_pair_is_matched_in_a_region_its_matches_gave(
        tracking, from_matches):
    h = tracking(**{'roi.max_age_s': 5.0, 'roi.decision_wait_s': 0.0,
                    'roi.regions_from_matches': from_matches})
    h.decide(block_decision(h.node, stamp_sec=1))
    h.publish_and_wait_processed(block_pair(stamp_sec=2, block=MOVED_BLOCK))
    assert whole_after_region(h.node) == 1, dict(h.node.searched)
    # no decision on that pair arrives: the next one is matched where its matches showed the
    # block, or (not looked for) on the whole image
    h.publish_and_wait_processed(block_pair(stamp_sec=3, block=MOVED_BLOCK))
    if not from_matches:
        assert h.node.searched['found_in_matches'] == 0
        assert h.node.searched['no_area'] == 1, dict(h.node.searched)
        return
    assert h.node.searched['found_in_matches'] == 1
    assert h.node.searched['area_from_matches'] == 1, dict(h.node.searched)
    assert h.node.searched['area'] == 1 and whole_after_region(h.node) == 1
    x, y, width, height = h.node.tracker._reference.roi
    u, v, block_width, block_height = MOVED_BLOCK
    assert x < u and y < v and x + width >= u + block_width and y + height >= v + block_height
    assert width * height < WIDTH * HEIGHT / 2
    wait_until(lambda: h.diagnostics and h.latest_values().get(
        'pairs matched in a region found in whole-image matches') == '1', TIMEOUT,
        'diagnostics with the found region', h.executor)


def test_a_region_whose_image_changed_goes_whole_without_being_matched_in_it(tracking):
    h = tracking(**{'roi.max_age_s': 5.0, 'roi.decision_wait_s': 0.0,
                    'roi.regions_from_matches': False})
    h.decide(block_decision(h.node, stamp_sec=1))
    h.publish_and_wait_processed(block_pair(stamp_sec=1))
    assert h.node.searched['area'] == 1, dict(h.node.searched)
    h.publish_and_wait_processed(block_pair(stamp_sec=2, block=MOVED_BLOCK))
    assert h.node.searched['scene_changed'] == 1, dict(h.node.searched)
    assert whole_after_region(h.node) == 0  # never matched in the old region
    assert h.node.tracker._area is None
    wait_until(lambda: h.diagnostics and h.latest_values().get(
        'pairs matched whole: scene_changed') == '1', TIMEOUT, 'diagnostics', h.executor)
