"""The work surface measured from the points, and the object segmentation helpers."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from stereo_fuzzy_perception.core.best_point.object_segmentation import (
    choose_object,
    grid_step,
    grown_region,
    image_regions,
    smoothed_on_grid,
    top_height,
)
from stereo_fuzzy_perception.core.best_point.work_surface import (
    SURFACE_ASSUMED,
    SURFACE_MEASURED,
    fit_work_surface,
    height_per_disparity,
)


def surface_points(rng, plane, count, sigma_px, per_px):
    """Points on z = sx x + sy y + c with height noise sigma_px * per_px [m]."""
    xy = rng.uniform([0.0, 0.0], [0.4, 0.3], (count, 2))
    scale = np.full(count, per_px)
    z = plane[0] * xy[:, 0] + plane[1] * xy[:, 1] + plane[2] + rng.normal(
        0.0, sigma_px, count) * scale
    return np.vstack([xy.T, z]), scale


@settings(max_examples=40, deadline=None)
@given(offset=st.floats(-0.008, 0.008), slope_x=st.floats(-0.015, 0.015),
       slope_y=st.floats(-0.015, 0.015), sigma_px=st.floats(0.05, 0.5),
       clutter=st.floats(0.0, 0.4), seed=st.integers(0, 2**16))
def test_the_plane_and_the_noise_are_recovered_under_clutter(offset, slope_x, slope_y, sigma_px,
                                                             clutter, seed):
    rng = np.random.default_rng(seed)
    world, scale = surface_points(rng, (slope_x, slope_y, offset), 4000, sigma_px, 0.004)
    # clutter: an object and wrong matches from 5 sigmas to 2 cm above the surface
    extra = int(clutter * 4000)
    xy = rng.uniform(0.1, 0.2, (2, extra))
    floor = slope_x * xy[0] + slope_y * xy[1] + offset + 5.0 * sigma_px * 0.004
    above = np.vstack([xy, floor + rng.uniform(0.0, 0.02, extra)])
    world = np.hstack([world, above])
    scale = np.concatenate([scale, np.full(extra, 0.004)])
    plane = fit_work_surface(world, scale, 0.02, 0.01, 0.2)
    assert plane.source == SURFACE_MEASURED
    # a tilt error of 0.01 sigma_px: a fraction of the height noise across the workspace
    assert plane.slope_x == pytest.approx(slope_x, abs=max(1e-3, 0.01 * sigma_px))
    assert plane.slope_y == pytest.approx(slope_y, abs=max(1e-3, 0.01 * sigma_px))
    assert plane.height_at(0.2, 0.15) == pytest.approx(
        offset + 0.2 * slope_x + 0.15 * slope_y, abs=max(0.0005, 0.004 * sigma_px))
    assert plane.disparity_sigma_px == pytest.approx(sigma_px, rel=0.2)


def test_the_same_points_give_the_same_plane():
    rng = np.random.default_rng(1)
    world, scale = surface_points(rng, (0.01, 0.0, 0.002), 3000, 0.2, 0.003)
    first = fit_work_surface(world, scale, 0.02, 0.01, 0.2)
    again = fit_work_surface(world[:, ::-1].copy(), scale[::-1].copy(), 0.02, 0.01, 0.2)
    assert first == fit_work_surface(world, scale, 0.02, 0.01, 0.2)
    assert again.offset_m == pytest.approx(first.offset_m, abs=1e-4)


def test_points_on_one_line_do_not_fix_a_plane():
    # A peer's message can hold anything: a single image row of the table, or that row with
    # a second one a hair beside it. A line does not fix a plane: the rig pose's is assumed,
    # without an error.
    x = np.linspace(0.0, 0.4, 2000)
    for width in (0.0, 1e-9):
        y = 0.1 + width * (np.arange(len(x)) % 2)
        world = np.vstack([x, y, 0.001 + 0.005 * x])
        plane = fit_work_surface(world, np.full(len(x), 0.003), 0.02, 0.01, 0.2)
        assert plane.source == SURFACE_ASSUMED
        assert np.all(np.isfinite(plane.heights(world)))


def test_too_few_surface_points_assume_the_rig_pose_plane():
    rng = np.random.default_rng(2)
    world, scale = surface_points(rng, (0.0, 0.0, 0.05), 500, 0.1, 0.003)  # all 5 cm up
    plane = fit_work_surface(world, scale, 0.02, 0.01, 0.25)
    assert plane.source == SURFACE_ASSUMED
    assert (plane.offset_m, plane.tilt_deg, plane.inliers) == (0.0, 0.0, 0)
    assert plane.disparity_sigma_px == 0.25


def test_noise_floor_and_heights():
    rng = np.random.default_rng(3)
    world, scale = surface_points(rng, (0.0, 0.0, 0.0), 2000, 1e-6, 0.003)
    plane = fit_work_surface(world, scale, 0.02, 0.05, 0.2)
    assert plane.disparity_sigma_px == 0.05
    points = np.array([[0.1, 0.2], [0.1, 0.1], [0.01, 0.03]])
    np.testing.assert_allclose(plane.heights(points), [0.01, 0.03], atol=1e-6)


def test_height_per_disparity_is_the_ray_over_the_disparity():
    world = np.array([[0.0, 0.3], [0.0, 0.0], [0.0, 0.1]])
    camera = np.array([0.0, 0.0, 0.5])
    along = height_per_disparity(world, camera, np.array([50.0, 100.0]),
                                 np.array([0.0, 0.0, 1.0]))
    np.testing.assert_allclose(along, [0.5 / 50.0, 0.4 / 100.0])


def test_grid_step_is_the_point_stride():
    columns = np.array([3.0, 9.0, 12.0, 30.0])
    assert grid_step(columns, columns) == 3.0
    assert grid_step(np.array([5.0]), np.array([1.0])) == 1.0
    assert grid_step(np.array([0.5, 1.7, 3.1, 9.9]), np.array([0.0, 2.0, 4.0, 8.0])) > 1.0
    # garbage coordinates cannot ask for a huge grid
    wild = np.array([0.0, 1.0, 2.0, 1e9])
    assert grid_step(wild, wild) >= 1e9 / 2000


def test_regions_join_across_one_missing_match_only():
    u = np.array([0, 1, 3, 10, 11], dtype=float)  # gap of one cell between 1 and 3
    v = np.zeros(5)
    labels, count = image_regions(u, v, np.ones(5, dtype=bool), 1.0)
    assert count == 2
    assert labels[0] == labels[1] == labels[2] != labels[3] == labels[4]
    labels, count = image_regions(u, v, np.array([True, False, False, True, True]), 1.0)
    assert count == 2 and labels[1] == labels[2] == 0


def test_a_region_is_an_object_by_its_height_not_its_size():
    labels = np.array([1] * 500 + [2] * 40 + [0] * 10)
    z = np.concatenate([np.full(500, 3.4), np.full(40, 9.0), np.zeros(10)])
    heights = np.concatenate([np.full(500, 0.003), np.full(40, 0.009), np.zeros(10)])
    sigmas = np.full(550, 0.001)
    found = choose_object(labels, 2, z, heights, sigmas, 6.0, 3.0, 20)
    assert (found.label, found.regions, found.objects, found.points) == (2, 2, 1, 40)
    assert found.top_m == pytest.approx(0.009)
    nothing = choose_object(labels, 2, z, heights, sigmas, 10.0, 3.0, 20)
    assert nothing.label == 0 and nothing.points == 500
    # significant once averaged, but its top is within the noise of one point: the
    # surface's own pattern, not an object
    low = choose_object(labels, 2, z, heights, np.full(550, 0.004), 6.0, 3.0, 20)
    assert low.label == 0
    assert choose_object(labels, 0, z, heights, sigmas, 6.0, 3.0, 20).label == 0


def test_top_height_is_the_face_not_the_wall_or_the_spikes():
    rng = np.random.default_rng(4)
    face = rng.normal(0.03, 0.0005, 2000)
    wall = rng.uniform(0.0, 0.03, 800)
    spikes = rng.uniform(0.031, 0.045, 60)
    heights = np.concatenate([face, wall, spikes])
    assert top_height(heights, np.full(len(heights), 0.0005)) == pytest.approx(0.03, abs=2e-4)


def test_smoothing_and_growing_work_on_the_image_grid():
    v, u = np.mgrid[0:20, 0:20].reshape(2, -1).astype(float) * 2  # stride 2
    values = (u >= 20).astype(float)
    mean = smoothed_on_grid(u, v, values, 2.0, 6.0)  # 3 x 3 cells
    assert mean[(u == 0)].max() == 0.0 and mean[(u == 38)].min() == 1.0
    assert np.all(np.isclose(mean[(u == 18) & (v == 20)], 1 / 3))
    member = (u == 10) & (v == 10)
    grown = grown_region(u, v, member, 2.0, 6.0)
    assert grown.sum() == 9
