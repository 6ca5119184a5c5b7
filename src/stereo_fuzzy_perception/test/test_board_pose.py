"""The camera's world pose from a rendered checkerboard lying at a known place (PnP)."""

import numpy as np
import pytest
from stereo_fuzzy_perception.core.board_pose import (
    BoardPoseError,
    CheckerBoard,
    board_pose,
)
from stereo_fuzzy_perception.core.frame_transforms import rotation_angle_deg
from stereo_fuzzy_perception.core.rig_geometry import StereoRig
from stereo_fuzzy_perception.simulation.scene_renderer import SceneRenderer, SensorModel

# Issue #16's targets for a rendered board seen from about 0.5 m.
POSITION_TARGET_MM = 1.0
ROTATION_TARGET_DEG = 0.1

LOOKING_DOWN_AT_HALF_A_METRE = StereoRig(alpha_deg=0.0, z0_m=0.5, x0_m=0.2, y0_m=0.15)
BOARD = CheckerBoard(11, 8, 0.03, origin_x_m=0.03, origin_y_m=0.0, yaw_deg=5.0)


def render_left(rig: StereoRig, board: CheckerBoard, sensor: SensorModel | None = None):
    with SceneRenderer(rig=rig, sensor=sensor) as renderer:
        s = board.square_m
        width, height = board.size_m
        left, _ = renderer.render_plane(board.texture(), board.world_from_board(),
                                        (-s, -s, width + s, height + s))
        return left, renderer.calibration.left


def errors(pose: np.ndarray, truth: np.ndarray) -> tuple[float, float]:
    return (1000.0 * float(np.linalg.norm(pose[:3, 3] - truth[:3, 3])),
            rotation_angle_deg(pose[:3, :3], truth[:3, :3]))


@pytest.mark.parametrize(('rig', 'board', 'sensor'), [
    (LOOKING_DOWN_AT_HALF_A_METRE, BOARD, None),
    # the demo rig (tilted 45 degrees, 0.57 m to the surface along its axis), board turned
    (StereoRig(), CheckerBoard(11, 8, 0.03, origin_x_m=0.36, origin_y_m=-0.03, yaw_deg=93.0),
     None),
    # lens distortion and sensor noise
    (StereoRig(), CheckerBoard(11, 8, 0.03, origin_x_m=0.05, origin_y_m=-0.03, yaw_deg=3.0),
     SensorModel(noise_std=2.0, distortion=(-0.1, 0.02, 0.0, 0.0, 0.0))),
], ids=['down-0.5m', 'demo-rig-board-turned', 'distorted-noisy'])
def test_rendered_board_gives_the_camera_pose_within_the_targets(rig, board, sensor):
    image, calibration = render_left(rig, board, sensor)
    found = board_pose(image, calibration, board)
    position_mm, rotation_deg = errors(found.world_from_camera, rig.world_from_left_camera())
    assert position_mm < POSITION_TARGET_MM, f'position off by {position_mm:.3f} mm'
    assert rotation_deg < ROTATION_TARGET_DEG, f'rotation off by {rotation_deg:.4f} deg'
    assert found.reprojection_rms_px < 0.3
    assert found.reprojection_max_px >= found.reprojection_rms_px


def test_board_placed_elsewhere_than_declared_moves_the_pose_by_as_much():
    image, calibration = render_left(LOOKING_DOWN_AT_HALF_A_METRE, BOARD)
    declared = CheckerBoard(11, 8, 0.03, origin_x_m=0.04, origin_y_m=0.0, yaw_deg=5.0)
    found = board_pose(image, calibration, declared)
    shift = found.world_from_camera[:3, 3] - LOOKING_DOWN_AT_HALF_A_METRE.world_from_left_camera(
    )[:3, 3]
    assert shift[0] == pytest.approx(0.01, abs=0.001)


def test_board_turned_by_half_a_turn_is_told_apart_by_its_colours():
    # The same board lying the other way round: the corner grid alone would fit both.
    turned = CheckerBoard(11, 8, 0.03, origin_x_m=0.03 + 0.36 * np.cos(np.radians(5.0))
                          - 0.27 * np.sin(np.radians(5.0)),
                          origin_y_m=0.36 * np.sin(np.radians(5.0))
                          + 0.27 * np.cos(np.radians(5.0)), yaw_deg=185.0)
    image, calibration = render_left(LOOKING_DOWN_AT_HALF_A_METRE, turned)
    np.testing.assert_allclose(turned.corners_world().mean(axis=0),
                               BOARD.corners_world().mean(axis=0), atol=1e-9)
    found = board_pose(image, calibration, turned)
    position_mm, rotation_deg = errors(found.world_from_camera,
                                       LOOKING_DOWN_AT_HALF_A_METRE.world_from_left_camera())
    assert position_mm < POSITION_TARGET_MM and rotation_deg < ROTATION_TARGET_DEG


def test_symmetric_board_is_refused():
    image, calibration = render_left(LOOKING_DOWN_AT_HALF_A_METRE, BOARD)
    with pytest.raises(BoardPoseError, match='turned by 180 degrees'):
        board_pose(image, calibration, CheckerBoard(9, 7, 0.03))


def test_image_without_the_board_is_refused():
    image, calibration = render_left(LOOKING_DOWN_AT_HALF_A_METRE, BOARD)
    with pytest.raises(BoardPoseError, match='no 7x4 checkerboard'):
        board_pose(np.full_like(image, 200), calibration, CheckerBoard(7, 4, 0.03))
