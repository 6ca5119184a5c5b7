"""A simulated Grbl 1.1 controller: the state machine only, no I/O, time passed in explicitly.

ROS-free. Bytes go in through `receive`, time advances through `advance`, and the lines the
controller would print come out of `output`. The simulator's I/O layer (grbl_simulator.py)
wires it to a pseudo-terminal or a TCP socket. This module holds the protocol side (receive
buffer, line parser, `$` commands, G-code words, status reports); the machine state and motion
are in controller_motion.py and the settings and fault injection in controller_settings.py
(both importable from here).

Simplifications, documented in the package README: constant-feed moves (no acceleration; a
feed hold keeps moving for `HOLD_DECELERATION_S` before `Hold:0`); homing goes to machine
0,0,0 and the travel is [0, $13x] (Grbl's HOMING_FORCE_SET_ORIGIN); no arcs, probing,
spindle, coolant, jogging or overrides.
"""

from __future__ import annotations

import math
import re
from collections import deque
from collections.abc import Callable

from .controller_motion import (
    HOLD_DECELERATION_S,
    PLANNER_BLOCKS,
    ControllerMotion,
    PlannedDwell,
    PlannedMove,
)
from .controller_settings import ControllerSettings, FaultInjection
from .gcode import AXES, Vector3
from .grbl_protocol import (
    CYCLE_START,
    FEED_HOLD,
    MAX_LINE_LENGTH,
    RX_BUFFER_SIZE,
    SOFT_RESET,
    STATUS_QUERY,
)

BANNER = "Grbl 1.1h ['$' for help]"
ALARM_LOCK_MESSAGE = "[MSG:'$H'|'$X' to unlock]"
#: A reply the fault injection garbles becomes this (not a valid Grbl line).
GARBLED_REPLY = 'o\ufffdk'


_WORD_RE = re.compile(r'([A-Z])([-+]?(?:\d+\.?\d*|\.\d+))?')
_SETTING_RE = re.compile(r'^\$(\d+)=(.*)$')


