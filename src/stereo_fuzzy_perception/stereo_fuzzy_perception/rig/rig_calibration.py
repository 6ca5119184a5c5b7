"""rig_calibration: write the rig's pose file (and the gantry's URDF) for a new rig.

    # The left camera's world pose from a checkerboard lying on the work surface at a known
    # place, seen by the calibrated left camera (an image file or one frame of a device):
    rig_calibration board --left-calibration left.yaml --image board.png \\
        --columns 9 --rows 6 --square 0.025 --origin-x 0.05 --origin-y 0.02 --yaw 0 \\
        --output rig_pose.yaml

    # The chapter's alpha, theta, z0 (+ x0, y0, vergence) converted to the same pose file; the
    # baseline comes from the calibration files when given:
    rig_calibration chapter --alpha 45 --theta 0 --z0 0.40 --x0 0.20 --y0 -0.25 \\
        --vergence 6 --left-calibration left.yaml --right-calibration right.yaml \\
        --output rig_pose.yaml

    # The URDF of the gantry (limits = workspace) with the cameras of a pose file (and the
    # right camera from the calibration files, when given):
    rig_calibration urdf --pose-file rig_pose.yaml --output cartesian_3p.urdf

The pose file is what fuzzy_best_point_node (rig_pose_file), rig_transforms_node and tf2_ros'
static_transform_publisher read. ROS-free: a command-line adapter around core/board_pose.py,
core/rig_pose.py, core/pose_file.py and core/rig_description.py.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import cv2
import numpy as np

from stereo_fuzzy_perception.core.board_pose import BoardPoseError, CheckerBoard, board_pose
from stereo_fuzzy_perception.core.camera_calibration_file import (
    CalibrationFileError,
    read_calibration_yaml,
)
from stereo_fuzzy_perception.core.camera_model import StereoCalibration
from stereo_fuzzy_perception.core.frame_transforms import (
    LEFT_CAMERA_FRAME,
    WORLD_FRAME,
    RigPoseError,
    Transform,
    rpy_from_matrix,
)
from stereo_fuzzy_perception.core.pose_file import read_pose_file, write_pose_file
from stereo_fuzzy_perception.core.rig_description import JOINT_NAMES, gantry_urdf
from stereo_fuzzy_perception.core.rig_geometry import StereoRig
from stereo_fuzzy_perception.core.rig_pose import (
    chapter_left_camera_transform,
    right_camera_transform,
)

# A PnP fit worse than this is refused: the board, its place or the calibration is wrong.
DEFAULT_MAX_RMS_PX = 1.0
DEFAULT_WORKSPACE_MIN = (0.0, 0.0, 0.0)
DEFAULT_WORKSPACE_MAX = (0.40, 0.30, 0.20)


class RigCalibrationError(ValueError):
    """Input the helper cannot use; the message says which and why."""


def describe(transform: Transform) -> str:
    """Return the transform as one readable line (translation [m], roll/pitch/yaw [deg])."""
    roll, pitch, yaw = (math.degrees(angle) for angle in rpy_from_matrix(
        transform.matrix()[:3, :3]))
    x, y, z = transform.translation
    return (f'{transform.frame_id} -> {transform.child_frame_id}: '
            f'translation ({x:.4f}, {y:.4f}, {z:.4f}) m, roll/pitch/yaw '
            f'({roll:.3f}, {pitch:.3f}, {yaw:.3f}) deg, quaternion (x, y, z, w) '
            f'({", ".join(f"{q:.6f}" for q in transform.rotation)})')


def read_image(image: str, device: str, skip_frames: int = 0) -> np.ndarray:
    """Return the grey image of a file, or a frame of an OpenCV capture device.

    Args:
        image: Image file, or '' to read `device`.
        device: Device index or path (or a video file).
        skip_frames: Frames of the device to drop first (auto exposure settling).
    """
    if image:
        loaded = cv2.imread(image, cv2.IMREAD_GRAYSCALE)
        if loaded is None:
            raise RigCalibrationError(f'--image {image}: cannot read it as an image')
        return np.asarray(loaded)
    capture = cv2.VideoCapture(int(device) if device.isdigit() else device)
    try:
        for _ in range(skip_frames):
            capture.grab()
        ok, frame = capture.read()
    finally:
        capture.release()
    if not ok or frame is None:
        raise RigCalibrationError(f'--device {device}: no frame could be read')
    return np.asarray(cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY))


def run_board(args: argparse.Namespace) -> str:
    """Find the left camera's world pose from a board image; write the pose file."""
    left = read_calibration_yaml(args.left_calibration)
    board = CheckerBoard(args.columns, args.rows, args.square, args.origin_x, args.origin_y,
                         args.yaw, args.surface_z)
    image = read_image(args.image, args.device, args.skip_frames)
    if (image.shape[1], image.shape[0]) != (left.width, left.height):
        raise RigCalibrationError(
            f'image is {image.shape[1]}x{image.shape[0]} but {args.left_calibration} is for '
            f'{left.width}x{left.height}')
    found = board_pose(image, left, board)
    transform = Transform.from_matrix(args.world_frame, args.camera_frame,
                                      found.world_from_camera)
    report = [f'{len(found.corners_px)} corners found; reprojection error RMS '
              f'{found.reprojection_rms_px:.3f} px, max {found.reprojection_max_px:.3f} px',
              describe(transform)]
    if found.reprojection_rms_px > args.max_rms_px:
        raise RigCalibrationError(
            '\n'.join(report) + f'\nreprojection RMS {found.reprojection_rms_px:.3f} px is above '
            f'--max-rms-px {args.max_rms_px}: check the board size, the square size and the '
            'calibration; nothing written')
    write_pose_file(args.output, [transform], (
        f'Pose of {args.camera_frame} in {args.world_frame}, written by rig_calibration board\n'
        f'from a {args.columns}x{args.rows} board ({args.square} m squares) at '
        f'({args.origin_x}, {args.origin_y}, {args.surface_z}) m, yaw {args.yaw} deg;\n'
        f'reprojection error RMS {found.reprojection_rms_px:.3f} px, max '
        f'{found.reprojection_max_px:.3f} px.\n'
        'Publish with: ros2 run tf2_ros static_transform_publisher --ros-args '
        '-r __node:=left_camera_pose --params-file THIS_FILE'))
    report.append(f'wrote {args.output}')
    return '\n'.join(report)


