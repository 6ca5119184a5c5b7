"""The object among the regions above the surface (object_segmentation.py): the area test, and
a textured object on a plain table."""

import dataclasses
import math

import numpy as np
import pytest
from grid_scenes import Box, grid_matches
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import special
from stereo_fuzzy_perception.core.best_point.correlation_area import (
    LOOK_MATCHES,
    LOOK_TEXTURED_REGION,
    NO_OBJECT,
    STATUS_OK,
    TOO_FEW_POINTS,
    AreaConfig,
    CorrelationArea,
    _measured_points,
    _object_area,
    find_correlation_area,
    find_textured_area,
)
from stereo_fuzzy_perception.core.best_point.object_segmentation import (
    choose_object,
    choose_textured_object,
    plausible_average,
    textured_regions,
    top_height,
    top_mode,
)
from stereo_fuzzy_perception.core.best_point.point_selectors import decision_area
from stereo_fuzzy_perception.core.best_point.work_surface import SURFACE_PLAIN
from stereo_fuzzy_perception.core.camera_model import CameraCalibration
from stereo_fuzzy_perception.core.matched_points import MatchedPoints, RectifiedImage
from stereo_fuzzy_perception.core.rig_geometry import StereoRig
from stereo_fuzzy_perception.simulation.synthetic_scenes import (
    default_camera_matrix,
    rectified_calibration,
)

# 0.8 m from the surface along the optical axis, 10 cm baseline (as test_correlation_area)
FAR_RIG = StereoRig(baseline_m=0.10, alpha_deg=30.0, x0_m=0.2, y0_m=-0.25,
                    z0_m=0.8 * math.cos(math.radians(30.0)), vergence_deg=6.0)
NEAR_RIG = StereoRig(baseline_m=0.05, alpha_deg=20.0, theta_deg=10.0, x0_m=0.22, y0_m=-0.05,
                     z0_m=0.3, vergence_deg=2.0)
RIGS = {'default': StereoRig(), 'far': FAR_RIG, 'near': NEAR_RIG}
DEFAULTS = AreaConfig()
NO_AREA_TEST = AreaConfig(area_top_sigmas=0.0)


def area_in(rig: StereoRig, box: Box | None, noise_px: float, stride: int = 1,
            config: AreaConfig = DEFAULTS, seed: int = 0) -> CorrelationArea:
    points, left, right = grid_matches(rig, box, noise_px, stride, seed=seed)
    return find_correlation_area(points, rig.world_from_left_camera(), config,
                                 float(left.P[0, 2] - right.P[0, 2]))


def centre_error_m(area: CorrelationArea, box: Box) -> float:
    centre = np.average(area.xyz_world[:, :2], axis=0, weights=area.point_weights())
    return float(np.hypot(*(centre - box.centre_xy)))


# One region of 10 averaging squares (100 points of 10 each) with a median below object_sigmas,
# one of a single square with the same median.
SQUARE_POINTS = 10.0
LABELS = np.array([1] * 100 + [2] * 10 + [0] * 10)
Z_SCORES = np.concatenate([np.full(110, 3.4), np.zeros(10)])
SIGMAS = np.full(120, 0.001)


def heights_with_top(top_m: float) -> np.ndarray:
    return np.concatenate([np.full(110, top_m), np.zeros(10)])


def test_a_large_region_is_an_object_by_its_area_when_its_top_stands_out():
    found = choose_object(LABELS, 2, Z_SCORES, heights_with_top(0.0035), SIGMAS, 5.0, 2.0, 5,
                          SQUARE_POINTS, 3.0)
    assert (found.label, found.objects, found.points) == (1, 1, 100), (
        'expected the region of 10 squares (median 3.4 * sqrt(10) > 5) only')
    assert found.top_m == pytest.approx(0.0035)


