"""Settings of rig_transforms_node: its parameters' names, defaults and docs, once.

ROS-free, so the README table and the node read the same declarations.
"""

from __future__ import annotations

from dataclasses import dataclass

from stereo_fuzzy_parameters.spec import parameter, parameter_specs

from stereo_fuzzy_perception.core.frame_transforms import LEFT_CAMERA_FRAME, RIGHT_CAMERA_FRAME


@dataclass(frozen=True)
class RigTransformsSettings:
    """Parameters of rig_transforms_node, typed (all wiring: read-only)."""

    rig_pose_file: str = parameter(
        '', 'Pose file (static_transform_publisher form, written by rig_calibration): the left '
        'camera optical frame in world, and any other static frames; required', read_only=True)
    left_calibration_file: str = parameter(
        '', 'Left camera calibration YAML; with the right one, the right camera frame is '
        'published from the calibration (R of each camera, baseline of the right P); empty = '
        'not published', read_only=True)
    right_calibration_file: str = parameter(
        '', 'Right camera calibration YAML', read_only=True)
    left_frame: str = parameter(
        LEFT_CAMERA_FRAME, 'Left camera optical frame (parent of the right camera frame)',
        read_only=True)
    right_frame: str = parameter(
        RIGHT_CAMERA_FRAME, 'Right camera optical frame', read_only=True)


PARAMETERS = parameter_specs(RigTransformsSettings)
