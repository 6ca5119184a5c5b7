"""The correlation area, its border points and four areas (steps 1-3), on synthetic points."""

import dataclasses
import math

import numpy as np
import pytest
from grid_scenes import Box, grid_matches
from stereo_fuzzy_perception.core.best_point.correlation_area import (
    DEGENERATE_AREA,
    NO_OBJECT,
    NO_POINTS,
    STATUS_OK,
    TOO_FEW_POINTS,
    UNCERTAIN_TOP,
    AreaConfig,
    CorrelationArea,
    CorrelationAreaError,
    find_correlation_area,
)
from stereo_fuzzy_perception.core.best_point.four_areas import split_into_areas
from stereo_fuzzy_perception.core.best_point.object_segmentation import (
    across_m,
    hull_fill,
    width_m,
)
from stereo_fuzzy_perception.core.best_point.work_surface import SURFACE_MEASURED, SURFACE_PLAIN
from stereo_fuzzy_perception.core.matched_points import MatchedPoints
from stereo_fuzzy_perception.core.rig_geometry import StereoRig
from stereo_fuzzy_perception.simulation.synthetic_scenes import GeometricSceneSource

RIG = StereoRig()
WORLD_FROM_LEFT = RIG.world_from_left_camera()
# 0.8 m from the surface along the optical axis, 10 cm baseline
FAR_RIG = StereoRig(baseline_m=0.10, alpha_deg=30.0, x0_m=0.2, y0_m=-0.25,
                    z0_m=0.8 * math.cos(math.radians(30.0)), vergence_deg=6.0)
NEAR_RIG = StereoRig(baseline_m=0.05, alpha_deg=20.0, theta_deg=10.0, x0_m=0.22, y0_m=-0.05,
                     z0_m=0.3, vergence_deg=2.0)


DEFAULTS = AreaConfig()


def area_in(rig: StereoRig, box: Box | None, noise_px: float, stride: int = 1,
            config: AreaConfig = DEFAULTS, **scene) -> CorrelationArea:
    points, left, right = grid_matches(rig, box, noise_px, stride, **scene)
    return find_correlation_area(points, rig.world_from_left_camera(), config,
                                 float(left.P[0, 2] - right.P[0, 2]))


@pytest.mark.parametrize('rig', [RIG, FAR_RIG, NEAR_RIG], ids=['default', 'far', 'near'])
@pytest.mark.parametrize('stride', [1, 3])
@pytest.mark.parametrize('noise_px', [0.05, 0.2, 0.5])
def test_a_noisy_table_alone_has_no_object(rig, stride, noise_px):
    area = area_in(rig, None, noise_px, stride, seed=int(100 * noise_px) + stride)
    assert area.status == NO_OBJECT, f'expected no object, got {area.status} {area.reason}'
    assert 'no object on the work surface' in area.reason
    assert area.surface.source == SURFACE_MEASURED
    assert area.surface.disparity_sigma_px == pytest.approx(noise_px, rel=0.15)


@pytest.mark.parametrize('stride', [1, 3])
def test_a_disc_5_mm_high_at_0_8_m_is_found(stride):
    disc = Box((0.2, 0.15), 0.05, 0.005, round=True)
    area = area_in(FAR_RIG, disc, 0.1, stride)
    assert area.status == STATUS_OK, area.reason
    assert area.top_height == pytest.approx(0.005, abs=0.001)
    centre = np.average(area.xyz_world[:, :2], axis=0, weights=area.point_weights())
    assert np.hypot(*(centre - disc.centre_xy)) < 0.003
    inside = np.hypot(*(area.xyz_world[:, :2] - disc.centre_xy).T) <= 0.025 + 0.002
    assert inside.mean() > 0.97, 'expected the top face, not the surface around it'


@pytest.mark.parametrize('rig', [RIG, FAR_RIG, NEAR_RIG], ids=['default', 'far', 'near'])
@pytest.mark.parametrize('height', [0.02, 0.06])
def test_the_top_face_of_a_box_is_the_area(rig, height):
    box = Box((0.2, 0.1), 0.05, height)
    area = area_in(rig, box, 0.15, 1)
    assert area.status == STATUS_OK, area.reason
    assert area.top_height == pytest.approx(height, abs=0.001)
    grown = Box(box.centre_xy, box.size + 0.004, height)  # 2 mm of depth noise around it
    assert np.all(grown.covers(*area.xyz_world[:, :2].T)), 'expected only top-face points'
    centre = np.average(area.xyz_world[:, :2], axis=0, weights=area.point_weights())
    assert np.hypot(*(centre - box.centre_xy)) < 0.002, 'expected the weighted centre'


