"""The top face's outline from the left rectified image (face_outline.py), on ray-cast grids."""

import dataclasses

import numpy as np
import pytest
from grid_scenes import TILTED_RIG as RIG
from grid_scenes import Box, camera_distance, grid_matches
from stereo_fuzzy_perception.core.best_point.correlation_area import (
    NO_OBJECT,
    OUTLINE_IMAGE,
    OUTLINE_MATCHES,
    UNCERTAIN_TOP,
    AreaConfig,
    find_correlation_area,
)
from stereo_fuzzy_perception.core.best_point.face_outline import (
    face_from_image,
    on_top_plane,
    plain_face_from_image,
    plain_region,
)
from stereo_fuzzy_perception.core.best_point.object_segmentation import across_m
from stereo_fuzzy_perception.core.best_point.point_selectors import BestPointChooser
from stereo_fuzzy_perception.core.matched_points import RectifiedImage

BOX = Box((0.2, 0.15), 0.04, 0.03)
DISC = Box((0.18, 0.12), 0.05, 0.005, round=True)
DEFAULTS = AreaConfig()
IMAGE_OFF = AreaConfig(outline_from_image=False)


def error_mm(points, left, right, box, config=DEFAULTS, selector='centroid'):
    chooser = dataclasses.replace(BestPointChooser.create(selector, config, RIG),
                                  world_from_camera=RIG.world_from_left_camera())
    decision = chooser.decide(points, left, right)
    assert decision.best_point_world is not None, decision.reason
    target = np.array([*box.centre_xy, box.height])
    return 1000.0 * float(np.linalg.norm(decision.best_point_world - target)), decision


def pixel_floor_mm(box, stride):
    """Return the error [mm] of the centre of the grid pixels that do see the top: what any
    outline on this pixel grid is held to."""
    points, left, right = grid_matches(RIG, box, 0.0, stride, image=True)
    pose = RIG.world_from_left_camera()
    area = find_correlation_area(points, pose, DEFAULTS, float(left.P[0, 2] - right.P[0, 2]))
    world = points.xyz.astype(float) @ pose[:3, :3].T + pose[:3, 3]
    on_top = world[:, 2] > 0.5 * box.height
    floor = on_top_plane(area, points.u_left[on_top].astype(float),
                          points.v_left[on_top].astype(float), left, right, pose)
    weight = floor.point_weights()
    centre = (floor.xyz_world * weight[:, None]).sum(axis=0) / weight.sum()
    return 1000.0 * float(np.linalg.norm(centre - [*box.centre_xy, box.height]))


@pytest.mark.parametrize('box', [BOX, DISC], ids=['box', 'disc'])
@pytest.mark.parametrize('stride', [1, 3])
def test_the_image_puts_a_fattened_face_back_in_place(box, stride):
    points, left, right = grid_matches(RIG, box, 0.05, stride, fatten_px=4, image=True)
    fattened, _ = error_mm(points, left, right, box, IMAGE_OFF)
    outlined, decision = error_mm(points, left, right, box)
    floor = pixel_floor_mm(box, stride)
    # within half a pixel of the floor (a pixel at the top's depth: about 1 mm here)
    left_calibration = grid_matches(RIG, None, 0.0, 8)[1]
    half_pixel_mm = 500.0 * camera_distance(RIG) / float(left_calibration.P[0, 0])
    assert outlined - floor < half_pixel_mm < fattened - floor, (
        outlined, floor, fattened, half_pixel_mm)


def test_a_stray_match_at_the_tops_height_does_not_widen_the_outline():
    points, left, right = grid_matches(RIG, BOX, 0.05, 1, fatten_px=4, image=True)
    clean, _ = error_mm(points, left, right, BOX)
    # one match of the top's disparity 30 px right of the face: a mismatch on the table
    top = np.flatnonzero(points.xyz[:, 2] == points.xyz[:, 2].min())[0]
    stray = np.concatenate([np.arange(len(points)), [top]])
    spoiled = points.subset(stray)
    spoiled.u_left = spoiled.u_left.copy()
    spoiled.u_right = spoiled.u_right.copy()
    spoiled.u_left[-1] += 30.0
    spoiled.u_right[-1] += 30.0
    spoiled.xyz = spoiled.xyz.copy()
    depth = float(spoiled.xyz[-1, 2])
    # the same depth, on the ray of its new column
    focal, cx = float(left.P[0, 0]), float(left.P[0, 2])
    rectified = np.asarray(left.R) @ spoiled.xyz[-1]
    rectified[0] = (spoiled.u_left[-1] - cx) / focal * rectified[2]
    spoiled.xyz[-1] = np.asarray(left.R).T @ rectified
    assert depth > 0.0
    with_stray, decision = error_mm(spoiled, left, right, BOX)
    assert decision.points_used > 0
    assert with_stray == pytest.approx(clean, abs=0.05)


