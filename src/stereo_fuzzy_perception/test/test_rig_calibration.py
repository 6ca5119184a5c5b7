"""rig_calibration: pose files from a rendered board, from the chapter's numbers; the URDF."""

from pathlib import Path
from xml.etree import ElementTree

import cv2
import numpy as np
import pytest
from stereo_fuzzy_perception.core.board_pose import CheckerBoard
from stereo_fuzzy_perception.core.camera_calibration_file import write_calibration_yaml
from stereo_fuzzy_perception.core.frame_transforms import (
    LEFT_CAMERA_FRAME,
    Transform,
    rotation_angle_deg,
)
from stereo_fuzzy_perception.core.pose_file import camera_pose_from_file, read_pose_file
from stereo_fuzzy_perception.core.rig_description import JOINT_NAMES, gantry_urdf
from stereo_fuzzy_perception.core.rig_geometry import StereoRig
from stereo_fuzzy_perception.core.rig_pose import chapter_left_camera_transform
from stereo_fuzzy_perception.rig.rig_calibration import main
from stereo_fuzzy_perception.simulation.scene_model import SimulatedCamera
from stereo_fuzzy_perception.simulation.scene_renderer import SceneRenderer, stereo_calibration

RIG = StereoRig(alpha_deg=0.0, z0_m=0.5, x0_m=0.2, y0_m=0.15)
BOARD = CheckerBoard(11, 8, 0.03, origin_x_m=0.03, origin_y_m=0.0, yaw_deg=5.0)


@pytest.fixture(scope='module')
def board_files(tmp_path_factory) -> tuple[Path, Path, Path]:
    folder = tmp_path_factory.mktemp('board')
    with SceneRenderer(rig=RIG) as renderer:
        s = BOARD.square_m
        width, height = BOARD.size_m
        left, _ = renderer.render_plane(BOARD.texture(), BOARD.world_from_board(),
                                        (-s, -s, width + s, height + s))
        calibration = renderer.calibration
    image = folder / 'board.png'
    cv2.imwrite(str(image), cv2.cvtColor(left, cv2.COLOR_RGB2BGR))
    write_calibration_yaml(calibration.left, 'left', folder / 'left.yaml')
    write_calibration_yaml(calibration.right, 'right', folder / 'right.yaml')
    return image, folder / 'left.yaml', folder / 'right.yaml'


def board_arguments(image: Path, left: Path, output: Path, **overrides: str) -> list[str]:
    values = {'--columns': '11', '--rows': '8', '--square': '0.03', '--origin-x': '0.03',
              '--origin-y': '0.0', '--yaw': '5.0', **overrides}
    return ['board', '--left-calibration', str(left), '--image', str(image),
            '--output', str(output)] + [part for item in values.items() for part in item]


def test_board_writes_the_pose_file_and_prints_the_reprojection_error(board_files, tmp_path,
                                                                      capsys):
    image, left, _ = board_files
    output = tmp_path / 'rig_pose.yaml'
    assert main(board_arguments(image, left, output)) == 0
    printed = capsys.readouterr().out
    assert '88 corners found; reprojection error RMS' in printed
    assert f'world -> {LEFT_CAMERA_FRAME}: translation' in printed
    pose = camera_pose_from_file(output)
    truth = RIG.world_from_left_camera()
    assert np.linalg.norm(pose[:3, 3] - truth[:3, 3]) < 0.001
    assert rotation_angle_deg(pose[:3, :3], truth[:3, :3]) < 0.1
    assert 'reprojection error RMS' in output.read_text().splitlines()[2]


def test_board_refuses_a_fit_worse_than_the_limit_and_writes_nothing(board_files, tmp_path,
                                                                     capsys):
    image, left, _ = board_files
    output = tmp_path / 'rig_pose.yaml'
    assert main(board_arguments(image, left, output, **{'--max-rms-px': '0.001'})) == 1
    assert 'is above --max-rms-px 0.001' in capsys.readouterr().err
    assert not output.exists()


def test_board_image_of_the_wrong_size_is_refused(board_files, tmp_path, capsys):
    image, left, _ = board_files
    small = tmp_path / 'small.png'
    cv2.imwrite(str(small), cv2.imread(str(image))[:240, :320])
    assert main(board_arguments(small, left, tmp_path / 'out.yaml')) == 1
    assert 'image is 320x240 but' in capsys.readouterr().err


def test_chapter_numbers_with_the_calibration_baseline(board_files, tmp_path):
    _, left, right = board_files
    output = tmp_path / 'rig_pose.yaml'
    arguments = ['chapter', '--alpha', '0', '--theta', '0', '--z0', '0.5', '--x0', '0.2',
                 '--y0', '0.15', '--vergence', '6', '--left-calibration', str(left),
                 '--right-calibration', str(right), '--output', str(output)]
    assert main(arguments) == 0
    np.testing.assert_allclose(camera_pose_from_file(output), RIG.world_from_left_camera(),
                               atol=1e-9)


def test_chapter_baseline_that_disagrees_with_the_calibration_is_refused(board_files,
                                                                         tmp_path, capsys):
    _, left, right = board_files
    arguments = ['chapter', '--alpha', '45', '--theta', '0', '--z0', '0.4', '--x0', '0.2',
                 '--y0', '-0.25', '--baseline', '0.10', '--left-calibration', str(left),
                 '--right-calibration', str(right), '--output', str(tmp_path / 'out.yaml')]
    assert main(arguments) == 1
    error = capsys.readouterr().err
    assert '0.1000' in error and '0.0600' in error