def test_the_area_test_needs_its_own_higher_top():
    # 2.5 sigmas: enough for a region high on its own (2), not for one found by its area (3)
    low = choose_object(LABELS, 2, Z_SCORES, heights_with_top(0.0025), SIGMAS, 5.0, 2.0, 5,
                        SQUARE_POINTS, 3.0)
    assert low.label == 0 and low.objects == 0
    high_on_its_own = choose_object(LABELS, 2, np.full(120, 5.5), heights_with_top(0.0025),
                                    SIGMAS, 5.0, 2.0, 5, SQUARE_POINTS, 3.0)
    assert high_on_its_own.label == 1, 'expected the 2 sigma top of the plain test'


def test_without_the_area_test_only_the_median_counts():
    for square_points, area_top_sigmas in ((0.0, 3.0), (SQUARE_POINTS, 0.0)):
        found = choose_object(LABELS, 2, Z_SCORES, heights_with_top(0.0035), SIGMAS, 5.0, 2.0,
                              5, square_points, area_top_sigmas)
        assert found.label == 0, f'area test off ({square_points}, {area_top_sigmas})'



def test_no_region_lower_than_the_lowest_object_is_one():
    # The same region passes both sigma tests with a top of 3.5 mm (the first test above);
    # below min_top_m it is the surface's own pattern, however far it stands out.
    kept = choose_object(LABELS, 2, Z_SCORES, heights_with_top(0.0035), SIGMAS, 5.0, 2.0, 5,
                         SQUARE_POINTS, 3.0, min_top_m=0.003)
    assert kept.label == 1
    low = choose_object(LABELS, 2, Z_SCORES, heights_with_top(0.0035), SIGMAS, 5.0, 2.0, 5,
                        SQUARE_POINTS, 3.0, min_top_m=0.004)
    assert (low.label, low.objects) == (0, 0)


def tall_plain_object_region() -> np.ndarray:
    """Return the heights [m] of a region around a tall object with a poorly matched top: the
    surface at its foot (600 points), wall and mismatches anywhere up to 45 mm (250), and the
    top's own matches scattered around 48 mm (100)."""
    rng = np.random.default_rng(7)
    return np.concatenate([rng.normal(0.0005, 0.0005, 600), rng.uniform(0.002, 0.045, 250),
                           rng.normal(0.048, 0.0015, 100)])


@pytest.mark.parametrize('median_sigmas, is_object', [(30.0, True), (15.0, False)])
def test_a_tall_region_whose_densest_heights_are_its_foot_has_its_top_from_what_stands_up(
        median_sigmas, is_object):
    heights = tall_plain_object_region()
    found = choose_object(np.ones(len(heights), dtype=np.int64), 1,
                          np.full(len(heights), median_sigmas), heights,
                          np.full(len(heights), 0.0005), 5.0, 2.0, 20, 10.0, 3.0, 0.002)
    # Its densest heights are the surface's: a top of half a millimetre, no object, unless
    # the region stands out by far more than object_sigmas (TALL_REGION_SHARE times)
    assert (found.label == 1) == is_object, found
    if is_object:
        assert found.top_m == pytest.approx(0.048, abs=0.0015)  # its matches scatter by 1.5 mm


@pytest.mark.parametrize('rig', ['default', 'near'])
@pytest.mark.parametrize('stride', [1, 3])
def test_a_flat_label_on_the_table_is_no_object(rig, stride):
    # 60 mm square, 1.5 mm high, matched with 0.05 px of noise: dozens of sigmas above the
    # surface on these rigs, and still lower than any object (min_object_height_m, 2 mm).
    label = Box((0.2, 0.15), 0.06, 0.0015)
    area = area_in(RIGS[rig], label, 0.05, stride)
    assert area.status == NO_OBJECT, f'expected no object, got {area.status}: {area.reason}'
    assert 'min_object_height_m=0.002' in area.reason
    found = area_in(RIGS[rig], label, 0.05, stride,
                    config=dataclasses.replace(DEFAULTS, min_object_height_m=0.0))
    assert found.status == STATUS_OK, f'expected the label found without the limit: {found.reason}'


