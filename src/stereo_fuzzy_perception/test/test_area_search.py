"""The tracked correlation area: its search region, the region's check and when it is used."""

import dataclasses
import threading

import numpy as np
import pytest
from grid_scenes import Box, grid_matches
from stereo_fuzzy_perception.core.camera_model import StereoCalibration
from stereo_fuzzy_perception.core.matching.area_search import (
    AT_DISPARITY_LIMIT,
    OBJECT_AT_EDGE,
    OBJECT_LOST,
    OBJECT_MOVED,
    AreaProjectionError,
    SearchRegion,
    TrackedArea,
    region_from_matches,
    region_problem,
    search_region,
    surface_disparity_plane,
)
from stereo_fuzzy_perception.core.matching.area_tracker import (
    MAX_PERIODIC_SKIPPED,
    NO_AREA,
    NO_REGION,
    PERIODIC,
    SCENE_CHANGED,
    STALE_AREA,
    TRACKING_OFF,
    AreaTracker,
    TrackingConfig,
)
from stereo_fuzzy_perception.core.matching.scene_change import (
    BLOCK_PX,
    block_means,
    changed_blocks,
    changed_outside,
    changed_share_inside,
)
from stereo_fuzzy_perception.core.matching.window_matcher import (
    DisparityMap,
    MatcherConfig,
    MatchStatus,
)
from stereo_fuzzy_perception.core.rig_geometry import StereoRig

RIGS = [StereoRig(),
        StereoRig(baseline_m=0.10, alpha_deg=30.0, z0_m=0.7, y0_m=-0.3, vergence_deg=8.0),
        StereoRig(baseline_m=0.08, alpha_deg=0.0, x0_m=0.2, y0_m=0.15, z0_m=0.75,
                  vergence_deg=0.0)]
BOX = Box((0.2, 0.15), 0.05, 0.04)
FULL_RANGE = (1, 400)


def _world(rig: StereoRig, xyz: np.ndarray) -> np.ndarray:
    pose = rig.world_from_left_camera()
    world: np.ndarray = xyz @ pose[:3, :3].T + pose[:3, 3]
    return world


