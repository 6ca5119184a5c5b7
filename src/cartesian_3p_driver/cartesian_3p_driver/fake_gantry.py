"""Grbl 1.1 simulator on a pseudo-terminal (skeleton: behaviour comes with the driver issue)."""

import os
import tty

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node

from .fake_gantry_parameters import PARAMETERS
from .ros_parameters import declare_parameters


class FakeGantry(Node):
    """Simulated Grbl controller behind a pseudo-terminal."""

    def __init__(self) -> None:
        super().__init__('fake_gantry')
        self.parameters = declare_parameters(self, PARAMETERS)
        self._controller_fd, self._device_fd = os.openpty()
        tty.setraw(self._device_fd)
        self.get_logger().info(f'fake_gantry on {os.ttyname(self._device_fd)}')

    def destroy_node(self) -> None:
        """Close the pseudo-terminal, then the node."""
        os.close(self._controller_fd)
        os.close(self._device_fd)
        super().destroy_node()


def main(args: list[str] | None = None) -> None:
    """Run the simulator until shutdown."""
    rclpy.init(args=args)
    node = None
    try:
        node = FakeGantry()
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    main()
