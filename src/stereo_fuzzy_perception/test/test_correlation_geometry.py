"""Rectification (undoes the chapter's Eqs. 2-6) and triangulation (Eq. 1), correlation stage."""

import math
import weakref

import cv2
import numpy as np
import pytest
from stereo_fuzzy_perception.core.camera_model import (
    CalibrationError,
    CameraCalibration,
    StereoCalibration,
)
from stereo_fuzzy_perception.core.matching.rectification import (
    RectificationError,
    StereoRectifier,
    rectified_stereo,
)
from stereo_fuzzy_perception.core.matching.stereo_matching import StereoMatchingPipeline
from stereo_fuzzy_perception.core.matching.triangulation import depth_from_disparity, triangulate
from stereo_fuzzy_perception.core.matching.window_matcher import MatcherConfig
from stereo_fuzzy_perception.core.rig_geometry import StereoRig, rotation_y, transform_points

WIDTH, HEIGHT = 320, 240
K = np.array([[300.0, 0.0, 160.0], [0.0, 300.0, 120.0], [0.0, 0.0, 1.0]])


def verged_calibration(rig: StereoRig, distortion: np.ndarray) -> StereoCalibration:
    """Calibrate the rig's two toed-in cameras as cv2.stereoRectify would."""
    rotation, translation = rig.right_from_left()
    R1, R2, P1, P2, *_ = cv2.stereoRectify(K, distortion, K, distortion, (WIDTH, HEIGHT),
                                           rotation, translation.reshape(3, 1), alpha=0)
    return StereoCalibration(
        CameraCalibration(WIDTH, HEIGHT, K, distortion, R1, P1, frame_id='left_optical'),
        CameraCalibration(WIDTH, HEIGHT, K, distortion, R2, P2, frame_id='right_optical'))


def project(points_camera: np.ndarray, distortion: np.ndarray) -> np.ndarray:
    pixels, _ = cv2.projectPoints(points_camera, np.zeros(3), np.zeros(3), K, distortion)
    return pixels.reshape(-1, 2)


def render_spots(pixels: np.ndarray) -> np.ndarray:
    """A dark image with a small Gaussian spot at each sub-pixel position."""
    ys, xs = np.mgrid[0:HEIGHT, 0:WIDTH].astype(np.float64)
    image = np.zeros((HEIGHT, WIDTH))
    for u, v in pixels:
        image += 250 * np.exp(-((xs - u) ** 2 + (ys - v) ** 2) / (2 * 1.5 ** 2))
    return np.clip(image, 0, 255).astype(np.uint8)


def spot_centroids(image: np.ndarray) -> np.ndarray:
    count, labels, stats, centroids = cv2.connectedComponentsWithStats(
        (image > 40).astype(np.uint8))
    refined = []
    for label in range(1, count):
        mask = labels == label
        ys, xs = np.nonzero(mask)
        weights = image[mask].astype(np.float64)
        total = weights.sum()
        refined.append((np.sum(xs * weights) / total, np.sum(ys * weights) / total))
    return np.array(sorted(refined, key=lambda p: p[0]))