@pytest.mark.parametrize('side_m, refused', [(0.014, True), (0.02, False)])
def test_a_face_smaller_in_the_image_than_any_object_is_refused(side_m, refused):
    # On the default rig a 14 mm top covers about 80 px of the left image, a 20 mm one about
    # 290 px: an object's top covers at least MIN_OBJECT_AREA_PX (200 px), the size of a blob
    # of mismatches on a bare textured table. The width test (min_object_across_m) is off, so
    # that only the area decides.
    rig = RIGS['default']
    points, left, right = grid_matches(rig, Box((0.2, 0.15), side_m, 0.04), 0.05, 1)
    area = decision_area(points, left, right, rig.world_from_left_camera(),
                         dataclasses.replace(DEFAULTS, min_object_across_m=0.0))
    if refused:
        assert area.status == NO_OBJECT and 'less than any object' in area.reason, area.reason
    else:
        assert area.status == STATUS_OK, area.reason
        assert area.look == LOOK_MATCHES

@settings(max_examples=30, deadline=None)
@given(rig=st.sampled_from(sorted(RIGS)), stride=st.sampled_from([1, 3]),
       noise_px=st.floats(0.03, 0.8), seed=st.integers(0, 2 ** 31 - 1))
def test_a_noisy_table_alone_never_gives_an_object(rig, stride, noise_px, seed):
    area = area_in(RIGS[rig], None, noise_px, stride, seed=seed)
    assert area.status == NO_OBJECT, (
        f'expected no object on a bare table ({rig} rig, stride {stride}, noise {noise_px:.2f} '
        f'px, seed {seed}), got {area.status}: {area.reason}')


@settings(max_examples=20, deadline=None)
@given(diameter_m=st.floats(0.03, 0.08), noise_px=st.floats(0.05, 0.12),
       stride=st.sampled_from([1, 3]), seed=st.integers(0, 2 ** 31 - 1))
def test_a_disc_5_mm_high_at_0_8_m_is_always_found(diameter_m, noise_px, stride, seed):
    disc = Box((0.2, 0.15), diameter_m, 0.005, round=True)
    area = area_in(FAR_RIG, disc, noise_px, stride, seed=seed)
    assert area.status == STATUS_OK, (
        f'expected the disc ({1000 * diameter_m:.0f} mm, noise {noise_px:.2f} px, stride '
        f'{stride}, seed {seed}) found: {area.reason}')
    assert area.top_height == pytest.approx(0.005, abs=0.0015)
    # A face one or two sigmas of a point's noise above the table: its centre scatters by a few
    # millimetres; a bias of a centimetre does not pass.
    assert centre_error_m(area, disc) < 0.006


@pytest.mark.parametrize('seed', [0, 3])
def test_a_low_disc_in_noise_is_found_by_its_area(seed):
    # 5 mm high, 30 mm across, 0.8 m away, 0.2 px of disparity noise: its region's median is
    # below object_sigmas (about 4.5 sigmas), the region covers several averaging squares
    disc = Box((0.2, 0.15), 0.03, 0.005, round=True)
    without = area_in(FAR_RIG, disc, 0.2, seed=seed, config=NO_AREA_TEST)
    assert without.status == NO_OBJECT, 'expected a disc the plain median test misses'
    area = area_in(FAR_RIG, disc, 0.2, seed=seed)
    assert area.status == STATUS_OK, area.reason
    assert area.object_height_sigmas < DEFAULTS.object_sigmas
    assert centre_error_m(area, disc) < 0.003


@pytest.mark.parametrize('seed', [0, 5])
def test_a_low_wide_disc_is_found_over_wider_squares(seed):
    # 5 mm high, 70 mm across, 0.8 m away, 0.25 px of disparity noise: over squares of
    # smoothing_px no region stands out as an object, over squares twice as wide the disc does
    disc = Box((0.2, 0.15), 0.07, 0.005, round=True)
    points, left, right = grid_matches(FAR_RIG, disc, 0.25, seed=seed)
    shift = float(left.P[0, 2] - right.P[0, 2])
    pose = FAR_RIG.world_from_left_camera()
    first, none_stood_out = _object_area(_measured_points(points, pose, DEFAULTS, shift),
                                         DEFAULTS, DEFAULTS.smoothing_px)
    assert first.status == NO_OBJECT and none_stood_out, first.reason
    area = find_correlation_area(points, pose, DEFAULTS, shift)
    assert area.status == STATUS_OK, area.reason
    assert area.top_height == pytest.approx(0.005, abs=0.0015)
    assert centre_error_m(area, disc) < 0.003


