"""The stereo scene renderer: camera model, calibration, determinism, objects and sensors.

Rendering takes about 0.1-0.3 s per scene, so each test renders only a few.
"""

import cv2
import numpy as np
import pytest
from stereo_fuzzy_perception.core.rig_geometry import StereoRig, transform_points
from stereo_fuzzy_perception.simulation.scene_model import (
    OBJECT_TYPES,
    SimulatedCamera,
    random_scene,
)
from stereo_fuzzy_perception.simulation.scene_renderer import (
    RenderError,
    SceneRenderer,
    SensorModel,
    render_scene,
    stereo_calibration,
)

# Points spread over the workspace box and beyond its corners, in `world` [m].
MARKERS = np.array([
    [0.05, 0.02, 0.0], [0.35, 0.28, 0.10], [0.20, 0.15, 0.05], [0.02, 0.25, 0.15],
    [0.38, 0.03, 0.01], [0.10, 0.10, 0.20],
])
DISTORTION = (-0.12, 0.05, 0.001, -0.001, 0.0)


@pytest.fixture(scope='module')
def renderer():
    with SceneRenderer() as scene_renderer:
        yield scene_renderer


def centroid(mask):
    rows, columns = np.nonzero(mask)
    assert len(rows) > 0, 'the marker is not in the image'
    return np.array([columns.mean(), rows.mean()])


def project_with_lens(pose, points, K, D):
    camera_from_world = np.linalg.inv(pose)
    rotation, _ = cv2.Rodrigues(camera_from_world[:3, :3])
    pixels, _ = cv2.projectPoints(points, rotation, camera_from_world[:3, 3], K, np.array(D))
    return pixels.reshape(-1, 2)


def test_markers_appear_where_the_pinhole_model_projects_them(renderer):
    left_masks, right_masks = renderer.render_markers(MARKERS, radius_m=0.004)
    for masks, pose in ((left_masks, renderer.rig.world_from_left_camera()),
                        (right_masks, renderer.rig.world_from_right_camera())):
        expected = renderer.camera.project(pose, MARKERS)
        seen = np.array([centroid(mask) for mask in masks])
        error = np.abs(seen - expected)
        assert error.max() < 0.3, f'marker centroids off the projection by {error} px'


def test_markers_of_a_distorting_lens_appear_where_opencv_projects_them_with_d():
    with SceneRenderer(sensor=SensorModel(distortion=DISTORTION)) as distorted:
        left_masks, right_masks = distorted.render_markers(MARKERS, radius_m=0.004)
        K = distorted.camera.intrinsics()
        for masks, pose in ((left_masks, distorted.rig.world_from_left_camera()),
                            (right_masks, distorted.rig.world_from_right_camera())):
            expected = project_with_lens(pose, MARKERS, K, DISTORTION)
            ideal = distorted.camera.project(pose, MARKERS)
            assert np.abs(expected - ideal).max() > 3.0, 'distortion too weak to test'
            seen = np.array([centroid(mask) for mask in masks])
            error = np.abs(seen - expected)
            assert error.max() < 0.5, f'distorted marker centroids off by {error} px'


def test_undistorting_with_the_published_d_recovers_the_ideal_image():
    scene = random_scene(5, 'cylinder')
    with SceneRenderer(encoding='mono8') as ideal_renderer:
        ideal = ideal_renderer.render(scene).left.astype(float)
    with SceneRenderer(encoding='mono8', sensor=SensorModel(distortion=DISTORTION)) as lens:
        frame = lens.render(scene)
    calibration = frame.calibration.left
    np.testing.assert_allclose(calibration.D, DISTORTION)
    undistorted = cv2.undistort(frame.left, calibration.K, calibration.D).astype(float)
    inner = (slice(40, -40), slice(40, -40))
    before = np.abs(frame.left[inner] - ideal[inner]).mean()
    after = np.abs(undistorted[inner] - ideal[inner]).mean()
    assert after < 4.0 and after < 0.35 * before, (
        f'undistorted image differs from the ideal one by {after:.2f} grey levels on average '
        f'(distorted: {before:.2f})')


def test_the_rectified_calibration_is_valid_and_carries_the_baseline():
    rig = StereoRig()
    calibration = stereo_calibration(SimulatedCamera(), rig, DISTORTION)
    assert calibration.problem() is None
    assert calibration.right.P[0, 3] < 0.0
    assert calibration.baseline_m == pytest.approx(rig.baseline_m, rel=1e-9)
    for camera in (calibration.left, calibration.right):
        np.testing.assert_allclose(camera.R @ camera.R.T, np.eye(3), atol=1e-9)
        assert camera.frame_id.endswith('_camera_optical_frame')
    np.testing.assert_allclose(calibration.left.P[:, :3], calibration.right.P[:, :3])


