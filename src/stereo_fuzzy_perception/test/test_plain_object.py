"""One plain object on a textured surface, from the images when the matches show none
(plain_object.py), on ray-cast pairs."""

import dataclasses

import numpy as np
import pytest
from grid_scenes import TILTED_RIG as RIG
from grid_scenes import Box, grid_matches, plain_box_pair
from stereo_fuzzy_perception.core.best_point import plain_object
from stereo_fuzzy_perception.core.best_point.correlation_area import (
    LOOK_PLAIN_OBJECT,
    NO_OBJECT,
    OUTLINE_IMAGE,
    AreaConfig,
    find_correlation_area,
)
from stereo_fuzzy_perception.core.best_point.face_outline import plain_face_from_image
from stereo_fuzzy_perception.core.best_point.plain_object import (
    plain_face_without_side_wall,
    plain_object_from_image,
    plain_top_at_matched_height,
)
from stereo_fuzzy_perception.core.best_point.point_selectors import decision_area
from stereo_fuzzy_perception.core.matched_points import RectifiedImage

POSE = RIG.world_from_left_camera()
CONFIG = AreaConfig()


def bare_table_matches():
    """The table's own matches: what window correlation gives where a plain top stands out of
    nothing (a low one) or is matched only as the table around it."""
    points, left, right = grid_matches(RIG, None, 0.05, 1)
    refused = find_correlation_area(points, POSE, CONFIG, float(left.P[0, 2] - right.P[0, 2]))
    assert refused.status == NO_OBJECT, refused.reason
    return points, left, right, refused


def with_images(points, left_image, right_image):
    return dataclasses.replace(points, left_image=left_image, right_image=right_image)


def face_centre(area):
    return np.average(area.xyz_world, axis=0, weights=area.point_weights())


@pytest.mark.parametrize('height', [0.005, 0.03])
def test_a_plain_disc_is_found_in_the_images_at_its_height(height):
    disc = Box((0.2, 0.15), 0.04, height, round=True)
    points, left, right, refused = bare_table_matches()
    left_image, right_image, _, _, _ = plain_box_pair(RIG, disc, top_grey=200.0)
    found = plain_object_from_image(refused, with_images(points, left_image, right_image), left,
                                    right, POSE, CONFIG)
    assert found is not None and found.ok
    assert found.outline == OUTLINE_IMAGE
    assert found.top_height == pytest.approx(height, abs=0.0015)
    assert np.linalg.norm(face_centre(found) - [*disc.centre_xy, height]) < 0.002


def test_step_one_gives_a_plain_disc_its_face_when_nothing_stands_out():
    disc = Box((0.2, 0.15), 0.04, 0.005, round=True)
    points, left, right, _ = bare_table_matches()
    left_image, right_image, _, _, _ = plain_box_pair(RIG, disc, top_grey=200.0)
    area = decision_area(with_images(points, left_image, right_image), left, right, POSE,
                         CONFIG)
    assert area.ok, area.reason
    assert area.look == LOOK_PLAIN_OBJECT
    assert np.linalg.norm(face_centre(area) - [*disc.centre_xy, 0.005]) < 0.002
    # Without the right image there is no height to take it at: the refusal stands.
    alone = decision_area(with_images(points, left_image, None), left, right, POSE, CONFIG)
    assert alone.status == NO_OBJECT


def test_a_plain_patch_printed_on_the_table_is_no_object():
    patch = Box((0.2, 0.15), 0.04, 0.0)
    points, left, right, refused = bare_table_matches()
    pair = with_images(points, *plain_box_pair(RIG, patch, top_grey=200.0)[:2])
    assert plain_object_from_image(refused, pair, left, right, POSE, CONFIG) is None
    # It is refused for its height alone: its rim aligns at the surface's.
    on_surface = plain_object_from_image(refused, pair, left, right, POSE,
                                         dataclasses.replace(CONFIG, min_object_height_m=0.0))
    assert on_surface is not None and on_surface.top_height < 0.001


def test_two_plain_objects_are_not_told_apart():
    first, second = Box((0.2, 0.15), 0.04, 0.03), Box((0.28, 0.1), 0.04, 0.02, round=True)
    points, left, right, refused = bare_table_matches()
    # The same table and sensor noise (one seed) in all three pairs: each object's pixels are
    # the ones its pair changes.
    table = plain_box_pair(RIG, Box((0.2, 0.15), 0.0, 0.0), top_grey=200.0)[:2]
    one = plain_box_pair(RIG, first, top_grey=200.0)[:2]
    other = plain_box_pair(RIG, second, top_grey=60.0)[:2]
    both = [RectifiedImage(np.where(a.pixels != bare.pixels, a.pixels, b.pixels))
            for a, b, bare in zip(one, other, table, strict=True)]
    for single in (one, other):
        assert plain_object_from_image(refused, with_images(points, *single), left, right, POSE,
                                       CONFIG) is not None
    assert plain_object_from_image(refused, with_images(points, *both), left, right, POSE,
                                   CONFIG) is None