def test_a_refused_region_names_the_area_test():
    area = area_in(FAR_RIG, None, 0.3, seed=5)
    assert area.status == NO_OBJECT
    assert 'area_top_sigmas=3' in area.reason and 'squares' in area.reason, area.reason
    assert area.reason.endswith('(nor over squares of 31 px)'), area.reason
    off = area_in(FAR_RIG, None, 0.3, seed=5, config=NO_AREA_TEST)
    assert 'area_top_sigmas' not in off.reason


def test_a_negative_area_top_is_a_configuration_error():
    assert AreaConfig(area_top_sigmas=-1.0).problem() == (
        'area_top_sigmas=-1.0 must not be negative')
    assert dataclasses.replace(AreaConfig(), area_top_sigmas=0.0).problem() is None


def test_plausible_average_leaves_out_what_no_object_reaches():
    u = np.array([0.0, 1.0, 2.0, 10.0])
    v = np.zeros(4)
    values = np.array([1.0, 3.0, 100.0, 7.0])
    plausible = np.array([True, True, False, False])
    mean = plausible_average(u, v, values, plausible, 1.0, 5.0)
    assert mean[:3] == pytest.approx([2.0, 2.0, 2.0]), 'expected the mismatch left out'
    assert mean[3] == -np.inf, 'expected no average where no plausible match is near'


def with_mismatches_above(points: MatchedPoints, disparity_shift: float, scale: float
                          ) -> MatchedPoints:
    """Return the points with a patch of the image moved toward the camera (mismatches)."""
    patch = ((points.u_left > 250) & (points.u_left < 330) & (points.v_left > 150)
             & (points.v_left < 230))
    xyz = points.xyz.copy()
    xyz[patch] *= scale
    disparity = points.u_left - points.u_right - disparity_shift
    u_right = np.where(patch, points.u_left - disparity_shift - disparity / scale,
                       points.u_right)
    return dataclasses.replace(points, xyz=xyz, u_right=u_right)


@pytest.mark.parametrize('plausible', [False, True])
def test_mismatches_high_above_a_bare_table_are_no_object(plausible):
    points, left, right = grid_matches(FAR_RIG, None, 0.1, 1, seed=11)
    shift = float(left.P[0, 2] - right.P[0, 2])
    lifted = with_mismatches_above(points, shift, 0.75)
    area = find_correlation_area(lifted, FAR_RIG.world_from_left_camera(),
                                 AreaConfig(plausible_average=plausible), shift)
    assert area.status == NO_OBJECT, area.reason


def test_plausible_average_finds_a_box_beside_mismatches():
    box = Box((0.12, 0.1), 0.05, 0.03)
    points, left, right = grid_matches(FAR_RIG, box, 0.1, 1, seed=12)
    shift = float(left.P[0, 2] - right.P[0, 2])
    lifted = with_mismatches_above(points, shift, 0.75)
    area = find_correlation_area(lifted, FAR_RIG.world_from_left_camera(),
                                 AreaConfig(plausible_average=True), shift)
    assert area.status == STATUS_OK, area.reason
    assert area.top_height == pytest.approx(0.03, abs=0.002)
    assert centre_error_m(area, box) < 0.003


