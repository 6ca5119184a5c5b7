"""Publish the rig's static frames on /tf_static, as tf2_ros' static_transform_publisher does.

From one pose file (core/pose_file.py; what rig_calibration writes): world -> the left camera's
optical frame and any other static transform in it; from the stereo calibration files, when
given: left -> right optical frame (R of each camera, baseline of the right P). All of them go
out in one tf2_msgs/TFMessage on /tf_static (reliable, transient local, depth 1), so RViz,
Foxglove, `ros2 bag` and fuzzy_best_point_node, started before or after, get them.
"""

from __future__ import annotations

from typing import Any

from rclpy.node import Node
from stereo_fuzzy_parameters.declaration import declare_settings, run_node

from stereo_fuzzy_perception.core.camera_calibration_file import (
    CalibrationFileError,
    read_calibration_yaml,
)
from stereo_fuzzy_perception.core.camera_model import StereoCalibration
from stereo_fuzzy_perception.core.frame_transforms import RigPoseError, Transform
from stereo_fuzzy_perception.core.pose_file import read_pose_file
from stereo_fuzzy_perception.core.rig_pose import right_camera_transform
from stereo_fuzzy_perception.nodes import qos, topic_names
from stereo_fuzzy_perception.nodes.conversions import transforms_to_tf_message
from stereo_fuzzy_perception.nodes.rig_transforms_parameters import RigTransformsSettings
from tf2_msgs.msg import TFMessage


def rig_transforms(settings: RigTransformsSettings) -> list[Transform]:
    """Return the static transforms the settings describe.

    Raises:
        RigPoseError: No pose file, an unusable one, only one calibration file, or calibration
            files that are not a rectified stereo pair; the message names the parameter.
    """
    pose_file = settings.rig_pose_file
    if not pose_file:
        raise RigPoseError('rig_pose_file is empty: give the pose file written by '
                           'rig_calibration (or by hand, in static_transform_publisher form)')
    transforms = read_pose_file(pose_file)
    left_file, right_file = settings.left_calibration_file, settings.right_calibration_file
    if bool(left_file) != bool(right_file):
        raise RigPoseError('left_calibration_file and right_calibration_file go together; '
                           f'got {left_file!r} and {right_file!r}')
    if left_file:
        try:
            calibration = StereoCalibration(read_calibration_yaml(left_file),
                                            read_calibration_yaml(right_file))
        except CalibrationFileError as error:
            raise RigPoseError(str(error)) from error
        right = right_camera_transform(calibration, settings.left_frame, settings.right_frame)
        if any(t.child_frame_id == right.child_frame_id for t in transforms):
            raise RigPoseError(f'{pose_file} already places {right.child_frame_id}; the '
                               'calibration files would place it a second time')
        transforms.append(right)
    return transforms


def transforms_problem(settings: RigTransformsSettings) -> str | None:
    """Return why the settings give no usable transforms, or None."""
    try:
        rig_transforms(settings)
    except RigPoseError as error:
        return str(error)
    return None


class RigTransformsNode(Node):
    """Publish the rig's static frames on /tf_static."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__('rig_transforms_node', **kwargs)
        self.settings = declare_settings(self, RigTransformsSettings, check=transforms_problem)
        self.transforms = rig_transforms(self.settings)
        self.publisher = self.create_publisher(TFMessage, topic_names.TF_STATIC,
                                               qos.TF_STATIC_BROADCAST)
        self.publisher.publish(transforms_to_tf_message(
            self.transforms, self.get_clock().now().to_msg()))
        self.get_logger().info('publishing on /tf_static: ' + ', '.join(
            f'{t.frame_id} -> {t.child_frame_id}' for t in self.transforms))


def main(args: list[str] | None = None) -> None:
    """Run the node until shutdown; an unusable pose or calibration file ends it (exit 1)."""
    run_node(RigTransformsNode, args)
