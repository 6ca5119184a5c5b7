"""Grbl 1.1 simulator on a pseudo-terminal (and TCP): the demo's gantry and the tests' target.

A thin adapter: parameters in, a GrblSimulator (grbl_simulator.py) running a GrblController
(grbl_controller.py) in its own I/O thread. The executor only serves parameters, so serial
I/O never waits on it and it never waits on serial I/O.
"""

from __future__ import annotations

import re

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from stereo_fuzzy_parameters.declaration import declare_parameters
from stereo_fuzzy_parameters.spec import ParameterValue

from .fake_gantry_parameters import PARAMETERS
from .grbl_controller import ControllerSettings, FaultInjection, GrblController
from .grbl_simulator import GrblSimulator, SimulatorOptions


def faults_from(values: dict[str, ParameterValue]) -> FaultInjection:
    """Build the controller's fault injection from parameter values."""
    return FaultInjection(
        drop_reply_to_line=int(values['drop_reply_to_line']),
        garble_reply_to_line=int(values['garble_reply_to_line']),
        drop_reply_every_lines=int(values['drop_reply_every_lines']),
        garble_reply_every_lines=int(values['garble_reply_every_lines']),
        refuse_line_pattern=str(values['refuse_line_pattern']),
        refuse_error_code=int(values['refuse_error_code']),
        alarm_axis=str(values['alarm_axis']),
        alarm_at_mm=float(values['alarm_at_mm']),  # type: ignore[arg-type]
        alarm_code=int(values['alarm_code']),
    )


def _validate(values: dict[str, ParameterValue]) -> str | None:
    for name in ('max_travel_mm', 'max_rate_mm_min', 'work_offset_mm'):
        if len(values[name]) != 3:  # type: ignore[arg-type]
            return f'{name} needs 3 values (x, y, z), got {values[name]!r}'
    if any(value <= 0 for value in values['max_rate_mm_min']):  # type: ignore[union-attr]
        return f'max_rate_mm_min must be > 0, got {values["max_rate_mm_min"]!r}'
    if values['soft_limits'] and not values['homing_enabled']:
        return 'soft_limits needs homing_enabled (Grbl error:10)'
    if values['refuse_line_pattern']:
        try:
            re.compile(str(values['refuse_line_pattern']))
        except re.error as error:
            return f'refuse_line_pattern is not a regular expression: {error}'
    return None


class FakeGantry(Node):
    """Simulated Grbl controller behind a pseudo-terminal."""

    def __init__(self) -> None:
        super().__init__('fake_gantry')
        self.parameters = declare_parameters(self, PARAMETERS, validate=_validate,
                                             apply=self._apply)
        values = self.parameters
        settings = ControllerSettings(
            max_travel_mm=[float(v) for v in values['max_travel_mm']],  # type: ignore[union-attr]
            max_rate_mm_min=[float(v) for v in values['max_rate_mm_min']],  # type: ignore[union-attr]
            soft_limits=bool(values['soft_limits']),
            homing_enabled=bool(values['homing_enabled']),
            homing_rate_mm_min=float(values['homing_rate_mm_min']),  # type: ignore[arg-type]
            report_machine_position=bool(values['report_machine_position']),
        )
        offset = [float(v) for v in values['work_offset_mm']]  # type: ignore[union-attr]
        controller = GrblController(settings, faults_from(values),
                                    work_offset_mm=(offset[0], offset[1], offset[2]))
        options = SimulatorOptions(
            link_path=str(values['link_path']), tcp_port=int(values['tcp_port']),
            time_scale=float(values['time_scale']),  # type: ignore[arg-type]
            reply_delay_s=float(values['reply_delay_s']),  # type: ignore[arg-type]
            boot_delay_s=float(values['boot_delay_s']),  # type: ignore[arg-type]
            vanish_on_line=int(values['vanish_on_line']),
            vanish_every_lines=int(values['vanish_every_lines']),
            vanish_duration_s=float(values['vanish_duration_s']),  # type: ignore[arg-type]
            received_lines_log=str(values['received_lines_log']))
        self.simulator = GrblSimulator(controller, options, self.get_logger().info)
        self.simulator.start()

    def _apply(self, values: dict[str, ParameterValue]) -> None:
        simulator = self.simulator
        simulator.set_time_scale(float(values['time_scale']))  # type: ignore[arg-type]
        with simulator.lock:
            simulator.options.reply_delay_s = float(values['reply_delay_s'])  # type: ignore[arg-type]
            simulator.options.boot_delay_s = float(values['boot_delay_s'])  # type: ignore[arg-type]
            simulator.options.vanish_on_line = int(values['vanish_on_line'])
            simulator.options.vanish_every_lines = int(values['vanish_every_lines'])
            simulator.options.vanish_duration_s = float(values['vanish_duration_s'])  # type: ignore[arg-type]
            simulator.controller.set_faults(faults_from(values))

    def destroy_node(self) -> None:
        """Stop the simulator (closing the pty, removing the link), then the node."""
        self.simulator.stop()
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