def plain_table_scene(rig: StereoRig, object_box: Box, lift_m: float, stride: int,
                      seed: int = 0, textured: bool = True
                      ) -> tuple[MatchedPoints, float]:
    """Return matches of a plain table with a textured object, and the disparity shift.

    The object's matches are confident and stand lift_m above the table (0: a printed patch
    lying on it). The table's windows hold sensor noise: most of its matches score low, and
    one in six is a confident mismatch anywhere from 20 mm below the table to 60 mm above it,
    as on the rendered low-texture tables. The left image is plain (sensor noise of 1 grey
    level) but for the object's pixels, textured unless `textured` is False.
    """
    flat = dataclasses.replace(object_box, height=max(lift_m, 1e-4))
    pixels_grid, left, right = grid_matches(rig, flat, 0.0, 1)
    pose = rig.world_from_left_camera()
    grid_world = pixels_grid.xyz @ pose[:3, :3].T + pose[:3, 3]
    on_object = flat.covers(grid_world[:, 0], grid_world[:, 1])
    rng = np.random.default_rng(seed)
    picture = 60.0 + rng.normal(0.0, 1.0, (left.height, left.width))
    if textured:
        rows = pixels_grid.v_left[on_object].astype(int)
        columns = pixels_grid.u_left[on_object].astype(int)
        picture[rows, columns] += 60.0 + rng.normal(0.0, 25.0, len(rows))
    image = RectifiedImage(np.clip(picture, 0, 255).astype(np.uint8))
    points, _, _ = grid_matches(rig, flat, 0.05, stride, seed=seed)
    points.left_image = image
    world = points.xyz @ pose[:3, :3].T + pose[:3, 3]
    table = np.flatnonzero(~flat.covers(world[:, 0], world[:, 1]))
    mismatches = table[rng.random(len(table)) < 1.0 / 6.0]
    moved_to_heights(points, pose, mismatches, rng.uniform(-0.02, 0.06, len(mismatches)))
    points.score[:] = 0.9
    points.score[np.setdiff1d(table, mismatches)] = rng.uniform(0.25, 0.45,
                                                                 len(table) - len(mismatches))
    if lift_m == 0.0:
        moved_to_heights(points, pose, np.flatnonzero(flat.covers(world[:, 0], world[:, 1])),
                         0.0)
    return points, float(left.P[0, 2] - right.P[0, 2])


def moved_to_heights(points: MatchedPoints, pose: np.ndarray, chosen: np.ndarray,
                     heights: np.ndarray | float) -> None:
    """Move the chosen matches along their rays to the given heights above z = 0 of world."""
    rays = points.xyz[chosen] @ pose[:3, :3].T
    scale = (heights - pose[2, 3]) / rays[:, 2]
    disparity = points.u_left[chosen] - points.u_right[chosen]
    points.xyz[chosen] *= scale[:, np.newaxis]
    points.u_right[chosen] = points.u_left[chosen] - disparity / scale


@pytest.mark.parametrize('stride', [1, 3])
def test_a_textured_disc_on_a_plain_table_is_found_in_the_image(stride):
    # 5 mm high, 50 mm across, 0.8 m away: the plain table's confident mismatches set the
    # unit of the averaged heights, and the disc does not stand out of it; the image shows it
    # as the one textured region, and its own matches stand a few mm above the table.
    disc = Box((0.2, 0.15), 0.05, 0.005, round=True)
    points, shift = plain_table_scene(FAR_RIG, disc, disc.height, stride)
    pose = FAR_RIG.world_from_left_camera()
    without_image = find_correlation_area(dataclasses.replace(points, left_image=None), pose,
                                          DEFAULTS, shift)
    assert without_image.status == NO_OBJECT, (
        f'expected the disc hidden without the image, got {without_image.status}')
    assert without_image.surface.source == SURFACE_PLAIN
    area = find_correlation_area(points, pose, DEFAULTS, shift)
    assert area.status == STATUS_OK, area.reason
    assert area.top_height == pytest.approx(0.005, abs=0.001)
    assert centre_error_m(area, disc) < 0.002


