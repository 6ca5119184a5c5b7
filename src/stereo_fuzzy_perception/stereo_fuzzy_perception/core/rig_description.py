"""The URDF of the 3P gantry and its camera mounts, for robot_state_publisher on a full install.

Three prismatic joints in series carry the tool: x (world -> gantry_x_carriage), y (->
gantry_y_carriage), z (-> tool), each along its world axis with zero offset, so the joint
positions the driver publishes on joint_states are the tool's world coordinates and the joint
limits are the workspace box. The cameras hang off `world` by fixed joints whose origins are
the transforms of a pose file (core/pose_file.py), so the URDF and the pose file cannot disagree
when one is generated from the other.

ROS-free: the standard library (and numpy through frame_transforms).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from xml.etree import ElementTree

from stereo_fuzzy_perception.core.frame_transforms import (
    WORLD_FRAME,
    RigPoseError,
    Transform,
    matrix_from_quaternion,
    rpy_from_matrix,
)

JOINT_NAMES = ('gantry_x_joint', 'gantry_y_joint', 'gantry_z_joint')
CARRIAGE_LINKS = ('gantry_x_carriage', 'gantry_y_carriage', 'tool')
TOOL_FRAME = 'tool'
# Joint limits a URDF must give for prismatic joints: [N], [m/s] (the driver clamps feeds).
EFFORT_LIMIT_N = 100.0
VELOCITY_LIMIT_M_S = 0.1


def _number(value: float) -> str:
    text = f'{value:.9f}'.rstrip('0').rstrip('.')
    return '0' if text in ('-0', '') else text


def _vector(values: Sequence[float]) -> str:
    return ' '.join(_number(float(value)) for value in values)


def _box_visual(link: ElementTree.Element, size: Sequence[float],
                colour: tuple[str, str]) -> None:
    visual = ElementTree.SubElement(link, 'visual')
    geometry = ElementTree.SubElement(visual, 'geometry')
    ElementTree.SubElement(geometry, 'box', size=_vector(size))
    material = ElementTree.SubElement(visual, 'material', name=colour[0])
    ElementTree.SubElement(material, 'color', rgba=colour[1])


def gantry_urdf(workspace_min: Sequence[float], workspace_max: Sequence[float],
                mounts: Sequence[Transform] = (), joint_names: Sequence[str] = JOINT_NAMES,
                robot_name: str = 'cartesian_3p') -> str:
    """Return the URDF text of the gantry and its static mounts.

    Args:
        workspace_min: Lower (x, y, z) limits of the tool in `world` [m].
        workspace_max: Upper (x, y, z) limits [m].
        mounts: Static transforms to add as fixed joints (e.g. those of a pose file); each
            parent must be `world` or a frame added before it.
        joint_names: The x, y, z joint names, as the driver publishes them on joint_states.
        robot_name: The robot's name.

    Raises:
        RigPoseError: A limit pair that is empty, or a mount whose parent is unknown.
    """
    for axis, low, high in zip('xyz', workspace_min, workspace_max, strict=True):
        if not low < high:
            raise RigPoseError(f'workspace {axis}: lower limit {low} is not below upper {high}')
    robot = ElementTree.Element('robot', name=robot_name)
    ElementTree.SubElement(robot, 'link', name=WORLD_FRAME)
    span = [high - low for low, high in zip(workspace_min, workspace_max, strict=True)]
    sizes = ((0.03, span[1] + 0.06, 0.03), (0.04, 0.04, 0.04), (0.01, 0.01, 0.05))
    colours = (('rail', '0.6 0.6 0.65 1'), ('carriage', '0.3 0.3 0.35 1'),
               ('tool', '0.9 0.4 0.1 1'))
    parent = WORLD_FRAME
    for index, (joint_name, link_name) in enumerate(zip(joint_names, CARRIAGE_LINKS,
                                                        strict=True)):
        link = ElementTree.SubElement(robot, 'link', name=link_name)
        _box_visual(link, sizes[index], colours[index])
        joint = ElementTree.SubElement(robot, 'joint', name=joint_name, type='prismatic')
        ElementTree.SubElement(joint, 'parent', link=parent)
        ElementTree.SubElement(joint, 'child', link=link_name)
        ElementTree.SubElement(joint, 'origin', xyz='0 0 0', rpy='0 0 0')
        ElementTree.SubElement(joint, 'axis', xyz=_vector(
            [1.0 if k == index else 0.0 for k in range(3)]))
        ElementTree.SubElement(joint, 'limit', lower=_number(workspace_min[index]),
                               upper=_number(workspace_max[index]),
                               effort=_number(EFFORT_LIMIT_N),
                               velocity=_number(VELOCITY_LIMIT_M_S))
        parent = link_name
    known = {WORLD_FRAME, *CARRIAGE_LINKS}
    for mount in mounts:
        if mount.frame_id not in known:
            raise RigPoseError(f'mount {mount.child_frame_id}: parent {mount.frame_id!r} is '
                               f'not a link of the URDF ({", ".join(sorted(known))})')
        link = ElementTree.SubElement(robot, 'link', name=mount.child_frame_id)
        if mount.child_frame_id.endswith('camera_optical_frame'):
            # A camera body: 3 cm deep behind the optical centre, along optical z.
            visual = ElementTree.SubElement(link, 'visual')
            ElementTree.SubElement(visual, 'origin', xyz='0 0 -0.015', rpy='0 0 0')
            geometry = ElementTree.SubElement(visual, 'geometry')
            ElementTree.SubElement(geometry, 'box', size='0.03 0.02 0.03')
            material = ElementTree.SubElement(visual, 'material', name='camera')
            ElementTree.SubElement(material, 'color', rgba='0.1 0.1 0.1 1')
        joint = ElementTree.SubElement(robot, 'joint', name=f'{mount.child_frame_id}_joint',
                                       type='fixed')
        ElementTree.SubElement(joint, 'parent', link=mount.frame_id)
        ElementTree.SubElement(joint, 'child', link=mount.child_frame_id)
        roll, pitch, yaw = rpy_from_matrix(matrix_from_quaternion(mount.rotation))
        ElementTree.SubElement(joint, 'origin', xyz=_vector(mount.translation),
                               rpy=_vector([_wrap(roll), _wrap(pitch), _wrap(yaw)]))
        known.add(mount.child_frame_id)
    ElementTree.indent(robot, space='  ')
    body = ElementTree.tostring(robot, encoding='unicode')
    return '<?xml version="1.0"?>\n' + body + '\n'


def _wrap(angle: float) -> float:
    return math.remainder(angle, 2.0 * math.pi)
