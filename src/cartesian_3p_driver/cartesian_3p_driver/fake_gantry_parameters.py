"""Settings of fake_gantry, the Grbl 1.1 simulator: its parameters, once."""

from __future__ import annotations

import re
from dataclasses import dataclass

from stereo_fuzzy_parameters.spec import parameter, parameter_specs

from .grbl_controller import ControllerSettings, FaultInjection
from .grbl_simulator import SimulatorOptions

Vector3 = tuple[float, float, float]


@dataclass(frozen=True)
class FakeGantrySettings:
    """Parameters of fake_gantry, typed."""

    # --- wiring
    link_path: str = parameter(
        '', "Symlink created to the pseudo-terminal device, for the driver's port parameter "
        "('' = none)", read_only=True)
    tcp_port: int = parameter(
        23000, 'Also serve the controller on socket://127.0.0.1:<port> (0 = off; if the port is '
        'taken, pty only)', 0, 65535, read_only=True)
    received_lines_log: str = parameter(
        '', "File the simulator appends every received line to, in order ('' = off)",
        read_only=True)
    # --- speed
    time_scale: float = parameter(
        1.0, 'Simulated seconds per wall-clock second (motion, dwell, homing); > 1 runs faster',
        0.01, 1000.0)
    boot_delay_s: float = parameter(
        0.05, 'Time from a host opening the port to the banner [s]', 0.0, 5.0)
    # --- Grbl settings
    homing_enabled: bool = parameter(
        True, '$22: $H available; boots in Alarm until $H or $X', read_only=True)
    soft_limits: bool = parameter(
        False, '$20: targets outside the travel raise ALARM:2', read_only=True)
    max_travel_mm: Vector3 = parameter(
        (400.0, 300.0, 200.0), '$130-$132: travel per axis, machine space [0, travel] after '
        'homing to 0,0,0 [mm]', read_only=True)
    max_rate_mm_min: Vector3 = parameter(
        (6000.0, 6000.0, 3000.0), '$110-$112: maximum rate per axis [mm/min]', read_only=True)
    homing_rate_mm_min: float = parameter(
        3000.0, '$25: homing rate [mm/min]', 1.0, 100000.0, read_only=True)
    report_machine_position: bool = parameter(
        True, '$10 bit 0: report MPos (true) or WPos with an intermittent WCO (false)',
        read_only=True)
    work_offset_mm: Vector3 = parameter(
        (0.0, 0.0, 0.0), 'G54 work offset reported as WCO [mm]', read_only=True)
    # --- fault injection
    reply_delay_s: float = parameter(
        0.0, 'Fault injection: delay before each reply [s]', 0.0, 10.0)
    drop_reply_to_line: int = parameter(
        0, 'Fault injection: never answer the n-th received line, counted from start (it still '
        'runs; 0 = off)', 0, 1000000)
    garble_reply_to_line: int = parameter(
        0, 'Fault injection: answer the n-th received line with a corrupt reply (0 = off)',
        0, 1000000)
    refuse_line_pattern: str = parameter(
        '', 'Fault injection: answer lines matching this regular expression with '
        "error:refuse_error_code ('' = off)")
    refuse_error_code: int = parameter(
        20, 'Fault injection: the error:N for refused lines', 1, 255)
    alarm_axis: str = parameter(
        '', "Fault injection: raise alarm_code once when this axis crosses alarm_at_mm while "
        "moving ('' = off)", choices=('', 'x', 'y', 'z'))
    alarm_at_mm: float = parameter(
        0.0, 'Fault injection: machine position of that trip point [mm]', -10000.0, 10000.0)
    alarm_code: int = parameter(
        1, 'Fault injection: the ALARM:N raised (1 = hard limit)', 1, 12)
    vanish_on_line: int = parameter(
        0, 'Fault injection: close the pty right after receiving the n-th line, before '
        'answering it (0 = never; once)', 0, 1000000)
    vanish_duration_s: float = parameter(
        1.0, 'Fault injection: time until the pty comes back at the same link_path [s]',
        0.0, 60.0)

    def controller_settings(self) -> ControllerSettings:
        """Return the simulated controller's $ settings."""
        return ControllerSettings(
            max_travel_mm=list(self.max_travel_mm), max_rate_mm_min=list(self.max_rate_mm_min),
            soft_limits=self.soft_limits, homing_enabled=self.homing_enabled,
            homing_rate_mm_min=self.homing_rate_mm_min,
            report_machine_position=self.report_machine_position)

    def faults(self) -> FaultInjection:
        """Return the controller's fault injection."""
        return FaultInjection(
            drop_reply_to_line=self.drop_reply_to_line,
            garble_reply_to_line=self.garble_reply_to_line,
            refuse_line_pattern=self.refuse_line_pattern,
            refuse_error_code=self.refuse_error_code, alarm_axis=self.alarm_axis,
            alarm_at_mm=self.alarm_at_mm, alarm_code=self.alarm_code)

    def simulator_options(self) -> SimulatorOptions:
        """Return the simulator's wiring, speed and link faults."""
        return SimulatorOptions(
            link_path=self.link_path, tcp_port=self.tcp_port, time_scale=self.time_scale,
            reply_delay_s=self.reply_delay_s, boot_delay_s=self.boot_delay_s,
            vanish_on_line=self.vanish_on_line, vanish_duration_s=self.vanish_duration_s,
            received_lines_log=self.received_lines_log)

    def problem(self) -> str | None:
        """Return why these settings cannot work together, or None."""
        if any(value <= 0 for value in self.max_rate_mm_min):
            return f'max_rate_mm_min={list(self.max_rate_mm_min)} must be > 0 on every axis'
        if self.soft_limits and not self.homing_enabled:
            return 'soft_limits=true needs homing_enabled=true (Grbl error:10)'
        if self.refuse_line_pattern:
            try:
                re.compile(self.refuse_line_pattern)
            except re.error as error:
                return (f'refuse_line_pattern={self.refuse_line_pattern!r} is not a regular '
                        f'expression: {error}')
        return None


PARAMETERS = parameter_specs(FakeGantrySettings)