def test_rectifying_a_verged_pair_puts_corresponding_points_on_one_row_and_triangulates():
    rig = StereoRig(baseline_m=0.08, vergence_deg=8.0)
    distortion = np.array([-0.05, 0.01, 0.0, 0.0, 0.0])
    calibration = verged_calibration(rig, distortion)
    # Points 0.5..0.7 m in front of the left camera, towards the corners of the view, where
    # toe-in makes the rows of corresponding points differ most (keystone).
    points_left = np.array([[-0.16, -0.12, 0.55], [-0.05, 0.13, 0.6], [0.14, -0.13, 0.65],
                            [0.2, 0.15, 0.7]])
    right_from_left = np.linalg.inv(rig.world_from_right_camera()) @ rig.world_from_left_camera()
    points_right = transform_points(right_from_left, points_left)
    raw_left = render_spots(project(points_left, distortion))
    raw_right = render_spots(project(points_right, distortion))
    raw_rows_differ = np.abs(project(points_left, distortion)[:, 1]
                             - project(points_right, distortion)[:, 1])
    assert raw_rows_differ.max() > 1.0, 'the raw pair must be verged for this test to mean much'

    rectifier = StereoRectifier()
    left_rect, right_rect, rectified = rectifier.rectify(raw_left, raw_right, calibration)
    left_spots, right_spots = spot_centroids(left_rect), spot_centroids(right_rect)
    assert len(left_spots) == len(right_spots) == len(points_left)
    assert np.abs(left_spots[:, 1] - right_spots[:, 1]).max() < 0.3

    disparity = np.full((HEIGHT, WIDTH), np.nan, np.float32)
    score = np.ones((HEIGHT, WIDTH), np.float32)
    for (u_left, v), (u_right, _) in zip(left_spots, right_spots, strict=True):
        disparity[round(v), round(u_left)] = u_left - u_right + (round(u_left) - u_left)
    points = triangulate(disparity, score, rectified)
    order = np.argsort(points.u_left)
    # Centroids are rounded to whole pixels for the disparity map: 1 px at 300 px focal length.
    assert np.allclose(points.xyz[order], points_left, atol=0.006)

    assert np.allclose(rectified.left.K, calibration.left.P[:3, :3])
    assert not np.any(rectified.left.D)
    assert np.array_equal(rectified.right.R, calibration.right.R)
    assert rectified.baseline_m == pytest.approx(0.08, rel=1e-6)


def test_maps_are_cached_until_the_calibration_changes():
    rig = StereoRig(baseline_m=0.06, vergence_deg=4.0)
    calibration = verged_calibration(rig, np.zeros(5))
    image = np.zeros((HEIGHT, WIDTH), np.uint8)
    rectifier = StereoRectifier()
    rectifier.rectify(image, image, calibration)
    rectifier.rectify(image, image, verged_calibration(rig, np.zeros(5)))  # equal values
    assert rectifier.map_builds == 1
    rectifier.rectify(image, image, verged_calibration(StereoRig(vergence_deg=5.0), np.zeros(5)))
    assert rectifier.map_builds == 2


def test_rectifier_refuses_wrong_sizes_and_bad_calibrations():
    calibration = verged_calibration(StereoRig(), np.zeros(5))
    rectifier = StereoRectifier()
    with pytest.raises(RectificationError, match='left image is 100x240 but its calibration'):
        rectifier.rectify(np.zeros((HEIGHT, 100), np.uint8), np.zeros((HEIGHT, WIDTH), np.uint8),
                          calibration)
    uncalibrated = StereoCalibration(
        CameraCalibration(WIDTH, HEIGHT, np.zeros((3, 3)), np.zeros(5), np.eye(3),
                          calibration.left.P), calibration.right)
    image = np.zeros((HEIGHT, WIDTH), np.uint8)
    with pytest.raises(CalibrationError, match='not calibrated'):
        rectifier.rectify(image, image, uncalibrated)


def rectified_pair_calibration(f: float, cx_left: float, cx_right: float, baseline: float,
                               rotation: np.ndarray) -> StereoCalibration:
    left_p = np.array([[f, 0, cx_left, 0], [0, f, 120.0, 0], [0, 0, 1, 0]])
    right_p = np.array([[f, 0, cx_right, -f * baseline], [0, f, 120.0, 0], [0, 0, 1, 0]])
    return StereoCalibration(
        CameraCalibration(WIDTH, HEIGHT, left_p[:, :3], np.zeros(5), rotation, left_p),
        CameraCalibration(WIDTH, HEIGHT, right_p[:, :3], np.zeros(5), rotation, right_p))


def test_triangulation_matches_a_hand_computed_point():
    # f = 500 px, B = 0.1 m, d = 25 px -> Z = 500 * 0.1 / 25 = 2 m;
    # X = (200 - 160) * 2 / 500 = 0.16 m, Y = (150 - 120) * 2 / 500 = 0.12 m.
    calibration = rectified_pair_calibration(500.0, 160.0, 160.0, 0.1, np.eye(3))
    disparity = np.full((HEIGHT, WIDTH), np.nan, np.float32)
    disparity[150, 200] = 25.0
    score = np.full((HEIGHT, WIDTH), 0.9, np.float32)
    points = triangulate(disparity, score, calibration)
    assert len(points) == 1
    assert np.allclose(points.xyz[0], [0.16, 0.12, 2.0], atol=1e-6)
    assert points.u_right[0] == pytest.approx(175.0)
    assert points.score[0] == pytest.approx(0.9)
    assert depth_from_disparity(25.0, calibration) == pytest.approx(2.0)


