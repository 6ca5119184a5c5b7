"""Publish the rig's static frames on /tf_static, as tf2_ros' static_transform_publisher does.

From one pose file (core/rig_pose.py; what rig_calibration writes): world -> the left camera's
optical frame and any other static transform in it; from the stereo calibration files, when
given: left -> right optical frame (R of each camera, baseline of the right P). All of them go
out in one tf2_msgs/TFMessage on /tf_static (reliable, transient local, depth 1), so RViz,
Foxglove, `ros2 bag` and fuzzy_best_point_node, started before or after, get them.
"""

from __future__ import annotations

import sys
from typing import Any

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from stereo_fuzzy_parameters.declaration import declare_parameters
from stereo_fuzzy_parameters.spec import ParameterValue

from stereo_fuzzy_perception.core.camera_calibration_file import (
    CalibrationFileError,
    read_calibration_yaml,
)
from stereo_fuzzy_perception.core.camera_model import StereoCalibration
from stereo_fuzzy_perception.core.rig_pose import (
    RigPoseError,
    Transform,
    read_pose_file,
    right_camera_transform,
)
from stereo_fuzzy_perception.nodes import qos
from stereo_fuzzy_perception.nodes.conversions import transforms_to_tf_message
from stereo_fuzzy_perception.nodes.rig_transforms_parameters import PARAMETERS
from tf2_msgs.msg import TFMessage

TF_STATIC_TOPIC = '/tf_static'


def rig_transforms(values: dict[str, ParameterValue]) -> list[Transform]:
    """Return the static transforms the parameter values describe.

    Raises:
        RigPoseError: No pose file, an unusable one, only one calibration file, or calibration
            files that are not a rectified stereo pair; the message names the parameter.
    """
    pose_file = str(values['rig_pose_file'])
    if not pose_file:
        raise RigPoseError('rig_pose_file is empty: give the pose file written by '
                           'rig_calibration (or by hand, in static_transform_publisher form)')
    transforms = read_pose_file(pose_file)
    left_file, right_file = str(values['left_calibration_file']), str(
        values['right_calibration_file'])
    if bool(left_file) != bool(right_file):
        raise RigPoseError('left_calibration_file and right_calibration_file go together; '
                           f'got {left_file!r} and {right_file!r}')
    if left_file:
        try:
            calibration = StereoCalibration(read_calibration_yaml(left_file),
                                            read_calibration_yaml(right_file))
        except CalibrationFileError as error:
            raise RigPoseError(str(error)) from error
        right = right_camera_transform(calibration, str(values['left_frame']),
                                       str(values['right_frame']))
        if any(t.child_frame_id == right.child_frame_id for t in transforms):
            raise RigPoseError(f'{pose_file} already places {right.child_frame_id}; the '
                               'calibration files would place it a second time')
        transforms.append(right)
    return transforms


def check_parameters(values: dict[str, ParameterValue]) -> str | None:
    """Return why the parameter values cannot work, or None."""
    try:
        rig_transforms(values)
    except RigPoseError as error:
        return str(error)
    return None


class RigTransformsNode(Node):
    """Publish the rig's static frames on /tf_static."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__('rig_transforms_node', **kwargs)
        self.parameters = declare_parameters(self, PARAMETERS, validate=check_parameters)
        self.transforms = rig_transforms(self.parameters)
        self.publisher = self.create_publisher(TFMessage, TF_STATIC_TOPIC,
                                               qos.TF_STATIC_BROADCAST)
        self.publisher.publish(transforms_to_tf_message(
            self.transforms, self.get_clock().now().to_msg()))
        self.get_logger().info('publishing on /tf_static: ' + ', '.join(
            f'{t.frame_id} -> {t.child_frame_id}' for t in self.transforms))


def main(args: list[str] | None = None) -> None:
    """Run the node until shutdown; an unusable pose or calibration file ends it (exit 1)."""
    rclpy.init(args=args)
    node = None
    failed = False
    try:
        node = RigTransformsNode()
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except ValueError as error:  # RigPoseError, or a parameter refused at declaration
        rclpy.logging.get_logger('rig_transforms_node').fatal(f'cannot start: {error}')
        failed = True
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    if failed:
        sys.exit(1)


if __name__ == '__main__':
    main()
