"""A low object's top face refined from its appearance (face_appearance.py), on ray-cast grids."""

import dataclasses
import math

import numpy as np
import pytest
from grid_scenes import TILTED_RIG as RIG
from grid_scenes import Box, grid_matches
from scipy import ndimage
from stereo_fuzzy_perception.core.best_point.correlation_area import (
    AreaConfig,
    find_correlation_area,
)
from stereo_fuzzy_perception.core.best_point.face_appearance import (
    LOW_WALL_PX,
    low_face_from_appearance,
    side_wall_px,
)
from stereo_fuzzy_perception.core.best_point.face_outline import face_from_image, on_top_plane
from stereo_fuzzy_perception.core.best_point.point_selectors import decision_area
from stereo_fuzzy_perception.core.matched_points import RectifiedImage

POSE = RIG.world_from_left_camera()
DISC = Box((0.18, 0.12), 0.05, 0.005, round=True)
BOX = Box((0.2, 0.15), 0.04, 0.03)
DEFAULTS = AreaConfig()


def striped_top_scene(box, stride=1):
    """Return (matches, left, right, which matches see the top) with a left image whose top
    is striped like wood grain (strong edges inside it) on a smooth textured table of the same
    mean grey: only the texture tells them apart."""
    points, left, right = grid_matches(RIG, box, 0.0, stride, image=True)
    world = points.xyz.astype(float) @ POSE[:3, :3].T + POSE[:3, 3]
    on_top = world[:, 2] > 0.5 * box.height
    shape = points.left_image.pixels.shape
    rng = np.random.default_rng(3)
    table = ndimage.gaussian_filter(rng.normal(size=shape), 2.0)
    grey = 120.0 + 25.0 * table / table.std()
    # every pixel of the grid, whichever stride the matches were kept at
    full, _, _ = grid_matches(RIG, box, 0.0, 1)
    full_world = full.xyz.astype(float) @ POSE[:3, :3].T + POSE[:3, 3]
    top_pixels = np.zeros(shape, bool)
    top_pixels[full.v_left.astype(int), full.u_left.astype(int)] = (
        full_world[:, 2] > 0.5 * box.height)
    columns = np.arange(shape[1])[None, :].repeat(shape[0], axis=0)
    stripes = np.where((columns // 3) % 2 == 0, 85.0, 155.0)
    grey = np.where(top_pixels, stripes + rng.normal(0.0, 3.0, shape), grey)
    image = RectifiedImage(np.clip(grey, 0, 255).astype(np.uint8), window_size=9)
    return dataclasses.replace(points, left_image=image), left, right, on_top


def centre_error_mm(area, box):
    weight = area.point_weights()
    centre = (area.xyz_world * weight[:, None]).sum(axis=0) / weight.sum()
    return 1000.0 * float(np.linalg.norm(centre[:2] - np.asarray(box.centre_xy)))


def face_cut_at_a_stripe(points, left, right, on_top, cut_px):
    """Return the top's area with its pixels within cut_px of its left rim left out: an image
    outline that followed a stripe's edge inside the face."""
    area = find_correlation_area(points, POSE, DEFAULTS, float(left.P[0, 2] - right.P[0, 2]))
    assert area.ok, area.reason
    u, v = points.u_left[on_top].astype(float), points.v_left[on_top].astype(float)
    kept = np.ones(len(u), bool)
    for row in np.unique(v):
        in_row = v == row
        kept[in_row] = u[in_row] >= u[in_row].min() + cut_px
    cut = on_top_plane(area, u[kept], v[kept], left, right, POSE)
    whole = on_top_plane(area, u, v, left, right, POSE)
    return cut, whole


@pytest.mark.parametrize('stride', [1, 3])
def test_a_low_face_cut_at_a_texture_edge_is_grown_back_to_its_rim(stride):
    points, left, right, on_top = striped_top_scene(DISC, stride)
    cut, whole = face_cut_at_a_stripe(points, left, right, on_top, cut_px=4)
    assert side_wall_px(cut, left, POSE) < LOW_WALL_PX
    refined = low_face_from_appearance(cut, points.left_image, left, right, POSE,
                                       DEFAULTS.min_points)
    assert refined is not None
    floor, before, after = (centre_error_mm(area, DISC) for area in (whole, cut, refined))
    # floor: the centre of the grid pixels that do see the top; a pixel at the top's depth is
    # about 1 mm here, and the cut moved the centre by 2-3 mm
    assert before - floor > 1.5
    assert after - floor < 0.5 * (before - floor), (floor, before, after)
    assert refined.top_height == cut.top_height


def test_a_low_face_already_at_its_rim_stays_there():
    points, left, right, on_top = striped_top_scene(DISC)
    _, whole = face_cut_at_a_stripe(points, left, right, on_top, cut_px=0)
    refined = low_face_from_appearance(whole, points.left_image, left, right, POSE,
                                       DEFAULTS.min_points)
    assert refined is not None
    assert abs(centre_error_mm(refined, DISC) - centre_error_mm(whole, DISC)) < 0.3


def test_a_tall_objects_face_is_left_as_it_is():
    # its side wall, of the top's texture in another shade, would join the face
    points, left, right, on_top = striped_top_scene(BOX)
    cut, _ = face_cut_at_a_stripe(points, left, right, on_top, cut_px=4)
    assert side_wall_px(cut, left, POSE) > LOW_WALL_PX
    assert low_face_from_appearance(cut, points.left_image, left, right, POSE,
                                    DEFAULTS.min_points) is None


def test_the_side_wall_in_the_image_grows_with_the_objects_height():
    points, left, right, on_top = striped_top_scene(DISC)
    _, face = face_cut_at_a_stripe(points, left, right, on_top, cut_px=0)
    low = side_wall_px(face, left, POSE)
    higher = side_wall_px(dataclasses.replace(face, top_height=4 * face.top_height), left, POSE)
    assert 0.5 < low < LOW_WALL_PX
    assert higher == pytest.approx(4 * low, rel=0.1)


def test_a_face_near_the_edge_of_the_image_sent_stands():
    points, left, right, on_top = striped_top_scene(DISC)
    cut, _ = face_cut_at_a_stripe(points, left, right, on_top, cut_px=4)
    whole = points.left_image
    # the image sent ends five pixels right of the face: no ring of surroundings there
    last = int(cut.u_left.max()) + 5
    narrow = RectifiedImage(whole.pixels[:, :last], window_size=whole.window_size)
    assert low_face_from_appearance(cut, narrow, left, right, POSE,
                                    DEFAULTS.min_points) is None


def test_a_face_too_small_for_its_model_stands():
    points, left, right, on_top = striped_top_scene(DISC)
    _, whole = face_cut_at_a_stripe(points, left, right, on_top, cut_px=0)
    centre = np.array([np.median(whole.u_left), np.median(whole.v_left)])
    near = np.hypot(whole.u_left - centre[0], whole.v_left - centre[1]) <= 3.0
    tiny = on_top_plane(whole, whole.u_left[near], whole.v_left[near], left, right, POSE)
    assert low_face_from_appearance(tiny, points.left_image, left, right, POSE,
                                    DEFAULTS.min_points) is None


def test_the_decision_area_refines_a_low_face_only():
    for box, refined in ((DISC, True), (BOX, False)):
        points, left, right, _ = striped_top_scene(box)
        shift = float(left.P[0, 2] - right.P[0, 2])
        matched = find_correlation_area(points, POSE, DEFAULTS, shift)
        outlined = face_from_image(matched, points.left_image, left, right, POSE,
                                   DEFAULTS.min_points)
        decided = decision_area(points, left, right, POSE, DEFAULTS)
        expected = low_face_from_appearance(outlined, points.left_image, left, right, POSE,
                                            DEFAULTS.min_points) if refined else outlined
        assert expected is not None
        np.testing.assert_array_equal(decided.u_left, expected.u_left)
        np.testing.assert_array_equal(decided.v_left, expected.v_left)


def test_a_mark_of_the_tops_texture_touching_its_rim_pulls_it_out_by_the_reach_only():
    points, left, right, on_top = striped_top_scene(DISC)
    _, whole = face_cut_at_a_stripe(points, left, right, on_top, cut_px=0)
    # stripes like the top's, 14 px wide, touching its right rim over a third of its height
    pixels = points.left_image.pixels.astype(float)
    rows = np.percentile(whole.v_left, [35, 65]).astype(int)
    first = int(whole.u_left.max()) - 2
    columns = np.arange(first, first + 14)
    pixels[rows[0]:rows[1], first:first + 14] = np.where((columns // 3) % 2 == 0, 85.0, 155.0)
    marked = RectifiedImage(pixels.astype(np.uint8), window_size=9)
    refined = low_face_from_appearance(whole, marked, left, right, POSE, DEFAULTS.min_points)
    assert refined is not None
    # REACH_PX (4 px, a few millimetres on a short arc) of the mark at most joins the face
    assert centre_error_mm(refined, DISC) < 1.2


def test_a_face_whose_wall_cannot_be_placed_is_taken_as_tall():
    points, left, right, on_top = striped_top_scene(DISC)
    cut, _ = face_cut_at_a_stripe(points, left, right, on_top, cut_px=4)
    # a top height that is not a number (a peer's garbage that got this far) projects nowhere
    broken = dataclasses.replace(cut, top_height=float('nan'))
    assert math.isnan(side_wall_px(broken, left, POSE))
    assert low_face_from_appearance(broken, points.left_image, left, right, POSE,
                                    DEFAULTS.min_points) is None