def test_urdf_has_three_prismatic_joints_limited_to_the_workspace_and_the_cameras(tmp_path):
    pose_file = tmp_path / 'rig_pose.yaml'
    transform = chapter_left_camera_transform(StereoRig())
    from stereo_fuzzy_perception.core.pose_file import write_pose_file

    write_pose_file(pose_file, [transform])
    output = tmp_path / 'gantry.urdf'
    assert main(['urdf', '--pose-file', str(pose_file), '--output', str(output)]) == 0
    robot = ElementTree.parse(output).getroot()
    joints = {joint.get('name'): joint for joint in robot.iter('joint')}
    prismatic = [name for name, joint in joints.items() if joint.get('type') == 'prismatic']
    assert prismatic == list(JOINT_NAMES)
    limits = [(float(joints[name].find('limit').get('lower')),
               float(joints[name].find('limit').get('upper'))) for name in JOINT_NAMES]
    assert limits == [(0.0, 0.4), (0.0, 0.3), (0.0, 0.2)]
    camera = joints[f'{LEFT_CAMERA_FRAME}_joint']
    assert camera.get('type') == 'fixed' and camera.find('parent').get('link') == 'world'
    origin = camera.find('origin')
    xyz = [float(value) for value in origin.get('xyz').split()]
    roll, pitch, yaw = (float(value) for value in origin.get('rpy').split())
    from stereo_fuzzy_perception.core.rig_geometry import rotation_x, rotation_y, rotation_z

    pose = StereoRig().world_from_left_camera()
    np.testing.assert_allclose(xyz, pose[:3, 3], atol=1e-8)
    np.testing.assert_allclose(rotation_z(yaw) @ rotation_y(pitch) @ rotation_x(roll),
                               pose[:3, :3], atol=1e-8)


def test_urdf_refuses_a_mount_on_an_unknown_frame():
    from stereo_fuzzy_perception.core.frame_transforms import RigPoseError

    mount = Transform('camera_bar', LEFT_CAMERA_FRAME, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))
    with pytest.raises(RigPoseError, match="parent 'camera_bar' is not a link"):
        gantry_urdf((0.0, 0.0, 0.0), (0.4, 0.3, 0.2), [mount])


def test_right_calibration_gives_the_demo_rig_pose_file_round_trip(tmp_path):
    calibration = stereo_calibration(SimulatedCamera(), StereoRig())
    write_calibration_yaml(calibration.left, 'left', tmp_path / 'l.yaml')
    write_calibration_yaml(calibration.right, 'right', tmp_path / 'r.yaml')
    output = tmp_path / 'pose.yaml'
    assert main(['chapter', '--alpha', '45', '--theta', '0', '--z0', '0.4', '--x0', '0.2',
                 '--y0', '-0.25', '--vergence', '6', '--left-calibration',
                 str(tmp_path / 'l.yaml'), '--right-calibration', str(tmp_path / 'r.yaml'),
                 '-o', str(output)]) == 0
    (read,) = read_pose_file(output)
    np.testing.assert_allclose(read.matrix(), StereoRig().world_from_left_camera(), atol=1e-9)


def test_committed_demo_pose_file_and_urdf_are_what_the_helper_writes(tmp_path):
    """The demo rig's pose file and the gantry URDF are generated; regenerate them with the
    commands below when the demo rig or the driver's workspace changes."""
    repo = Path(__file__).resolve().parents[3]
    pose_file = repo / 'src/stereo_fuzzy_perception/config/demo_rig_pose.yaml'
    urdf_file = repo / 'src/cartesian_3p_driver/urdf/cartesian_3p.urdf'
    assert main(['chapter', '--alpha', '45', '--theta', '0', '--z0', '0.4', '--x0', '0.2',
                 '--y0', '-0.25', '--vergence', '6', '--baseline', '0.06',
                 '-o', str(tmp_path / 'pose.yaml')]) == 0
    assert (tmp_path / 'pose.yaml').read_text() == pose_file.read_text()
    assert main(['urdf', '--pose-file', str(pose_file), '-o', str(tmp_path / 'g.urdf')]) == 0
    assert (tmp_path / 'g.urdf').read_text() == urdf_file.read_text()
    import sys

    sys.path.insert(0, str(repo / 'src/cartesian_3p_driver'))
    from cartesian_3p_driver.gantry_driver_parameters import PARAMETERS

    defaults = {spec.name: spec.default for spec in PARAMETERS}
    robot = ElementTree.parse(urdf_file).getroot()
    joints = {joint.get('name'): joint for joint in robot.iter('joint')}
    for axis, name in enumerate(defaults['joint_names']):
        limit = joints[name].find('limit')
        assert float(limit.get('lower')) == defaults['workspace_min_m'][axis]
        assert float(limit.get('upper')) == defaults['workspace_max_m'][axis]


def test_board_from_a_capture_device_drops_the_first_frames(board_files, tmp_path):
    # An image pattern stands in for a camera: frame 0 is black (exposure still settling).
    image, left, _ = board_files
    frame = cv2.imread(str(image))
    cv2.imwrite(str(tmp_path / 'cam_000.png'), np.zeros_like(frame))
    cv2.imwrite(str(tmp_path / 'cam_001.png'), frame)
    arguments = board_arguments(image, left, tmp_path / 'pose.yaml')
    at = arguments.index('--image')
    arguments[at:at + 2] = ['--device', str(tmp_path / 'cam_%03d.png'), '--skip-frames', '1']
    assert main(arguments) == 0
    pose = camera_pose_from_file(tmp_path / 'pose.yaml')
    assert np.linalg.norm(pose[:3, 3] - RIG.world_from_left_camera()[:3, 3]) < 0.001
    at = arguments.index('--skip-frames')
    arguments[at + 1] = '0'
    assert main(arguments) == 1, 'the black first frame has no board'