def test_a_face_at_the_edge_of_the_image_sent_keeps_the_matches_outline():
    points, left, right = grid_matches(RIG, BOX, 0.05, 1, fatten_px=4, image=True)
    pose = RIG.world_from_left_camera()
    area = find_correlation_area(points, pose, DEFAULTS, float(left.P[0, 2] - right.P[0, 2]))
    assert area.ok and area.outline == OUTLINE_MATCHES
    whole = points.left_image
    assert face_from_image(area, whole, left, right, pose, DEFAULTS.min_points) is not None
    # the image sent ends two pixels right of the face's matches
    last = int(area.u_left.max()) + 2
    cut = RectifiedImage(whole.pixels[:, :last], window_size=whole.window_size)
    assert face_from_image(area, cut, left, right, pose, DEFAULTS.min_points) is None
    _, decision = error_mm(dataclasses.replace(points, left_image=cut), left, right, BOX)
    _, without = error_mm(points, left, right, BOX, IMAGE_OFF)
    np.testing.assert_array_equal(decision.best_point_world, without.best_point_world)


def test_the_outlined_area_is_the_faces_pixels_on_the_top_plane():
    points, left, right = grid_matches(RIG, BOX, 0.05, 3, fatten_px=4, image=True)
    pose = RIG.world_from_left_camera()
    area = find_correlation_area(points, pose, DEFAULTS, float(left.P[0, 2] - right.P[0, 2]))
    outlined = face_from_image(area, points.left_image, left, right, pose, DEFAULTS.min_points)
    assert outlined is not None and outlined.outline == OUTLINE_IMAGE
    # on the matches' grid, every point at the top's height above the measured surface
    assert np.all(outlined.u_left % 3 == 0) and np.all(outlined.v_left % 3 == 0)
    np.testing.assert_allclose(area.surface.heights(outlined.xyz_world.T), area.top_height,
                               atol=1e-9)
    # projected back, each point lands on its own pixel in both rectified images
    camera = (outlined.xyz_world - pose[:3, 3]) @ pose[:3, :3]
    rectified = camera @ np.asarray(left.R).T  # both projections act on the left's frame
    for calibration, columns in ((left, outlined.u_left), (right, outlined.u_right)):
        pixel = np.c_[rectified, np.ones(len(rectified))] @ np.asarray(calibration.P).T
        np.testing.assert_allclose(pixel[:, 0] / pixel[:, 2], columns, atol=1e-6)
        np.testing.assert_allclose(pixel[:, 1] / pixel[:, 2], outlined.v_left, atol=1e-6)


# A plain top: matched only within a correlation window's radius (and a pixel) of its rim.
PLAIN_RIM_PX = 5


def plain_top(box, stride, **changes):
    return grid_matches(RIG, box, 0.05, stride, image=True, plain_rim_px=PLAIN_RIM_PX,
                        **changes)


def decide(points, left, right, config=DEFAULTS):
    chooser = dataclasses.replace(BestPointChooser.create('centroid', config, RIG),
                                  world_from_camera=RIG.world_from_left_camera())
    return chooser.decide(points, left, right)


@pytest.mark.parametrize('box', [BOX, DISC], ids=['box', 'disc'])
@pytest.mark.parametrize('stride', [1, 3])
def test_a_plain_top_matched_only_at_its_rim_is_taken_whole_from_the_image(box, stride):
    points, left, right = plain_top(box, stride)
    pose = RIG.world_from_left_camera()
    area = find_correlation_area(points, pose, DEFAULTS, float(left.P[0, 2] - right.P[0, 2]))
    assert area.status == UNCERTAIN_TOP and area.face_in_pieces is not None, area.reason
    assert decide(points, left, right, IMAGE_OFF).status == UNCERTAIN_TOP
    outlined, decision = error_mm(points, left, right, box)
    assert decision.status == 'ok'
    left_calibration = grid_matches(RIG, None, 0.0, 8)[1]
    pixel_mm = 1000.0 * camera_distance(RIG) / float(left_calibration.P[0, 0])
    assert outlined - pixel_floor_mm(box, stride) < pixel_mm


