"""The correlation area, its border points and four areas (steps 1-3), on synthetic points."""

import numpy as np
import pytest
from scipy import ndimage
from stereo_fuzzy_perception.core.best_point.correlation_area import (
    DEGENERATE_AREA,
    NO_POINTS,
    STATUS_OK,
    TOO_FEW_POINTS,
    TOP_BIN_M,
    TOP_DENSE_SHARE,
    TOP_QUANTILE,
    AreaConfig,
    CorrelationArea,
    CorrelationAreaError,
    find_correlation_area,
    split_into_areas,
)
from stereo_fuzzy_perception.core.matched_points import MatchedPoints
from stereo_fuzzy_perception.core.rig_geometry import StereoRig, transform_points
from stereo_fuzzy_perception.simulation.synthetic_scenes import GeometricSceneSource

RIG = StereoRig()
WORLD_FROM_LEFT = RIG.world_from_left_camera()


def points_from_world(world: np.ndarray, score: np.ndarray | None = None) -> MatchedPoints:
    """Matched points at given world positions (image coordinates are arbitrary here)."""
    camera = transform_points(np.linalg.inv(WORLD_FROM_LEFT), world)
    count = len(world)
    u = 320.0 + 600.0 * camera[:, 0] / camera[:, 2]
    v = 240.0 + 600.0 * camera[:, 1] / camera[:, 2]
    return MatchedPoints(camera, u, v, u - 40.0,
                         np.ones(count) if score is None else score)


