"""The top face fitted as a disc or a rectangle to both images (top_shape_fit.py)."""

import dataclasses
import math
import multiprocessing
from types import SimpleNamespace

import cv2
import numpy as np
import pytest
from grid_scenes import TILTED_RIG as RIG
from grid_scenes import Box, grid_matches, plain_box_pair
from stereo_fuzzy_perception.core.best_point import top_shape_fit
from stereo_fuzzy_perception.core.best_point.correlation_area import (
    LOOK_FITTED_PIECES,
    LOOK_FITTED_SMALL_FACE,
    NO_OBJECT,
    UNCERTAIN_TOP,
    AreaConfig,
)
from stereo_fuzzy_perception.core.best_point.point_selectors import BestPointChooser
from stereo_fuzzy_perception.core.best_point.top_shape_fit import (
    DISC,
    RECTANGLE,
    TopShapeCosts,
    TopShapeFit,
    TopShapeMemory,
    centre_for_refused_face,
    fit_top_shape,
    moved_toward_fit,
    principal_axes,
    signed_distances,
    top_shape_costs,
)
from stereo_fuzzy_perception.core.best_point.work_surface import SURFACE_MEASURED, SurfacePlane

POSE = RIG.world_from_left_camera()
TABLE = SurfacePlane(SURFACE_MEASURED, 0.0, 0.0, 0.0, 0.1, 1000)


def test_a_disc_is_negative_inside_zero_on_its_rim_and_the_distance_outside():
    disc = np.array([0.1, 0.2, 0.03])
    points = np.array([[0.1, 0.2], [0.13, 0.2], [0.1, 0.25]])
    assert signed_distances(DISC, disc, points) == pytest.approx([-0.03, 0.0, 0.02])


def test_a_turned_rectangle_measures_along_its_own_sides():
    # 40 x 20 mm, its long side along the diagonal
    rectangle = np.array([0.0, 0.0, math.pi / 4, 0.04, 0.02])
    along = np.array([math.cos(math.pi / 4), math.sin(math.pi / 4)])
    across = np.array([-along[1], along[0]])
    points = np.array([0.0 * along, 0.03 * along, 0.02 * across, 0.03 * along + 0.02 * across])
    assert signed_distances(RECTANGLE, rectangle, points) == pytest.approx(
        [-0.01, 0.01, 0.01, math.hypot(0.01, 0.01)])


@pytest.mark.parametrize('shape, parameters', [
    (DISC, np.array([0.01, -0.005, 0.012])),
    (RECTANGLE, np.array([0.01, -0.005, 0.4, 0.03, 0.012])),
    (RECTANGLE, np.array([0.0, 0.0, 0.0, 0.02, 0.02]))])
def test_a_segment_runs_inside_and_comes_nearest_where_its_points_say(shape, parameters):
    # the exact crossing and least distance against the segment's points, densely sampled
    rng = np.random.default_rng(7)
    cos, sin = math.cos(parameters[2]), math.sin(parameters[2])
    t = np.linspace(0.0, 1.0, 4001)
    for _ in range(300):
        start, end = rng.uniform(-0.04, 0.05, 2), rng.uniform(-0.04, 0.05, 2)
        if rng.random() < 0.2:  # axis-parallel segments: the slabs' degenerate case
            end[rng.integers(2)] = start[rng.integers(2)]
        t_in, t_out, nearest, nearest_at = top_shape_fit._segment_in_shape(
            shape, parameters, cos, sin, *start, *end)
        distances = signed_distances(shape, parameters, start + t[:, None] * (end - start))
        assert nearest == pytest.approx(distances.min(), abs=2e-5)
        assert 0.0 <= nearest_at <= 1.0
        inside = distances < -1e-6
        assert np.all((t[inside] > t_in - 1e-3) & (t[inside] < t_out + 1e-3))
        clearly = distances < -1e-4
        if clearly.any():
            assert t_in < t_out