class GrblController(ControllerMotion):
    """Grbl 1.1 state machine: RX buffer, parser, planner, motion, status and alarms.

    Args:
        settings: `$` settings.
        faults: Faults to inject.
        on_line_received: Called with each line as it completes in the RX buffer.
    """

    def __init__(self, settings: ControllerSettings | None = None,
                 faults: FaultInjection | None = None,
                 on_line_received: Callable[[str], None] | None = None,
                 work_offset_mm: Vector3 = (0.0, 0.0, 0.0)) -> None:
        super().__init__(settings or ControllerSettings(), work_offset_mm)
        self.set_faults(faults or FaultInjection())
        self.on_line_received = on_line_received
        self.lines_received = 0
        self.rx_overflow_bytes = 0
        self._rx_lines: deque[tuple[int, str]] = deque()
        self._rx_partial = bytearray()
        self._status_count = 0
        self.power_cycle(0.0)

    def set_faults(self, faults: FaultInjection) -> None:
        """Replace the injected faults (line numbers keep counting from the start)."""
        self.faults = faults
        self._refuse_re = (re.compile(faults.refuse_line_pattern)
                           if faults.refuse_line_pattern else None)

    # -- start-up and reset ------------------------------------------------------------------

    def _reset_modes(self) -> None:
        self._motion = 0
        self._inches = False
        self._relative = False
        self._feed = 0.0

    def _clear_buffers(self) -> None:
        self._rx_lines.clear()
        self._rx_partial.clear()
        self._planner.clear()
        self._block = None
        self._block_elapsed = 0.0
        self._waiting = None
        self._hold_until = None

    def power_cycle(self, now: float) -> None:
        """Boot as after power-up (or a DTR reset): banner, Alarm if homing is enabled."""
        self._now = now
        self._clear_buffers()
        self._reset_modes()
        self.critical = False
        self._pins = ''
        self.sub_state = -1
        self.state = 'Alarm' if self.settings.homing_enabled else 'Idle'
        self._emit_banner()

    def _emit_banner(self) -> None:
        self.output.append('')
        self.output.append(BANNER)
        if self.state == 'Alarm':
            self.output.append(ALARM_LOCK_MESSAGE)

    def _soft_reset(self) -> None:
        if self.state == 'Home':
            self._raise_alarm(6)  # homing fail: reset during the homing cycle
        elif self._moving():
            self._raise_alarm(3)
        self._clear_buffers()
        self._reset_modes()
        self.critical = False
        self._pins = ''
        self.sub_state = -1
        if self.state != 'Alarm':
            self.state = 'Idle'
        self._emit_banner()

    # -- bytes in -----------------------------------------------------------------------------

    @property
    def rx_used(self) -> int:
        """Bytes in the receive buffer [bytes]."""
        return len(self._rx_partial) + sum(len(line) + 1 for _, line in self._rx_lines)

    def receive(self, data: bytes, now: float) -> None:
        """Take bytes from the host at simulated time `now` [s]."""
        self.advance(now)
        for byte in data:
            if byte == STATUS_QUERY[0]:
                self.output.append(self.status_report())
            elif byte == FEED_HOLD[0]:
                self._feed_hold()
            elif byte == CYCLE_START[0]:
                self._cycle_start()
            elif byte == SOFT_RESET[0]:
                self._soft_reset()
            elif byte >= 0x80:
                continue  # other real-time commands (overrides, jog cancel): ignored here
            elif self.rx_used >= RX_BUFFER_SIZE:
                self.rx_overflow_bytes += 1  # Grbl drops bytes silently when full
            elif byte in (0x0A, 0x0D):
                self.lines_received += 1
                text = self._rx_partial.decode('ascii', errors='replace')
                self._rx_partial.clear()
                self._rx_lines.append((self.lines_received, text))
                if self.on_line_received is not None:
                    self.on_line_received(text)
                # Grbl's main loop consumes lines while bytes keep arriving.
                self._process_lines()
            else:
                self._rx_partial.append(byte)
        self.advance(now)

    # -- time ---------------------------------------------------------------------------------

    def advance(self, now: float) -> None:
        """Run motion and the line parser up to simulated time `now` [s]."""
        dt = max(0.0, now - self._now)
        self._now = max(self._now, now)
        self._run_motion(dt)
        self._process_lines()

    # -- lines --------------------------------------------------------------------------------

    def _reply(self, number: int, text: str) -> None:
        if self.faults.drops_reply_to(number):
            return
        if self.faults.garbles_reply_to(number):
            text = GARBLED_REPLY
        self.output.append(text)

    def _process_lines(self) -> None:
        while True:
            if self._waiting is not None:
                number, done, messages = self._waiting
                if not done():
                    return
                self._waiting = None
                self.output.extend(messages)
                self._reply(number, 'ok')
            if self.critical or not self._rx_lines:
                return
            if len(self._planner) >= PLANNER_BLOCKS:
                return
            number, raw = self._rx_lines.popleft()
            reply = self._execute(number, raw)
            if reply is not None:
                self._reply(number, reply)

    def _execute(self, number: int, raw: str) -> str | None:
        """Run one line; return its reply, or None when the reply is deferred or never sent."""
        line = re.sub(r'\(.*?\)|;.*$', '', raw)
        line = ''.join(ch for ch in line if ch.isprintable() and not ch.isspace()).upper()
        if len(line) > MAX_LINE_LENGTH:
            return 'error:11'
        if not line:
            return 'ok'
        if self._refuse_re is not None and self._refuse_re.search(raw):
            return f'error:{self.faults.refuse_error_code}'
        if line.startswith('$'):
            return self._system_command(number, line)
        if self.state == 'Alarm':
            return 'error:9'
        return self._gcode(number, line)

    def _system_command(self, number: int, line: str) -> str | None:
        if line == '$':
            self.output.append('[HLP:$$ $# $G $I $N $x=val $Nx=line $J=line $SLP $C $X $H '
                               '~ ! ? ctrl-x]')
            return 'ok'
        if line == '$$':
            self.output.extend(self.settings.as_dollar_lines())
            return 'ok'
        if line == '$G':
            self.output.append(f'[GC:G{self._motion} G54 G17 G{20 if self._inches else 21} '
                               f'G{91 if self._relative else 90} G94 M5 M9 T0 F{self._feed:g} '
                               'S0]')
            return 'ok'
        if line == '$I':
            self.output.extend(['[VER:1.1h.20190830:fake_gantry]',
                                f'[OPT:V,{PLANNER_BLOCKS - 1},{RX_BUFFER_SIZE}]'])
            return 'ok'
        if line == '$X':
            if self.state == 'Alarm':
                self.state, self.sub_state = 'Idle', -1
                self.output.append('[MSG:Caution: Unlocked]')
            return 'ok'
        if line == '$H':
            if not self.settings.homing_enabled:
                return 'error:5'
            if self.state not in ('Idle', 'Alarm'):
                return 'error:8'
            self.state, self.sub_state = 'Home', -1
            self._homing_rate = self.settings.homing_rate_mm_min / 60.0
            self._waiting = (number, lambda: self.state != 'Home', [])
            return None
        match = _SETTING_RE.match(line)
        if match:
            if self.state not in ('Idle', 'Alarm'):
                return 'error:8'
            try:
                value = float(match.group(2))
            except ValueError:
                return 'error:2'
            code = self.settings.set(int(match.group(1)), value)
            return f'error:{code}' if code else 'ok'
        return 'error:3'

    def _gcode(self, number: int, line: str) -> str | None:
        words: dict[str, float] = {}
        g_codes: list[float] = []
        m_codes: list[float] = []
        position = 0
        for match in _WORD_RE.finditer(line):
            if match.start() != position:
                return 'error:1'
            position = match.end()
            letter, text = match.group(1), match.group(2)
            if text is None:
                return 'error:2'
            value = float(text)
            if letter == 'G':
                g_codes.append(value)
            elif letter == 'M':
                m_codes.append(value)
            elif letter in 'XYZFPN':
                if letter in words:
                    return 'error:25'
                words[letter] = value
            else:
                return 'error:20'
        if position != len(line):
            return 'error:1'
        if 'N' in words and not 1 <= words['N'] <= 9_999_999:
            return 'error:27'
        motion = None
        machine_coordinates = dwell = False
        for code in g_codes:
            if code in (0, 1):
                if motion is not None:
                    return 'error:21'
                motion = int(code)
            elif code == 4:
                dwell = True
            elif code in (20, 21):
                self._inches = code == 20
            elif code in (90, 91):
                self._relative = code == 91
            elif code == 53:
                machine_coordinates = True
            elif code not in (94, 54, 17):
                return 'error:20'
        for code in m_codes:
            if code not in (2, 30, 5, 9):
                return 'error:20'
        if 'F' in words:
            if words['F'] < 0:
                return 'error:4'
            self._feed = words['F'] * (25.4 if self._inches else 1.0)
        if motion is not None:
            self._motion = motion
        axes = [axis for axis in AXES if axis in words]
        if dwell:
            if axes:
                return 'error:24'
            if 'P' not in words:
                return 'error:28'
            if words['P'] < 0:
                return 'error:4'
            self._planner.append(PlannedDwell(words['P']))
            self._start_cycle()
            self._waiting = (number, self._planner_empty, [])
            return None
        if axes:
            if machine_coordinates and self._motion not in (0, 1):
                return 'error:30'
            reply = self._plan_motion(words, axes, machine_coordinates)
            if reply != 'ok':
                return reply
        elif machine_coordinates:
            return 'error:26'
        if any(code in (2, 30) for code in m_codes):
            self._waiting = (number, self._planner_empty, ['[MSG:Pgm End]'])
            self._reset_modes_after_program_end()
            return None
        return 'ok'

    def _reset_modes_after_program_end(self) -> None:
        feed = self._feed
        self._reset_modes()
        self._motion = 1
        self._feed = feed

    def _plan_motion(self, words: dict[str, float], axes: list[str],
                     machine_coordinates: bool) -> str | None:
        scale = 25.4 if self._inches else 1.0
        start = self._planned_end()
        offset = (0.0, 0.0, 0.0) if machine_coordinates else self.work_offset_mm
        target = list(start)
        for axis in axes:
            i = AXES.index(axis)
            value = words[axis] * scale
            if self._relative and not machine_coordinates:
                target[i] = start[i] + value
            else:
                target[i] = value + offset[i]
        if self._motion == 1 and self._feed <= 0.0:
            return 'error:22'
        if self.settings.soft_limits and any(
                not -1e-6 <= target[i] <= self.settings.max_travel_mm[i] + 1e-6
                for i in range(3)):
            if self.state == 'Run':
                self._feed_hold()
            self._raise_alarm(2)
            return None
        delta = [target[i] - start[i] for i in range(3)]
        distance = math.sqrt(sum(d * d for d in delta))
        if distance == 0.0:
            return 'ok'
        rate = self._feed if self._motion == 1 else math.inf
        for i in range(3):
            if delta[i]:
                rate = min(rate, self.settings.max_rate_mm_min[i] * distance / abs(delta[i]))
        self._planner.append(PlannedMove((target[0], target[1], target[2]), rate / 60.0))
        self._start_cycle()
        return 'ok'

    # -- status -------------------------------------------------------------------------------

    def status_report(self) -> str:
        """Return the `<...>` status report for the current state."""
        state = self.state if self.sub_state < 0 else f'{self.state}:{self.sub_state}'
        self._status_count += 1
        fields = [state]
        if self.settings.report_machine_position:
            fields.append('MPos:' + ','.join(f'{value:.3f}' for value in self.position))
        else:
            work = [self.position[i] - self.work_offset_mm[i] for i in range(3)]
            fields.append('WPos:' + ','.join(f'{value:.3f}' for value in work))
        fields.append(f'FS:{self.current_feed_mm_min():.0f},0')
        if self._pins:
            fields.append(f'Pn:{self._pins}')
        if not self.settings.report_machine_position and self._status_count % 10 == 1:
            fields.append('WCO:' + ','.join(f'{value:.3f}' for value in self.work_offset_mm))
        return '<' + '|'.join(fields) + '>'


__all__ = [
    'ALARM_LOCK_MESSAGE', 'BANNER', 'GARBLED_REPLY', 'HOLD_DECELERATION_S', 'PLANNER_BLOCKS',
    'ControllerSettings', 'FaultInjection', 'GrblController',
]
