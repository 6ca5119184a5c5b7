"""Drive a Grbl-compatible 3-axis gantry from best points over a serial line."""

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node

from .gantry_driver_parameters import PARAMETERS
from .ros_parameters import declare_parameters


class GantryDriverNode(Node):
    """Drive a Grbl-compatible 3-axis gantry from best points over a serial line."""

    def __init__(self) -> None:
        super().__init__('gantry_driver_node')
        self.parameters = declare_parameters(self, PARAMETERS)
        self.get_logger().info('gantry_driver_node started')


def main(args: list[str] | None = None) -> None:
    """Run the node until shutdown."""
    rclpy.init(args=args)
    node = None
    try:
        node = GantryDriverNode()
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    main()