def test_a_face_in_pieces_whose_image_region_leaks_into_the_table_stays_refused():
    points, left, right = plain_top(BOX, 1)
    # the top painted with the table's texture and grey: no closed plain region around it
    table_only = grid_matches(RIG, None, 0.0, 1, image=True)[0].left_image
    points = dataclasses.replace(points, left_image=table_only)
    decision = decide(points, left, right)
    assert decision.status == UNCERTAIN_TOP, decision.status
    assert decision.best_point_world is None


def top_in_pieces(kept_rows, period, rail_px):
    """Return the textured box's matches with its top matched, as a top with stripes along
    the epipolar lines is, only in bands of kept_rows rows every period rows, and in full
    within rail_px columns of its left and right rims (0: separate stripes). The top's
    texture is strong: it is no plain region."""
    points, left, right = grid_matches(RIG, BOX, 0.05, 1, image=True, top_contrast=5.0)
    pose = RIG.world_from_left_camera()
    heights = (points.xyz.astype(float) @ pose[:3, :3].T + pose[:3, 3])[:, 2]
    on_top = heights > 0.5 * BOX.height
    columns = points.u_left[on_top]
    inner = ((points.u_left >= columns.min() + rail_px)
             & (points.u_left <= columns.max() - rail_px))
    dropped = on_top & inner & (points.v_left.astype(int) % period >= kept_rows)
    return points.subset(~dropped), left, right


def test_a_textured_face_with_holes_is_outlined_from_the_image():
    points, left, right = top_in_pieces(4, 9, 4)
    pose = RIG.world_from_left_camera()
    area = find_correlation_area(points, pose, DEFAULTS, float(left.P[0, 2] - right.P[0, 2]))
    assert area.status == UNCERTAIN_TOP and area.face_in_pieces is not None, area.reason
    # a textured top is no plain region: only its rim in the image makes it whole
    assert plain_face_from_image(area.face_in_pieces, points.left_image, left, right, pose,
                                 DEFAULTS.min_points, DEFAULTS.max_object_across_m) is None
    assert decide(points, left, right, IMAGE_OFF).status == UNCERTAIN_TOP
    outlined, decision = error_mm(points, left, right, BOX)
    assert decision.status == 'ok'
    left_calibration = grid_matches(RIG, None, 0.0, 8)[1]
    pixel_mm = 1000.0 * camera_distance(RIG) / float(left_calibration.P[0, 0])
    assert outlined - pixel_floor_mm(BOX, 1) < pixel_mm


@pytest.mark.parametrize('kept_rows, period, rail_px', [(1, 9, 4), (4, 9, 0)],
                         ids=['mostly-holes', 'separate-stripes'])
def test_a_face_too_much_in_pieces_stays_refused_though_the_image_has_its_rim(
        kept_rows, period, rail_px):
    points, left, right = top_in_pieces(kept_rows, period, rail_px)
    decision = decide(points, left, right)
    assert decision.status == UNCERTAIN_TOP and 'in pieces' in decision.reason
    assert decision.best_point_world is None


def test_a_plain_face_holds_the_matches_within_a_windows_radius_of_its_pixels():
    # A plain square 20 px across; 10 matches on it and 12 on a line 3 px below its edge, where
    # a window straddling the rim put them: most of the matches are the face's.
    plain = np.zeros((60, 60), dtype=bool)
    plain[20:40, 20:40] = True
    inside_rows, inside_columns = np.full(10, 30), np.arange(22, 32)
    rows = np.concatenate([inside_rows, np.full(12, 42)])
    columns = np.concatenate([inside_columns, np.arange(24, 36)])
    hull = plain_region(plain, rows, columns, reach=4)
    assert hull is not None
    assert (hull.min(axis=0).tolist(), hull.max(axis=0).tolist()) == ([20, 20], [39, 39])
    # counted only on the face's own pixels, 10 of 22 matches are not most of them
    assert plain_region(plain, rows, columns, reach=0) is None
    # nor are they when the line lies beyond the window's radius
    far = np.concatenate([inside_rows, np.full(12, 46)])
    assert plain_region(plain, far, columns, reach=4) is None


