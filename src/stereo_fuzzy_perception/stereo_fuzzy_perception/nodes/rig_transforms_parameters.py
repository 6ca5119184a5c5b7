"""Parameters of rig_transforms_node: the one place their names, defaults and ranges live.

ROS-free, so the README table, the config file test and the node read the same specs.
"""

from __future__ import annotations

from stereo_fuzzy_parameters.spec import ParameterSpec

from stereo_fuzzy_perception.core.rig_pose import LEFT_CAMERA_FRAME, RIGHT_CAMERA_FRAME

PARAMETERS = [
    ParameterSpec('rig_pose_file', '',
                  'Pose file (static_transform_publisher form, written by rig_calibration): '
                  'the left camera optical frame in world, and any other static frames; '
                  'required', read_only=True),
    ParameterSpec('left_calibration_file', '',
                  'Left camera calibration YAML; with the right one, the right camera frame '
                  'is published from the calibration (R of each camera, baseline of the right '
                  'P); empty = not published', read_only=True),
    ParameterSpec('right_calibration_file', '', 'Right camera calibration YAML',
                  read_only=True),
    ParameterSpec('left_frame', LEFT_CAMERA_FRAME,
                  'Left camera optical frame (parent of the right camera frame)',
                  read_only=True),
    ParameterSpec('right_frame', RIGHT_CAMERA_FRAME, 'Right camera optical frame',
                  read_only=True),
]
