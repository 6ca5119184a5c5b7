"""The rig's pose as ROS describes it: transforms (translation + quaternion) between named frames.

One representation: the pose of `left_camera_optical_frame` in `world` (and any other static
frame, e.g. a tool or a camera mount) as a transform, read from a *pose file* in the form
tf2_ros' static_transform_publisher takes as a parameter file, one section per transform::

    left_camera_pose:                  # a node name: -r __node:=left_camera_pose picks it
      ros__parameters:
        frame_id: world
        child_frame_id: left_camera_optical_frame
        translation: {x: 0.17, y: -0.25, z: 0.40}
        rotation: {x: 0.92388, y: 0.0, z: 0.0, w: 0.38268}   # unit quaternion

On a full ROS install the same file runs
`ros2 run tf2_ros static_transform_publisher --ros-args -r __node:=left_camera_pose
--params-file rig_pose.yaml`. The chapter's alpha, theta, z0 (plus x0, y0, vergence) are a
convenience converted to that transform by `chapter_left_camera_transform`.

The right camera needs no pose: it follows from the stereo calibration (R of each camera and
the baseline in the right camera's P), see `right_camera_transform`. A configured baseline that
disagrees with the calibration's is refused by `check_baseline` with both numbers.

ROS-free: numpy and PyYAML only.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from stereo_fuzzy_perception.core.camera_model import StereoCalibration
from stereo_fuzzy_perception.core.rig_geometry import StereoRig
from stereo_fuzzy_perception.core.yaml_file import read_yaml_file

WORLD_FRAME = 'world'
LEFT_CAMERA_FRAME = 'left_camera_optical_frame'
RIGHT_CAMERA_FRAME = 'right_camera_optical_frame'
# CameraPoseSource.origin when the pose comes from the chapter's numbers
RIG_PARAMETERS = 'the rig.* parameters'
# A configured baseline may differ from the calibration's by this much [m] (rounding in files).
BASELINE_TOLERANCE_M = 0.0005
_QUATERNION_NORM_TOLERANCE = 1e-3


class RigPoseError(ValueError):
    """A pose file or rig pose that cannot be used; the message names the value and the rule."""


@dataclass(frozen=True)
class Transform:
    """The pose of `child_frame_id` in `frame_id` (what geometry_msgs/TransformStamped holds).

    Attributes:
        frame_id: Parent frame.
        child_frame_id: Child frame.
        translation: (x, y, z) of the child's origin in the parent [m].
        rotation: Unit quaternion (x, y, z, w): parent <- child rotation.
    """

    frame_id: str
    child_frame_id: str
    translation: tuple[float, float, float]
    rotation: tuple[float, float, float, float]

    @classmethod
    def from_matrix(cls, frame_id: str, child_frame_id: str, pose: np.ndarray) -> Transform:
        """Return the transform of a 4x4 homogeneous pose (parent <- child)."""
        matrix = np.asarray(pose, dtype=float)
        x, y, z = (float(value) for value in matrix[:3, 3])
        return cls(frame_id, child_frame_id, (x, y, z), quaternion_from_matrix(matrix[:3, :3]))

    def matrix(self) -> np.ndarray:
        """Return the 4x4 homogeneous pose parent <- child."""
        pose = np.eye(4)
        pose[:3, :3] = matrix_from_quaternion(self.rotation)
        pose[:3, 3] = self.translation
        return pose

    def problem(self) -> str | None:
        """Return why this transform is unusable, or None."""
        if not self.frame_id or not self.child_frame_id:
            return f'frame_id {self.frame_id!r} and child_frame_id {self.child_frame_id!r} ' \
                   'must both be set'
        if self.frame_id == self.child_frame_id:
            return f'frame_id and child_frame_id are both {self.frame_id!r}'
        for frame in (self.frame_id, self.child_frame_id):
            if frame.startswith('/'):
                return f'frame {frame!r} starts with / (tf2 refuses such frame ids)'
        values = (*self.translation, *self.rotation)
        if not all(math.isfinite(value) for value in values):
            return f'{self.child_frame_id}: translation or rotation holds NaN or infinity'
        norm = math.sqrt(sum(value * value for value in self.rotation))
        if abs(norm - 1.0) > _QUATERNION_NORM_TOLERANCE:
            return (f'{self.child_frame_id}: rotation (x, y, z, w) = {self.rotation} has norm '
                    f'{norm:.6f}; expected a unit quaternion')
        return None


# --- rotations -------------------------------------------------------------------------------


def matrix_from_quaternion(quaternion: Sequence[float]) -> np.ndarray:
    """Return the 3x3 rotation of a quaternion (x, y, z, w); normalised first."""
    x, y, z, w = (float(value) for value in quaternion)
    norm = math.sqrt(x * x + y * y + z * z + w * w)
    if norm == 0.0:
        raise RigPoseError('rotation quaternion (0, 0, 0, 0) has no direction')
    x, y, z, w = x / norm, y / norm, z / norm, w / norm
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def quaternion_from_matrix(rotation: np.ndarray) -> tuple[float, float, float, float]:
    """Return the unit quaternion (x, y, z, w) of a 3x3 rotation, with w >= 0."""
    m = np.asarray(rotation, dtype=float)
    trace = float(m[0, 0] + m[1, 1] + m[2, 2])
    if trace > 0.0:
        s = 2.0 * math.sqrt(trace + 1.0)
        q = (float(m[2, 1] - m[1, 2]) / s, float(m[0, 2] - m[2, 0]) / s,
             float(m[1, 0] - m[0, 1]) / s, 0.25 * s)
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * math.sqrt(max(1.0 + m[0, 0] - m[1, 1] - m[2, 2], 0.0))
        q = (0.25 * s, float(m[0, 1] + m[1, 0]) / s, float(m[0, 2] + m[2, 0]) / s,
             float(m[2, 1] - m[1, 2]) / s)
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * math.sqrt(max(1.0 + m[1, 1] - m[0, 0] - m[2, 2], 0.0))
        q = (float(m[0, 1] + m[1, 0]) / s, 0.25 * s, float(m[1, 2] + m[2, 1]) / s,
             float(m[0, 2] - m[2, 0]) / s)
    else:
        s = 2.0 * math.sqrt(max(1.0 + m[2, 2] - m[0, 0] - m[1, 1], 0.0))
        q = (float(m[0, 2] + m[2, 0]) / s, float(m[1, 2] + m[2, 1]) / s, 0.25 * s,
             float(m[1, 0] - m[0, 1]) / s)
    norm = math.sqrt(sum(value * value for value in q))
    sign = -1.0 if q[3] < 0.0 else 1.0
    x, y, z, w = (sign * value / norm for value in q)
    return (x, y, z, w)


def rpy_from_matrix(rotation: np.ndarray) -> tuple[float, float, float]:
    """Return URDF roll, pitch, yaw [rad]: R = Rz(yaw) Ry(pitch) Rx(roll)."""
    m = np.asarray(rotation, dtype=float)
    pitch = math.asin(max(-1.0, min(1.0, -float(m[2, 0]))))
    if abs(math.cos(pitch)) > 1e-9:
        roll = math.atan2(float(m[2, 1]), float(m[2, 2]))
        yaw = math.atan2(float(m[1, 0]), float(m[0, 0]))
    else:  # gimbal lock: put everything into yaw
        roll = 0.0
        yaw = math.atan2(-float(m[0, 1]), float(m[1, 1]))
    return roll, pitch, yaw


def rotation_angle_deg(rotation_a: np.ndarray, rotation_b: np.ndarray) -> float:
    """Return the angle of the rotation that takes `rotation_a` to `rotation_b` [deg]."""
    relative = np.asarray(rotation_a).T @ np.asarray(rotation_b)
    cosine = (float(np.trace(relative)) - 1.0) / 2.0
    return math.degrees(math.acos(max(-1.0, min(1.0, cosine))))


# --- the rig's frames ------------------------------------------------------------------------


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


def lookup_transform(transforms: Iterable[Transform], target_frame: str,
                     source_frame: str) -> np.ndarray:
    """Return the 4x4 pose of `source_frame` in `target_frame` through a tree of transforms.

    Like tf2's lookupTransform(target, source) on static transforms: frames are joined by
    walking each one up to its root.

    Raises:
        RigPoseError: When the frames are not connected (the message lists the known frames).
    """
    parent_of: dict[str, Transform] = {}
    for transform in transforms:
        parent_of[transform.child_frame_id] = transform

    def to_root(frame: str) -> tuple[str, np.ndarray, list[str]]:
        pose, chain = np.eye(4), [frame]
        while frame in parent_of:
            transform = parent_of[frame]
            pose = transform.matrix() @ pose
            frame = transform.frame_id
            if frame in chain:
                raise RigPoseError(f'transforms form a loop through {frame!r}')
            chain.append(frame)
        return frame, pose, chain

    target_root, root_from_target, _ = to_root(target_frame)
    source_root, root_from_source, _ = to_root(source_frame)
    if target_root != source_root:
        known = sorted({t.frame_id for t in parent_of.values()} | set(parent_of))
        raise RigPoseError(
            f'no transform from {source_frame!r} to {target_frame!r}; known frames: '
            f'{", ".join(known) or "none"}')
    pose: np.ndarray = np.linalg.inv(root_from_target) @ root_from_source
    return pose


# --- pose files ------------------------------------------------------------------------------


def read_pose_file(path: str | Path) -> list[Transform]:
    """Read the transforms of a pose file (static_transform_publisher parameter sections).

    Every top-level section `<node name>: ros__parameters:` with frame_id, child_frame_id,
    translation {x, y, z} and rotation {x, y, z, w} is one transform; the dotted form
    (`translation.x: ...`) is read too.

    Raises:
        RigPoseError: When the file cannot be read, holds no transform, or a transform is
            incomplete or not a unit rotation; the message names the file and section.
    """
    path = Path(path)
    document = read_yaml_file(path, RigPoseError, 'pose file')
    if not isinstance(document, dict) or not document:
        raise RigPoseError(f'{path}: expected sections `<name>: ros__parameters: {{frame_id, '
                           f'child_frame_id, translation, rotation}}`, got {document!r:.80}')
    transforms = []
    for section, body in document.items():
        if not isinstance(body, dict) or not isinstance(body.get('ros__parameters'), dict):
            raise RigPoseError(f'{path}: section {section!r} has no ros__parameters mapping')
        transforms.append(_transform_of(body['ros__parameters'], f'{path}: {section}'))
    children = [transform.child_frame_id for transform in transforms]
    duplicates = sorted({child for child in children if children.count(child) > 1})
    if duplicates:
        raise RigPoseError(f'{path}: frame(s) {", ".join(duplicates)} have more than one pose')
    return transforms


def _transform_of(parameters: dict[str, Any], where: str) -> Transform:
    flat = _flatten(parameters)
    missing = [key for key in ('frame_id', 'child_frame_id', 'translation.x', 'translation.y',
                               'translation.z', 'rotation.x', 'rotation.y', 'rotation.z',
                               'rotation.w') if key not in flat]
    if missing:
        raise RigPoseError(f'{where}: missing {", ".join(missing)}')
    numbers = {}
    for key in ('translation.x', 'translation.y', 'translation.z', 'rotation.x', 'rotation.y',
                'rotation.z', 'rotation.w'):
        value = flat[key]
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise RigPoseError(f'{where}: {key} must be a number, got {value!r}')
        numbers[key] = float(value)
    transform = Transform(
        str(flat['frame_id']), str(flat['child_frame_id']),
        (numbers['translation.x'], numbers['translation.y'], numbers['translation.z']),
        (numbers['rotation.x'], numbers['rotation.y'], numbers['rotation.z'],
         numbers['rotation.w']))
    problem = transform.problem()
    if problem:
        raise RigPoseError(f'{where}: {problem}')
    return transform


def _flatten(mapping: dict[str, Any], prefix: str = '') -> dict[str, Any]:
    flat: dict[str, Any] = {}
    for key, value in mapping.items():
        name = f'{prefix}{key}'
        if isinstance(value, dict):
            flat.update(_flatten(value, name + '.'))
        else:
            flat[name] = value
    return flat


def section_name(transform: Transform) -> str:
    """Return the section (node) name a transform gets in a pose file: `<child>_pose`."""
    child = transform.child_frame_id.removesuffix('_optical_frame').removesuffix('_frame')
    return f'{child}_pose'


def pose_file_text(transforms: Sequence[Transform], comment: str = '') -> str:
    """Return a pose file holding `transforms`, with `comment` lines at the top."""
    document = {
        section_name(transform): {'ros__parameters': {
            'frame_id': transform.frame_id,
            'child_frame_id': transform.child_frame_id,
            'translation': dict(zip('xyz', (round(v, 9) for v in transform.translation),
                                    strict=True)),
            'rotation': dict(zip('xyzw', (round(v, 12) for v in transform.rotation),
                                 strict=True)),
        }} for transform in transforms}
    header = ''.join(f'# {line}\n' if line else '#\n' for line in comment.splitlines())
    body: str = yaml.safe_dump(document, sort_keys=False, default_flow_style=None)
    return header + body


def write_pose_file(path: str | Path, transforms: Sequence[Transform], comment: str = '') -> None:
    """Write `transforms` to a pose file (overwritten)."""
    Path(path).write_text(pose_file_text(transforms, comment))


def camera_pose_from_file(path: str | Path, world_frame: str = WORLD_FRAME,
                          camera_frame: str = LEFT_CAMERA_FRAME) -> np.ndarray:
    """Return the 4x4 pose of `camera_frame` in `world_frame` from a pose file.

    Raises:
        RigPoseError: When the file is unusable or does not connect the two frames.
    """
    transforms = read_pose_file(path)
    try:
        return lookup_transform(transforms, world_frame, camera_frame)
    except RigPoseError as error:
        raise RigPoseError(f'{path}: {error}') from error


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
