"""The moves a Grbl session owes an answer for: the running one and those waiting behind it.

ROS-free, no I/O. A move is finished only when the controller reports Idle at the goal after
its last line was acknowledged (an `ok` only means "queued"); Idle elsewhere, several reports
in a row, fails it.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

from .gcode import MotionConfig, MovePlan, TargetRejectedError, Vector3, plan_move
from .grbl_protocol import StatusReport
from .link_events import LinkEvent, MoveFeedback, MoveFinished

#: Idle reports away from the goal, after every line was answered, before a move fails.
IDLE_AWAY_REPORTS = 3


@dataclass
class Move:
    """A requested move and how far it got."""

    job_id: int
    target_m: Vector3
    feed_mm_min: float
    plan: MovePlan | None = None
    lines_left: int = 0
    acked_at: float | None = None
    idle_away: int = 0


class MoveQueue:
    """The running move and the moves waiting behind it.

    Args:
        emit: Receives MoveFeedback and MoveFinished events.
    """

    def __init__(self, emit: Callable[[LinkEvent], None]) -> None:
        self._emit = emit
        self.waiting: deque[Move] = deque()
        self.active: Move | None = None

    def __len__(self) -> int:
        return len(self.waiting) + (self.active is not None)

    def waiting_lines(self) -> int:
        """Lines of the planned moves still waiting."""
        return sum(len(move.plan.lines) if move.plan else 0 for move in self.waiting)

    def fail_all(self, outcome: str, position_m: Vector3 | None) -> None:
        """Fail the running and the waiting moves with `outcome`."""
        moves = ([self.active] if self.active is not None else []) + list(self.waiting)
        self.active = None
        self.waiting.clear()
        for move in moves:
            self._emit(MoveFinished(move.job_id, False, outcome, position_m))

    def refuse(self, move: Move, outcome: str, position_m: Vector3 | None) -> None:
        """Answer a move that never entered the queue."""
        self._emit(MoveFinished(move.job_id, False, outcome, position_m))

    def cancel_waiting(self, job_id: int, position_m: Vector3 | None) -> bool:
        """Drop a waiting move as cancelled; return whether it was waiting."""
        for move in self.waiting:
            if move.job_id == job_id:
                self.waiting.remove(move)
                self._emit(MoveFinished(job_id, False, 'cancelled', position_m))
                return True
        return False

    def start_next(self, motion: MotionConfig,
                   position_m: Vector3 | None) -> tuple[int, tuple[str, ...]] | None:
        """Plan the next waiting move and make it the running one.

        Returns:
            (job id, its lines), or None when nothing waits or the plan was refused (that
            move is then answered with the reason).
        """
        if self.active is not None or not self.waiting:
            return None
        move = self.waiting.popleft()
        try:
            move.plan = plan_move(move.target_m, position_m, move.feed_mm_min, motion)
        except TargetRejectedError as error:
            self._emit(MoveFinished(move.job_id, False, error.reason, position_m))
            return None
        self.active = move
        move.lines_left = len(move.plan.lines)
        return move.job_id, move.plan.lines

    def line_acknowledged(self, now: float) -> None:
        """Count an `ok` for a line of the running move, received at `now` [s]."""
        move = self.active
        if move is not None and move.lines_left > 0:
            move.lines_left -= 1
            if move.lines_left == 0:
                move.acked_at = now

    def on_status(self, report: StatusReport, machine_mm: Vector3, world_m: Vector3,
                  tolerance_mm: float) -> None:
        """Report progress; finish the running move on Idle at its goal, or Idle elsewhere."""
        move = self.active
        if move is None or move.plan is None:
            return
        distance_mm = math.dist(machine_mm, move.plan.goal_machine_mm)
        distance_m = math.dist(world_m, move.plan.goal_world_m)
        self._emit(MoveFeedback(move.job_id, world_m, report.state, distance_m))
        if move.lines_left > 0 or move.acked_at is None:
            return
        if report.state != 'Idle':
            move.idle_away = 0
            return
        if distance_mm <= tolerance_mm:
            self.active = None
            self._emit(MoveFinished(move.job_id, True, 'reached', world_m))
            return
        move.idle_away += 1
        if move.idle_away >= IDLE_AWAY_REPORTS:
            self.active = None
            self._emit(MoveFinished(
                move.job_id, False, f'controller idle {distance_mm:.3f} mm away from the '
                                    'goal after every line was acknowledged', world_m))