def block(rng, centre, size, height, count):
    xy = rng.uniform(-0.5, 0.5, (count, 2)) * size + centre
    z = rng.uniform(0.005, height, count)  # clear of the surface margin
    z[: count // 2] = height  # half on the top face
    return np.column_stack([xy, z])


def test_surface_and_outside_points_are_not_object_points():
    rng = np.random.default_rng(0)
    top = np.column_stack([rng.uniform(0.1, 0.14, 200), rng.uniform(0.1, 0.14, 200),
                           np.full(200, 0.03)])
    surface = np.column_stack([rng.uniform(0.0, 0.4, 300), rng.uniform(0.0, 0.3, 300),
                               rng.normal(0.0, 0.0003, 300)])
    outside = np.array([[0.5, 0.1, 0.03], [0.1, -0.05, 0.03], [0.1, 0.1, 0.3]])
    area = find_correlation_area(points_from_world(np.vstack([top, surface, outside])),
                                 WORLD_FROM_LEFT, AreaConfig())
    assert area.status == STATUS_OK
    assert area.points_in == 503
    assert area.points_valid == 200
    assert area.points_used == 200
    assert area.top_height == pytest.approx(0.03)


def test_largest_cluster_is_kept_and_counted():
    rng = np.random.default_rng(1)
    big = block(rng, np.array([0.1, 0.1]), 0.04, 0.02, 1000)
    small = block(rng, np.array([0.3, 0.2]), 0.02, 0.05, 200)  # higher, but smaller
    points = points_from_world(np.vstack([big, small]))
    kept = find_correlation_area(points, WORLD_FROM_LEFT, AreaConfig())
    assert kept.clusters_found == 2
    assert np.all(np.abs(kept.xyz_world[:, 0] - 0.1) < 0.03), 'expected the big block only'
    assert kept.top_height == pytest.approx(0.02)
    everything = find_correlation_area(points, WORLD_FROM_LEFT,
                                       AreaConfig(keep_largest_cluster=False))
    assert everything.clusters_found == 2
    assert everything.top_height == pytest.approx(0.05), 'expected the higher block on top'


def test_top_band_holds_the_points_just_below_the_top():
    rng = np.random.default_rng(2)
    world = block(rng, np.array([0.2, 0.15]), 0.05, 0.04, 2000)
    area = find_correlation_area(points_from_world(world), WORLD_FROM_LEFT,
                                 AreaConfig(top_band_m=0.005))
    assert area.xyz_world[:, 2].min() >= 0.035 - 1e-12
    expected = np.sum(world[:, 2] >= 0.035)
    assert area.points_used == expected


def test_sparse_wrong_matches_above_the_object_do_not_lift_its_top():
    rng = np.random.default_rng(5)
    cube = block(rng, np.array([0.2, 0.15]), 0.04, 0.03, 2000)
    # 3 % wrong matches up to 1.5 cm above the top face, joined to the cube's cluster: more
    # than the 1 % a 99 % quantile ignores (it put the top 8 mm high in rendered scenes)
    above = np.column_stack([rng.uniform(0.185, 0.215, 60), rng.uniform(0.135, 0.165, 60),
                             rng.uniform(0.031, 0.045, 60)])
    area = find_correlation_area(points_from_world(np.vstack([cube, above])), WORLD_FROM_LEFT,
                                 AreaConfig())
    assert area.status == STATUS_OK
    assert area.top_height == pytest.approx(0.03, abs=0.0005)
    assert area.points_used >= 1000  # the whole top face is in the band


def test_top_is_the_quantile_when_every_height_level_holds_one_point():
    # 100 points 1 mm apart in height: every 1 mm level is dense, and the 99 % quantile
    # (rank 98) is the first point of its level, an edge of the search by level
    heights = 0.0105 + 0.001 * np.arange(100)
    world = np.column_stack([np.full(100, 0.2), np.full(100, 0.15), heights])
    area = find_correlation_area(points_from_world(world), WORLD_FROM_LEFT,
                                 AreaConfig(top_band_m=0.0045, min_points=1))
    assert area.points_used == 6  # heights[94:]: at most 4.5 mm below heights[98]
    assert area.top_height == pytest.approx(0.5 * (heights[96] + heights[97]), abs=1e-12)


def test_nan_and_infinite_rows_are_ignored():
    rng = np.random.default_rng(3)
    world = block(rng, np.array([0.2, 0.15]), 0.05, 0.04, 500)
    points = points_from_world(world)
    points.xyz[0, 1] = np.nan
    points.u_left[1] = np.inf
    points.score[2] = -np.inf
    area = find_correlation_area(points, WORLD_FROM_LEFT, AreaConfig())
    assert area.points_in == 500
    assert area.points_valid == 497


def test_no_points_and_too_few_points_have_reasons():
    empty = find_correlation_area(MatchedPoints.empty(), WORLD_FROM_LEFT, AreaConfig())
    assert empty.status == NO_POINTS and 'none of 0' in empty.reason
    few = points_from_world(np.array([[0.2, 0.1, 0.02]] * 5))
    area = find_correlation_area(few, WORLD_FROM_LEFT, AreaConfig(min_points=6))
    assert area.status == TOO_FEW_POINTS and 'min_points=6' in area.reason


def test_bad_configuration_names_the_value():
    with pytest.raises(CorrelationAreaError, match='top_band_m=0'):
        find_correlation_area(MatchedPoints.empty(), WORLD_FROM_LEFT, AreaConfig(top_band_m=0.0))
    with pytest.raises(CorrelationAreaError, match='axis y'):
        find_correlation_area(MatchedPoints.empty(), WORLD_FROM_LEFT,
                              AreaConfig(workspace_min=(0, 0.3, 0), workspace_max=(0.4, 0.3, 1)))


def area_of(u, v, ur, world) -> CorrelationArea:
    n = len(u)
    return CorrelationArea(STATUS_OK, '', n, n, 1, n, 0.0, np.asarray(world, dtype=float),
                           np.asarray(u, dtype=float), np.asarray(v, dtype=float),
                           np.asarray(ur, dtype=float), np.ones(n), 0.01)


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
def test_top_height_of_noise_free_scene_is_the_object_top(kind):
    source = GeometricSceneSource(disparity_noise_px=(0.0, 0.0))
    scene = source.scene(np.random.default_rng(4), kind)
    area = find_correlation_area(scene.points, WORLD_FROM_LEFT, AreaConfig())
    assert area.status == STATUS_OK
    assert area.clusters_found == 1
    assert area.top_height == pytest.approx(scene.target_world[2], abs=1e-6)
    horizontal = np.hypot(*(area.xyz_world[:, :2].mean(axis=0) - scene.target_world[:2]))
    assert horizontal < 0.005, f'top band centroid {1000 * horizontal:.2f} mm off'


def plain_numpy_area(world: np.ndarray, config: AreaConfig) -> tuple[np.ndarray, float]:
    """Step 1's selection written plainly with numpy and scipy: (band points (M, 3), top)."""
    low = np.array(config.workspace_min, dtype=float)
    high = np.array(config.workspace_max, dtype=float)
    low[2] = max(low[2], config.surface_margin_m)
    world = world[np.all((world >= low) & (world <= high), axis=1)]
    start = world.min(axis=0)
    cells = np.floor((world.max(axis=0) - start) / config.cluster_gap_m).astype(int) + 1
    index = np.minimum(((world - start) / config.cluster_gap_m).astype(int), cells - 1)
    occupied = np.zeros(cells, dtype=bool)
    occupied[tuple(index.T)] = True
    labels, _ = ndimage.label(occupied, structure=np.ones((3, 3, 3)))
    point_labels = labels[tuple(index.T)]
    world = world[point_labels == np.argmax(np.bincount(point_labels)[1:]) + 1]
    heights = world[:, 2]
    bins = ((heights - heights.min()) / TOP_BIN_M).astype(int)
    per_bin = np.bincount(bins)
    top_bin = np.flatnonzero(per_bin >= TOP_DENSE_SHARE * per_bin.max()).max()
    below = np.sort(heights[bins <= top_bin])
    top = below[int(TOP_QUANTILE * (len(below) - 1))]
    band = world[heights >= top - config.top_band_m]
    return band, float(np.median(band[:, 2]))


@pytest.mark.parametrize('seed', range(5))
def test_compiled_area_steps_agree_with_plain_numpy(seed):
    rng = np.random.default_rng(seed)
    blocks = [block(rng, rng.uniform([0.05, 0.05], [0.35, 0.25]), rng.uniform(0.01, 0.06),
                    rng.uniform(0.01, 0.08), int(rng.integers(50, 3000))) for _ in range(4)]
    clutter = rng.uniform([-0.05, -0.05, -0.01], [0.45, 0.35, 0.25], (500, 3))
    world = np.vstack(blocks + [clutter])
    world = world[rng.permutation(len(world))]
    config = AreaConfig()
    area = find_correlation_area(points_from_world(world), WORLD_FROM_LEFT, config)
    band, median = plain_numpy_area(world, config)
    assert area.points_used == len(band)
    np.testing.assert_allclose(np.sort(area.xyz_world, axis=0), np.sort(band, axis=0),
                               atol=1e-12)
    assert area.top_height == pytest.approx(median, abs=1e-12)
    # steps 2-3 against bincount and lexsort
    areas = split_into_areas(area, (320.0, 240.0), (300.0, 240.0))
    u, v = area.u_left, area.v_left
    right = u >= 0.5 * (u.min() + u.max())
    bottom = v >= 0.5 * (v.min() + v.max())
    labels = 2 * right + bottom
    np.testing.assert_array_equal(areas.counts, np.bincount(labels, minlength=4))
    for axis in range(3):
        np.testing.assert_allclose(areas.centres[:, axis], np.bincount(
            labels, area.xyz_world[:, axis], 4) / areas.counts, rtol=1e-12)
    np.testing.assert_allclose(areas.centres_u_right, np.bincount(
        labels, area.u_right, 4) / areas.counts, rtol=1e-12)
    first_by_u = np.lexsort((*area.xyz_world.T[::-1], v, u))[0]
    np.testing.assert_array_equal(areas.border_points[0], area.xyz_world[first_by_u])
    np.testing.assert_allclose(areas.centre, area.xyz_world.mean(axis=0), rtol=1e-12)
