"""Rectifying only what a match reads: the same matches as on the wholly rectified pair."""

import dataclasses

import cv2
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from stereo_fuzzy_perception.core.camera_model import StereoCalibration
from stereo_fuzzy_perception.core.matching.area_search import OBJECT_LOST, SearchRegion
from stereo_fuzzy_perception.core.matching.rectification import (
    StereoRectifier,
    grown_block,
    missing_blocks,
    rectification_maps,
)
from stereo_fuzzy_perception.core.matching.stereo_matching import StereoMatchingPipeline
from stereo_fuzzy_perception.core.matching.window_matcher import (
    MatcherConfig,
    match,
    pixels_read,
)
from stereo_fuzzy_perception.core.rig_geometry import StereoRig
from stereo_fuzzy_perception.simulation.synthetic_scenes import rectified_calibration

WIDTH, HEIGHT = 160, 120


def verged_calibration() -> StereoCalibration:
    """A toed-in, distorted rig calibrated as cv2.stereoRectify would."""
    K = np.array([[150.0, 0.0, 80.0], [0.0, 150.0, 60.0], [0.0, 0.0, 1.0]])
    return StereoCalibration(*rectified_calibration(
        StereoRig(baseline_m=0.06, vergence_deg=6.0), K, WIDTH, HEIGHT,
        distortion=np.array([-0.05, 0.01, 0.0, 0.0, 0.0])))


def raw_pair(seed: int) -> tuple[np.ndarray, np.ndarray]:
    """A smoothed random texture and the same shifted by 8 px (left x meets right x - 8)."""
    rng = np.random.default_rng(seed)
    scene = cv2.GaussianBlur(rng.uniform(0, 255, (HEIGHT, WIDTH + 8)).astype(np.float32),
                             (0, 0), 1.2)
    scene = np.clip(128 + 4 * (scene - scene.mean()), 0, 255).astype(np.uint8)
    return scene[:, 8:].copy(), scene[:, :WIDTH].copy()


def assert_same_matches(first, second) -> None:
    np.testing.assert_array_equal(first.status, second.status)
    np.testing.assert_array_equal(first.disparity, second.disparity)
    np.testing.assert_array_equal(first.score, second.score)


blocks = st.tuples(st.integers(0, 12), st.integers(0, 12), st.integers(0, 12),
                   st.integers(0, 12)).map(lambda b: (min(b[0], b[1]), max(b[0], b[1]),
                                                      min(b[2], b[3]), max(b[2], b[3])))


@settings(max_examples=200, deadline=None)
@given(done=st.none() | blocks, wanted=blocks)
def test_the_missing_blocks_and_the_done_one_cover_what_is_wanted_once(done, wanted):
    covered = np.zeros((12, 12), int)
    held = np.zeros((12, 12), bool)
    if done is not None:
        held[done[0]:done[1], done[2]:done[3]] = True
    for first, stop, start, end in missing_blocks(done, wanted):
        covered[first:stop, start:end] += 1
    want = np.zeros((12, 12), bool)
    want[wanted[0]:wanted[1], wanted[2]:wanted[3]] = True
    assert covered.max() <= 1, 'a pixel rectified twice'
    assert np.all(covered[~want] == 0), 'a pixel rectified that was not asked for'
    assert np.all((covered > 0) | held | ~want), 'a wanted pixel left unrectified'
    grown = grown_block(done, wanted)
    now = np.zeros((12, 12), bool)
    now[grown[0]:grown[1], grown[2]:grown[3]] = True
    assert np.all(now <= (covered > 0) | held), 'a block claimed that was not rectified'
    assert np.all(want <= now)


@settings(max_examples=30, deadline=None)
@given(x=st.integers(0, WIDTH - 10), y=st.integers(0, HEIGHT - 10),
       width=st.integers(1, WIDTH), height=st.integers(1, HEIGHT),
       min_disparity=st.integers(-4, 20), disparity_range=st.integers(1, 32),
       lr=st.integers(-1, 2), window=st.sampled_from([3, 5, 9]), row_step=st.integers(1, 3))