@pytest.mark.parametrize('stride', [1, 3])
def test_a_textured_patch_lying_on_a_plain_table_is_no_object(stride):
    # The same disc's texture printed on the table, and the plain table alone: the textured
    # region's matches are at the table's height, and a plain image has no textured region.
    patch = Box((0.2, 0.15), 0.05, 0.005, round=True)
    pose = FAR_RIG.world_from_left_camera()
    for lift_m, textured in ((0.0, True), (0.005, False)):
        points, shift = plain_table_scene(FAR_RIG, patch, lift_m, stride, textured=textured)
        area = find_correlation_area(points, pose, DEFAULTS, shift)
        assert area.status == NO_OBJECT, (
            f'expected no object (lift {lift_m} m, textured {textured}), got {area.status}')
        assert area.reason.endswith('nor is a textured region of the image, its matches a '
                                    'median object_sigmas standard errors high)'), area.reason
        # the last look (point_selectors.decision_area) would look at the same regions again
        assert area.texture_tried
        assert not find_correlation_area(dataclasses.replace(points, left_image=None), pose,
                                         DEFAULTS, shift).texture_tried


def textured_region_heights(median_m: float, spread_m: float, matches: int = 810
                            ) -> np.ndarray:
    """Return heights with the given median and spread (MAD as a standard deviation)."""
    quantiles = (np.arange(matches) + 0.5) / matches
    return median_m + spread_m * np.sqrt(2.0) * special.erfinv(2.0 * quantiles - 1.0)


@pytest.mark.parametrize('median_m, spread_m, area_px, is_object', [
    (0.004, 0.002, 900, True),
    # 810 matches at stride 1 cover ten 9 x 9 windows, ten samples of the noise, not 810:
    # the standard error is 0.63 mm and 5 of them 3.2 mm
    (0.0025, 0.002, 900, False),
    (0.0015, 0.00001, 900, False),  # lower than any object (min_top_m)
    (0.004, 0.002, 150, False),  # a region smaller in the image than any object's top
])
def test_a_textured_region_is_an_object_by_its_height_in_standard_errors(
        median_m, spread_m, area_px, is_object):
    heights = textured_region_heights(median_m, spread_m)
    labels = np.ones(len(heights), dtype=np.int64)
    found = choose_textured_object(labels, np.array([10_000, area_px]), heights,
                                   np.full(len(heights), spread_m), 1.0, 9.0, 5.0, 20, 200.0,
                                   0.002)
    assert (found.label == 1) == is_object, found
    if is_object:
        assert found.top_m == pytest.approx(median_m, abs=0.0005)
        assert found.median_sigmas == pytest.approx(median_m / (spread_m / math.sqrt(10.0)),
                                                    rel=0.02)


def test_of_two_textured_objects_the_one_standing_out_most_is_chosen():
    # A plain table's sparse marks joined into one wide region: many matches, mismatched a
    # few millimetres up by chance (6 standard errors); beside it the disc's region, fewer
    # matches standing 12 standard errors out. The wide one's face would be longer than any
    # object.
    marks = textured_region_heights(0.0035, 0.003, matches=4000)
    disc = textured_region_heights(0.005, 0.0013, matches=900)
    heights = np.concatenate([marks, disc])
    labels = np.repeat([1, 2], [len(marks), len(disc)])
    found = choose_textured_object(labels, np.array([100_000, 40_000, 900]), heights,
                                   np.full(len(heights), 0.002), 1.0, 9.0, 5.0, 20, 200.0,
                                   0.002)
    assert found.label == 2, found
    assert found.objects == 2
    assert found.points == len(disc)
    assert found.median_sigmas == pytest.approx(0.005 / (0.0013 / math.sqrt(900 / 81)),
                                                rel=0.02)


@pytest.mark.parametrize('pixels', [np.zeros((0, 0), np.uint8), np.zeros((4, 5, 3), np.uint8)])
def test_an_image_without_pixels_or_of_colour_has_no_textured_region(pixels):
    labels, areas = textured_regions(RectifiedImage(pixels), np.arange(3.0), np.zeros(3))
    assert not labels.any() and list(areas) == [0]


