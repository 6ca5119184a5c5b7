"""Grbl 1.1 serial protocol: what the controller sends, parsed; codes with their meanings.

ROS-free. Sources: gnea/grbl v1.1h `doc/markdown/interface.md`, `grbl/report.h`, and the
grblHAL additions (errors 45/46/50, alarms 10-12).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from enum import Enum

from .gcode import Vector3

#: Real-time commands: single bytes, never buffered, no newline.
STATUS_QUERY = b'?'
FEED_HOLD = b'!'
CYCLE_START = b'~'
SOFT_RESET = b'\x18'
REALTIME_BYTES = frozenset({STATUS_QUERY[0], FEED_HOLD[0], CYCLE_START[0], SOFT_RESET[0]})

#: Usable bytes in Grbl's serial receive buffer (128-byte ring, one slot kept free).
RX_BUFFER_SIZE = 127
#: Longest line Grbl's pre-parser accepts [characters].
MAX_LINE_LENGTH = 80

BANNER_RE = re.compile(r'^Grbl(HAL)? (?P<version>\S+)')
STATES = ('Idle', 'Run', 'Hold', 'Jog', 'Alarm', 'Door', 'Check', 'Home', 'Sleep')

ERROR_CODES: dict[int, str] = {
    1: 'G-code words consist of a letter and a value; letter was not found',
    2: 'Numeric value format is not valid or missing an expected value',
    3: "Grbl '$' system command was not recognized or supported",
    4: 'Negative value received for an expected positive value',
    5: 'Homing cycle is not enabled via settings ($22)',
    6: 'Minimum step pulse time must be greater than 3 us',
    7: 'EEPROM read failed; reset and restored to default values',
    8: "Grbl '$' command cannot be used unless Grbl is IDLE",
    9: 'G-code locked out during alarm or jog state',
    10: 'Soft limits cannot be enabled without homing also enabled',
    11: 'Max characters per line exceeded; line was not processed',
    12: "Grbl '$' setting value exceeds the maximum step rate supported",
    13: 'Safety door detected as opened and door state initiated',
    14: 'Build info or startup line exceeded EEPROM line length limit',
    15: 'Jog target exceeds machine travel; command ignored',
    16: "Jog command with no '=' or contains prohibited g-code",
    17: 'Laser mode requires PWM output',
    20: 'Unsupported or invalid g-code command found in block',
    21: 'More than one g-code command from same modal group found in block',
    22: 'Feed rate has not yet been set or is undefined',
    23: 'G-code command in block requires an integer value',
    24: 'Two G-code commands that both require the use of the XYZ axis words were detected',
    25: 'A G-code word was repeated in the block',
    26: 'A G-code command implicitly or explicitly requires XYZ axis words in the block, '
        'but none were detected',
    27: 'N line number value is not within the valid range of 1 - 9,999,999',
    28: 'A G-code command was sent, but is missing some required P or L value words',
    29: 'Grbl supports six work coordinate systems G54-G59; G59.1-G59.3 are not supported',
    30: 'The G53 G-code command requires either a G0 seek or G1 feed motion mode to be active',
    31: 'There are unused axis words in the block and G80 motion mode cancel is active',
    32: 'A G2 or G3 arc was commanded but there are no XYZ axis words in the selected plane',
    33: 'The motion command has an invalid target',
    34: 'Arc radius value is invalid',
    35: 'A G2 or G3 arc, traced with the offset definition, is missing the IJK offset word',
    36: 'There are unused, leftover G-code words that are not used by any command in the block',
    37: 'The G43.1 dynamic tool length offset command cannot apply an offset to an axis '
        'other than its configured axis',
    38: 'Tool number greater than max supported value',
    45: 'Limit switch engaged (grblHAL)',
    46: 'Homing required (grblHAL)',
    50: 'E-stop active (grblHAL)',
}

ALARM_CODES: dict[int, str] = {
    1: 'Hard limit triggered; machine position is likely lost, re-homing is recommended',
    2: 'Soft limit: G-code motion target exceeds machine travel; machine position retained',
    3: 'Reset while in motion; machine position is likely lost, re-homing is recommended',
    4: 'Probe fail: the probe is not in the expected initial state',
    5: 'Probe fail: the probe did not contact the workpiece',
    6: 'Homing fail: reset during active homing cycle',
    7: 'Homing fail: safety door was opened during active homing cycle',
    8: 'Homing fail: cycle failed to clear limit switch when pulling off',
    9: 'Homing fail: could not find limit switch within search distance',
    10: 'E-stop asserted (grblHAL)',
    11: 'Homing required (grblHAL)',
    12: 'Limit switch engaged (grblHAL)',
}

#: Alarms after which Grbl waits for a soft reset before it accepts $X or $H.
CRITICAL_ALARMS = frozenset({1, 2, 10})


def error_text(code: int) -> str:
    """Return the meaning of `error:code`."""
    return ERROR_CODES.get(code, f'unknown error code {code}')


def alarm_text(code: int) -> str:
    """Return the meaning of `ALARM:code`."""
    return ALARM_CODES.get(code, f'unknown alarm code {code}')


class ProtocolError(ValueError):
    """A line from the controller that does not follow the Grbl 1.1 format."""


class ReplyKind(Enum):
    """What a line from the controller is."""

    OK = 'ok'
    ERROR = 'error'
    ALARM = 'alarm'
    STATUS = 'status'
    BANNER = 'banner'
    MESSAGE = 'message'      # [MSG:...], [GC:...], [VER:...], ... feedback in brackets
    SETTING = 'setting'      # $n=value from $$
    ECHO = 'echo'            # >startup-line:ok
    UNKNOWN = 'unknown'


@dataclass(frozen=True)
class Reply:
    """One classified line from the controller.

    Attributes:
        kind: Its kind.
        text: The line without its line ending.
        code: The number of error:N / ALARM:N, else 0.
    """

    kind: ReplyKind
    text: str
    code: int = 0


_CODE_RE = re.compile(r'^(error|ALARM):(\d+)$')


def classify(line: str) -> Reply:
    """Classify one line received from the controller (line ending already stripped)."""
    text = line.strip()
    if text == 'ok':
        return Reply(ReplyKind.OK, text)
    match = _CODE_RE.match(text)
    if match:
        kind = ReplyKind.ERROR if match.group(1) == 'error' else ReplyKind.ALARM
        return Reply(kind, text, int(match.group(2)))
    if text.startswith('<') and text.endswith('>'):
        return Reply(ReplyKind.STATUS, text)
    if BANNER_RE.match(text):
        return Reply(ReplyKind.BANNER, text)
    if text.startswith('[') and text.endswith(']'):
        return Reply(ReplyKind.MESSAGE, text)
    if re.match(r'^\$\d+=', text):
        return Reply(ReplyKind.SETTING, text)
    if text.startswith('>') and text.endswith(':ok'):
        return Reply(ReplyKind.ECHO, text)
    return Reply(ReplyKind.UNKNOWN, text)


@dataclass(frozen=True)
class StatusReport:
    """A parsed `<...>` status report.

    Attributes:
        state: One of STATES.
        sub_state: Hold:0/1, Door:0..3; -1 when the report carries none.
        machine_position_mm: MPos [mm], if the report had it.
        work_position_mm: WPos [mm], if the report had it.
        work_offset_mm: WCO [mm], if the report had it (Grbl sends it intermittently).
        feed_mm_min: Current feed from F: or FS: [mm/min], None if absent.
        spindle_rpm: Spindle speed from FS: [rpm], None if absent.
        pins: Triggered input pins from Pn: (for example 'XZ'), empty if none.
        buffer: (free planner blocks, free RX bytes) from Bf:, None if absent.
        line_number: Ln: value, None if absent.
    """

    state: str
    sub_state: int = -1
    machine_position_mm: Vector3 | None = None
    work_position_mm: Vector3 | None = None
    work_offset_mm: Vector3 | None = None
    feed_mm_min: float | None = None
    spindle_rpm: float | None = None
    pins: str = ''
    buffer: tuple[int, int] | None = None
    line_number: int | None = None
    fields: dict[str, str] = field(default_factory=dict, compare=False)

    def resolve_machine_position(self, last_work_offset_mm: Vector3 | None) -> Vector3 | None:
        """Return MPos [mm]: as reported, or WPos + WCO (this report's or the last one seen)."""
        if self.machine_position_mm is not None:
            return self.machine_position_mm
        offset = self.work_offset_mm or last_work_offset_mm
        if self.work_position_mm is None or offset is None:
            return None
        return (self.work_position_mm[0] + offset[0], self.work_position_mm[1] + offset[1],
                self.work_position_mm[2] + offset[2])


def _numbers(text: str, name: str, count: int | None = None) -> tuple[float, ...]:
    try:
        values = tuple(float(part) for part in text.split(','))
    except ValueError as error:
        raise ProtocolError(f'{name} field {text!r} is not a list of numbers') from error
    if count is not None and len(values) < count:
        raise ProtocolError(f'{name} field {text!r} needs {count} values')
    return values


def parse_status_report(line: str) -> StatusReport:
    """Parse a Grbl 1.1 status report such as `<Hold:0|MPos:1.000,2.000,3.000|FS:0,0|Pn:XZ>`.

    Args:
        line: The report, with its angle brackets.

    Returns:
        The parsed report; unknown fields are kept in `fields`.

    Raises:
        ProtocolError: When the line is not a well-formed status report.
    """
    text = line.strip()
    if not (text.startswith('<') and text.endswith('>')):
        raise ProtocolError(f'status report {text!r} is not enclosed in <>')
    parts = text[1:-1].split('|')
    state_text = parts[0]
    state, _, sub_text = state_text.partition(':')
    if state not in STATES:
        raise ProtocolError(f'unknown machine state {state!r} in {text!r}')
    sub_state = -1
    if sub_text:
        if not sub_text.isdigit():
            raise ProtocolError(f'sub-state {sub_text!r} of {state} is not a number')
        sub_state = int(sub_text)
    values: dict[str, object] = {}
    fields: dict[str, str] = {}
    for part in parts[1:]:
        name, separator, value = part.partition(':')
        if not separator:
            raise ProtocolError(f'field {part!r} in {text!r} has no ":"')
        fields[name] = value
        if name in ('MPos', 'WPos', 'WCO'):
            values[name] = _numbers(value, name, 3)[:3]
        elif name == 'FS':
            numbers = _numbers(value, name, 2)
            values['feed'], values['spindle'] = numbers[0], numbers[1]
        elif name == 'F':
            values['feed'] = _numbers(value, name, 1)[0]
        elif name == 'Pn':
            values['pins'] = value
        elif name == 'Bf':
            numbers = _numbers(value, name, 2)
            values['buffer'] = (int(numbers[0]), int(numbers[1]))
        elif name == 'Ln':
            values['line'] = int(_numbers(value, name, 1)[0])
    if 'MPos' not in values and 'WPos' not in values:
        raise ProtocolError(f'status report {text!r} has neither MPos nor WPos')
    return StatusReport(
        state=state, sub_state=sub_state,
        machine_position_mm=values.get('MPos'),  # type: ignore[arg-type]
        work_position_mm=values.get('WPos'),  # type: ignore[arg-type]
        work_offset_mm=values.get('WCO'),  # type: ignore[arg-type]
        feed_mm_min=values.get('feed'),  # type: ignore[arg-type]
        spindle_rpm=values.get('spindle'),  # type: ignore[arg-type]
        pins=str(values.get('pins', '')),
        buffer=values.get('buffer'),  # type: ignore[arg-type]
        line_number=values.get('line'),  # type: ignore[arg-type]
        fields=fields,
    )