def triangulate_world(calibration, rig, left_pixels, right_pixels):
    """Rectify raw pixels with the calibration, triangulate, and map to `world`."""
    left, right = calibration.left, calibration.right
    rectified_left = cv2.undistortPoints(left_pixels.reshape(-1, 1, 2), left.K, left.D,
                                         R=left.R, P=left.P).reshape(-1, 2)
    rectified_right = cv2.undistortPoints(right_pixels.reshape(-1, 1, 2), right.K, right.D,
                                          R=right.R, P=right.P).reshape(-1, 2)
    fx, cx, cy = left.P[0, 0], left.P[0, 2], left.P[1, 2]
    disparity = rectified_left[:, 0] - rectified_right[:, 0]
    depth = -right.P[0, 3] / disparity
    in_rectified = np.stack([(rectified_left[:, 0] - cx) * depth / fx,
                             (rectified_left[:, 1] - cy) * depth / fx, depth], axis=1)
    in_left_camera = in_rectified @ left.R  # R is rectified <- camera: apply R^T
    return transform_points(rig.world_from_left_camera(), in_left_camera), (
        rectified_left[:, 1] - rectified_right[:, 1])


def test_the_rectified_calibration_triangulates_known_points():
    rig = StereoRig()
    camera = SimulatedCamera()
    calibration = stereo_calibration(camera, rig, DISTORTION)
    K = camera.intrinsics()
    left_pixels = project_with_lens(rig.world_from_left_camera(), MARKERS, K, DISTORTION)
    right_pixels = project_with_lens(rig.world_from_right_camera(), MARKERS, K, DISTORTION)
    world, row_difference = triangulate_world(calibration, rig, left_pixels, right_pixels)
    np.testing.assert_allclose(row_difference, 0.0, atol=1e-3)
    np.testing.assert_allclose(world, MARKERS, atol=1e-6)


def test_rendered_markers_triangulate_to_their_world_position_within_a_millimetre(renderer):
    left_masks, right_masks = renderer.render_markers(MARKERS, radius_m=0.004)
    left = np.array([centroid(mask) for mask in left_masks])
    right = np.array([centroid(mask) for mask in right_masks])
    world, _ = triangulate_world(renderer.calibration, renderer.rig, left, right)
    error = np.linalg.norm(world - MARKERS, axis=1)
    assert error.max() < 1e-3, f'triangulated markers off by {error * 1000} mm'


def test_rendering_is_deterministic_and_depends_on_the_seed():
    sensor = SensorModel(noise_std=2.0, right_gain=1.05, right_offset=-3.0)
    scene = random_scene(11, 'cubic_square')
    with SceneRenderer(sensor=sensor) as first, SceneRenderer(sensor=sensor) as second:
        a, b = first.render(scene), second.render(scene)
        other = first.render(random_scene(12, 'cubic_square'))
    assert np.array_equal(a.left, b.left) and np.array_equal(a.right, b.right)
    assert not np.array_equal(a.left, other.left)


def test_a_scene_looks_the_same_whatever_was_rendered_before_it():
    # pybullet caches textures by file path per connection: reusing a file name once gave
    # every later scene the first scene's textures.
    scene = random_scene(21, 'cylinder')
    with SceneRenderer(encoding='mono8') as fresh, SceneRenderer(encoding='mono8') as used:
        expected = fresh.render(scene)
        used.render(random_scene(22, 'circle'))
        after_another = used.render(scene)
    assert np.array_equal(expected.left, after_another.left)
    assert np.array_equal(expected.right, after_another.right)


@pytest.mark.parametrize('kind', OBJECT_TYPES)
def test_each_object_type_is_visible_textured_and_unsaturated_in_both_images(renderer, kind):
    frame = renderer.render(random_scene(21, kind), with_maps=True)
    grey_left = cv2.cvtColor(frame.left, cv2.COLOR_RGB2GRAY)
    grey_right = cv2.cvtColor(frame.right, cv2.COLOR_RGB2GRAY)
    for side, mask, grey in (('left', frame.left_mask, grey_left),
                             ('right', frame.right_mask, grey_right)):
        assert mask.sum() > 300, f'{kind.value} covers only {mask.sum()} px of the {side} image'
        pixels = grey[mask]
        assert pixels.std() > 8.0, f'{kind.value} is untextured in the {side} image'
        assert np.mean(pixels >= 250) < 0.01, f'{kind.value} saturates in the {side} image'
    # The object is where its outline projects.
    outline = frame.scene.scene_object.outline_points()
    uv = renderer.camera.project(renderer.rig.world_from_left_camera(), outline)
    rows, columns = np.nonzero(frame.left_mask)
    assert abs(columns.min() - uv[:, 0].min()) < 2.0 and abs(columns.max() - uv[:, 0].max()) < 2.0
    assert abs(rows.min() - uv[:, 1].min()) < 2.0 and abs(rows.max() - uv[:, 1].max()) < 2.0