def run_chapter(args: argparse.Namespace) -> str:
    """Convert the chapter's numbers into the pose file."""
    baseline = args.baseline
    if args.left_calibration or args.right_calibration:
        if not (args.left_calibration and args.right_calibration):
            raise RigCalibrationError('--left-calibration and --right-calibration go together')
        calibration = StereoCalibration(read_calibration_yaml(args.left_calibration),
                                        read_calibration_yaml(args.right_calibration))
        problem = calibration.problem()
        if problem:
            raise RigCalibrationError(f'calibration files: {problem}')
        if baseline is not None and abs(baseline - calibration.baseline_m) > 0.0005:
            raise RigCalibrationError(
                f"--baseline {baseline:.4f} m disagrees with the calibration's baseline "
                f'{calibration.baseline_m:.4f} m (-Tx/fx of the right P)')
        baseline = calibration.baseline_m
    if baseline is None:
        raise RigCalibrationError('give --baseline or the two calibration files: the left '
                                  'camera sits baseline/2 from the midpoint x0, y0, z0')
    rig = StereoRig(baseline_m=baseline, alpha_deg=args.alpha, theta_deg=args.theta,
                    x0_m=args.x0, y0_m=args.y0, z0_m=args.z0, vergence_deg=args.vergence)
    transform = chapter_left_camera_transform(rig, args.world_frame, args.camera_frame)
    write_pose_file(args.output, [transform], (
        f'Pose of {args.camera_frame} in {args.world_frame}, converted by rig_calibration '
        f'chapter from\nalpha {args.alpha} deg, theta {args.theta} deg, x0 {args.x0} m, '
        f'y0 {args.y0} m, z0 {args.z0} m,\nvergence {args.vergence} deg, baseline '
        f'{baseline:.4f} m.'))
    return f'{describe(transform)}\nwrote {args.output}'


def run_urdf(args: argparse.Namespace) -> str:
    """Write the gantry's URDF with the mounts of a pose file."""
    mounts = read_pose_file(args.pose_file) if args.pose_file else []
    if args.left_calibration or args.right_calibration:
        if not (args.left_calibration and args.right_calibration):
            raise RigCalibrationError('--left-calibration and --right-calibration go together')
        mounts.append(right_camera_transform(StereoCalibration(
            read_calibration_yaml(args.left_calibration),
            read_calibration_yaml(args.right_calibration))))
    text = gantry_urdf(args.workspace_min, args.workspace_max, mounts, args.joint_names)
    Path(args.output).write_text(text)
    return f'wrote {args.output} ({len(mounts)} mount(s) from {args.pose_file or "no file"})'