@pytest.mark.parametrize('shape, parameters', [
    (DISC, np.array([0.01, -0.005, 0.012])),
    (RECTANGLE, np.array([0.01, -0.005, 0.4, 0.04, 0.008]))])
def test_a_segment_is_never_skipped_where_it_comes_near_the_shape(shape, parameters):
    # _total_cost skips a segment whose lower bound of the distance passes half a pixel: the
    # bound must never exceed the segment's true least distance from the shape
    rng = np.random.default_rng(11)
    cos, sin = math.cos(parameters[2]), math.sin(parameters[2])
    reach = parameters[2] if shape == DISC else 0.5 * math.hypot(*parameters[3:5])
    t = np.linspace(0.0, 1.0, 2001)
    tighter = 0
    for _ in range(500):
        start, end = rng.uniform(-0.05, 0.06, 2), rng.uniform(-0.05, 0.06, 2)
        bound = top_shape_fit._apart_at_least(shape, parameters, cos, sin, reach, *start, *end)
        distances = signed_distances(shape, parameters, start + t[:, None] * (end - start))
        assert bound <= max(distances.min(), 0.0) + 1e-9
        circle = top_shape_fit._segment_distance(*start, *end, *parameters[:2]) - reach
        tighter += bound > circle + 0.001
    # a disc's bound is its circle's; a long thin rectangle's own box bounds the distance far
    # better than its circle
    if shape == DISC:
        assert tighter == 0
    else:
        assert tighter > 100


def _pixel_grid(metres_per_px: float, side: int) -> np.ndarray:
    columns, rows = np.meshgrid(np.arange(side), np.arange(side))
    return np.column_stack([columns.ravel(), rows.ravel()]).astype(float) * metres_per_px


def test_the_fit_finds_the_disc_whose_pixels_match_the_top_and_the_rest_the_surface():
    metres_per_px = 0.001
    on_top = _pixel_grid(metres_per_px, 60)
    true_disc = np.array([0.031, 0.028, 0.012])
    inside = signed_distances(DISC, true_disc, on_top) < 0.0
    # no wall and nothing hidden from the right camera: the rays below the top and the view
    # lines to the right camera all run far outside the disc
    far = np.tile([1.0, 1.0, 1.01, 1.0], (len(on_top), 1))
    costs = TopShapeCosts(on_top, far, far, np.full(len(on_top), metres_per_px),
                          np.where(inside, 0.1, 1.2), np.ones((len(on_top), 2)),
                          np.where(inside, 1.2, 0.1), 1.2, 0.0, len(on_top))
    fit = fit_top_shape(costs, np.array([0.027, 0.031]), (0.0, 0.02, 0.02))
    assert fit.shape == 'disc'
    assert np.hypot(*(fit.centre - true_disc[:2])) < 0.5 * metres_per_px
    assert fit.drop_per_px > 0.0


def _disc_costs():
    """A crop whose pixels match the top inside a 10 mm disc and the surface outside it."""
    metres_per_px = 0.001
    on_top = _pixel_grid(metres_per_px, 40)
    inside = signed_distances(DISC, np.array([0.02, 0.02, 0.01]), on_top) < 0.0
    far = np.tile([1.0, 1.0, 1.01, 1.0], (len(on_top), 1))
    return TopShapeCosts(on_top, far, far, np.full(len(on_top), metres_per_px),
                         np.where(inside, 0.1, 1.2), np.ones((len(on_top), 2)),
                         np.where(inside, 1.2, 0.1), 1.2, 0.0, len(on_top))


def _fit_in_child(results):
    fit = fit_top_shape(_disc_costs(), np.array([0.018, 0.021]), (0.0, 0.02, 0.02))
    results.put(fit.shape)


def test_a_process_forked_after_a_fit_fits_too():
    # the disc is fitted on a worker thread; a forked child (benchmarks' process pools) must
    # not wait for the parent's thread, which it does not have
    fit_top_shape(_disc_costs(), np.array([0.018, 0.021]), (0.0, 0.02, 0.02))
    context = multiprocessing.get_context('fork')
    results = context.Queue()
    child = context.Process(target=_fit_in_child, args=(results,))
    child.start()
    child.join(60.0)
    hung = child.is_alive()
    if hung:
        child.kill()
    assert not hung and child.exitcode == 0
    assert results.get(timeout=5.0) == 'disc'


