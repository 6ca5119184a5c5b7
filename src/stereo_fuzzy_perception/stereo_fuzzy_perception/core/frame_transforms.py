"""Rigid transforms between named frames, as tf2 holds them: translation + unit quaternion.

`Transform` is what a geometry_msgs/TransformStamped carries (parent frame, child frame, the
child's pose in the parent); `lookup_transform` joins static transforms as tf2's
lookupTransform does. The rotation conversions (quaternion, matrix, URDF roll-pitch-yaw) are
the ones the rig's pose files, URDFs and renderer share. The rig's frame names live here too.

ROS-free: numpy only.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

# The rig's frame names: the best point's frame and the cameras' optical frames.
WORLD_FRAME = 'world'
LEFT_CAMERA_FRAME = 'left_camera_optical_frame'
RIGHT_CAMERA_FRAME = 'right_camera_optical_frame'
_QUATERNION_NORM_TOLERANCE = 1e-3


class RigPoseError(ValueError):
    """A transform, pose file or rig pose that cannot be used; the message says why."""


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


# --- joining transforms ------------------------------------------------------------------------


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