def test_triangulation_handles_principal_point_shift_and_rotates_back_to_the_optical_frame():
    # Principal points 10 px apart: the effective disparity is d - (cx_l - cx_r) = 15 + 10.
    rotation = rotation_y(math.radians(10.0))  # rectified <- left optical
    calibration = rectified_pair_calibration(500.0, 160.0, 170.0, 0.1, rotation)
    disparity = np.full((HEIGHT, WIDTH), np.nan, np.float32)
    disparity[150, 200] = 15.0
    points = triangulate(disparity, np.ones((HEIGHT, WIDTH), np.float32), calibration)
    expected = rotation.T @ np.array([0.16, 0.12, 2.0])
    assert np.allclose(points.xyz[0], expected, atol=1e-6)


def test_points_behind_the_cameras_are_dropped():
    calibration = rectified_pair_calibration(500.0, 160.0, 160.0, 0.1, np.eye(3))
    disparity = np.full((HEIGHT, WIDTH), np.nan, np.float32)
    disparity[10, 10], disparity[20, 20] = -3.0, 5.0
    points = triangulate(disparity, np.ones_like(disparity), calibration)
    assert len(points) == 1 and points.xyz[0, 2] == pytest.approx(10.0)


def test_pipeline_recovers_depth_f_b_over_d_on_a_rectified_shift():
    rng = np.random.default_rng(3)
    scene = cv2.GaussianBlur(rng.uniform(0, 255, (HEIGHT, WIDTH + 20)).astype(np.float32),
                             (0, 0), 1.2)
    scene = np.clip(128 + 3 * (scene - scene.mean()), 0, 255).astype(np.uint8)
    left, right = scene[:, 0:WIDTH], scene[:, 10:10 + WIDTH]  # disparity 10 px
    calibration = rectified_pair_calibration(300.0, 160.0, 160.0, 0.06, np.eye(3))
    pipeline = StereoMatchingPipeline(MatcherConfig(window_size=9, disparity_range=32))
    result = pipeline.process(left, right, calibration)
    assert len(result.points) > 0.8 * HEIGHT * (WIDTH - 50)
    assert np.median(result.points.xyz[:, 2]) == pytest.approx(300.0 * 0.06 / 10.0, rel=1e-3)
    assert set(result.timings_ms) == {'rectify', 'match', 'triangulate'}
    assert rectified_stereo(calibration).left.same_as(result.rectified.left)


def test_pipeline_points_do_not_depend_on_matching_only_the_strided_rows():
    rng = np.random.default_rng(4)
    scene = cv2.GaussianBlur(rng.uniform(0, 255, (HEIGHT, WIDTH + 20)).astype(np.float32),
                             (0, 0), 1.2)
    scene = np.clip(128 + 3 * (scene - scene.mean()), 0, 255).astype(np.uint8)
    left, right = scene[:, 0:WIDTH], scene[:, 7:7 + WIDTH]
    calibration = rectified_pair_calibration(300.0, 160.0, 160.0, 0.06, np.eye(3))
    pipeline = StereoMatchingPipeline(MatcherConfig(window_size=9, disparity_range=32),
                                      point_stride=2)
    strided_rows = pipeline.process(left, right, calibration)
    every_row = pipeline.process(left, right, calibration, full_disparity=True)
    assert len(strided_rows.points) > 0
    np.testing.assert_array_equal(strided_rows.points.xyz, every_row.points.xyz)
    np.testing.assert_array_equal(strided_rows.points.score, every_row.points.score)
    assert np.isnan(strided_rows.disparity_map.disparity[1::2]).all()
    assert np.isfinite(every_row.disparity_map.disparity[1::2]).any()