@pytest.mark.parametrize('rig', sorted(RIGS))
@pytest.mark.parametrize('stride', [1, 3])
def test_a_bare_textured_table_with_its_image_gives_no_object(rig, stride):
    # The image is textured everywhere: its textured regions are the table, matched at its
    # own height, so the image finds no object where the heights found none.
    points, left, right = grid_matches(RIGS[rig], None, 0.3, stride, seed=2, image=True)
    assert points.left_image is not None
    area = find_correlation_area(points, RIGS[rig].world_from_left_camera(), DEFAULTS,
                                 float(left.P[0, 2] - right.P[0, 2]))
    assert area.status == NO_OBJECT, f'expected no object, got {area.status}: {area.reason}'
    assert area.reason.endswith('standard errors high)'), area.reason


def rectified_pair(rig: StereoRig) -> tuple[CameraCalibration, CameraCalibration]:
    """Return the left and right rectified calibrations grid_matches uses for rig."""
    return rectified_calibration(rig, default_camera_matrix(vertical_fov_deg=45.0))


@pytest.mark.parametrize('stride', [1, 3])
def test_a_box_refused_with_the_tables_mismatches_is_found_in_the_image(stride):
    # 40 mm high on the near rig: the grid's region takes the plain table's mismatches at the
    # top's height around it, and its face is longer than any object. Refused however the
    # face is looked at, the pair is looked at as the image's textured regions.
    box = Box((0.2, 0.15), 0.05, 0.04)
    rig = RIGS['near']
    points, shift = plain_table_scene(rig, box, box.height, stride)
    pose = rig.world_from_left_camera()
    first = find_correlation_area(points, pose, DEFAULTS, shift)
    assert first.status == NO_OBJECT and 'longer than any object' in first.reason, first.reason
    assert not first.texture_tried, 'a region of the grid stood out: the texture is still to see'
    area = decision_area(points, *rectified_pair(rig), pose, DEFAULTS)
    assert area.status == STATUS_OK, area.reason
    assert area.look == LOOK_TEXTURED_REGION  # the look that gave it, for benchmarks and logs
    assert area.top_height == pytest.approx(0.04, abs=0.001)
    assert centre_error_m(area, box) < 0.002
    assert find_textured_area(dataclasses.replace(points, left_image=None), pose, DEFAULTS,
                              shift) is None


def test_a_face_too_thin_at_a_coarse_stride_is_left_for_the_second_look():
    # 20 mm high on the near rig at stride 3: the face is found and has too few matches, a
    # refusal that the second look at stride 1 (second_look.py) answers with better matches
    # than the image's textured region at this stride.
    box = Box((0.2, 0.15), 0.05, 0.02)
    rig = RIGS['near']
    points, shift = plain_table_scene(rig, box, box.height, 3)
    pose = rig.world_from_left_camera()
    area = decision_area(points, *rectified_pair(rig), pose, DEFAULTS)
    assert area.status == TOO_FEW_POINTS, area.reason
    textured = find_textured_area(points, pose, DEFAULTS, shift)
    assert textured is not None and textured.ok, 'expected the textured region there'
    # a row of NaN (a peer's) does not make the stride-3 grid look like stride 1
    points.u_left[0] = np.nan
    assert decision_area(points, *rectified_pair(rig), pose, DEFAULTS).status == TOO_FEW_POINTS


@pytest.mark.parametrize('seed', range(4))
def test_the_top_mode_is_the_centre_of_a_top_spread_wider_than_its_bins(seed):
    # A top whose heights spread by 1 mm, binned at a quarter of that, with a side wall below:
    # top_height's level lies on the upper side of the spread, top_mode at its centre.
    rng = np.random.default_rng(seed)
    heights = np.concatenate([0.05 + rng.normal(0.0, 0.001, 3000), rng.uniform(0.0, 0.05, 300)])
    sigmas = np.full(len(heights), 0.00025)
    level = top_height(heights, sigmas)
    assert level > 0.0505
    assert top_mode(heights, sigmas, level) == pytest.approx(0.05, abs=0.0002)


def test_the_top_mode_of_one_height_is_that_height():
    assert top_mode(np.array([0.03]), np.array([0.001]), 0.03) == 0.03
    # a start with nothing within its window stays where it is
    assert top_mode(np.array([0.03]), np.array([0.001]), 0.09) == 0.09
