"""Pose files: the rig's static transforms in the form tf2_ros' static_transform_publisher takes.

One section per transform, named after the node that would publish it::

    left_camera_pose:                  # a node name: -r __node:=left_camera_pose picks it
      ros__parameters:
        frame_id: world
        child_frame_id: left_camera_optical_frame
        translation: {x: 0.17, y: -0.25, z: 0.40}
        rotation: {x: 0.92388, y: 0.0, z: 0.0, w: 0.38268}   # unit quaternion

On a full ROS install the same file runs
`ros2 run tf2_ros static_transform_publisher --ros-args -r __node:=left_camera_pose
--params-file rig_pose.yaml`. rig_calibration writes these files; the nodes read them.

ROS-free: numpy and PyYAML only.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from stereo_fuzzy_perception.core.frame_transforms import (
    LEFT_CAMERA_FRAME,
    WORLD_FRAME,
    RigPoseError,
    Transform,
    lookup_transform,
)
from stereo_fuzzy_perception.core.yaml_file import read_yaml_file


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