def test_a_plain_surface_shows_no_object():
    points, left, right, refused = bare_table_matches()
    rng = np.random.default_rng(1)
    plain = [RectifiedImage(np.clip(np.round(120.0 + rng.normal(0.0, 1.5, (left.height,
                                                                            left.width))),
                                    0, 255).astype(np.uint8)) for _ in range(2)]
    assert plain_object_from_image(refused, with_images(points, *plain), left, right, POSE,
                                   CONFIG) is None


@pytest.mark.parametrize('shape', [(0, 0), (1, 640), (480,)])
def test_an_empty_or_malformed_image_is_no_object(shape):
    points, left, right, refused = bare_table_matches()
    broken = RectifiedImage(np.zeros(shape, np.uint8))
    good = plain_box_pair(RIG, Box((0.2, 0.15), 0.04, 0.03), top_grey=200.0)[0]
    for pair in ((broken, good), (good, broken)):
        assert plain_object_from_image(refused, with_images(points, *pair), left, right, POSE,
                                       CONFIG) is None


def scattered_plain_face(box, matched_height):
    """The face a plain top's matches give (its rim: plain_rim_px) at a matched height, as
    CorrelationArea.scattered_face holds it, with the pair's matches."""
    points, left, right = grid_matches(RIG, box, 0.05, 1, image=True, plain_rim_px=5)
    area = find_correlation_area(points, POSE, CONFIG, float(left.P[0, 2] - right.P[0, 2]))
    face = area.face_in_pieces if area.face_in_pieces is not None else area.scattered_face
    assert face is not None, area.reason
    return dataclasses.replace(face, top_height=matched_height), points, left, right


@pytest.mark.parametrize('wall_grey', [70.0, 200.0])
def test_a_scattered_plain_face_is_taken_at_its_matched_height_where_both_images_agree(
        wall_grey):
    # With walls of the top's grey the plain region reaches down them to the table, and
    # plain_top_height finds no clear height; the matched height, where the region's rim
    # lies in both images far better than on the surface, is the top's.
    box = Box((0.2, 0.15), 0.04, 0.03)
    face, points, left, right = scattered_plain_face(box, 0.0305)
    images = plain_box_pair(RIG, box, top_grey=200.0, wall_grey=wall_grey)[:2]
    found = plain_top_at_matched_height(face, with_images(points, *images), left, right, POSE,
                                        CONFIG)
    assert found is not None and found.ok
    assert found.top_height == face.top_height
    assert np.linalg.norm(face_centre(found) - [*box.centre_xy, 0.0305]) < 0.002


@pytest.mark.parametrize('wall_grey', [200.0, 70.0])
def test_a_plain_face_taken_whole_loses_a_side_wall_of_its_grey(wall_grey):
    # The face taken whole from the plain region at its matched height: with walls of the
    # top's grey the region reaches down the nearer walls to the table, and its pixels cut
    # with the top's plane lie beyond the rim toward the cameras; cut above its own foot it is
    # the top. With walls of another grey the region is the top alone, and stays whole.
    box = Box((0.2, 0.15), 0.04, 0.03)
    face, points, left, right = scattered_plain_face(box, 0.03)
    left_image, right_image = plain_box_pair(RIG, box, top_grey=200.0, wall_grey=wall_grey)[:2]
    whole = plain_face_from_image(face, left_image, left, right, POSE, CONFIG.min_points,
                                  CONFIG.max_object_across_m)
    assert whole is not None and whole.ok
    cut = plain_face_without_side_wall(whole, with_images(points, left_image, right_image),
                                       left, right, POSE, CONFIG)
    true_centre = [*box.centre_xy, 0.03]
    if wall_grey == 200.0:
        assert np.linalg.norm(face_centre(whole) - true_centre) > 0.004
        assert np.linalg.norm(face_centre(cut) - true_centre) < 0.002
    else:
        assert cut is whole
        assert np.linalg.norm(face_centre(whole) - true_centre) < 0.002


@pytest.mark.parametrize('kept_share', [0.6, 0.7])
def test_a_plain_region_that_is_mostly_wall_gives_no_face(monkeypatch, kept_share):
    # The box's walls of the top's grey take a third of its plain region (the top keeps 0.67
    # of it). Where that is a wall's strip (MIN_KEPT_SHARE 0.6) the face is cut to the top;
    # where it is more than a strip (0.7), the region is mostly wall and gives no face, not
    # the whole region, whose centre lies beyond the top's rim.
    box = Box((0.2, 0.15), 0.04, 0.03)
    face, points, left, right = scattered_plain_face(box, 0.03)
    left_image, right_image = plain_box_pair(RIG, box, top_grey=200.0, wall_grey=200.0)[:2]
    whole = plain_face_from_image(face, left_image, left, right, POSE, CONFIG.min_points,
                                  CONFIG.max_object_across_m)
    assert whole is not None
    monkeypatch.setattr(plain_object, 'MIN_KEPT_SHARE', kept_share)
    cut = plain_face_without_side_wall(whole, with_images(points, left_image, right_image),
                                       left, right, POSE, CONFIG)
    if kept_share == 0.6:
        assert cut is not None and cut is not whole
    else:
        assert cut is None