def _area(box, outline, shape):
    """What top_shape_costs reads of a correlation area: the pixels within the top's outline in
    the left image (the box's square, round or not), the surface and the top's height."""
    mask = np.zeros(shape, np.uint8)
    cv2.fillPoly(mask, [np.round(outline).astype(np.int32)], 1)
    v_left, u_left = np.nonzero(mask)
    return SimpleNamespace(surface=TABLE, top_height=box.height, u_left=u_left.astype(float),
                           v_left=v_left.astype(float))


def _box_seen_with_a_guess(box, top_texture):
    """Return (left image, right image, left, right, area, true centre, guess) for the box
    ray-cast in both images: a plain or textured top on a textured table, its walls plain and
    darker; the area the chain would hand over is the top's outline in the left image, its
    centre 2-3 mm off."""
    left_image, right_image, left, right, outline = plain_box_pair(
        RIG, box, top_grey=200.0, right_gain=0.9, right_offset=12.0, top_texture=top_texture)
    area = _area(box, outline, left_image.pixels.shape)
    truth = np.array(box.centre_xy)
    return left_image, right_image, left, right, area, truth, truth + np.array([0.002, -0.0025])


def _fitted_from_a_guess(box, top_texture):
    """Return (fit, true centre, guess) for the box of _box_seen_with_a_guess, fitted from the
    guess by fit_top_shape."""
    left_image, right_image, left, right, area, truth, guess = _box_seen_with_a_guess(
        box, top_texture)
    axes = (0.1, 0.9 * box.size, 0.9 * box.size)
    costs = top_shape_costs(area, left_image, right_image, left, right, POSE, guess, axes)
    assert costs is not None
    return fit_top_shape(costs, guess, axes), truth, guess


@pytest.mark.parametrize('box, top_texture, within_m', [
    (Box((0.21, 0.16), 0.04, 0.03), 0.0, 0.5e-3),
    (Box((0.21, 0.16), 0.04, 0.03), 20.0, 0.5e-3),
    (Box((0.19, 0.14), 0.045, 0.02, round=True), 0.0, 0.5e-3),
    # scored on every second pixel (FULL_RESOLUTION_PX): half of their spacing
    (Box((0.2, 0.15), 0.075, 0.025), 20.0, 1.0e-3)])
def test_a_ray_cast_top_is_found_from_a_guess_millimetres_off(box, top_texture, within_m):
    fit, truth, guess = _fitted_from_a_guess(box, top_texture)
    assert fit.shape == ('disc' if box.round else 'rectangle')
    assert np.hypot(*(fit.centre - truth)) < within_m
    assert fit.drop_per_px >= top_shape_fit.MIN_DROP
    assert fit.spread_m <= top_shape_fit.MAX_SPREAD_M  # found again from the shifted starts
    moved = moved_toward_fit(np.array([*guess, box.height]), fit)
    assert np.hypot(*(moved[:2] - truth)) < 0.4 * np.hypot(*(guess - truth))


def test_a_disc_of_the_lowest_objects_height_is_fitted_on_a_near_rig():
    # a 5 mm disc stands about 0.75 px out of the table on this rig: less than a pixel, and
    # still told from the table pixel by pixel
    fit, truth, _ = _fitted_from_a_guess(Box((0.19, 0.14), 0.045, 0.005, round=True), 20.0)
    assert fit.shape == 'disc'
    assert np.hypot(*(fit.centre - truth)) < 0.5e-3