def numpy_triangulation(disparity: np.ndarray, score: np.ndarray,
                        calibration: StereoCalibration, stride: int) -> np.ndarray:
    """Eq. 1 for rectified cameras over the valid pixels, row by row: (N, 7) float64 rows."""
    left_p, right_p = np.asarray(calibration.left.P), np.asarray(calibration.right.P)
    rows, columns = np.nonzero(np.isfinite(disparity[::stride, ::stride]))
    rows, columns = rows * stride, columns * stride
    d = disparity[rows, columns].astype(np.float64)
    effective = d - (left_p[0, 2] - right_p[0, 2])
    keep = effective > 0
    rows, columns, d, effective = rows[keep], columns[keep], d[keep], effective[keep]
    z = (left_p[0, 3] - right_p[0, 3]) / effective
    x = ((columns - left_p[0, 2]) * z - left_p[0, 3]) / left_p[0, 0]
    y = ((rows - left_p[1, 2]) * z - left_p[1, 3]) / left_p[1, 1]
    xyz = np.stack([x, y, z], axis=1) @ np.asarray(calibration.left.R)
    return np.column_stack([xyz, columns, rows, columns - d, score[rows, columns]])


@pytest.mark.parametrize('stride', [1, 3])
def test_triangulation_agrees_with_numpy_on_every_valid_pixel(stride):
    rotation = rotation_y(math.radians(4.0))
    calibration = rectified_pair_calibration(500.0, 160.0, 166.0, 0.1, rotation)
    rng = np.random.default_rng(21)
    disparity = rng.uniform(-10.0, 60.0, (HEIGHT, WIDTH)).astype(np.float32)
    disparity[rng.random((HEIGHT, WIDTH)) < 0.3] = np.nan
    score = rng.uniform(-1.0, 1.0, (HEIGHT, WIDTH)).astype(np.float32)
    points = triangulate(disparity, score, calibration, stride)
    expected = numpy_triangulation(disparity, score, calibration, stride)
    assert len(points) == len(expected) > 1000
    got = np.column_stack([points.xyz, points.u_left, points.v_left, points.u_right,
                           points.score])
    np.testing.assert_allclose(got, expected, rtol=1e-6, atol=1e-6)


def test_the_point_cloud_holds_the_triangulated_points_whatever_their_layout():
    # triangulated points are views of the cloud's rows (copied once); points made any other
    # way are interleaved first: both clouds must read back the same points
    from std_msgs.msg import Header
    from stereo_fuzzy_perception.core.matched_points import MatchedPoints
    from stereo_fuzzy_perception.nodes.conversions import (
        cloud_to_matched_points,
        matched_points_to_cloud,
    )

    calibration = rectified_pair_calibration(500.0, 160.0, 160.0, 0.1, np.eye(3))
    rng = np.random.default_rng(22)
    disparity = rng.uniform(5.0, 40.0, (HEIGHT, WIDTH)).astype(np.float32)
    disparity[rng.random((HEIGHT, WIDTH)) < 0.5] = np.nan
    points = triangulate(disparity, np.ones_like(disparity), calibration, 2)
    assert points.xyz.base is points.score.base  # the rows of one block
    copies = MatchedPoints(points.xyz.copy(), points.u_left.copy(), points.v_left.copy(),
                           points.u_right.copy(), points.score.copy())
    header = Header(frame_id='left_optical')
    cloud, cloud_of_copies = (matched_points_to_cloud(each, header) for each in (points, copies))
    assert bytes(cloud.data) == bytes(cloud_of_copies.data)
    assert len(cloud.data) == cloud.row_step == 28 * len(points) > 0
    back = cloud_to_matched_points(cloud)
    np.testing.assert_array_equal(back.xyz, points.xyz)
    np.testing.assert_array_equal(back.u_right, points.u_right)


def test_kept_points_are_never_overwritten_and_dropped_ones_are_recycled():
    calibration = rectified_pair_calibration(500.0, 160.0, 160.0, 0.1, np.eye(3))
    rng = np.random.default_rng(23)
    first, second = (rng.uniform(5.0, 40.0, (HEIGHT, WIDTH)).astype(np.float32)
                     for _ in range(2))
    kept = triangulate(first, np.ones_like(first), calibration)
    kept_xyz = kept.xyz.copy()
    other = triangulate(second, np.ones_like(second), calibration)
    np.testing.assert_array_equal(kept.xyz, kept_xyz)
    block = weakref.ref(other.xyz.base)
    del other
    again = triangulate(second, np.ones_like(second), calibration)
    assert again.xyz.base is block()  # nothing held the block: it was reused
    np.testing.assert_array_equal(kept.xyz, kept_xyz)