def test_a_plain_patch_on_the_table_is_not_raised_to_a_scattered_faces_height():
    # A plain patch printed on the table where the left image would show a top 30 mm high,
    # and matches around it that claim that top: the patch's rim lies in both images where
    # the table's does, not 30 mm up.
    box = Box((0.2, 0.15), 0.04, 0.03)
    face, points, left, right = scattered_plain_face(box, 0.03)
    camera = POSE[:3, 3]
    along = camera[2] / (camera[2] - box.height)  # the left ray through the top, to the table
    under = camera[:2] + along * (np.asarray(box.centre_xy) - camera[:2])
    patch = Box(tuple(under), box.size * along, 0.0)
    images = plain_box_pair(RIG, patch, top_grey=200.0)[:2]
    assert plain_top_at_matched_height(face, with_images(points, *images), left, right, POSE,
                                       CONFIG) is None


@pytest.mark.parametrize('refused_face', ['scattered_face', 'face_in_pieces'])
def test_a_plain_object_that_does_not_hold_the_face_the_matches_found_is_not_taken(
        refused_face):
    # The matches found a face (refused for its scatter, or in pieces) where a plain top's rim
    # would be, and the images show a plain object elsewhere: a plain patch printed on a
    # textured top is such an object, at the top's height, off its centre.
    points, left, right, refused = bare_table_matches()
    face, _, _, _ = scattered_plain_face(Box((0.2, 0.15), 0.04, 0.03), 0.03)
    images = plain_box_pair(RIG, Box((0.3, 0.05), 0.04, 0.03), top_grey=200.0)[:2]
    alone = plain_object_from_image(refused, with_images(points, *images), left, right, POSE,
                                    CONFIG)
    assert alone is not None and alone.ok  # the object itself is found...
    with_face = dataclasses.replace(refused, **{refused_face: face})
    assert plain_object_from_image(with_face, with_images(points, *images), left, right, POSE,
                                   CONFIG) is None  # ...but it is not the face matched
    # The face's own plain top holds its rim's matches, and is taken.
    same = plain_box_pair(RIG, Box((0.2, 0.15), 0.04, 0.03), top_grey=200.0)[:2]
    held = plain_object_from_image(with_face, with_images(points, *same), left, right, POSE,
                                   CONFIG)
    assert held is not None and held.ok


def test_a_scattered_face_that_no_plain_region_holds_is_not_taken():
    box = Box((0.2, 0.15), 0.04, 0.03)
    face, points, left, right = scattered_plain_face(box, 0.03)
    elsewhere = plain_box_pair(RIG, Box((0.3, 0.05), 0.04, 0.03), top_grey=200.0)[:2]
    assert plain_top_at_matched_height(face, with_images(points, *elsewhere), left, right, POSE,
                                       CONFIG) is None
    assert plain_top_at_matched_height(face, with_images(points, elsewhere[0], None), left,
                                       right, POSE, CONFIG) is None


def test_a_sliver_of_a_plain_tops_rim_gives_the_whole_top():
    # One arc of the rim, matched at the top's height: the plain region it bounds is the top.
    box = Box((0.2, 0.15), 0.04, 0.03)
    face, points, left, right = scattered_plain_face(box, 0.03)
    arc = face.u_left < np.percentile(face.u_left, 15)
    sliver = dataclasses.replace(face, u_left=face.u_left[arc], v_left=face.v_left[arc],
                                 u_right=face.u_right[arc], xyz_world=face.xyz_world[arc],
                                 score=face.score[arc], weight=None)
    images = plain_box_pair(RIG, box, top_grey=200.0)[:2]
    found = plain_top_at_matched_height(sliver, with_images(points, *images), left, right,
                                        POSE, CONFIG)
    assert found is not None
    assert np.linalg.norm(face_centre(found) - [*box.centre_xy, 0.03]) < 0.002
    assert len(found.u_left) > 5 * np.count_nonzero(arc)  # the whole top, not the arc


@pytest.mark.parametrize('matched_height', [0.022, 0.04])
def test_a_scattered_plain_face_is_not_taken_at_a_height_both_images_put_elsewhere(
        matched_height):
    # Matches that agree on a height 8-10 mm off the top's: the region's rim carried by that
    # height still lies on the right image's rim far better than carried by the surface's,
    # yet better still at the top's own height; the matched height is not confirmed.
    box = Box((0.2, 0.15), 0.04, 0.03)
    face, points, left, right = scattered_plain_face(box, matched_height)
    images = plain_box_pair(RIG, box, top_grey=200.0)[:2]
    assert plain_top_at_matched_height(face, with_images(points, *images), left, right, POSE,
                                       CONFIG) is None