@pytest.mark.parametrize('kind', OBJECT_TYPES)
def test_the_target_lies_on_the_rendered_top_face(renderer, kind):
    frame = renderer.render(random_scene(33, kind), with_maps=True)
    target = frame.ground_truth.target_world
    for pose, mask, depth in ((renderer.rig.world_from_left_camera(), frame.left_mask,
                               frame.left_depth),
                              (renderer.rig.world_from_right_camera(), frame.right_mask,
                               frame.right_depth)):
        u, v = renderer.camera.project(pose, target[None, :])[0]
        assert mask[int(round(v)), int(round(u))], 'the target is not on the object'
        seen_depth = cv2.getRectSubPix(depth.astype(np.float32), (1, 1), (u, v))[0, 0]
        expected_depth = transform_points(np.linalg.inv(pose), target[None, :])[0, 2]
        assert seen_depth == pytest.approx(expected_depth, abs=3e-4), (
            f'rendered depth {seen_depth} m at the target, expected {expected_depth} m')


def test_encodings_and_the_right_cameras_gain_and_offset():
    scene = random_scene(4, 'circle')
    with SceneRenderer(encoding='rgb8') as rgb_renderer:
        rgb = rgb_renderer.render(scene)
    with SceneRenderer(encoding='bgr8') as bgr_renderer:
        bgr = bgr_renderer.render(scene)
    sensor = SensorModel(right_gain=0.8, right_offset=10.0)
    with SceneRenderer(encoding='mono8', sensor=sensor) as mono_renderer:
        mono = mono_renderer.render(scene)
    assert rgb.left.shape == (480, 640, 3) and mono.left.shape == (480, 640)
    assert np.array_equal(bgr.left, rgb.left[:, :, ::-1])
    expected_right = np.clip(np.round(
        cv2.cvtColor(rgb.right, cv2.COLOR_RGB2GRAY) * 0.8 + 10.0), 0, 255)
    assert np.abs(mono.right.astype(float) - expected_right).max() <= 1.0
    assert np.array_equal(mono.left, cv2.cvtColor(rgb.left, cv2.COLOR_RGB2GRAY))
    with pytest.raises(RenderError, match='mono16'):
        SceneRenderer(encoding='mono16')


def test_render_scene_returns_images_calibration_and_ground_truth():
    frame = render_scene(2, 'cylinder', camera=SimulatedCamera(width=160, height=120))
    assert frame.left.shape == (120, 160, 3) and frame.right.shape == (120, 160, 3)
    assert frame.calibration.problem() is None
    assert frame.ground_truth.target_world[2] == frame.scene.scene_object.height_m


def test_an_oversampled_render_is_the_same_scene_antialiased_with_the_same_maps():
    # TinyRenderer puts every texture edge on whole pixels; a camera's pixel integrates light
    # over its area. Oversampling averages 3 x 3 rendered samples per pixel.
    scene = random_scene(7, 'cubic_square', camera=SimulatedCamera(width=160, height=120))
    with SceneRenderer(camera=SimulatedCamera(width=160, height=120),
                       encoding='mono8') as renderer:
        sharp = renderer.render(scene, with_maps=True)
        smooth = renderer.render(scene, with_maps=True, oversampling=3)
        with pytest.raises(RenderError, match='oversampling must be an odd factor'):
            renderer.render(scene, oversampling=2)
    for side in ('left', 'right'):
        aliased, integrated = (getattr(frame, side).astype(float) for frame in (sharp, smooth))
        # the same scene at the same place: the images agree once the pixel-scale detail is
        # blurred away ...
        blur = [cv2.GaussianBlur(image, (0, 0), 3.0) for image in (aliased, integrated)]
        assert np.abs(blur[0] - blur[1]).mean() < 2.0
        # ... and differ in it: averaged samples have less pixel-to-pixel contrast
        steps = [np.abs(np.diff(image, axis=1)).mean() for image in (aliased, integrated)]
        assert steps[1] < 0.9 * steps[0], steps
    assert np.array_equal(sharp.left_mask, smooth.left_mask)
    assert np.array_equal(sharp.right_depth, smooth.right_depth)
