"""face_matched_again: a periodic top in pieces matched again on its pieces' plane."""

from dataclasses import replace
from types import SimpleNamespace

import cv2
import numpy as np
from grid_scenes import TILTED_RIG as RIG
from grid_scenes import Box, plain_box_pair
from stereo_fuzzy_perception.core.best_point.face_matched_again import face_matched_again
from stereo_fuzzy_perception.core.best_point.plain_top_height import _plane_disparity
from stereo_fuzzy_perception.core.best_point.work_surface import SURFACE_MEASURED, SurfacePlane
from stereo_fuzzy_perception.core.matched_points import MatchedPoints

POSE = RIG.world_from_left_camera()
TABLE = SurfacePlane(SURFACE_MEASURED, 0.0, 0.0, 0.0, 0.1, 1000)
BOX = Box((0.21, 0.16), 0.05, 0.04)
STRIPES_M = 0.006
"""The top's stripes repeat about every 6 px in these images."""


def _striped_box_in_pieces(height_error_m: float):
    """Return (points, left, right, pieces, top pixels) for a box whose top is striped: the
    pair's matches are a few table pixels with both images attached, and the pieces are the
    left half of the top's pixels at the box's height plus height_error_m."""
    left_image, right_image, left, right, outline = plain_box_pair(
        RIG, BOX, top_grey=120.0, right_gain=0.9, right_offset=12.0, top_stripes_m=STRIPES_M)
    mask = np.zeros(left_image.pixels.shape, np.uint8)
    cv2.fillPoly(mask, [np.round(outline).astype(np.int32)], 1)
    mask = cv2.erode(mask, np.ones((5, 5), np.uint8))  # the top's own pixels, not its rim
    rows, columns = np.nonzero(mask)
    half = columns < np.median(columns)
    pieces = SimpleNamespace(u_left=columns[half].astype(float), v_left=rows[half].astype(float),
                             surface=TABLE, top_height=BOX.height + height_error_m)
    table_u, table_v = (grid.ravel().astype(float) for grid in np.meshgrid(
        np.arange(20.0, 60.0), np.arange(20.0, 60.0)))
    points = MatchedPoints(np.zeros((len(table_u), 3)), table_u, table_v, table_u - 40.0,
                           np.ones(len(table_u)), left_image, right_image)
    return points, left, right, pieces, (columns.astype(float), rows.astype(float))


def test_the_whole_striped_top_is_matched_on_its_pieces_plane():
    points, left, right, pieces, (columns, rows) = _striped_box_in_pieces(0.0)
    again = face_matched_again(pieces, points, left, right, POSE)
    assert again is not None
    true_right = _plane_disparity(left, right, POSE, TABLE)
    new = len(points) <= np.arange(len(again))
    # the hull of the left half holds about half the top; nearly all of it matched again
    assert new.sum() > 0.4 * len(columns)
    expected = true_right(again.u_left[new], again.v_left[new], BOX.height)
    assert np.median(np.abs(again.u_right[new] - expected)) < 0.1
    assert np.all(np.abs(again.u_right[new] - expected) < 0.6)
    # the table's matches outside the hull are kept as they were
    assert np.array_equal(again.u_left[~new], points.u_left)


def test_pieces_half_a_stripe_off_the_top_are_not_confirmed():
    # A plane whose disparity lies half a repeat from the top's: every window peaks beyond
    # the search, at the top's own disparity or a repeat from it.
    points, left, right, pieces, (columns, _) = _striped_box_in_pieces(0.0)
    true_right = _plane_disparity(left, right, POSE, TABLE)
    u, v = float(np.median(pieces.u_left)), float(np.median(pieces.v_left))
    heights = np.linspace(BOX.height - 0.03, BOX.height + 0.03, 601)
    shift = true_right(np.full(len(heights), u), np.full(len(heights), v), heights) - true_right(
        np.array([u]), np.array([v]), BOX.height)
    off = float(heights[np.argmin(np.abs(shift - 3.0))])  # 3 px: half of the stripes' repeat
    pieces.top_height = off
    again = face_matched_again(pieces, points, left, right, POSE)
    taken = 0 if again is None else len(again) - len(points)
    assert taken < 0.05 * len(columns)


def test_pieces_spread_over_less_than_any_top_are_not_matched_again():
    # A blob of matches a repeat off on a wood or woven table is such a piece: confirmed on
    # its own plane, it would make a face where there is none.
    points, left, right, pieces, _ = _striped_box_in_pieces(0.0)
    centre_u, centre_v = np.median(pieces.u_left), np.median(pieces.v_left)
    small = (np.abs(pieces.u_left - centre_u) <= 6) & (np.abs(pieces.v_left - centre_v) <= 6)
    pieces.u_left, pieces.v_left = pieces.u_left[small], pieces.v_left[small]
    assert face_matched_again(pieces, points, left, right, POSE) is None
    # the same top's pieces over a square of 16 px (256 px²) are matched again
    points, left, right, pieces, _ = _striped_box_in_pieces(0.0)
    square = (np.abs(pieces.u_left - centre_u) <= 8) & (np.abs(pieces.v_left - centre_v) <= 8)
    pieces.u_left, pieces.v_left = pieces.u_left[square], pieces.v_left[square]
    assert face_matched_again(pieces, points, left, right, POSE) is not None


def test_a_rendered_wood_top_in_pieces_gets_its_point_from_its_plane():
    # Validation scene 73 (seed 2000073): a box with a wood top 74 px across whose grain the
    # matcher matched a repeat off in places: its face is refused in pieces after every other
    # look, and matched again on the pieces' plane it is the top.
    from stereo_fuzzy_perception.core.best_point.correlation_area import (
        LOOK_PIECES_MATCHED_AGAIN,
        UNCERTAIN_TOP,
        AreaConfig,
    )
    from stereo_fuzzy_perception.core.best_point.point_selectors import (
        BestPointChooser,
        decision_area,
    )
    from stereo_fuzzy_perception.core.rig_geometry import StereoRig
    from stereo_fuzzy_perception.simulation.distribution_source import match_scene
    from stereo_fuzzy_perception.simulation.scene_distribution import split_plan

    scene = match_scene(split_plan('validation', 50)[73].draw(), (1,)).matched[1]
    pose = scene.rig.world_from_left_camera()
    before = decision_area(scene.points, scene.left, scene.right, pose, AreaConfig(),
                           match_again=False)
    assert before.status == UNCERTAIN_TOP and 'pieces' in before.reason
    chooser = BestPointChooser.create('fuzzy_fitted', AreaConfig(), StereoRig())
    decision = replace(chooser, world_from_camera=pose).decide(scene.points, scene.left,
                                                               scene.right)
    assert decision.look == LOOK_PIECES_MATCHED_AGAIN
    error = np.linalg.norm(decision.best_point_world - scene.target_world)
    assert error < 0.003, f'{1000 * error:.1f} mm from the top-face centre'
