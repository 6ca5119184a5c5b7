"""Match a stereo pair by window correlation and publish triangulated matches."""

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node

from .correlation_parameters import PARAMETERS
from .ros_parameters import declare_parameters


class CorrelationNode(Node):
    """Match a stereo pair by window correlation and publish triangulated matches."""

    def __init__(self) -> None:
        super().__init__('correlation_node')
        self.parameters = declare_parameters(self, PARAMETERS)
        self.get_logger().info('correlation_node started')


def main(args: list[str] | None = None) -> None:
    """Run the node until shutdown."""
    rclpy.init(args=args)
    node = None
    try:
        node = CorrelationNode()
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    main()
