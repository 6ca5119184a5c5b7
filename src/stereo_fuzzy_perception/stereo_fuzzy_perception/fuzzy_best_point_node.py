"""Choose the best point of the correlation area with the fuzzy system."""

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node

from .fuzzy_best_point_parameters import PARAMETERS
from .ros_parameters import declare_parameters


class FuzzyBestPointNode(Node):
    """Choose the best point of the correlation area with the fuzzy system."""

    def __init__(self) -> None:
        super().__init__('fuzzy_best_point_node')
        self.parameters = declare_parameters(self, PARAMETERS)
        self.get_logger().info('fuzzy_best_point_node started')


def main(args: list[str] | None = None) -> None:
    """Run the node until shutdown."""
    rclpy.init(args=args)
    node = None
    try:
        node = FuzzyBestPointNode()
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    main()