def plain_face(image=None, max_across_m=DEFAULTS.max_object_across_m):
    """Return plain_face_from_image on the plain box's face in pieces (its own image by
    default), and that face."""
    points, left, right = plain_top(BOX, 1)
    pose = RIG.world_from_left_camera()
    area = find_correlation_area(points, pose, DEFAULTS, float(left.P[0, 2] - right.P[0, 2]))
    face = area.face_in_pieces
    assert face is not None
    return plain_face_from_image(face, points.left_image if image is None else image, left,
                                 right, pose, DEFAULTS.min_points, max_across_m), face


def test_a_plain_region_longer_than_any_object_stays_refused():
    whole, _ = plain_face()
    assert whole is not None
    assert plain_face(max_across_m=0.95 * across_m(whole.xyz_world[:, :2]))[0] is None


def test_plain_face_needs_the_matches_inside_the_image_sent():
    whole, face = plain_face()
    assert whole is not None
    image = plain_top(BOX, 1)[0].left_image
    last = int(face.u_left.max()) - 5
    cut = RectifiedImage(image.pixels[:, :last], window_size=image.window_size)
    assert plain_face(cut)[0] is None


def test_max_score_decides_on_the_matches_even_when_the_image_comes_with_them():
    points, left, right = grid_matches(RIG, BOX, 0.05, 1, fatten_px=4, image=True)
    pose = RIG.world_from_left_camera()
    world = points.xyz.astype(float) @ pose[:3, :3].T + pose[:3, 3]
    on_top = np.flatnonzero(world[:, 2] > 0.5 * BOX.height)
    points.score = points.score.copy()
    points.score[on_top[len(on_top) // 3]] = 2.0
    chooser = dataclasses.replace(BestPointChooser.create('max_score', DEFAULTS, RIG),
                                  world_from_camera=pose)
    decision = chooser.decide(points, left, right)
    np.testing.assert_allclose(decision.best_point_world[:2], world[on_top[len(on_top) // 3], :2])


def test_a_sliver_of_a_face_is_refused_as_narrower_than_any_object():
    # Only a 6 mm strip of the box's top is matched (the rest plain and unmatched, and no image
    # to outline it from): its centre is not the face's.
    points, left, right = grid_matches(RIG, BOX, 0.05, 1)
    pose = RIG.world_from_left_camera()
    world = points.xyz.astype(float) @ pose[:3, :3].T + pose[:3, 3]
    on_top = world[:, 2] > 0.5 * BOX.height
    keep = ~on_top | (np.abs(world[:, 0] - (BOX.centre_xy[0] + 0.012)) <= 0.003)
    sliver = points.subset(keep)
    decision = decide(sliver, left, right)
    assert decision.status == NO_OBJECT, decision.reason
    assert 'narrower than any object (min_object_across_m=0.01)' in decision.reason
    assert decision.best_point_world is None
    # 132 px of the image: without the width test, the area test refuses it too
    allowed = decide(sliver, left, right, AreaConfig(min_object_across_m=0.0))
    assert allowed.status == NO_OBJECT and 'less than any object' in allowed.reason, (
        allowed.reason)


def test_the_smallest_object_is_not_refused_as_too_narrow():
    # 15 mm across, where its top covers 250 px of the left image; further away, at 186 px,
    # it covers less than any object may (MIN_OBJECT_AREA_PX): refused for that, not its width
    small = Box((0.2, 0.05), 0.015, 0.03)
    points, left, right = grid_matches(RIG, small, 0.05, 1, image=True)
    error, decision = error_mm(points, left, right, small)
    assert decision.status == 'ok'
    assert error < 3.0
    further = Box((0.2, 0.15), 0.015, 0.03)
    decision = decide(*grid_matches(RIG, further, 0.05, 1, image=True))
    assert decision.status == NO_OBJECT and 'less than any object' in decision.reason, (
        decision.reason)
