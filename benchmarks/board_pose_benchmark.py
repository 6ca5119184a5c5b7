"""Accuracy of the camera's world pose from a rendered checkerboard (rig_calibration board).

    source scripts/env.sh
    nice python benchmarks/board_pose_benchmark.py                 # the default cases
    nice python benchmarks/board_pose_benchmark.py --oversampling 1 3 5

Renders an 11x8 (30 mm squares) board lying on the work surface at a known place with the
simulator (SceneRenderer.render_plane), finds the left camera's pose by PnP
(core/board_pose.py) and compares it with the pose the board was rendered from. Cases: a camera
0.5 m straight above the board, the demo rig (45 deg tilt, about 0.57 m along its axis) with
the board turned by 93 deg, and the demo rig with lens distortion and sensor noise; each at
every --oversampling (image pixels are the mean of oversampling^2 rendered ones; 1 = as
TinyRenderer renders, with no antialiasing). Prints a markdown table.
"""

from __future__ import annotations

import argparse

import numpy as np
from stereo_fuzzy_perception.core.board_pose import CheckerBoard, board_pose
from stereo_fuzzy_perception.core.frame_transforms import rotation_angle_deg
from stereo_fuzzy_perception.core.rig_geometry import StereoRig
from stereo_fuzzy_perception.simulation.scene_renderer import SceneRenderer, SensorModel

CASES = [
    ('0.5 m straight down', StereoRig(alpha_deg=0.0, z0_m=0.5, x0_m=0.2, y0_m=0.15),
     CheckerBoard(11, 8, 0.03, origin_x_m=0.03, origin_y_m=0.0, yaw_deg=5.0), SensorModel()),
    ('demo rig, board turned 93 deg', StereoRig(),
     CheckerBoard(11, 8, 0.03, origin_x_m=0.36, origin_y_m=-0.03, yaw_deg=93.0), SensorModel()),
    ('demo rig, distortion + noise 2', StereoRig(),
     CheckerBoard(11, 8, 0.03, origin_x_m=0.05, origin_y_m=-0.03, yaw_deg=3.0),
     SensorModel(noise_std=2.0, distortion=(-0.1, 0.02, 0.0, 0.0, 0.0))),
]


def main() -> None:
    """Print the pose errors of every case and oversampling factor."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--oversampling', type=int, nargs='+', default=[1, 3])
    args = parser.parse_args()
    print('| case | oversampling | position error [mm] | rotation error [deg] | '
          'reprojection RMS [px] |')
    print('|---|---|---|---|---|')
    for name, rig, board, sensor in CASES:
        for factor in args.oversampling:
            with SceneRenderer(rig=rig, sensor=sensor) as renderer:
                s = board.square_m
                width, height = board.size_m
                left, _ = renderer.render_plane(board.texture(), board.world_from_board(),
                                                (-s, -s, width + s, height + s),
                                                oversampling=factor)
                found = board_pose(left, renderer.calibration.left, board)
            truth = rig.world_from_left_camera()
            position_mm = 1000.0 * float(np.linalg.norm(found.world_from_camera[:3, 3]
                                                        - truth[:3, 3]))
            rotation_deg = rotation_angle_deg(found.world_from_camera[:3, :3], truth[:3, :3])
            print(f'| {name} | {factor} | {position_mm:.3f} | {rotation_deg:.4f} | '
                  f'{found.reprojection_rms_px:.3f} |')


if __name__ == '__main__':
    main()
