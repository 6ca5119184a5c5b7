"""Rig pose as transforms: quaternions, pose files, the chapter's numbers, baseline refusal."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from stereo_fuzzy_perception.core.frame_transforms import (
    LEFT_CAMERA_FRAME,
    RIGHT_CAMERA_FRAME,
    RigPoseError,
    Transform,
    lookup_transform,
    matrix_from_quaternion,
    quaternion_from_matrix,
    rotation_angle_deg,
    rpy_from_matrix,
)
from stereo_fuzzy_perception.core.pose_file import pose_file_text, read_pose_file, write_pose_file
from stereo_fuzzy_perception.core.rig_geometry import StereoRig, rotation_x, rotation_y, rotation_z
from stereo_fuzzy_perception.core.rig_pose import (
    CameraPoseSource,
    chapter_left_camera_transform,
    check_baseline,
    right_camera_transform,
)
from stereo_fuzzy_perception.simulation.scene_model import SimulatedCamera
from stereo_fuzzy_perception.simulation.scene_renderer import stereo_calibration

angles = st.floats(-math.pi, math.pi, allow_nan=False)


def rotation(roll: float, pitch: float, yaw: float) -> np.ndarray:
    return rotation_z(yaw) @ rotation_y(pitch) @ rotation_x(roll)


@settings(max_examples=200, deadline=None)
@given(angles, angles, angles)
def test_quaternion_round_trip_gives_the_same_rotation(roll, pitch, yaw):
    matrix = rotation(roll, pitch, yaw)
    quaternion = quaternion_from_matrix(matrix)
    assert math.isclose(sum(q * q for q in quaternion), 1.0, abs_tol=1e-12)
    assert quaternion[3] >= 0.0
    np.testing.assert_allclose(matrix_from_quaternion(quaternion), matrix, atol=1e-12)


@settings(max_examples=200, deadline=None)
@given(angles, st.floats(-1.5, 1.5), angles)
def test_rpy_rebuilds_the_rotation_as_urdf_composes_it(roll, pitch, yaw):
    matrix = rotation(roll, pitch, yaw)
    np.testing.assert_allclose(rotation(*rpy_from_matrix(matrix)), matrix, atol=1e-9)


def test_known_quaternion_half_turn_about_x():
    x, y, z, w = quaternion_from_matrix(np.diag([1.0, -1.0, -1.0]))
    assert (round(x, 12), round(y, 12), round(z, 12), round(w, 12)) == (1.0, 0.0, 0.0, 0.0)


def test_pose_file_round_trip_and_static_transform_publisher_layout(tmp_path):
    rig = StereoRig()
    transform = chapter_left_camera_transform(rig)
    path = tmp_path / 'rig_pose.yaml'
    write_pose_file(path, [transform], 'made by a test')
    text = path.read_text()
    assert text.startswith('# made by a test\n')
    # The parameters tf2_ros' static_transform_publisher declares.
    for key in ('left_camera_pose:', 'ros__parameters:', 'frame_id: world',
                f'child_frame_id: {LEFT_CAMERA_FRAME}', 'translation:', 'rotation:'):
        assert key in text
    (read,) = read_pose_file(path)
    assert (read.frame_id, read.child_frame_id) == ('world', LEFT_CAMERA_FRAME)
    np.testing.assert_allclose(read.matrix(), rig.world_from_left_camera(), atol=1e-9)


def test_pose_file_reads_the_dotted_form_and_chains_frames(tmp_path):
    path = tmp_path / 'pose.yaml'
    path.write_text(
        'mount_pose:\n  ros__parameters:\n    frame_id: world\n    child_frame_id: mount\n'
        '    translation.x: 0.1\n    translation.y: 0.0\n    translation.z: 0.5\n'
        '    rotation.x: 0.0\n    rotation.y: 0.0\n    rotation.z: 0.0\n    rotation.w: 1.0\n'
        'left_camera_pose:\n  ros__parameters:\n    frame_id: mount\n'
        f'    child_frame_id: {LEFT_CAMERA_FRAME}\n'
        '    translation: {x: 0.0, y: 0.02, z: 0.0}\n'
        '    rotation: {x: 1.0, y: 0.0, z: 0.0, w: 0.0}\n')
    pose = lookup_transform(read_pose_file(path), 'world', LEFT_CAMERA_FRAME)
    np.testing.assert_allclose(pose[:3, 3], [0.1, 0.02, 0.5])
    np.testing.assert_allclose(pose[:3, :3], np.diag([1.0, -1.0, -1.0]), atol=1e-12)
    # and the inverse direction
    np.testing.assert_allclose(lookup_transform(read_pose_file(path), LEFT_CAMERA_FRAME,
                                                'world'), np.linalg.inv(pose), atol=1e-12)


@pytest.mark.parametrize(('body', 'expected'), [
    ('[]', 'expected sections'),
    ('left_camera_pose: {frame_id: world}', 'no ros__parameters'),
    ('p:\n  ros__parameters: {frame_id: world, child_frame_id: c}', 'missing translation.x'),
    ('p:\n  ros__parameters: {frame_id: world, child_frame_id: c, translation: {x: 0, y: 0, '
     'z: a}, rotation: {x: 0, y: 0, z: 0, w: 1}}', "translation.z must be a number, got 'a'"),
    ('p:\n  ros__parameters: {frame_id: world, child_frame_id: c, translation: {x: 0, y: 0, '
     'z: 0}, rotation: {x: 0, y: 0, z: 0, w: 2}}', 'expected a unit quaternion'),
    ('p:\n  ros__parameters: {frame_id: c, child_frame_id: c, translation: {x: 0, y: 0, '
     'z: 0}, rotation: {x: 0, y: 0, z: 0, w: 1}}', "both 'c'"),
    ('not: [valid', 'not valid YAML'),
    ('p:\n  ros__parameters: {frame_id: /world, child_frame_id: c, translation: {x: 0, y: 0, '
     'z: 0}, rotation: {x: 0, y: 0, z: 0, w: 1}}', "'/world' starts with /"),
])
def test_bad_pose_files_are_refused_with_the_reason(tmp_path, body, expected):
    path = tmp_path / 'pose.yaml'
    path.write_text(body)
    with pytest.raises(RigPoseError, match='pose.yaml') as raised:
        read_pose_file(path)
    assert expected in str(raised.value)


def test_frames_that_loop_are_refused():
    transforms = [Transform('a', 'b', (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0)),
                  Transform('b', 'a', (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))]
    with pytest.raises(RigPoseError, match='loop'):
        lookup_transform(transforms, 'world', 'a')


def test_unconnected_frames_are_refused_naming_the_known_frames():
    transform = Transform('world', 'tool', (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))
    with pytest.raises(RigPoseError, match="no transform from 'left_camera_optical_frame'.*tool"):
        lookup_transform([transform], 'world', LEFT_CAMERA_FRAME)


@pytest.mark.parametrize('rig', [StereoRig(), StereoRig(baseline_m=0.12, vergence_deg=0.0),
                                 StereoRig(alpha_deg=20.0, theta_deg=-30.0, vergence_deg=10.0)])
def test_right_camera_pose_from_the_calibration_matches_the_rig(rig):
    calibration = stereo_calibration(SimulatedCamera(), rig)
    transform = right_camera_transform(calibration)
    assert (transform.frame_id, transform.child_frame_id) == (LEFT_CAMERA_FRAME,
                                                              RIGHT_CAMERA_FRAME)
    expected = np.linalg.inv(rig.world_from_left_camera()) @ rig.world_from_right_camera()
    np.testing.assert_allclose(transform.matrix(), expected, atol=1e-9)


def test_baseline_that_disagrees_with_the_calibration_is_refused_with_both_numbers():
    calibration = stereo_calibration(SimulatedCamera(), StereoRig(baseline_m=0.06))
    check_baseline(0.0602, calibration)
    with pytest.raises(RigPoseError) as raised:
        check_baseline(0.10, calibration)
    assert '0.1000' in str(raised.value) and '0.0600' in str(raised.value)


def test_pose_source_takes_the_baseline_from_the_calibration():
    calibration = stereo_calibration(SimulatedCamera(), StereoRig(baseline_m=0.08))
    source = CameraPoseSource.from_settings(StereoRig(baseline_m=0.0))
    np.testing.assert_allclose(source.world_from_camera(calibration),
                               StereoRig(baseline_m=0.08).world_from_left_camera(), atol=1e-12)
    refusing = CameraPoseSource.from_settings(StereoRig(baseline_m=0.10))
    with pytest.raises(RigPoseError, match='0.1000.*0.0800'):
        refusing.world_from_camera(calibration)


def test_pose_file_overrides_the_chapter_numbers(tmp_path):
    measured = Transform.from_matrix('world', LEFT_CAMERA_FRAME, StereoRig(
        alpha_deg=30.0, theta_deg=10.0, x0_m=0.1).world_from_left_camera())
    path = tmp_path / 'rig_pose.yaml'
    path.write_text(pose_file_text([measured]))
    source = CameraPoseSource.from_settings(StereoRig(baseline_m=0.0), str(path))
    calibration = stereo_calibration(SimulatedCamera(), StereoRig())
    pose = source.world_from_camera(calibration)
    np.testing.assert_allclose(pose, measured.matrix(), atol=1e-9)
    assert rotation_angle_deg(pose[:3, :3], StereoRig().world_from_left_camera()[:3, :3]) > 5.0
    assert source.connects(LEFT_CAMERA_FRAME) and not source.connects('other_frame')
    with pytest.raises(RigPoseError, match="rig_pose.yaml: no transform from 'other_frame'"):
        source.world_from_camera(calibration, 'other_frame')
    with pytest.raises(RigPoseError, match="no transform mentions the world frame 'map'"):
        CameraPoseSource.from_settings(StereoRig(), str(path), world_frame='map')
