"""The geometric scene source: visible surfaces only, consistent rectified projection."""

import numpy as np
import pytest
from stereo_fuzzy_perception.core.rig_geometry import transform_points
from stereo_fuzzy_perception.simulation.synthetic_scenes import (
    OBJECT_TYPES,
    GeometricSceneSource,
    default_camera_matrix,
)

SOURCE = GeometricSceneSource(disparity_noise_px=(0.0, 0.0))


def test_default_camera_matches_the_project_camera():
    K = default_camera_matrix()
    assert K[0, 0] == pytest.approx(579.4, abs=0.1)
    assert (K[0, 2], K[1, 2]) == (320.0, 239.0)


@pytest.mark.parametrize('kind', OBJECT_TYPES)
def test_object_points_are_on_surfaces_both_cameras_see(kind):
    scene = SOURCE.scene(np.random.default_rng(11), kind)
    world = transform_points(scene.rig.world_from_left_camera(), scene.points.xyz)
    on_object = world[:, 2] > 1e-6
    assert on_object.sum() == scene.object_points > 100
    cameras = [scene.rig.world_from_left_camera()[:3, 3],
               scene.rig.world_from_right_camera()[:3, 3]]
    for camera in cameras:
        direction = camera - world
        nudged = world + 1e-6 * direction / np.linalg.norm(direction, axis=1, keepdims=True)
        hidden = scene.prism.segment_hits(nudged, camera)
        assert not np.any(hidden), f'{hidden.sum()} points hidden from a camera'
    assert world[on_object, 2].max() == pytest.approx(scene.prism.height)
    np.testing.assert_allclose(scene.target_world[2], scene.prism.height)


def test_matched_points_reproject_to_their_image_coordinates():
    scene = SOURCE.scene(np.random.default_rng(12), 'cubic_square')
    rectified = scene.points.xyz @ scene.left.R.T
    homogeneous = np.column_stack([rectified, np.ones(len(rectified))])
    left = homogeneous @ scene.left.P.T
    right = homogeneous @ scene.right.P.T
    np.testing.assert_allclose(left[:, 0] / left[:, 2], scene.points.u_left, atol=1e-6)
    np.testing.assert_allclose(left[:, 1] / left[:, 2], scene.points.v_left, atol=1e-6)
    np.testing.assert_allclose(right[:, 0] / right[:, 2], scene.points.u_right, atol=1e-6)


def test_disparity_noise_moves_points_along_their_rays_only():
    noisy = GeometricSceneSource(disparity_noise_px=(0.3, 0.3))
    clean_scene = SOURCE.scene(np.random.default_rng(13), 'cylinder')
    noisy_scene = noisy.scene(np.random.default_rng(13), 'cylinder')
    np.testing.assert_allclose(noisy_scene.points.u_left, clean_scene.points.u_left)
    assert not np.allclose(noisy_scene.points.xyz, clean_scene.points.xyz, atol=1e-5)
    cosine = np.einsum('ij,ij->i', noisy_scene.points.xyz, clean_scene.points.xyz) / (
        np.linalg.norm(noisy_scene.points.xyz, axis=1)
        * np.linalg.norm(clean_scene.points.xyz, axis=1))
    assert np.all(cosine > 1.0 - 1e-12)


def test_same_seed_gives_the_same_scenes():
    first = [s.target_world for s in SOURCE.scenes(3, seed=5)]
    again = [s.target_world for s in SOURCE.scenes(3, seed=5)]
    other = [s.target_world for s in SOURCE.scenes(3, seed=6)]
    np.testing.assert_array_equal(first, again)
    assert not np.allclose(first, other)