def test_a_top_over_a_hundred_pixels_wide_is_fitted_on_every_third_pixel():
    # 126 px across in the left image: scored on every third pixel (FULL_RESOLUTION_PX), and
    # fitted as long as it is no wider than MAX_TOP_WIDTH_PX
    box = Box((0.2, 0.15), 0.12, 0.025)
    left_image, right_image, left, right, area, truth, guess = _box_seen_with_a_guess(box, 20.0)
    assert 100 < np.ptp(area.u_left) <= top_shape_fit.MAX_TOP_WIDTH_PX
    across = np.linspace(-box.size / 2, box.size / 2, 20)  # the top's matches, evenly
    on_top = truth + np.stack(np.meshgrid(across, across), -1).reshape(-1, 2)
    area.ok, area.xyz_world = True, np.column_stack([on_top, np.full(len(on_top), box.height)])
    fit = top_shape_fit.fitted(area, SimpleNamespace(left_image=left_image,
                                                     right_image=right_image),
                               left, right, POSE, guess)
    assert fit is not None and fit.shape == 'rectangle'
    assert np.hypot(*(fit.centre - truth)) < 1.5e-3


def test_a_top_standing_too_little_out_in_disparity_is_not_scored():
    box = Box((0.21, 0.16), 0.04, 0.001)
    left_image, right_image, left, right, outline = plain_box_pair(RIG, box, top_grey=200.0)
    area = _area(box, outline, left_image.pixels.shape)
    assert top_shape_costs(area, left_image, right_image, left, right, POSE,
                           np.array(box.centre_xy), (0.0, 0.04, 0.04)) is None


def test_the_point_moves_part_way_only_for_a_near_and_clear_fit():
    chain = np.array([0.1, 0.1, 0.05])
    near = TopShapeFit('disc', np.array([0.102, 0.1]), drop_per_px=0.05, spread_m=0.0005)
    assert moved_toward_fit(chain, near, 0.5, 0.005, 0.02) == pytest.approx([0.101, 0.1, 0.05])
    far = TopShapeFit('disc', np.array([0.11, 0.1]), drop_per_px=0.05)
    unclear = TopShapeFit('disc', np.array([0.102, 0.1]), drop_per_px=0.01)
    failed = TopShapeFit('disc', np.array([np.nan, np.nan]), drop_per_px=np.nan)
    not_found_again = TopShapeFit('disc', np.array([0.102, 0.1]), 0.05, spread_m=0.003)
    for fit in (far, unclear, failed, not_found_again, None):
        assert moved_toward_fit(chain, fit, 0.5, 0.005, 0.02, 0.002, 0.008) == pytest.approx(
            chain)
    found_again = TopShapeFit('disc', np.array([0.102, 0.1]), 0.05, spread_m=0.001)
    assert moved_toward_fit(chain, found_again, 0.5, 0.005, 0.02, 0.002, 0.008) == pytest.approx(
        [0.101, 0.1, 0.05])


MOVE_RULE = dict(weight=0.5, max_move_m=0.005, min_drop=0.02, max_spread_m=0.002,
                 far_move_m=0.012, sharp_spread_m=0.0003)
"""moved_toward_fit's bounds in the tests below: half the way within 5 mm, whole within 12."""

CHAIN_POINT = np.array([0.1, 0.1, 0.05])


def _moved_to(x_m: float, spread_m: float, drop_per_px: float = 0.05,
              found_again: int = 4) -> np.ndarray:
    """CHAIN_POINT moved under MOVE_RULE toward a disc fitted at (x_m, 0.1)."""
    fit = TopShapeFit('disc', np.array([x_m, 0.1]), drop_per_px, spread_m, found_again)
    return moved_toward_fit(CHAIN_POINT, fit, **MOVE_RULE)


def test_a_near_fit_every_start_found_again_in_a_sharp_valley_is_taken_whole():
    assert _moved_to(0.104, spread_m=0.0002) == pytest.approx([0.104, 0.1, 0.05])
    # a wider valley, or a sharp one that not every start reached, is taken part way only
    assert _moved_to(0.104, spread_m=0.0004) == pytest.approx([0.102, 0.1, 0.05])
    assert _moved_to(0.104, spread_m=0.0002, found_again=3) == pytest.approx([0.102, 0.1, 0.05])


