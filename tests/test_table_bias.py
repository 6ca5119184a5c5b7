"""benchmarks/table_bias.py: the bare table's disparity error around the object, averaged."""

import math
from dataclasses import replace

import numpy as np

from benchmarks.table_bias import table_bias_mm, table_disparity_bias


def _scene_with_exact_table_matches(step: int = 2):
    """A geometric scene whose matches are every step-th pixel of the left image that sees the
    table (z = 0), matched exactly: each pixel's table point projected by the right camera."""
    from stereo_fuzzy_perception.core.matched_points import MatchedPoints
    from stereo_fuzzy_perception.core.rig_geometry import StereoRig
    from stereo_fuzzy_perception.simulation.synthetic_scenes import (
        GeometricSceneSource,
        project_rectified,
    )

    from benchmarks.true_top import left_pixel_rays

    scene = GeometricSceneSource(rig=StereoRig()).scene(np.random.default_rng(4), 'cubic_square')
    columns, rows = np.meshgrid(np.arange(0, 640, step, dtype=float),
                                np.arange(0, 480, step, dtype=float))
    u, v = columns.ravel(), rows.ravel()
    centre, rays = left_pixel_rays(scene, u, v)
    world = centre + rays * (-centre[2] / rays[:, 2])[:, None]
    u_right = project_rectified(world, scene.rig.world_from_left_camera(), scene.left,
                                scene.right)[2]
    # the points' 3D positions play no part in the measure
    points = MatchedPoints(np.zeros((len(u), 3), np.float32), u, v, u_right, np.ones(len(u)))
    return replace(scene, points=points)


def _object_column(scene) -> float:
    """The left rectified column of the top's centre: a band split there lies around it."""
    from stereo_fuzzy_perception.simulation.synthetic_scenes import project_rectified

    return float(project_rectified(scene.target_world[None, :],
                                   scene.rig.world_from_left_camera(), scene.left,
                                   scene.right)[0][0])


def _with_right_columns(scene, u_right):
    return replace(scene, points=replace(scene.points, u_right=u_right))


def test_exact_matches_and_a_constant_offset_have_no_spread():
    scene = _scene_with_exact_table_matches()
    spread, depth_per_px = table_disparity_bias(scene)
    assert spread < 1e-6
    assert depth_per_px > 0.0
    # a constant offset is the measured work surface's to take out, not a bias around the object
    shifted = _with_right_columns(scene, scene.points.u_right + 0.3)
    assert table_disparity_bias(shifted)[0] < 1e-6


def test_a_band_of_table_off_by_a_fraction_of_a_pixel_shows_and_per_match_noise_does_not():
    scene = _scene_with_exact_table_matches()
    u = scene.points.u_left
    centre = _object_column(scene)
    band = _with_right_columns(scene, scene.points.u_right + np.where(u < centre, 0.3, 0.0))
    band_spread = table_disparity_bias(band)[0]
    assert 0.1 < band_spread <= 0.3
    rng = np.random.default_rng(0)
    noisy = _with_right_columns(scene, scene.points.u_right + rng.normal(0.0, 0.2, len(u)))
    assert table_disparity_bias(noisy)[0] < 0.2 * band_spread


def test_mismatches_beyond_a_pixel_are_left_out_and_millimetres_scale_the_pixels():
    scene = _scene_with_exact_table_matches()
    rng = np.random.default_rng(1)
    wrong = rng.random(len(scene.points)) < 0.1
    mismatched = _with_right_columns(scene, scene.points.u_right + np.where(wrong, 7.0, 0.0))
    assert table_disparity_bias(mismatched)[0] < 1e-6
    u = scene.points.u_left
    band = _with_right_columns(scene, scene.points.u_right
                               + np.where(u < _object_column(scene), 0.3, 0.0))
    spread, depth_per_px = table_disparity_bias(band)
    assert math.isclose(table_bias_mm(band), spread * depth_per_px)


def test_no_table_matched_around_the_object_gives_nan():
    scene = _scene_with_exact_table_matches()
    far = _with_right_columns(scene, scene.points.u_right + 5.0)  # every match a mismatch
    assert math.isnan(table_disparity_bias(far)[0])