@pytest.mark.parametrize('offset_m, slope', [(0.004, (0.0, 0.0)), (-0.005, (0.008, -0.005)),
                                             (0.0, (-0.01, 0.0))])
def test_a_surface_off_the_rig_pose_is_measured_and_heights_follow_it(offset_m, slope):
    box = Box((0.2, 0.15), 0.05, 0.03)
    area = area_in(FAR_RIG, box, 0.1, 3, surface_z=offset_m, surface_slope=slope)
    assert area.status == STATUS_OK, area.reason
    surface = area.surface
    assert surface.source == SURFACE_MEASURED
    assert surface.slope_x == pytest.approx(slope[0], abs=5e-4)
    assert surface.slope_y == pytest.approx(slope[1], abs=5e-4)
    assert surface.offset_m == pytest.approx(offset_m, abs=0.001)
    # heights come from the measured surface, not from the rig pose: the box is 3 cm high
    # (it stands on z = offset_m; the tilted surface meets its foot only at x = y = 0)
    tilt_drop = slope[0] * 0.2 + slope[1] * 0.1  # the surface under the box's centre
    assert area.top_height == pytest.approx(0.03 - tilt_drop, abs=0.0015)


def test_wrong_matches_above_the_object_do_not_lift_its_top():
    box = Box((0.2, 0.15), 0.05, 0.03)
    points, left, right = grid_matches(RIG, box, 0.1, 1)
    rng = np.random.default_rng(5)
    world = (points.xyz @ WORLD_FROM_LEFT[:3, :3].T) + WORLD_FROM_LEFT[:3, 3]
    on_top = np.flatnonzero(world[:, 2] > 0.02)
    lifted = rng.choice(on_top, size=len(on_top) // 20, replace=False)  # 5 %, up to 15 mm
    factor = 1.0 - rng.uniform(0.005, 0.04, len(lifted))  # nearer along their rays
    points.xyz[lifted] *= factor[:, np.newaxis]
    area = find_correlation_area(points, WORLD_FROM_LEFT, AreaConfig())
    assert area.status == STATUS_OK
    assert area.top_height == pytest.approx(0.03, abs=0.0005)


def test_nan_and_infinite_rows_are_ignored():
    points, left, right = grid_matches(RIG, Box((0.2, 0.15), 0.05, 0.03), 0.1, 3)
    points.xyz[0, 1] = np.nan
    points.u_left[1] = np.inf
    points.score[2] = -np.inf
    area = find_correlation_area(points, WORLD_FROM_LEFT, AreaConfig())
    assert area.status == STATUS_OK
    assert area.points_in == len(points)
    assert area.points_valid <= len(points) - 3


def test_no_points_and_too_few_points_have_reasons():
    empty = find_correlation_area(MatchedPoints.empty(), WORLD_FROM_LEFT, AreaConfig())
    assert empty.status == NO_POINTS and 'none of 0' in empty.reason
    area = area_in(RIG, Box((0.2, 0.15), 0.05, 0.03), 0.1, 3, config=AreaConfig(
        min_points=1_000_000))
    assert area.status == NO_OBJECT and '1000000 points' in area.reason
    area = area_in(RIG, Box((0.2, 0.15), 0.05, 0.03), 0.1, 3, config=AreaConfig(
        min_points=20, top_band_sigmas=0.1))  # a band too thin to hold the face
    assert area.status == TOO_FEW_POINTS and 'min_points=20' in area.reason


def test_a_top_face_scattered_beyond_its_noise_is_uncertain_not_taken():
    box = Box((0.2, 0.15), 0.05, 0.03)
    # 0.8 m away, 0.5 px of disparity noise everywhere: the face's heights scatter by
    # millimetres, all of it the points' own noise: one level face, taken
    noisy = area_in(FAR_RIG, box, 0.5, 1, seed=3)
    assert noisy.status == STATUS_OK, noisy.reason
    assert 1000.0 * float(np.std(noisy.surface.heights(noisy.xyz_world.T))) > 2.0
    # the same face, its matches 4 mm off up and down (matched worse than the table): refused
    points, left, right = grid_matches(FAR_RIG, box, 0.05, 1, seed=3)
    world = points.xyz @ FAR_RIG.world_from_left_camera()[:3, :3].T
    on_face = world[:, 2] + FAR_RIG.world_from_left_camera()[2, 3] > 0.02
    rng = np.random.default_rng(4)
    world[on_face, 2] += rng.normal(0.0, 0.004, int(on_face.sum()))
    spoiled = dataclasses.replace(
        points, xyz=world @ FAR_RIG.world_from_left_camera()[:3, :3])
    shift = float(left.P[0, 2] - right.P[0, 2])
    refused = find_correlation_area(spoiled, FAR_RIG.world_from_left_camera(), DEFAULTS, shift)
    assert refused.status == UNCERTAIN_TOP, refused.reason
    assert "beyond what its points' noise" in refused.reason
    assert 'max_top_spread_m=0.002' in refused.reason
    assert 'not measured well enough' in refused.reason
    loose = find_correlation_area(spoiled, FAR_RIG.world_from_left_camera(),
                                  AreaConfig(max_top_spread_m=0.0), shift)
    assert loose.status == STATUS_OK, loose.reason
    # the refused face comes along, for a plain top's height from both images
    assert refused.scattered_face is not None and refused.face_in_pieces is None
    np.testing.assert_array_equal(refused.scattered_face.u_left, loose.u_left)


def test_a_top_face_in_pieces_is_uncertain_not_taken():
    points, left, right = grid_matches(RIG, Box((0.2, 0.15), 0.06, 0.03), 0.1, 1)
    world = (points.xyz @ WORLD_FROM_LEFT[:3, :3].T) + WORLD_FROM_LEFT[:3, 3]
    # a low-texture top: only its rim is matched (a ring 6 mm wide), the table all around
    inner = (np.abs(world[:, 0] - 0.2) < 0.024) & (np.abs(world[:, 1] - 0.15) < 0.024)
    ring = points.subset(~(inner & (world[:, 2] > 0.02)))
    shift = float(left.P[0, 2] - right.P[0, 2])
    area = find_correlation_area(ring, WORLD_FROM_LEFT, AreaConfig(), shift)
    assert area.status == UNCERTAIN_TOP, area.reason
    assert 'min_top_fill=0.5' in area.reason and 'in pieces' in area.reason
    allowed = find_correlation_area(ring, WORLD_FROM_LEFT, AreaConfig(min_top_fill=0.0), shift)
    assert allowed.status == STATUS_OK, allowed.reason


@pytest.mark.parametrize(('face_noise_mm', 'seed'), [(0.5, 0), (0.5, 2), (0.5, 3), (0.8, 1),
                                                     (0.8, 2), (0.8, 3)])
def test_a_top_matched_worse_than_the_table_comes_whole_at_its_mode(face_noise_mm, seed):
    # The table matched to 0.03 px, the top's heights spread by half a millimetre or more:
    # the densest upper level of the top lies on the upper side of that spread, and the band
    # below it holds only a third of the face: refused in pieces, with the face at the mode
    # of its heights, which passes every test (decision_area takes it when the image shows
    # no plain face).
    box = Box((0.2, 0.15), 0.06, 0.04)
    points, left, right = grid_matches(RIG, box, 0.03, 1, seed=seed)
    world = points.xyz @ WORLD_FROM_LEFT[:3, :3].T + WORLD_FROM_LEFT[:3, 3]
    on_face = world[:, 2] > 0.03
    rng = np.random.default_rng(seed + 10)
    world[on_face, 2] += rng.normal(0.0, face_noise_mm / 1000.0, int(on_face.sum()))
    spoiled = dataclasses.replace(points, xyz=(world - WORLD_FROM_LEFT[:3, 3])
                                  @ WORLD_FROM_LEFT[:3, :3])
    area = find_correlation_area(spoiled, WORLD_FROM_LEFT, DEFAULTS,
                                 float(left.P[0, 2] - right.P[0, 2]))
    if area.status == STATUS_OK:  # the band at the densest level held enough of the face
        at_mode = area
    else:
        assert area.status == UNCERTAIN_TOP and 'in pieces' in area.reason, area.reason
        assert area.face_in_pieces is not None and area.face_at_mode is not None
        at_mode = area.face_at_mode
        assert at_mode.status == STATUS_OK
        assert len(at_mode.u_left) > 1.5 * len(area.face_in_pieces.u_left)
    assert at_mode.top_height == pytest.approx(0.04, abs=0.0007)
    assert hull_fill(at_mode.u_left, at_mode.v_left, 1.0) >= DEFAULTS.min_top_fill


@pytest.mark.parametrize('step', [1, 3])
def test_hull_fill_is_one_for_a_solid_patch_and_small_for_a_ring(step):
    u, v = (grid.ravel() for grid in np.meshgrid(np.arange(0, 60, step),
                                                 np.arange(0, 45, step)))
    assert hull_fill(u, v, step) == pytest.approx(1.0)
    rim = (np.minimum(u, 57 - u) < 6) | (np.minimum(v, 42 - v) < 6)
    assert hull_fill(u[rim], v[rim], step) < 0.5
    assert hull_fill(u[:2], v[:2], step) == 1.0  # no outline to fill
    assert hull_fill(np.arange(10.0), np.zeros(10), step) <= 1.0  # a line of cells


def test_bad_configuration_names_the_value():
    with pytest.raises(CorrelationAreaError, match='min_top_fill=-0.1 must not be negative'):
        find_correlation_area(MatchedPoints.empty(), WORLD_FROM_LEFT,
                              AreaConfig(min_top_fill=-0.1))
    with pytest.raises(CorrelationAreaError, match='top_band_sigmas=0'):
        find_correlation_area(MatchedPoints.empty(), WORLD_FROM_LEFT,
                              AreaConfig(top_band_sigmas=0.0))
    with pytest.raises(CorrelationAreaError, match='object_sigmas=2'):
        find_correlation_area(MatchedPoints.empty(), WORLD_FROM_LEFT,
                              AreaConfig(object_sigmas=2.0))
    with pytest.raises(CorrelationAreaError, match='axis y'):
        find_correlation_area(MatchedPoints.empty(), WORLD_FROM_LEFT,
                              AreaConfig(workspace_min=(0, 0.3, 0), workspace_max=(0.4, 0.3, 1)))
    with pytest.raises(CorrelationAreaError, match='min_object_height_m=-0.001 must not be'):
        find_correlation_area(MatchedPoints.empty(), WORLD_FROM_LEFT,
                              AreaConfig(min_object_height_m=-0.001))
    with pytest.raises(CorrelationAreaError,
                       match='min_object_height_m=0.1 must be below max_object_height_m=0.1'):
        find_correlation_area(MatchedPoints.empty(), WORLD_FROM_LEFT,
                              AreaConfig(min_object_height_m=0.1))


def area_of(u, v, ur, world) -> CorrelationArea:
    n = len(u)
    return CorrelationArea(STATUS_OK, '', n, n, 1, n, 0.0, np.asarray(world, dtype=float),
                           np.asarray(u, dtype=float), np.asarray(v, dtype=float),
                           np.asarray(ur, dtype=float), np.ones(n))


def test_areas_are_numbered_as_in_fig4_and_ratios_use_each_principal_point():
    # one point near each corner of the bounding box, plus the centre (falls in area 4)
    u = [100, 100, 200, 200, 150]
    v = [50, 150, 50, 150, 100]
    ur = [60, 60, 160, 160, 110]
    world = [[0, 0, 0], [0, 1, 0], [1, 0, 0], [1, 1, 0], [9, 9, 9]]
    areas = split_into_areas(area_of(u, v, ur, world), (320.0, 240.0), (300.0, 240.0))
    assert areas.status == STATUS_OK
    assert list(areas.counts) == [1, 1, 1, 2]
    np.testing.assert_allclose(areas.centres_u_left, [100, 100, 200, 175])
    np.testing.assert_allclose(areas.centres_v_left, [50, 150, 50, 125])
    np.testing.assert_allclose(areas.d1, [np.hypot(220, 190), np.hypot(220, 90),
                                          np.hypot(120, 190), np.hypot(145, 115)])
    np.testing.assert_allclose(areas.d2, [np.hypot(240, 190), np.hypot(240, 90),
                                          np.hypot(140, 190), np.hypot(165, 115)])
    np.testing.assert_allclose(areas.ratio, areas.d1 / areas.d2)
    # border points: min u, max u, min v, max v (ties broken by the smallest v, then world)
    np.testing.assert_allclose(areas.border_points, [[0, 0, 0], [1, 0, 0], [0, 0, 0],
                                                     [0, 1, 0]])
    assert areas.border_distances[0] == pytest.approx(1.0)  # |min u - max u|, Eq. 9
    assert areas.border_distances[1] == pytest.approx(0.0)
    np.testing.assert_allclose(areas.union_centre((3, 4)), [(1 + 1 + 9) / 3, 10 / 3, 3])


def test_points_on_a_vertical_line_are_degenerate_not_an_error():
    count = 30
    area = area_of(np.full(count, 300.0), np.linspace(10, 200, count), np.full(count, 250.0),
                   np.zeros((count, 3)))
    areas = split_into_areas(area, (320.0, 240.0), (320.0, 240.0))
    assert areas.status == DEGENERATE_AREA
    assert '0 x 190 px' in areas.reason


def test_a_centre_on_the_right_principal_point_has_an_infinite_ratio():
    u = [100, 100, 200, 200]
    v = [50, 150, 50, 150]
    area = area_of(u, v, [300, 60, 160, 160], np.zeros((4, 3)))
    areas = split_into_areas(area, (320.0, 240.0), (300.0, 50.0))
    assert areas.status == STATUS_OK
    assert areas.d2[0] == 0.0 and areas.ratio[0] == np.inf
    assert np.all(np.isfinite(areas.ratio[1:]))


def test_an_empty_area_is_reported_but_not_degenerate():
    u = [100, 200, 200, 150]
    v = [50, 50, 150, 100]  # nothing in the bottom-left quarter
    area = area_of(u, v, [60, 160, 160, 110], np.eye(4, 3))
    areas = split_into_areas(area, (320.0, 240.0), (300.0, 240.0))
    assert areas.status == STATUS_OK
    assert list(areas.counts) == [1, 0, 1, 2]
    assert np.isnan(areas.ratio[1]) and np.all(np.isfinite(areas.ratio[[0, 2, 3]]))


@pytest.mark.parametrize('kind', ['circle', 'cylinder', 'cubic_rectangle', 'cubic_square'])
def test_top_height_of_geometric_scene_is_the_object_top(kind):
    source = GeometricSceneSource()
    scene = source.scene(np.random.default_rng(4), kind)
    area = find_correlation_area(scene.points, WORLD_FROM_LEFT, AreaConfig())
    assert area.status == STATUS_OK, area.reason
    assert area.top_height == pytest.approx(scene.target_world[2], abs=0.001)
    horizontal = np.hypot(*(area.xyz_world[:, :2].mean(axis=0) - scene.target_world[:2]))
    assert horizontal < 0.005, f'top band centroid {1000 * horizontal:.2f} mm off'


@pytest.mark.parametrize('face, why, limit, wider', [
    # A 150 mm slab is a patch of the surface or of the view's edge, not an object to pick.
    (Box((0.2, 0.15), 0.15, 0.03), 'longer than any object', 'max_object_across_m=0.1',
     AreaConfig(max_object_across_m=0.3)),
    # Within its noise of max_object_height_m a face is kept, and refused as too high.
    (Box((0.2, 0.15), 0.04, 0.1005), 'higher than any object', 'max_object_height_m=0.1',
     AreaConfig(max_object_height_m=0.2)),
], ids=['long', 'high'])
def test_a_face_beyond_any_objects_size_is_refused_by_name(face, why, limit, wider):
    area = area_in(RIG, face, 0.1, 3)
    assert area.status == NO_OBJECT, f'expected the face refused, got {area.status}'
    assert why in area.reason
    assert limit in area.reason
    allowed = area_in(RIG, face, 0.1, 3, config=wider)
    assert allowed.status == STATUS_OK, allowed.reason


def test_the_largest_object_is_not_refused_for_its_size():
    # An 80 mm box (the largest object) along its diagonal is still an object.
    area = area_in(FAR_RIG, Box((0.2, 0.15), 0.08, 0.03), 0.15, 1)
    assert area.status == STATUS_OK, area.reason


@pytest.mark.parametrize('side, expected', [(across_m, 0.08), (width_m, 0.02)],
                         ids=['long side', 'short side'])
def test_a_strips_sides_are_measured_whatever_the_orientation(side, expected):
    rng = np.random.default_rng(3)
    strip = rng.uniform([-0.04, -0.01], [0.04, 0.01], (4000, 2))
    angle = math.radians(35.0)
    rotation = np.array([[math.cos(angle), -math.sin(angle)], [math.sin(angle), math.cos(angle)]])
    assert side(strip) == pytest.approx(expected, rel=0.03)
    assert side(strip @ rotation.T) == pytest.approx(expected, rel=0.03)
    assert side(strip[:1]) == 0.0


def test_a_zero_max_object_across_is_refused():
    with pytest.raises(CorrelationAreaError, match='max_object_across_m=0'):
        find_correlation_area(MatchedPoints.empty(), WORLD_FROM_LEFT,
                              AreaConfig(max_object_across_m=0.0))


def test_a_top_higher_than_any_object_is_refused():
    # A face 150 mm up: no object stands that high (a blob of mismatches floats there). Its
    # matches are left out, and nothing else stands out of the surface.
    tower = Box((0.2, 0.15), 0.04, 0.15)
    area = area_in(RIG, tower, 0.1, 3)
    assert area.status == NO_OBJECT, f'expected the face refused, got {area.status}'
    allowed = area_in(RIG, tower, 0.1, 3, config=AreaConfig(max_object_height_m=0.2))
    assert allowed.status == STATUS_OK, allowed.reason
    assert allowed.top_height == pytest.approx(0.15, abs=0.002)


def lifted_along_rays(points: MatchedPoints, chosen: np.ndarray, heights: np.ndarray
                      ) -> None:
    """Move the chosen matches of the table (z = 0) nearer along their rays, to `heights`."""
    camera_z = WORLD_FROM_LEFT[2, 3]
    nearer = (camera_z - heights) / camera_z  # the ray's length shrinks with the depth
    disparity = points.u_left[chosen] - points.u_right[chosen]
    points.xyz[chosen] *= nearer[:, np.newaxis]
    points.u_right[chosen] = points.u_left[chosen] - disparity / nearer


@pytest.mark.parametrize('stride', [1, 3])
def test_matches_higher_than_any_object_are_left_out(stride):
    # A sheet of mismatches floating 150-190 mm over a patch of table larger than the box (a
    # periodic table matched a period off) would be the largest region; no object is that
    # high, so it takes no part and the box is found.
    box = Box((0.2, 0.15), 0.04, 0.03)
    points, left, right = grid_matches(RIG, box, 0.1, stride)
    world = (points.xyz @ WORLD_FROM_LEFT[:3, :3].T) + WORLD_FROM_LEFT[:3, 3]
    patch = ((points.u_left > 40) & (points.u_left < 240) & (points.v_left > 40)
             & (points.v_left < 240) & (world[:, 2] < 0.01)
             & (np.hypot(world[:, 0] - 0.2, world[:, 1] - 0.15) > 0.06))
    chosen = np.flatnonzero(patch)
    assert len(chosen) > 4 * np.count_nonzero(world[:, 2] > 0.02), 'expected a large sheet'
    rng = np.random.default_rng(stride)
    lifted_along_rays(points, chosen, rng.uniform(0.15, 0.19, len(chosen)))
    area = find_correlation_area(points, WORLD_FROM_LEFT, AreaConfig(),
                                 float(left.P[0, 2] - right.P[0, 2]))
    assert area.status == STATUS_OK, area.reason
    assert area.top_height == pytest.approx(0.03, abs=0.001)
    centre = np.average(area.xyz_world[:, :2], axis=0, weights=area.point_weights())
    assert np.hypot(*(centre - box.centre_xy)) < 0.002


@pytest.mark.parametrize('changes, message', [
    ({'min_object_across_m': -0.01}, 'min_object_across_m=-0.01 must not be negative'),
    ({'min_object_across_m': 0.1}, 'min_object_across_m=0.1 must be below max_object_across_m'),
])
def test_a_bad_min_object_across_is_refused(changes, message):
    with pytest.raises(CorrelationAreaError, match=message):
        find_correlation_area(MatchedPoints.empty(), WORLD_FROM_LEFT, AreaConfig(**changes))



@pytest.mark.parametrize('stride', [1, 3])
def test_a_plain_table_matched_on_noise_leaves_the_object_its_confident_matches(stride):
    # A plain table's windows hold sensor noise: each is matched anywhere along the search
    # range, with a low score. The plane fitted to those heights and their scatter would hide
    # the box; its own matches, confident, show it above the surface the rig pose gives.
    box = Box((0.2, 0.15), 0.05, 0.03)
    points, left, right = grid_matches(RIG, box, 0.1, stride)
    world = (points.xyz @ WORLD_FROM_LEFT[:3, :3].T) + WORLD_FROM_LEFT[:3, 3]
    table = np.flatnonzero(world[:, 2] < 0.01)
    rng = np.random.default_rng(stride)
    lifted_along_rays(points, table, rng.uniform(-0.02, 0.08, len(table)))
    on_box = world[:, 2] >= 0.01
    points.score[table] = rng.uniform(0.25, 0.45, len(table))
    points.score[on_box] = rng.uniform(0.6, 1.0, int(on_box.sum()))
    shift = float(left.P[0, 2] - right.P[0, 2])
    area = find_correlation_area(points, WORLD_FROM_LEFT, AreaConfig(), shift)
    assert area.status == STATUS_OK, area.reason
    assert area.surface.source == SURFACE_PLAIN
    assert area.top_height == pytest.approx(0.03, abs=0.001)
    centre = np.average(area.xyz_world[:, :2], axis=0, weights=area.point_weights())
    assert np.hypot(*(centre - box.centre_xy)) < 0.002
    every_match = find_correlation_area(points, WORLD_FROM_LEFT,
                                        AreaConfig(min_surface_score=0.0), shift)
    assert every_match.surface.source != SURFACE_PLAIN
    assert not every_match.ok or abs(every_match.top_height - 0.03) > 0.001


@pytest.mark.parametrize('stride', [1, 3])
def test_a_plain_table_whose_confident_matches_all_float_is_refused_not_an_error(stride):
    # A bare plain table (rendered, low texture, stride 3) whose only confident matches were
    # mismatches far above it: nothing is left to look for an object in.
    points, left, right = grid_matches(RIG, None, 0.1, stride)
    confident = np.arange(0, len(points), 7)
    rng = np.random.default_rng(stride)
    lifted_along_rays(points, confident, rng.uniform(0.15, 0.19, len(confident)))
    points.score[:] = 0.3  # the table's own matches: sensor noise
    points.score[confident] = 0.9
    area = find_correlation_area(points, WORLD_FROM_LEFT, AreaConfig(),
                                 float(left.P[0, 2] - right.P[0, 2]))
    assert area.status == NO_POINTS, f'expected no points left, got {area.status}: {area.reason}'
    assert 'higher above the work surface than any object' in area.reason
    assert area.surface.source == SURFACE_PLAIN

def test_a_textured_table_is_measured_whatever_some_matches_score():
    box = Box((0.2, 0.15), 0.05, 0.03)
    points, left, right = grid_matches(RIG, box, 0.1, 1)
    points.score[::3] = 0.3  # a third of the matches weak: the median is still confident
    area = find_correlation_area(points, WORLD_FROM_LEFT, AreaConfig(),
                                 float(left.P[0, 2] - right.P[0, 2]))
    assert area.status == STATUS_OK, area.reason
    assert area.surface.source == SURFACE_MEASURED
    assert area.points_used > 0 and np.any(area.score == 0.3), 'expected every match used'


@pytest.mark.parametrize('value', [-0.1, 1.0, math.nan])
def test_a_bad_min_surface_score_is_refused(value):
    with pytest.raises(CorrelationAreaError, match='min_surface_score=.* must be in'):
        find_correlation_area(MatchedPoints.empty(), WORLD_FROM_LEFT,
                              AreaConfig(min_surface_score=value))