def build_parser() -> argparse.ArgumentParser:
    """Return the command line of rig_calibration."""
    parser = argparse.ArgumentParser(prog='rig_calibration', description=__doc__.split(
        '\n')[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    commands = parser.add_subparsers(dest='command', required=True)

    def frames(command: argparse.ArgumentParser) -> None:
        command.add_argument('--world-frame', default=WORLD_FRAME)
        command.add_argument('--camera-frame', default=LEFT_CAMERA_FRAME)
        command.add_argument('--output', '-o', required=True, help='pose file to write')

    board = commands.add_parser('board', help='left camera pose from a checkerboard (PnP)')
    board.add_argument('--left-calibration', required=True,
                       help='left camera calibration YAML (ROS camera-calibration format)')
    source = board.add_mutually_exclusive_group(required=True)
    source.add_argument('--image', default='', help='image file of the left camera')
    source.add_argument('--device', default='', help='OpenCV capture device (index or path)')
    board.add_argument('--skip-frames', type=int, default=10,
                       help='with --device: frames to drop first, while exposure settles')
    board.add_argument('--columns', type=int, default=9, help='inner corners along board x')
    board.add_argument('--rows', type=int, default=6, help='inner corners along board y')
    board.add_argument('--square', type=float, default=0.025, help='square side [m]')
    board.add_argument('--origin-x', type=float, required=True,
                       help='world x of the printed corner at the dark corner square [m]')
    board.add_argument('--origin-y', type=float, required=True, help='its world y [m]')
    board.add_argument('--yaw', type=float, default=0.0,
                       help='angle of the board x axis from world x [deg]')
    board.add_argument('--surface-z', type=float, default=0.0,
                       help='world z of the board top (surface + thickness) [m]')
    board.add_argument('--max-rms-px', type=float, default=DEFAULT_MAX_RMS_PX,
                       help='refuse a fit with a larger reprojection RMS [px]')
    frames(board)
    board.set_defaults(run=run_board)

    chapter = commands.add_parser('chapter', help="the chapter's alpha, theta, z0 as a pose")
    chapter.add_argument('--alpha', type=float, required=True, help='tilt [deg]')
    chapter.add_argument('--theta', type=float, required=True, help='pan [deg]')
    chapter.add_argument('--z0', type=float, required=True, help='height of the midpoint [m]')
    chapter.add_argument('--x0', type=float, required=True, help='x of the midpoint [m]')
    chapter.add_argument('--y0', type=float, required=True, help='y of the midpoint [m]')
    chapter.add_argument('--vergence', type=float, default=0.0, help='total toe-in [deg]')
    chapter.add_argument('--baseline', type=float, default=None,
                         help='[m]; checked against the calibration files when given')
    chapter.add_argument('--left-calibration', default='')
    chapter.add_argument('--right-calibration', default='')
    frames(chapter)
    chapter.set_defaults(run=run_chapter)

    urdf = commands.add_parser('urdf', help='URDF of the gantry with the mounts of a pose file')
    urdf.add_argument('--pose-file', default='', help='pose file whose frames to mount')
    urdf.add_argument('--workspace-min', type=float, nargs=3, default=DEFAULT_WORKSPACE_MIN,
                      metavar=('X', 'Y', 'Z'), help='lower joint limits [m]')
    urdf.add_argument('--workspace-max', type=float, nargs=3, default=DEFAULT_WORKSPACE_MAX,
                      metavar=('X', 'Y', 'Z'), help='upper joint limits [m]')
    urdf.add_argument('--joint-names', nargs=3, default=list(JOINT_NAMES))
    urdf.add_argument('--left-calibration', default='',
                      help='with --right-calibration: mount the right camera on the left one')
    urdf.add_argument('--right-calibration', default='')
    urdf.add_argument('--output', '-o', required=True, help='URDF file to write')
    urdf.set_defaults(run=run_urdf)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run rig_calibration; print the result, or one line saying what is wrong (exit 1)."""
    args = build_parser().parse_args(argv)
    try:
        print(args.run(args))
    except (RigCalibrationError, RigPoseError, BoardPoseError, CalibrationFileError,
            OSError) as error:
        print(f'rig_calibration {args.command}: {error}', file=sys.stderr)
        return 1
    return 0


if __name__ == '__main__':
    sys.exit(main())
