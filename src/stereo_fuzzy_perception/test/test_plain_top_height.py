"""A plain top's height from both rectified images (plain_top_height.py), on ray-cast pairs."""

import dataclasses

import numpy as np
import pytest
from grid_scenes import TILTED_RIG as RIG
from grid_scenes import Box, grid_matches, plain_box_pair
from stereo_fuzzy_perception.core.best_point.correlation_area import (
    AreaConfig,
    find_correlation_area,
)
from stereo_fuzzy_perception.core.best_point.face_outline import plain_face_from_image
from stereo_fuzzy_perception.core.best_point.plain_top_height import plain_top_height
from stereo_fuzzy_perception.core.best_point.work_surface import SURFACE_MEASURED, SurfacePlane
from stereo_fuzzy_perception.core.matched_points import RectifiedImage

POSE = RIG.world_from_left_camera()
TABLE = SurfacePlane(SURFACE_MEASURED, 0.0, 0.0, 0.0, 0.1, 1000)
TOLERANCE = 12.0  # grey levels around the top's grey that make it plain


@pytest.mark.parametrize('height', [0.005, 0.03, 0.06])
@pytest.mark.parametrize('gain, offset', [(1.0, 0.0), (0.8, 20.0), (1.2, -25.0)])
def test_a_plain_tops_height_is_where_its_rim_lies_in_both_images(height, gain, offset):
    box = Box((0.2, 0.15), 0.04, height)
    # Walls drawn from the footprint: with the rays that clip a wall's corner showing that
    # wall, the height comes out over a millimetre high (benchmarks/EXPERIMENTS.md,
    # nineteenth session): a bias of plain_top_height not corrected yet.
    left_image, right_image, left, right, outline = plain_box_pair(
        RIG, box, top_grey=200.0, right_gain=gain, right_offset=offset,
        walls_from_footprint=True)
    found = plain_top_height(outline, 200.0, TOLERANCE, left_image, right_image, left, right,
                             POSE, TABLE, 0.1)
    assert found is not None
    assert found.height_m == pytest.approx(height, abs=0.0015)


def test_a_top_of_the_tables_own_grey_gives_no_height():
    # The table's texture passes through the top's grey: its rim is not clear in either image,
    # and a height that might be the table's is not given.
    box = Box((0.2, 0.15), 0.04, 0.06)
    left_image, right_image, left, right, outline = plain_box_pair(RIG, box, top_grey=140.0)
    assert plain_top_height(outline, 140.0, TOLERANCE, left_image, right_image, left, right,
                            POSE, TABLE, 0.1) is None


def test_a_right_image_without_the_top_gives_no_height():
    box = Box((0.2, 0.15), 0.04, 0.03)
    left_image, _, left, right, outline = plain_box_pair(RIG, box, top_grey=200.0)
    _, table_only, _, _, _ = plain_box_pair(RIG, Box((0.2, 0.15), 0.0, 0.0), top_grey=200.0)
    assert plain_top_height(outline, 200.0, TOLERANCE, left_image, table_only, left, right,
                            POSE, TABLE, 0.1) is None


def test_a_band_past_the_image_sent_gives_no_height():
    box = Box((0.2, 0.15), 0.04, 0.03)
    left_image, right_image, left, right, outline = plain_box_pair(RIG, box, top_grey=200.0)
    column = int(outline[:, 0].mean())
    cut = RectifiedImage(left_image.pixels[:, column:], column, 0)
    assert plain_top_height(outline, 200.0, TOLERANCE, cut, right_image, left, right, POSE,
                            TABLE, 0.1) is None


def test_a_scattered_plain_face_takes_its_height_from_both_images():
    # The face as its matches give it: the rim of a plain top, and a height 10 mm off (the
    # median of heights that scatter). With the right image its height is the top's; without,
    # the matched height stands.
    box = Box((0.2, 0.15), 0.04, 0.03)
    points, left, right = grid_matches(RIG, box, 0.05, 1, image=True, plain_rim_px=5)
    area = find_correlation_area(points, POSE, AreaConfig(), float(left.P[0, 2] - right.P[0, 2]))
    assert area.face_in_pieces is not None, area.reason
    scattered = dataclasses.replace(area.face_in_pieces,
                                    top_height=area.face_in_pieces.top_height + 0.01)
    left_image, right_image, _, _, _ = plain_box_pair(RIG, box, top_grey=200.0)
    whole = plain_face_from_image(scattered, left_image, left, right, POSE, 20, 0.1,
                                  right_image=right_image)
    assert whole is not None
    assert whole.top_height == pytest.approx(0.03, abs=0.0015)
    centre = np.average(whole.xyz_world, axis=0, weights=whole.point_weights())
    assert np.linalg.norm(centre - [*box.centre_xy, box.height]) < 0.002
    matched = plain_face_from_image(scattered, left_image, left, right, POSE, 20, 0.1)
    assert matched is not None and matched.top_height == scattered.top_height


@pytest.mark.parametrize('raised', [0.0, 0.004, 0.015])
def test_a_scattered_face_is_not_taken_at_a_height_below_nearly_all_its_matches(raised):
    # Both images put the plain top 30 mm up. Matches that stand around that height, or a
    # little above it (mismatches above a plain top are common), leave it there; matches that
    # all stand 15 mm higher say the rim found belongs to another level: no face.
    box = Box((0.2, 0.15), 0.04, 0.03)
    points, left, right = grid_matches(RIG, box, 0.05, 1, image=True, plain_rim_px=5)
    area = find_correlation_area(points, POSE, AreaConfig(), float(left.P[0, 2] - right.P[0, 2]))
    assert area.face_in_pieces is not None, area.reason
    face = area.face_in_pieces
    scattered = dataclasses.replace(face, xyz_world=face.xyz_world + [0.0, 0.0, raised],
                                    top_height=face.top_height + raised)
    left_image, right_image, _, _, _ = plain_box_pair(RIG, box, top_grey=200.0)
    whole = plain_face_from_image(scattered, left_image, left, right, POSE, 20, 0.1,
                                  right_image=right_image)
    if raised > 0.01:
        assert whole is None
    else:
        assert whole is not None
        assert whole.top_height == pytest.approx(0.03, abs=0.0015)
