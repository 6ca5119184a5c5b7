"""Grbl 1.1 simulator on a pseudo-terminal (and TCP): the demo's gantry and the tests' target.

A thin adapter: parameters in, a GrblSimulator (grbl_simulator.py) running a GrblController
(grbl_controller.py) in its own I/O thread. The executor only serves parameters, so serial
I/O never waits on it and it never waits on serial I/O.
"""

from __future__ import annotations

from rclpy.node import Node
from stereo_fuzzy_parameters.declaration import StartupError, declare_settings, run_node

from .fake_gantry_parameters import FakeGantrySettings
from .grbl_controller import GrblController
from .grbl_simulator import GrblSimulator


class FakeGantry(Node):
    """Simulated Grbl controller behind a pseudo-terminal."""

    def __init__(self) -> None:
        super().__init__('fake_gantry')
        self.settings = declare_settings(self, FakeGantrySettings, apply=self._apply_settings)
        settings = self.settings
        controller = GrblController(settings.controller_settings(), settings.faults(),
                                    work_offset_mm=settings.work_offset_mm)
        try:
            self.simulator = GrblSimulator(controller, settings.simulator_options(),
                                           self.get_logger().info)
        except OSError as error:  # link_path or received_lines_log unusable
            raise StartupError(
                f'cannot serve the simulated controller (link_path={settings.link_path!r}, '
                f'received_lines_log={settings.received_lines_log!r}): {error}',
                self.get_name()) from None
        self.simulator.start()

    def _apply_settings(self, settings: FakeGantrySettings) -> None:
        self.settings = settings
        simulator = self.simulator
        simulator.set_time_scale(settings.time_scale)
        with simulator.lock:
            simulator.options.reply_delay_s = settings.reply_delay_s
            simulator.options.boot_delay_s = settings.boot_delay_s
            simulator.options.vanish_on_line = settings.vanish_on_line
            simulator.options.vanish_duration_s = settings.vanish_duration_s
            simulator.controller.set_faults(settings.faults())

    def destroy_node(self) -> None:
        """Stop the simulator (closing the pty, removing the link), then the node."""
        self.simulator.stop()
        super().destroy_node()


def main(args: list[str] | None = None) -> None:
    """Run the simulator until shutdown; a bad parameter ends it with one FATAL line."""
    run_node(FakeGantry, args)


if __name__ == '__main__':
    main()
