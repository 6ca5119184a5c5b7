"""The simulated Grbl controller's machine state and motion: planner, moves, holds, alarms.

ROS-free and I/O-free, with time passed in explicitly. Moves run at constant feed (no
acceleration); a feed hold keeps moving for `HOLD_DECELERATION_S` before `Hold:0`; homing goes
to machine 0,0,0. The line parser and the status reports are in grbl_controller.py, which
builds on this class.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

from .controller_settings import ControllerSettings, FaultInjection
from .gcode import AXES, Vector3
from .grbl_protocol import CRITICAL_ALARMS

PLANNER_BLOCKS = 16
#: Simulated time a feed hold keeps moving before it reports Hold:0 [s].
HOLD_DECELERATION_S = 0.05


@dataclass
class PlannedMove:
    """A straight move in the planner: to `target` [mm] at `rate_mm_s` [mm/s]."""

    target: Vector3
    rate_mm_s: float


@dataclass
class PlannedDwell:
    """A G4 dwell in the planner, `seconds` [s] long."""

    seconds: float


class ControllerMotion:
    """Grbl's machine state (Idle, Run, Hold, Home, Alarm) and the motion of its planner.

    Args:
        settings: `$` settings (travel, rates, homing).
        work_offset_mm: Work coordinate offset (G54) [mm].
    """

    faults: FaultInjection

    def __init__(self, settings: ControllerSettings, work_offset_mm: Vector3) -> None:
        self.settings = settings
        self.work_offset_mm = work_offset_mm
        self.output: deque[str] = deque()
        self.position: list[float] = [0.0, 0.0, 0.0]
        self._planner: deque[PlannedMove | PlannedDwell] = deque()
        self._block: PlannedMove | PlannedDwell | None = None
        self._block_elapsed = 0.0
        self._now = 0.0
        self._hold_until: float | None = None
        self._alarm_fired = False
        self._pins = ''
        # A line whose reply waits for something (homing, dwell, program end).
        self._waiting: tuple[int, Callable[[], bool], list[str]] | None = None
        self._homing_rate = 0.0
        self.state = 'Idle'
        self.sub_state = -1
        self.critical = False

    def _moving(self) -> bool:
        return self.state in ('Run', 'Home') or (self.state == 'Hold' and self.sub_state == 1)

    def _raise_alarm(self, code: int) -> None:
        self._planner.clear()
        self._block = None
        self._waiting = None
        self._hold_until = None
        self.state, self.sub_state = 'Alarm', -1
        self.output.append(f'ALARM:{code}')
        if code in CRITICAL_ALARMS:
            self.critical = True
            self.output.append('[MSG:Reset to continue]')

    def _feed_hold(self) -> None:
        if self.state in ('Alarm', 'Home', 'Sleep'):
            return
        if self.state == 'Run':
            self.state, self.sub_state = 'Hold', 1
            self._hold_until = self._now + HOLD_DECELERATION_S
        elif self.state == 'Idle':
            self.state, self.sub_state = 'Hold', 0

    def _cycle_start(self) -> None:
        if self.state == 'Hold' and self.sub_state == 0:
            self._hold_until = None
            self.state, self.sub_state = ('Run' if self._block or self._planner else 'Idle'), -1

    def _run_motion(self, dt: float) -> None:
        if self.state == 'Home':
            _, reached = self._step_towards((0.0, 0.0, 0.0), self._homing_rate, dt)
            if reached:
                self.state, self.sub_state = 'Idle', -1
            return
        t = self._now - dt
        while dt > 0.0 and (self.state == 'Run' or (self.state == 'Hold' and self.sub_state == 1)):
            chunk = dt
            if self.state == 'Hold':
                remaining = (self._hold_until or t) - t
                if remaining <= 0.0:
                    self.sub_state, self._hold_until = 0, None
                    break
                chunk = min(dt, remaining)
            if self._block is None:
                if not self._planner:
                    if self.state == 'Run':
                        self.state, self.sub_state = 'Idle', -1
                    else:
                        self.sub_state, self._hold_until = 0, None
                    break
                self._block = self._planner.popleft()
                self._block_elapsed = 0.0
            used, finished = self._run_block(chunk)
            if self.state == 'Alarm':
                return
            if finished:
                self._block = None
            t += used
            dt -= used
        if self.state == 'Run' and self._block is None and not self._planner:
            self.state, self.sub_state = 'Idle', -1

    def _run_block(self, dt: float) -> tuple[float, bool]:
        """Run the current block for up to `dt` [s]; return (time used [s], finished)."""
        block = self._block
        if isinstance(block, PlannedDwell):
            used = min(dt, block.seconds - self._block_elapsed)
            self._block_elapsed += used
            return used, self._block_elapsed >= block.seconds
        assert block is not None
        return self._step_towards(block.target, block.rate_mm_s, dt)

    def _step_towards(self, target: Vector3, rate_mm_s: float, dt: float) -> tuple[float, bool]:
        """Move towards `target` at `rate_mm_s` [mm/s] for up to `dt` [s].

        Returns:
            (time used [s], target reached).
        """
        delta = [target[i] - self.position[i] for i in range(3)]
        distance = math.sqrt(sum(d * d for d in delta))
        if distance <= 1e-9:
            self.position = list(target)
            return 0.0, True
        start = list(self.position)
        if rate_mm_s * dt >= distance:
            self.position = list(target)
            used, reached = distance / rate_mm_s, True
        else:
            step = rate_mm_s * dt
            self.position = [self.position[i] + delta[i] * step / distance for i in range(3)]
            used, reached = dt, False
        self._check_trip(start)
        return used, reached and self.state != 'Alarm'

    def _check_trip(self, start: list[float]) -> None:
        faults = self.faults
        if self._alarm_fired or faults.alarm_axis.upper() not in AXES:
            return
        axis = AXES.index(faults.alarm_axis.upper())
        low, high = sorted((start[axis], self.position[axis]))
        if low <= faults.alarm_at_mm <= high and start[axis] != self.position[axis]:
            self._alarm_fired = True
            self.position[axis] = faults.alarm_at_mm
            self._pins = AXES[axis]
            self._raise_alarm(faults.alarm_code)

    def _planner_empty(self) -> bool:
        return self._block is None and not self._planner and self.state != 'Run'

    def _planned_end(self) -> list[float]:
        for block in reversed(self._planner):
            if isinstance(block, PlannedMove):
                return list(block.target)
        if isinstance(self._block, PlannedMove):
            return list(self._block.target)
        return list(self.position)

    def _start_cycle(self) -> None:
        if self.state == 'Idle':
            self.state, self.sub_state = 'Run', -1

    def current_feed_mm_min(self) -> float:
        """Return the feed of the move being run, 0 when stopped [mm/min]."""
        if isinstance(self._block, PlannedMove) and (self.state == 'Run' or self.sub_state == 1):
            return self._block.rate_mm_s * 60.0
        if self.state == 'Home':
            return self._homing_rate * 60.0
        return 0.0
