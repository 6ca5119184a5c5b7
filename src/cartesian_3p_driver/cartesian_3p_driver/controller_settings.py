"""The simulated Grbl controller's configuration: its `$` settings and the faults it injects.

ROS-free and I/O-free; used by the controller model (grbl_controller.py), by fake_gantry's
parameters and by tests that set up a controller.
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class ControllerSettings:
    """The `$` settings the simulator honours (Grbl numbers in brackets).

    Attributes:
        max_travel_mm: Travel per axis [$130-$132] [mm].
        max_rate_mm_min: Maximum rate per axis [$110-$112] [mm/min].
        soft_limits: Refuse targets outside the travel with ALARM:2 [$20].
        hard_limits: Limit switches raise ALARM:1 [$21] (see the alarm fault injection).
        homing_enabled: `$H` is available and the controller boots in Alarm [$22].
        homing_rate_mm_min: Homing seek rate [$25] [mm/min].
        report_machine_position: MPos (True) or WPos with WCO (False) [$10 bit 0].
    """

    max_travel_mm: list[float] = field(default_factory=lambda: [400.0, 300.0, 200.0])
    max_rate_mm_min: list[float] = field(default_factory=lambda: [6000.0, 6000.0, 3000.0])
    soft_limits: bool = False
    hard_limits: bool = False
    homing_enabled: bool = True
    homing_rate_mm_min: float = 3000.0
    report_machine_position: bool = True

    def as_dollar_lines(self) -> list[str]:
        """Return the settings as `$$` prints them."""
        lines = [f'$10={1 if self.report_machine_position else 0}',
                 f'$20={int(self.soft_limits)}', f'$21={int(self.hard_limits)}',
                 f'$22={int(self.homing_enabled)}', f'$25={self.homing_rate_mm_min:.3f}']
        lines += [f'${110 + i}={value:.3f}' for i, value in enumerate(self.max_rate_mm_min)]
        lines += [f'${130 + i}={value:.3f}' for i, value in enumerate(self.max_travel_mm)]
        return lines

    def set(self, number: int, value: float) -> int:
        """Apply `$number=value`; return 0 or the Grbl error code."""
        if number == 10:
            self.report_machine_position = bool(int(value) & 1)
        elif number == 20:
            if value and not self.homing_enabled:
                return 10
            self.soft_limits = bool(value)
        elif number == 21:
            self.hard_limits = bool(value)
        elif number == 22:
            self.homing_enabled = bool(value)
        elif number == 25:
            if value <= 0:
                return 4
            self.homing_rate_mm_min = value
        elif 110 <= number <= 112:
            if value <= 0:
                return 4
            self.max_rate_mm_min[number - 110] = value
        elif 130 <= number <= 132:
            if value < 0:
                return 4
            self.max_travel_mm[number - 130] = value
        else:
            return 3
        return 0


@dataclass
class FaultInjection:
    """Faults the simulator injects on purpose, for tests. Line numbers count from 1.

    Attributes:
        drop_reply_to_line: Never answer this line (it still runs); 0 = off.
        garble_reply_to_line: Answer this line with a corrupt reply; 0 = off.
        drop_reply_every_lines: Never answer every n-th line (lines n, 2n, ...); 0 = off.
        garble_reply_every_lines: Answer every n-th line with a corrupt reply; 0 = off.
        refuse_line_pattern: Answer lines matching this regex with `refuse_error_code`.
        refuse_error_code: The error:N for refused lines.
        alarm_axis: 'x', 'y' or 'z': raise `alarm_code` once when that axis crosses
            `alarm_at_mm` while moving ('' = off).
        alarm_at_mm: Position of that trip point [mm].
        alarm_code: ALARM:N to raise (1 = hard limit).
    """

    drop_reply_to_line: int = 0
    garble_reply_to_line: int = 0
    drop_reply_every_lines: int = 0
    garble_reply_every_lines: int = 0
    refuse_line_pattern: str = ''
    refuse_error_code: int = 20
    alarm_axis: str = ''
    alarm_at_mm: float = 0.0
    alarm_code: int = 1

    def drops_reply_to(self, number: int) -> bool:
        """Return True when the reply to line `number` is never sent."""
        return number == self.drop_reply_to_line or _every(number, self.drop_reply_every_lines)

    def garbles_reply_to(self, number: int) -> bool:
        """Return True when line `number` is answered with a corrupt reply."""
        return number == self.garble_reply_to_line \
            or _every(number, self.garble_reply_every_lines)


def _every(number: int, period: int) -> bool:
    """Return True when line `number` is a multiple of `period` (0 = never)."""
    return period > 0 and number % period == 0