def test_a_fit_found_again_from_every_start_further_off_than_a_move_is_taken_whole():
    assert _moved_to(0.109, spread_m=0.001) == pytest.approx([0.109, 0.1, 0.05])
    too_far = _moved_to(0.113, spread_m=0.001)
    not_found_again = _moved_to(0.109, spread_m=0.003)
    unclear = _moved_to(0.109, spread_m=0.001, drop_per_px=0.01)
    # the spread counts only the starts that ended as low: here three of four went elsewhere
    found_by_one_start = _moved_to(0.109, spread_m=0.001, found_again=1)
    found_by_no_start = _moved_to(0.109, spread_m=0.0, found_again=0)
    for moved in (too_far, not_found_again, unclear, found_by_one_start, found_by_no_start):
        assert moved == pytest.approx(CHAIN_POINT)
    # within max_move_m the spread alone decides
    assert _moved_to(0.104, spread_m=0.001, found_again=1) == pytest.approx([0.102, 0.1, 0.05])


def test_a_fit_on_a_flat_cost_ends_where_each_start_began_and_says_so():
    # every pixel costs the same whatever the shape: Nelder-Mead stops where it started, so
    # the starts shifted by SHIFTED_START_M end that far from the fit, as good as it
    pixels = np.column_stack([np.linspace(0.09, 0.11, 50), np.full(50, 0.1)])
    segments = np.column_stack([pixels, pixels])
    ones = np.ones(50)
    costs = TopShapeCosts(pixels, segments, segments, np.full(50, 0.001), ones,
                          np.ones((50, 2)), ones, 1.0, 0.0, 50)
    fit = fit_top_shape(costs, np.array([0.1, 0.1]), (0.0, 0.02, 0.02))
    assert fit.centre == pytest.approx([0.1, 0.1])
    assert fit.spread_m == pytest.approx(top_shape_fit.SHIFTED_START_M)
    assert fit.found_again == 4
    assert moved_toward_fit(np.array([0.101, 0.1, 0.02]), fit, min_drop=-1.0) == pytest.approx(
        [0.101, 0.1, 0.02])


def test_the_memory_gives_a_fit_again_for_the_same_object_and_pose_only():
    memory = TopShapeMemory()
    fit = TopShapeFit('disc', np.array([0.1, 0.1]), 0.05)
    point = np.array([0.1, 0.1, 0.03])
    assert memory.recall(point, POSE) == (False, None)
    memory.remember(point, POSE, fit)
    assert memory.recall(point + [0.001, -0.001, 0.0005], POSE) == (True, fit)
    assert memory.recall(point + [0.01, 0.0, 0.0], POSE) == (False, None)
    moved_pose = POSE.copy()
    moved_pose[0, 3] += 0.01
    assert memory.recall(point, moved_pose) == (False, None)
    assert memory.counts == dict(fitted=1, recalled=1, moved=0, pieces=0, small=0)


def test_the_principal_axes_of_a_uniform_strip_are_its_sides_and_direction():
    rng = np.random.default_rng(3)
    along, across = rng.uniform(-0.02, 0.02, 20000), rng.uniform(-0.005, 0.005, 20000)
    angle = 0.3
    xy = np.column_stack([along * math.cos(angle) - across * math.sin(angle),
                          along * math.sin(angle) + across * math.cos(angle)])
    found_angle, long_side, short_side = principal_axes(xy)
    assert long_side == pytest.approx(0.04, rel=0.02)
    assert short_side == pytest.approx(0.01, rel=0.02)
    assert math.sin(2 * (found_angle - angle)) == pytest.approx(0.0, abs=0.02)


