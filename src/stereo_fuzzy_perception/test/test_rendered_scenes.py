"""The rendered scene source: pybullet images through the correlation stage, as a scene record."""

import dataclasses

import numpy as np
import pytest
from stereo_fuzzy_perception.core.best_point.correlation_area import AreaConfig
from stereo_fuzzy_perception.core.best_point.point_selectors import BestPointChooser
from stereo_fuzzy_perception.core.matching.rectification import rectification_maps
from stereo_fuzzy_perception.core.rig_geometry import transform_points
from stereo_fuzzy_perception.simulation.distribution_source import perfect_points
from stereo_fuzzy_perception.simulation.rendered_scenes import RenderedSceneSource
from stereo_fuzzy_perception.simulation.synthetic_scenes import SCENE_SOURCES, SyntheticScene


@pytest.fixture(scope='module')
def scene():
    with RenderedSceneSource() as source:
        yield source.scene(np.random.default_rng(3), 'cubic_square')


def test_rendered_source_is_registered():
    source = SCENE_SOURCES['rendered']()
    assert isinstance(source, RenderedSceneSource)


def test_rendered_scene_is_a_valid_scene_record(scene):
    assert isinstance(scene, SyntheticScene)
    assert scene.object_type == 'cubic_square'
    assert len(scene.points) > 1000 and scene.object_points > 100
    assert scene.target_world[2] == pytest.approx(scene.prism.height)
    np.testing.assert_allclose(scene.prism.top_centre(), scene.target_world, atol=1e-9)
    # Points are in the left optical frame: the top face's points lie near the top height.
    world = transform_points(scene.rig.world_from_left_camera(), scene.points.xyz)
    on_top = scene.prism.contains_xy(world[:, :2]) & (world[:, 2] > 0.5 * scene.prism.height)
    median_top = np.median(world[on_top, 2])
    assert median_top == pytest.approx(scene.prism.height, abs=0.003), (
        f'top points at {median_top:.4f} m, object {scene.prism.height:.4f} m high')
    # The rectified calibration reprojects the points to their left image coordinates.
    rectified = scene.points.xyz @ scene.left.R.T
    left = np.column_stack([rectified, np.ones(len(rectified))]) @ scene.left.P.T
    np.testing.assert_allclose(left[:, 0] / left[:, 2], scene.points.u_left, atol=1e-3)


def test_the_centroid_selector_finds_the_rendered_top(scene):
    chooser = BestPointChooser.create('centroid', AreaConfig(), scene.rig)
    decision = chooser.decide(scene.points, scene.left, scene.right)
    assert decision.has_best_point, decision.status_text()
    error_mm = 1000.0 * np.linalg.norm(decision.best_point_world - scene.target_world)
    assert error_mm < 10.0, f'centroid {error_mm:.1f} mm from the top-face centre'


def test_a_frame_with_maps_gives_the_same_scene_and_its_perfect_points():
    # What table1_benchmark.py's ceiling rows decide on: the same pixels from the depth buffer.
    with RenderedSceneSource() as source:
        plain = source.scene_of_seed(7, 'cylinder')
        frame = source.render(7, 'cylinder', with_maps=True)
        result = source.match(frame)
        scene = source.scene_of_frame(frame, result)
    np.testing.assert_array_equal(scene.points.xyz, plain.points.xyz)
    perfect = perfect_points(frame, result.rectified)
    chooser = BestPointChooser.create('centroid', AreaConfig(), scene.rig)
    decision = chooser.decide(perfect, scene.left, scene.right)
    assert decision.has_best_point, decision.status_text()
    error_mm = 1000.0 * np.linalg.norm(decision.best_point_world - scene.target_world)
    assert error_mm < 3.0, f'centroid on perfect points {error_mm:.1f} mm from the top centre'


def test_perfect_points_keep_a_surface_that_fills_the_view():
    # A rig looking straight down sees nothing but the table: its farthest pixels are table
    # too, and the ceiling must keep them (only pixels that see nothing are left out).
    with RenderedSceneSource() as source:
        frame = source.render(7, 'cylinder', with_maps=True)
        result = source.match(frame)
    height, width = frame.left_depth.shape
    table = np.repeat(np.linspace(0.40, 0.45, height)[:, np.newaxis], width, axis=1)
    perfect = perfect_points(dataclasses.replace(frame, left_depth=table), result.rectified, 3)
    # every pixel of the grid whose ray stays inside the raw image (the rectification maps)
    maps = rectification_maps(frame.calibration.left)
    assert maps.map_x is not None and maps.map_y is not None
    raw_x, raw_y = maps.map_x[::3, ::3], maps.map_y[::3, ::3]
    inside = int(np.sum((raw_x >= 0) & (raw_x <= width - 1) & (raw_y >= 0)
                        & (raw_y <= height - 1)))
    assert len(perfect) == pytest.approx(inside, rel=0.005)
    assert float(np.max(perfect.xyz[:, 2])) == pytest.approx(0.45, abs=0.001)
    nothing = table.copy()
    nothing[: height // 2] = np.inf
    half = perfect_points(dataclasses.replace(frame, left_depth=nothing), result.rectified, 3)
    assert 0.4 * inside < len(half) < 0.6 * inside
    assert np.all(np.isfinite(half.xyz))