def test_rectifying_only_what_a_match_reads_gives_the_matches_of_the_whole_pair(
        x, y, width, height, min_disparity, disparity_range, lr, window, row_step):
    calibration = verged_calibration()
    rectifier = StereoRectifier()
    config = MatcherConfig(window_size=window, min_disparity=min_disparity,
                           disparity_range=disparity_range, lr_check_max_diff=lr,
                           roi=(x, y, min(width, WIDTH - x), min(height, HEIGHT - y)))
    left, right = raw_pair(1)
    expected = match(*rectifier.rectify(left, right, calibration)[:2], config,
                     row_step=row_step)
    # the buffers first hold another pair, which must not leak into this one's matches
    other_left, other_right = raw_pair(2)
    rectifier.rectify_part(other_left, other_right, calibration, (0, HEIGHT),
                           ((0, WIDTH), (0, WIDTH)))
    read = pixels_read(config, WIDTH, HEIGHT)
    left_rect, right_rect, _ = rectifier.rectify_part(
        left, right, calibration, read.rows, (read.left_columns, read.right_columns))
    assert_same_matches(match(left_rect, right_rect, config, row_step=row_step), expected)


def test_a_region_reads_fewer_columns_than_the_whole_image():
    config = MatcherConfig(window_size=9, min_disparity=10, disparity_range=20,
                           roi=(100, 40, 30, 30))
    read = pixels_read(config, WIDTH, HEIGHT)
    assert read.rows == (36, 74)
    # left-right reach 19 and radius 4 on each side; the right image shifted by 10..29
    assert read.left_columns == (100 - 19 - 4, 130 + 19 + 4)
    assert read.right_columns == (100 - 19 - 4 - 29, 130 + 19 + 4 - 10)
    assert pixels_read(dataclasses.replace(config, preprocess='edges'), WIDTH,
                       HEIGHT).left_columns == (0, WIDTH)


def test_a_refused_region_then_the_whole_image_gives_the_whole_images_matches():
    calibration = verged_calibration()
    config = MatcherConfig(window_size=7, min_disparity=0, disparity_range=24)
    pipeline = StereoMatchingPipeline(config, point_stride=1)
    left, right = raw_pair(3)
    whole = pipeline.process(left, right, calibration)
    expected = (whole.disparity_map.disparity.copy(), whole.disparity_map.status.copy(),
                whole.points.xyz.copy())
    del whole
    # a top face far larger than the region: too few matches stand out, the object is lost
    region = SearchRegion((40, 30, 50, 40), 4, 12, (0.0, 0.0, 0.0), 1e6, 1e6)
    other_left, other_right = raw_pair(4)
    pipeline.process(other_left, other_right, calibration, region=region)
    refused = pipeline.process(left, right, calibration, region=region)
    assert refused.region_problem == OBJECT_LOST
    assert refused.region is None
    np.testing.assert_array_equal(refused.disparity_map.disparity, expected[0])
    np.testing.assert_array_equal(refused.disparity_map.status, expected[1])
    np.testing.assert_array_equal(refused.points.xyz, expected[2])


def test_continuing_on_other_arrays_rectifies_everything_again():
    calibration = verged_calibration()
    rectifier = StereoRectifier()
    first_left, first_right = raw_pair(5)
    rectifier.rectify_part(first_left, first_right, calibration, (20, 80),
                           ((10, 120), (0, WIDTH)))
    left, right = raw_pair(6)
    whole = ((0, WIDTH), (0, WIDTH))
    continued = rectifier.rectify_part(left, right, calibration, (0, HEIGHT), whole,
                                       continued=True)
    expected = StereoRectifier().rectify(left, right, calibration)
    np.testing.assert_array_equal(continued[0], expected[0])
    np.testing.assert_array_equal(continued[1], expected[1])


@given(st.integers(0, WIDTH - 2), st.integers(0, HEIGHT - 2), st.integers(2, WIDTH),
       st.integers(2, HEIGHT))
@settings(max_examples=25, deadline=None)
def test_the_raw_box_holds_every_raw_pixel_a_rectified_roi_reads(x, y, width, height):
    calibration = verged_calibration()
    rectifier = StereoRectifier()
    box = rectifier.raw_box(calibration, (x, y, width, height))
    maps = rectification_maps(calibration.left)
    assert maps.map_x is not None and maps.map_y is not None
    x1, y1 = min(calibration.left.width, x + width), min(calibration.left.height, y + height)
    read = np.floor(np.column_stack([maps.map_x[y:y1, x:x1].ravel(),
                                     maps.map_y[y:y1, x:x1].ravel()])).astype(int)
    inside = ((read[:, 0] >= 0) & (read[:, 1] >= 0) & (read[:, 0] < calibration.left.width)
              & (read[:, 1] < calibration.left.height))
    read = read[inside]
    x0_box, y0_box, x1_box, y1_box = box
    if len(read):
        assert x0_box <= read[:, 0].min() and y0_box <= read[:, 1].min()
        assert x1_box >= min(calibration.left.width, read[:, 0].max() + 1)
        assert y1_box >= min(calibration.left.height, read[:, 1].max() + 1)