def box_area(stamp_s: float = 0.0) -> TrackedArea:
    x, y = BOX.centre_xy
    half = BOX.size / 2
    border = np.array([[x - half, y, BOX.height], [x + half, y, BOX.height],
                       [x, y - half, BOX.height], [x, y + half, BOX.height]])
    return TrackedArea(stamp_s, border, BOX.height, (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 0.1)


def first_rig_view() -> tuple[StereoCalibration, np.ndarray]:
    """The calibration of the first rig's pair and its left camera's pose in world."""
    rig = RIGS[0]
    _, left, right = grid_matches(rig, None, 0.0, 8)
    return StereoCalibration(left, right), rig.world_from_left_camera()


@pytest.mark.parametrize('rig', RIGS)
def test_the_surface_disparity_is_affine_in_the_pixel(rig):
    points, left, right = grid_matches(rig, None, 0.0, 8, surface_z=0.01)
    calibration = StereoCalibration(left, right)
    transform = np.linalg.inv(rig.world_from_left_camera())
    transform[:3] = np.asarray(left.R) @ transform[:3]
    a, b, c = surface_disparity_plane(calibration, transform, np.array([0.0, 0.0, 0.01]),
                                      np.array([0.0, 0.0, 1.0]))
    predicted = a * points.u_left + b * points.v_left + c
    assert np.allclose(predicted, points.u_left - points.u_right, atol=1e-3)


@pytest.mark.parametrize('rig', RIGS)
def test_the_region_holds_the_box_with_its_disparities_and_standing_out(rig):
    points, left, right = grid_matches(rig, BOX, 0.0, 2)
    world = _world(rig, points.xyz)
    on_box = BOX.covers(world[:, 0], world[:, 1]) & (world[:, 2] > BOX.height / 2)
    assert np.count_nonzero(on_box) > 20
    region = search_region(box_area(), StereoCalibration(left, right),
                           rig.world_from_left_camera(), FULL_RANGE, 1.0, 0.02)
    x, y, width, height = region.roi
    u, v = points.u_left[on_box], points.v_left[on_box]
    assert np.all((u >= x) & (u < x + width) & (v >= y) & (v < y + height))
    assert width < left.width or height < left.height
    disparity = points.u_left - points.u_right
    inside = (points.u_left >= x) & (points.u_left < x + width) & (points.v_left >= y) & (
        points.v_left < y + height)
    assert disparity[inside].min() >= region.min_disparity
    assert disparity[inside].max() <= region.min_disparity + region.disparity_range - 1
    a, b, c = region.surface_plane
    excess = disparity - (a * points.u_left + b * points.v_left + c)
    assert np.all(excess[on_box] > region.standing_px)
    surface = world[:, 2] < BOX.height / 2
    assert np.all(np.abs(excess[surface & inside]) < region.standing_px)


def test_an_area_behind_the_camera_or_outside_the_range_gives_no_region():
    rig = RIGS[0]
    _, left, right = grid_matches(rig, None, 0.0, 8)
    calibration = StereoCalibration(left, right)
    behind = box_area()
    behind = TrackedArea(0.0, behind.border_points + np.array([0.0, 0.0, 5.0]), 0.04,
                         (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 0.1)
    with pytest.raises(AreaProjectionError):
        search_region(behind, calibration, rig.world_from_left_camera(), FULL_RANGE, 1.0, 0.02)
    with pytest.raises(AreaProjectionError, match='whole-image range'):
        search_region(box_area(), calibration, rig.world_from_left_camera(), (400, 10), 1.0,
                      0.02)


def _disparity_map(disparity: np.ndarray) -> DisparityMap:
    status = np.where(np.isfinite(disparity), MatchStatus.VALID,
                      MatchStatus.LOW_TEXTURE).astype(np.uint8)
    return DisparityMap(disparity.astype(np.float32), np.ones_like(disparity, np.float32),
                        status, (0, 0, disparity.shape[1], disparity.shape[0]), MatcherConfig())


REGION = SearchRegion((20, 20, 60, 60), 0, 32, (0.0, 0.0, 8.0), 1.0, 256.0, (50.0, 50.0))


@pytest.mark.parametrize(('block', 'top', 'expected'), [
    ((40, 40), 10.0, None),  # inside, away from the ring, where the top face was
    ((20, 40), 10.0, OBJECT_AT_EDGE),  # reaches the region's left edge
    ((40, 65), 10.0, OBJECT_AT_EDGE),  # reaches its bottom edge
    ((40, 40), 31.0, AT_DISPARITY_LIMIT),  # taller than the range searched
    (None, 10.0, OBJECT_LOST),  # only the surface
    ((52, 28), 10.0, OBJECT_MOVED),  # inside, but off the top face's centre
], ids=['inside', 'left-edge', 'bottom-edge', 'at-limit', 'gone', 'moved'])
@pytest.mark.parametrize('stride', [1, 3])
def test_the_region_check_finds_an_object_at_its_edge_gone_moved_or_too_tall(
        block, top, expected, stride):
    disparity = np.full((100, 100), 8.0)
    disparity[::7, ::5] += 0.5  # noise below the standing threshold
    if block is not None:
        disparity[block[1]:block[1] + 20, block[0]:block[0] + 20] = top
    assert region_problem(_disparity_map(disparity), REGION, stride) == expected


def test_a_few_mismatches_in_the_ring_are_tolerated():
    disparity = np.full((100, 100), 8.0)
    disparity[40:60, 40:60] = 10.0
    disparity[21, 30:33] = 12.0  # three stray matches in the ring
    assert region_problem(_disparity_map(disparity), REGION, 1) is None


def test_the_tracker_searches_everywhere_until_an_area_then_on_schedule():
    calibration, pose = first_rig_view()
    tracker = AreaTracker(TrackingConfig(full_frame_every=3, max_age_s=0.5))

    def plan(stamp: float) -> str:
        found = tracker.plan(stamp, calibration, pose, FULL_RANGE)
        return 'area' if found.region is not None else found.reason

    assert plan(0.0) == NO_AREA
    tracker.observe(box_area(0.0))
    assert [plan(0.1), plan(0.2), plan(0.3), plan(0.4)] == ['area', 'area', PERIODIC, 'area']
    assert plan(0.6) == STALE_AREA
    tracker.observe(box_area(0.6))
    tracker.observe(box_area(0.5))  # an older decision does not replace a newer one
    assert plan(1.0) == 'area'
    assert tracker.plan(1.0, calibration, None, FULL_RANGE).reason == TRACKING_OFF
    tracker.region_failed(OBJECT_LOST)
    assert plan(1.0) == NO_AREA
    tracker.observe(box_area(1.0))
    tracker.observe(None)  # the object was lost
    assert plan(1.0) == NO_AREA
    tracker.observe(box_area(1.0))
    assert tracker.plan(1.0, calibration, pose, (400, 10)).reason == NO_REGION
    tracker.config = TrackingConfig(enabled=False)
    assert plan(1.0) == TRACKING_OFF


def test_an_area_with_unusable_values_is_not_tracked():
    area = box_area()
    bad = TrackedArea(0.0, area.border_points, float('nan'), (0.0, 0.0, 0.0),
                      (0.0, 0.0, 1.0), 0.1)
    assert bad.problem()
    tracker = AreaTracker()
    tracker.observe(bad)
    assert tracker.plan(0.0, *first_rig_view(), FULL_RANGE).reason == NO_AREA


def test_after_a_failed_region_the_next_plan_waits_once_for_that_pairs_decision():
    calibration, pose = first_rig_view()
    tracker = AreaTracker(TrackingConfig(decision_wait_s=60.0))
    assert tracker.wait_for_decision() is None  # nothing failed: no wait
    tracker.region_failed(OBJECT_LOST, stamp_s=2.0)
    # the decision on pair 2.0 (matched whole) arrives while the next pair waits for it
    decider = threading.Thread(target=tracker.observe, args=(box_area(2.0),))
    decider.start()
    assert tracker.wait_for_decision() is True
    decider.join()
    assert tracker.plan(2.1, calibration, pose, FULL_RANGE).region is not None
    assert tracker.wait_for_decision() is None  # waited once

    tracker.config = TrackingConfig(decision_wait_s=0.01)
    tracker.region_failed(OBJECT_LOST, stamp_s=3.0)
    tracker.observe(None, stamp_s=2.5)  # an older pair's decision is not the one awaited
    assert tracker.wait_for_decision() is False
    assert tracker.plan(3.1, calibration, pose, FULL_RANGE).reason == NO_AREA
    tracker.region_failed(OBJECT_LOST, stamp_s=4.0)
    tracker.observe(None, stamp_s=4.0)  # it found nothing: it arrived, the image is searched
    assert tracker.wait_for_decision() is True
    assert tracker.plan(4.1, calibration, pose, FULL_RANGE).reason == NO_AREA
    tracker.config = TrackingConfig(decision_wait_s=0.0)
    tracker.region_failed(OBJECT_LOST, stamp_s=5.0)
    assert tracker.wait_for_decision() is None  # waiting turned off


def test_a_failed_region_counts_as_a_whole_image_for_the_periodic_one():
    calibration, pose = first_rig_view()
    tracker = AreaTracker(TrackingConfig(full_frame_every=3))
    tracker.observe(box_area(0.0))
    assert tracker.plan(0.1, calibration, pose, FULL_RANGE).region is not None
    assert tracker.plan(0.2, calibration, pose, FULL_RANGE).region is not None
    tracker.region_failed(OBJECT_LOST)  # pair 0.2 was matched on the whole image after all
    tracker.observe(box_area(0.2))
    reasons = [tracker.plan(stamp, calibration, pose, FULL_RANGE).reason
               for stamp in (0.3, 0.4, 0.5)]
    assert reasons == ['', '', PERIODIC]


def textured_image(seed: int = 1, shape: tuple[int, int] = (96, 128)) -> np.ndarray:
    """A grey image with texture at every scale the blocks see."""
    rng = np.random.default_rng(seed)
    coarse = rng.integers(30, 220, (shape[0] // 16, shape[1] // 16)).astype(np.float32)
    image = np.kron(coarse, np.ones((16, 16), np.float32))
    image += rng.normal(0.0, 10.0, shape)
    return np.clip(image, 0, 255).astype(np.uint8)


def test_block_means_see_an_object_change_but_not_noise_or_a_lighting_change():
    image = textured_image()
    before = block_means(image)
    assert before.shape == (96 // BLOCK_PX, 128 // BLOCK_PX)
    assert block_means(image.astype(np.uint16) * 257) == pytest.approx(before, abs=0.5)
    rng = np.random.default_rng(2)
    noisy = np.clip(image + rng.normal(0.0, 3.0, image.shape), 0, 255).astype(np.uint8)
    assert not changed_blocks(block_means(noisy), before, 8.0).any()
    brighter = np.clip(image.astype(int) + 20, 0, 255).astype(np.uint8)
    assert not changed_blocks(block_means(brighter), before, 8.0).any()
    moved = image.copy()
    moved[32:64, 48:80] = textured_image(seed=3)[32:64, 48:80]  # an object put down
    changed = changed_blocks(block_means(moved), before, 8.0)
    assert changed[4:8, 6:10].mean() > 0.5 and not changed[:4].any() and not changed[8:].any()
    now = block_means(moved)
    assert changed_share_inside(now, before, (48, 32, 80, 64), 8.0) > 0.5
    assert changed_share_inside(now, before, (0, 0, 40, 30), 8.0) == 0.0
    assert changed_outside(now, before, (40, 24, 88, 72), 8.0) == 0
    assert changed_outside(now, before, (0, 0, 40, 30), 8.0) > 0
    # nothing to compare with (first pair, another image size): the region is tried, the
    # periodic whole image is not skipped
    assert changed_share_inside(now, None, (0, 0, 40, 30), 8.0) == 0.0
    assert changed_outside(now, before[:-1], (0, 0, 40, 30), 8.0) == now.size


def whole_image_box(roi: tuple[int, int, int, int]) -> tuple[int, int, int, int]:
    """raw_box of a rig whose raw and rectified images are the same."""
    x, y, width, height = roi
    return x, y, x + width, y + height


def test_a_changed_region_goes_to_the_whole_image_at_once_and_its_area_is_forgotten():
    calibration, pose = first_rig_view()
    tracker = AreaTracker(TrackingConfig(decision_wait_s=0.01))
    tracker.observe(box_area(0.0))
    region = tracker.plan(0.1, calibration, pose, FULL_RANGE).region
    assert region is not None
    x, y, width, height = region.roi
    shape = (calibration.left.height, calibration.left.width)
    image = textured_image(shape=shape)
    still = tracker.plan(0.2, calibration, pose, FULL_RANGE, block_means(image),
                         whole_image_box)
    assert still.region is not None  # nothing to compare with: not a change yet
    assert tracker.plan(0.3, calibration, pose, FULL_RANGE, block_means(image),
                        whole_image_box).region is not None
    changed = image.copy()
    changed[y:y + height, x:x + width] = textured_image(
        seed=9, shape=shape)[y:y + height, x:x + width]
    plan = tracker.plan(0.4, calibration, pose, FULL_RANGE, block_means(changed),
                        whole_image_box)
    assert (plan.region, plan.reason) == (None, SCENE_CHANGED)
    # as after a failed region: the next pair waits for this one's decision, and a late
    # decision on an earlier pair does not bring the old area back
    tracker.observe(box_area(0.3))
    assert tracker.wait_for_decision() is False
    assert tracker.plan(0.5, calibration, pose, FULL_RANGE, block_means(changed),
                        whole_image_box).reason == NO_AREA
    tracker.observe(box_area(0.4))
    assert tracker.plan(0.6, calibration, pose, FULL_RANGE, block_means(changed),
                        whole_image_box).region is not None
    tracker.config = TrackingConfig(detect_scene_change=False)
    assert tracker.plan(0.7, calibration, pose, FULL_RANGE, block_means(image),
                        whole_image_box).region is not None


def test_the_periodic_whole_image_is_skipped_while_nothing_changed_outside_the_region():
    calibration, pose = first_rig_view()
    tracker = AreaTracker(TrackingConfig(full_frame_every=1))  # every pair due
    shape = (calibration.left.height, calibration.left.width)
    image = textured_image(shape=shape)
    blocks = block_means(image)
    assert tracker.plan(0.0, calibration, pose, FULL_RANGE, blocks,
                        whole_image_box).reason == NO_AREA  # the last whole image: this one
    tracker.observe(box_area(0.0))

    def plan(stamp: float, now: np.ndarray) -> tuple[bool, str, bool]:
        found = tracker.plan(stamp, calibration, pose, FULL_RANGE, now, whole_image_box)
        return found.region is not None, found.reason, found.periodic_skipped

    assert plan(0.1, blocks) == (True, '', True)  # due, but unchanged: in the region
    assert plan(0.2, blocks) == (True, '', True)
    for stamp in range(MAX_PERIODIC_SKIPPED - 2):
        assert plan(0.2 + 0.001 * stamp, blocks) == (True, '', True)
    assert plan(0.29, blocks) == (False, PERIODIC, False)  # skipped often enough in a row
    assert plan(0.295, blocks) == (True, '', True)
    elsewhere = image.copy()
    elsewhere[:24, :24] = 255 - elsewhere[:24, :24]  # something came in, far from the box
    assert plan(0.3, block_means(elsewhere)) == (False, PERIODIC, False)
    assert plan(0.4, block_means(elsewhere)) == (True, '', True)  # compared with 0.3 now
    region = tracker.plan(0.41, calibration, pose, FULL_RANGE, block_means(elsewhere),
                          whole_image_box).region
    assert region is not None
    x, y, width, height = region.roi
    inside = elsewhere.copy()
    inside[y:y + height, x:x + width] = 255 - inside[y:y + height, x:x + width]
    # due on the whole image anyway, but the region changed: its area is forgotten too
    assert plan(0.42, block_means(inside)) == (False, SCENE_CHANGED, False)
    assert plan(0.43, block_means(inside)) == (False, NO_AREA, False)
    tracker.observe(box_area(0.42))
    tracker.config = TrackingConfig(full_frame_every=1, detect_scene_change=False)
    assert plan(0.5, blocks) == (False, PERIODIC, False)


def test_a_region_is_found_around_the_one_object_standing_out_in_whole_image_matches():
    rig = RIGS[0]
    _, left, right = grid_matches(rig, None, 0.0, 8)
    calibration = StereoCalibration(left, right)
    floor = np.full((120, 160), 8.0)
    floor[::7, ::11] = 30.0  # scattered mismatches stand out too, one by one
    one = floor.copy()
    one[40:70, 90:120] = 10.0  # a block 2 px above the floor's 8 px
    found = region_from_matches(_disparity_map(one), REGION, calibration, 1, (0, 40), 1.0)
    assert found is not None
    x, y, width, height = found.roi
    assert x <= 90 - 29 and y <= 40 - 29 and x + width >= 120 + 29 - 1
    assert y + height >= 70 + 29 - 1 and width <= 160 - x
    assert found.min_disparity <= 8 - 3 and found.min_disparity + found.disparity_range > 12
    assert found.top_centre == pytest.approx((104.5, 54.5), abs=1.0)
    # its own check keeps the region on the same matches
    assert region_problem(_disparity_map(one), found, 1) is None
    assert region_from_matches(_disparity_map(floor), REGION, calibration, 1, (0, 40),
                               1.0) is None  # nothing but mismatches
    two = one.copy()
    two[80:100, 10:40] = 10.0  # another object: the fuzzy stage chooses, no region
    assert region_from_matches(_disparity_map(two), REGION, calibration, 1, (0, 40),
                               1.0) is None
    # a low object (0.5 px) after a tall one: found with the surface's noise, not with the
    # tall object's threshold
    low = floor.copy()
    low[40:70, 90:120] = 8.5
    assert region_from_matches(_disparity_map(low), REGION, calibration, 1, (0, 40),
                               1.0) is None
    noisy = dataclasses.replace(REGION, noise_px=0.3)
    found = region_from_matches(_disparity_map(low), noisy, calibration, 1, (0, 40), 1.0)
    assert found is not None and found.standing_px == pytest.approx(0.3)
    assert region_problem(_disparity_map(low), found, 1) is None
