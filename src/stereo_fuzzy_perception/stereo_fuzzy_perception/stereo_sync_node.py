"""Pair left and right images with their calibration into StereoPair messages."""

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node

from .ros_parameters import declare_parameters
from .stereo_sync_parameters import PARAMETERS


class StereoSyncNode(Node):
    """Pair left and right images with their calibration into StereoPair messages."""

    def __init__(self) -> None:
        super().__init__('stereo_sync_node')
        self.parameters = declare_parameters(self, PARAMETERS)
        self.get_logger().info('stereo_sync_node started')


def main(args: list[str] | None = None) -> None:
    """Run the node until shutdown."""
    rclpy.init(args=args)
    node = None
    try:
        node = StereoSyncNode()
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    main()
