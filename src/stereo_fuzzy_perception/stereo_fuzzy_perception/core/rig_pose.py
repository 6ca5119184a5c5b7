"""Where the camera is in `world`: from a pose file, /tf_static, or the chapter's rig numbers.

One representation: the pose of `left_camera_optical_frame` in `world` (and any other static
frame, e.g. a tool or a camera mount) as transforms (core/frame_transforms.py), read from a
pose file (core/pose_file.py) or received on /tf_static. The chapter's alpha, theta, z0 (plus
x0, y0, vergence) are a convenience converted to that transform by
`chapter_left_camera_transform`.

The right camera needs no pose: it follows from the stereo calibration (R of each camera and
the baseline in the right camera's P), see `right_camera_transform`. A configured baseline that
disagrees with the calibration's is refused by `check_baseline` with both numbers.
`CameraPoseSource` is what a node holds: the first of those sources it has.

ROS-free: numpy only.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from stereo_fuzzy_perception.core.camera_model import StereoCalibration
from stereo_fuzzy_perception.core.frame_transforms import (
    LEFT_CAMERA_FRAME,
    RIGHT_CAMERA_FRAME,
    WORLD_FRAME,
    RigPoseError,
    Transform,
    lookup_transform,
)
from stereo_fuzzy_perception.core.pose_file import read_pose_file
from stereo_fuzzy_perception.core.rig_geometry import StereoRig

# CameraPoseSource.origin when the pose comes from the chapter's numbers
RIG_PARAMETERS = 'the rig.* parameters'
# A configured baseline may differ from the calibration's by this much [m] (rounding in files).
BASELINE_TOLERANCE_M = 0.0005


def chapter_left_camera_transform(rig: StereoRig, world_frame: str = WORLD_FRAME,
                                  camera_frame: str = LEFT_CAMERA_FRAME) -> Transform:
    """Convert the chapter's rig description (alpha, theta, z0, x0, y0, vergence, baseline).

    Args:
        rig: The rig; its baseline places the left camera at -baseline/2 from the midpoint.
        world_frame: Parent frame.
        camera_frame: The left camera's optical frame.

    Returns:
        The pose of the left camera's optical frame in `world_frame`.
    """
    return Transform.from_matrix(world_frame, camera_frame, rig.world_from_left_camera())


def right_camera_transform(calibration: StereoCalibration,
                           left_frame: str = LEFT_CAMERA_FRAME,
                           right_frame: str = RIGHT_CAMERA_FRAME) -> Transform:
    """Return the right optical frame's pose in the left's, from the stereo calibration.

    The rectified frames differ by the baseline along x (right P: Tx = -fx * baseline), and each
    camera's R rotates its optical frame into its rectified frame, so
    left <- right = R_left^T [I | (baseline, 0, 0)] R_right.

    Raises:
        RigPoseError: When the calibration is not that of a rectified stereo pair.
    """
    problem = calibration.problem()
    if problem:
        raise RigPoseError(f'stereo calibration: {problem}')
    rectified = np.eye(4)
    rectified[0, 3] = calibration.baseline_m
    left_from_rect, right_rect_from_right = np.eye(4), np.eye(4)
    left_from_rect[:3, :3] = np.asarray(calibration.left.R).T
    right_rect_from_right[:3, :3] = np.asarray(calibration.right.R)
    return Transform.from_matrix(left_frame, right_frame,
                                 left_from_rect @ rectified @ right_rect_from_right)


def check_baseline(configured_m: float, calibration: StereoCalibration,
                   tolerance_m: float = BASELINE_TOLERANCE_M) -> None:
    """Refuse a configured baseline that disagrees with the calibration's.

    Args:
        configured_m: The configured baseline [m].
        calibration: The stereo calibration; its baseline is -Tx / fx of the right P.
        tolerance_m: Largest difference accepted [m].

    Raises:
        RigPoseError: Naming both baselines when they differ by more than `tolerance_m`.
    """
    calibrated = calibration.baseline_m
    if not abs(configured_m - calibrated) <= tolerance_m:
        raise RigPoseError(
            f"rig.baseline_m={configured_m:.4f} m disagrees with the calibration's baseline "
            f'{calibrated:.4f} m (-Tx/fx of the right camera_info P); set rig.baseline_m to 0 '
            'to take it from the calibration, or use a pose file (rig_pose_file)')


# --- where a node takes the camera pose from -------------------------------------------------


@dataclass(frozen=True)
class CameraPoseSource:
    """The camera's pose in `world`: from transforms (a pose file, /tf_static) or the chapter.

    Attributes:
        rig: The chapter's rig numbers; used when `transforms` is empty. Its baseline is
            replaced by the calibration's, so the left camera sits where the calibration says.
        configured_baseline_m: A baseline the user configured [m]; 0 = none (take the
            calibration's). When set, a calibration that disagrees is refused.
        transforms: Static transforms that connect `world_frame` with the camera frame.
        world_frame: Frame of the best point.
        origin: Where the pose comes from, for log lines.
    """

    rig: StereoRig
    configured_baseline_m: float = 0.0
    transforms: tuple[Transform, ...] = ()
    world_frame: str = WORLD_FRAME
    origin: str = RIG_PARAMETERS

    @classmethod
    def from_settings(cls, rig: StereoRig, pose_file: str = '',
                      world_frame: str = WORLD_FRAME) -> CameraPoseSource:
        """Build the source: `pose_file` (when not empty) overrides the rig's pose numbers.

        Args:
            rig: The chapter's numbers; rig.baseline_m > 0 is checked against calibrations.
            pose_file: A pose file, or '' for the chapter's numbers.
            world_frame: Frame of the best point; the pose file must contain it.

        Raises:
            RigPoseError: When the pose file is unusable or never mentions `world_frame`.
        """
        if not pose_file:
            return cls(rig, rig.baseline_m, world_frame=world_frame)
        transforms = tuple(read_pose_file(pose_file))
        frames = {t.frame_id for t in transforms} | {t.child_frame_id for t in transforms}
        if world_frame not in frames:
            raise RigPoseError(f'{pose_file}: no transform mentions the world frame '
                               f'{world_frame!r}; frames: {", ".join(sorted(frames))}')
        return cls(rig, rig.baseline_m, transforms, world_frame, f'pose file {pose_file}')

    def with_transforms(self, transforms: Iterable[Transform], origin: str) -> CameraPoseSource:
        """Return this source taking the pose from `transforms` (e.g. those of /tf_static)."""
        return CameraPoseSource(self.rig, self.configured_baseline_m, tuple(transforms),
                                self.world_frame, origin)

    def connects(self, camera_frame: str) -> bool:
        """Return True when the transforms place `camera_frame` in the world frame."""
        try:
            lookup_transform(self.transforms, self.world_frame, camera_frame)
        except RigPoseError:
            return False
        return True

    def world_from_camera(self, calibration: StereoCalibration,
                          camera_frame: str = LEFT_CAMERA_FRAME) -> np.ndarray:
        """Return the 4x4 world <- camera pose for matches made with `calibration`.

        Args:
            calibration: The rectified calibration the matches were made with.
            camera_frame: The matches' frame (the left optical frame).

        Raises:
            RigPoseError: When a configured baseline disagrees with the calibration's, or the
                transforms do not connect `camera_frame` with the world frame.
        """
        if self.configured_baseline_m > 0.0:
            check_baseline(self.configured_baseline_m, calibration)
        if self.transforms:
            try:
                return lookup_transform(self.transforms, self.world_frame, camera_frame)
            except RigPoseError as error:
                raise RigPoseError(f'{self.origin}: {error}') from error
        rig = StereoRig(baseline_m=calibration.baseline_m, alpha_deg=self.rig.alpha_deg,
                        theta_deg=self.rig.theta_deg, x0_m=self.rig.x0_m, y0_m=self.rig.y0_m,
                        z0_m=self.rig.z0_m, vergence_deg=self.rig.vergence_deg)
        return rig.world_from_left_camera()
