"""Scene descriptions: seeded, inside the workspace, in view, with the right ground truth."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from stereo_fuzzy_perception.core.rig_geometry import StereoRig
from stereo_fuzzy_perception.simulation.scene_model import (
    OBJECT_TYPES,
    SIZES,
    WORKSPACE,
    GroundTruth,
    ObjectType,
    SceneError,
    SimulatedCamera,
    in_view,
    parse_object_type,
    random_scene,
)


def test_camera_intrinsics_follow_the_field_of_view_and_the_renderer_principal_point():
    camera = SimulatedCamera()
    K = camera.intrinsics()
    expected_focal = 240.0 / math.tan(math.radians(22.5))
    assert K[0, 0] == pytest.approx(expected_focal) and K[1, 1] == pytest.approx(expected_focal)
    assert (K[0, 2], K[1, 2]) == (320.0, 239.0)


def test_same_seed_gives_the_same_scene_and_other_seeds_differ():
    assert random_scene(7, 'cylinder') == random_scene(7, 'cylinder')
    assert random_scene(7) == random_scene(7)
    assert random_scene(7, 'cylinder') != random_scene(8, 'cylinder')


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), kind=st.sampled_from(OBJECT_TYPES))
def test_random_objects_have_their_type_shape_and_lie_in_the_workspace_and_in_view(seed, kind):
    scene = random_scene(seed, kind)
    item = scene.scene_object
    assert item.object_type is kind
    if kind is ObjectType.CIRCLE:
        assert item.height_m == SIZES.disc_thickness_m
    else:
        assert SIZES.height_min_m <= item.height_m <= SIZES.height_max_m
    if kind.is_round:
        assert item.size_x_m == item.size_y_m
    if kind is ObjectType.CUBIC_SQUARE:
        assert item.size_x_m == item.size_y_m == item.height_m
    if kind is ObjectType.CUBIC_RECTANGLE:
        assert item.size_y_m <= 0.8 * item.size_x_m, 'a rectangle must not look like a square'
    assert SIZES.across_min_m - 1e-12 <= min(item.size_x_m, item.size_y_m)
    assert max(item.size_x_m, item.size_y_m) <= SIZES.across_max_m / 0.75 + 1e-12
    outline = item.outline_points()
    assert outline[:, 0].min() >= WORKSPACE.x_min and outline[:, 0].max() <= WORKSPACE.x_max
    assert outline[:, 1].min() >= WORKSPACE.y_min and outline[:, 1].max() <= WORKSPACE.y_max
    assert in_view(outline, StereoRig(), SimulatedCamera(), margin_px=15.0)


@pytest.mark.parametrize('kind', OBJECT_TYPES)
def test_ground_truth_target_is_the_centre_of_the_top_face(kind):
    scene = random_scene(3, kind)
    truth = GroundTruth.of(scene)
    item = scene.scene_object
    corners = item.top_corners()
    np.testing.assert_allclose(truth.target_world, corners.mean(axis=0), atol=1e-12)
    assert truth.target_world[2] == pytest.approx(item.height_m)
    top_outline = item.outline_points()[len(item.outline_points()) // 2:]
    np.testing.assert_allclose(top_outline[:, 2], item.height_m)
    np.testing.assert_allclose(top_outline[:, :2].mean(axis=0), truth.target_world[:2],
                               atol=1e-12)


def test_an_unknown_type_or_a_rig_looking_away_is_refused_with_a_reason():
    with pytest.raises(SceneError, match='unknown object type'):
        parse_object_type('sphere')
    away = StereoRig(x0_m=5.0, y0_m=5.0)
    with pytest.raises(SceneError, match='no placement'):
        random_scene(1, 'circle', rig=away, max_attempts=20)