def test_a_refused_face_takes_the_fitted_centre_only_from_a_clear_fit_found_again():
    chain = np.array([0.1, 0.1, 0.05])
    clear = TopShapeFit('rectangle', np.array([0.109, 0.1]), 0.05, spread_m=0.001)
    assert centre_for_refused_face(chain, clear) == pytest.approx([0.109, 0.1, 0.05])
    # a drop that moves an accepted face's point is too weak to give a point of its own
    weak = TopShapeFit('rectangle', np.array([0.109, 0.1]), 0.5 * (
        top_shape_fit.MIN_DROP + top_shape_fit.REFUSED_FACE_MIN_DROP), spread_m=0.001)
    not_found_again = TopShapeFit('rectangle', np.array([0.109, 0.1]), 0.05, spread_m=0.003)
    # no shifted start ended as low: the spread is 0, and still nothing confirms the fit
    found_only_once = TopShapeFit('rectangle', np.array([0.109, 0.1]), 0.05, 0.0, found_again=0)
    failed = TopShapeFit('disc', np.array([np.nan, np.nan]), drop_per_px=np.nan)
    for fit in (weak, not_found_again, found_only_once, failed, None):
        assert centre_for_refused_face(chain, fit) is None


def _top_in_pieces_seen_by_both_cameras(box):
    """Return (matches, left, right) of a textured box whose top is matched in one row of every
    nine and within 4 px of its left and right rims (a face too much in pieces for any look to
    make whole), with both images ray-cast; the top's texture is strong enough that no plain
    region of the image holds it."""
    points, left, right = grid_matches(RIG, box, 0.05, 1)
    heights = (points.xyz.astype(float) @ POSE[:3, :3].T + POSE[:3, 3])[:, 2]
    on_top = heights > 0.5 * box.height
    columns = points.u_left[on_top]
    inner = (points.u_left >= columns.min() + 4) & (points.u_left <= columns.max() - 4)
    dropped = on_top & inner & (points.v_left.astype(int) % 9 >= 1)
    left_image, right_image, *_ = plain_box_pair(RIG, box, top_grey=200.0, right_gain=0.9,
                                                 right_offset=12.0, top_texture=40.0)
    return (dataclasses.replace(points.subset(~dropped), left_image=left_image,
                                right_image=right_image), left, right)


def _top_too_small_seen_by_both_cameras(box):
    """Return (matches, left, right) of a textured box with both images ray-cast; a box 13 mm
    across has a top covering about 140 px of the left image, less than a face taken on its
    matches alone may (MIN_OBJECT_AREA_PX)."""
    points, left, right = grid_matches(RIG, box, 0.05, 1)
    left_image, right_image, *_ = plain_box_pair(RIG, box, top_grey=200.0, right_gain=0.9,
                                                 right_offset=12.0, top_texture=40.0)
    return dataclasses.replace(points, left_image=left_image, right_image=right_image), left, right


@pytest.mark.parametrize('side_m, seen, look, counted, refused_status, refused_as', [
    (0.04, _top_in_pieces_seen_by_both_cameras, LOOK_FITTED_PIECES, 'pieces', UNCERTAIN_TOP,
     'pieces'),
    (0.013, _top_too_small_seen_by_both_cameras, LOOK_FITTED_SMALL_FACE, 'small', NO_OBJECT,
     'less than any object')], ids=['face in pieces', 'face too small in the image'])
def test_a_refused_face_is_given_the_centre_of_the_top_fitted_to_both_images(
        side_m, seen, look, counted, refused_status, refused_as):
    box = Box((0.21, 0.16), side_m, 0.03)
    points, left, right = seen(box)
    chooser = dataclasses.replace(BestPointChooser.create('fuzzy_fitted', AreaConfig(), RIG),
                                  world_from_camera=POSE, top_shape_memory=TopShapeMemory())
    decision = chooser.decide(points, left, right)
    assert decision.look == look, decision.reason
    assert np.hypot(*(decision.best_point_world[:2] - box.centre_xy)) < 1e-3
    assert decision.best_point_world[2] == pytest.approx(box.height, abs=1e-3)
    assert chooser.top_shape_memory.counts[counted] == 1
    # without the fit the same face is refused, for what the fit would have made up for
    unfitted = dataclasses.replace(chooser, area_config=AreaConfig(fit_top_shape=False))
    refused = unfitted.decide(points, left, right)
    assert refused.status == refused_status and refused_as in refused.reason
    assert refused.best_point_world is None
