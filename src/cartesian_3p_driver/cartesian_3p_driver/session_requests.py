"""Commands to a Grbl session and the sequences they start: moves, home, unlock, stop.

ROS-free and I/O-free; part of GrblSession (grbl_session.py), split off to keep files short.
"""

from __future__ import annotations

from dataclasses import replace

from .gcode import Vector3
from .grbl_protocol import FEED_HOLD, SOFT_RESET
from .link_events import RequestFinished
from .move_queue import Move
from .session_core import Lockout, SessionCore, Stage, StopSequence, SystemCommand


class SessionRequests(SessionCore):
    """Moves, home/unlock/stop requests, the fault latch and the stop sequence."""

    # -- commands -----------------------------------------------------------------------------

    def submit_move(self, job_id: int, target_m: Vector3, feed_mm_min: float, now: float) -> None:
        """Take a move to a validated world target [m]; answered by a MoveFinished event."""
        move = Move(job_id, target_m, feed_mm_min)
        position = self._snapshot.world_position_m
        reason = self._may_move()
        stop = self._stop
        replacing = stop is not None and stop.then_move is not None
        if reason is not None and not replacing:
            self._moves.refuse(move, f'refused: {reason}', position)
        elif self._moves.active is None and not replacing:
            self._moves.waiting.append(move)
        elif self.config.new_target_policy == 'replace':
            if stop is not None and stop.then_move is not None:
                replaced, stop.then_move = stop.then_move, move
                self._moves.refuse(replaced, 'replaced by a newer target', position)
            else:
                self._fail_all_moves('replaced by a newer target')
                self._begin_stop('replaced by a newer target', now, then_move=move)
        elif len(self._moves.waiting) >= self.config.max_queued_moves:
            self._moves.refuse(move, f'refused: {len(self._moves.waiting)} moves already '
                                     'queued (max_queued_moves)', position)
        else:
            self._moves.waiting.append(move)
        self._progress(now)

    def cancel_move(self, job_id: int, now: float) -> None:
        """Cancel a move: dropped if waiting, stopped (feed hold, reset) if running."""
        if self._moves.cancel_waiting(job_id, self._snapshot.world_position_m):
            return
        active = self._moves.active
        if active is not None and active.job_id == job_id and self.stage is not Stage.CLOSED:
            self._fail_all_moves('cancelled')
            if self._stop is None:
                self._begin_stop('move cancelled', now)
        self._progress(now)

    def request(self, kind: str, request_id: int, now: float) -> None:
        """Take a 'home' ($H), 'unlock' ($X) or 'stop' request; answered by RequestFinished."""
        if kind == 'stop':
            self._request_stop(request_id, now)
        else:
            reason = None
            if not self.controller_seen:
                reason = 'not connected to the controller'
            elif self._system is not None or self._stop is not None:
                reason = 'busy with another home/unlock/stop request'
            elif len(self._moves):
                reason = 'a move is running: call gantry/stop first'
            if reason is not None:
                self._finished(RequestFinished(request_id, False, reason))
            else:
                self._system = SystemCommand(request_id, kind, '$H' if kind == 'home' else '$X')
        self._progress(now)

    def _request_stop(self, request_id: int, now: float) -> None:
        if not self.controller_seen:
            self._finished(RequestFinished(request_id, False, 'not connected to the controller'))
            return
        self._fail_all_moves('stopped by gantry/stop')
        if self.stage is Stage.SYSTEM_COMMAND and self._stop is None:
            self._reset_during_system_command(request_id, now)
        elif self._stop is None:
            self._begin_stop('gantry/stop', now, request_id=request_id)
        elif self._stop.request_id is not None:
            self._finished(RequestFinished(request_id, False, 'a stop is already running'))
        else:
            self._stop.request_id = request_id
            if self._stop.then_move is not None:
                self._moves.refuse(self._stop.then_move, 'stopped by gantry/stop',
                                   self._snapshot.world_position_m)
                self._stop.then_move = None

    def _set_fault(self, reason: str, now: float, stop_motion: bool = True,
                   reset_first: bool = False) -> None:
        """Latch a fault: drop the queue, fail the moves, stop buffered lines from running."""
        reset_first = reset_first or self.lockout is Lockout.FAULT_RESET_FIRST
        self.lockout = Lockout.FAULT_RESET_FIRST if reset_first else Lockout.FAULT
        self.fault_reason = reason
        self._log('error', f'gantry link: {reason}; call gantry/unlock or gantry/home')
        dropped = self._streamer.drop_queue()
        if dropped:
            self._log('warn', f'gantry link: dropped {len(dropped)} queued line(s)')
        self._fail_all_moves(reason)
        if stop_motion and self._streamer.in_flight and self._stop is None:
            # Character counting: lines already in Grbl's buffer would still run.
            self._begin_stop(f'fault: {reason}', now)
        self._emit_snapshot()

    # -- home / unlock / stop -----------------------------------------------------------------

    def _on_system_ok(self, system: SystemCommand, now: float) -> None:
        self._system = None
        self.lockout, self.fault_reason = Lockout.NONE, ''
        if system.kind == 'home':
            message = 'homed'
            self.homing_required = False
        else:
            message = 'unlocked'
            if self.homing_required:
                message += '; motion stays refused until gantry/home (position not trusted)'
        # $X / $H leave Alarm; (re)send the preamble so modes are known whatever happened.
        self._enter(Stage.QUERYING_STATE)
        self._query_status(now)
        self._done_when_ready = RequestFinished(system.request_id, True, message)
        self._emit_snapshot()

    def _end_system(self, success: bool, message: str) -> None:
        system, self._system = self._system, None
        if system is None:
            return
        if self.stage is Stage.SYSTEM_COMMAND:
            self._enter(system.resume_stage)
        self._finished(RequestFinished(system.request_id, success, message))

    def _finish_system(self, success: bool, message: str) -> None:
        """Answer the pending home/unlock (and one awaiting the preamble) with `message`."""
        if self._done_when_ready is not None:
            done, self._done_when_ready = self._done_when_ready, None
            self._finished(replace(done, success=False,
                                   message=f'{done.message}, but then {message}'))
        system, self._system = self._system, None
        if system is not None:
            self._finished(RequestFinished(system.request_id, success, message))

    def _begin_stop(self, reason: str, now: float, request_id: int | None = None,
                    then_move: Move | None = None) -> None:
        self._streamer.drop_queue()
        self._stop = StopSequence(reason, now + self.config.stop_timeout_s, self.stage,
                                  request_id, then_move)
        self._enter(Stage.FEED_HOLD)
        self._out.write(FEED_HOLD)
        self._query_status(now)

    def _reset_during_system_command(self, request_id: int, now: float) -> None:
        """Stop a home/unlock at once: Grbl ignores a feed hold while homing, not a reset.

        The reset leaves homing incomplete (Grbl raises ALARM:6 and stays in Alarm), so the
        position is not trusted and homing is required again.
        """
        system = self._system
        assert system is not None
        self._streamer.forget_in_flight()
        self._waiting_since = None
        self._end_system(False, f'{system.line} interrupted by gantry/stop (soft reset)')
        message = 'stopped with a soft reset'
        if system.kind == 'home':
            self.homing_required = True
            message += ('; homing is incomplete and the controller stays in Alarm: call '
                        'gantry/home')
        self._stop = StopSequence('gantry/stop during ' + system.line,
                                  now + self.config.stop_timeout_s, self.stage, request_id,
                                  done_at_banner=message)
        self._enter(Stage.RESETTING)
        self._out.write(SOFT_RESET)
        self._log('warn', f'gantry link: {message}')
        self._emit_snapshot()

    def _end_stop(self, success: bool, message: str) -> None:
        stop, self._stop = self._stop, None
        if stop is None:
            return
        if self.stage is Stage.FEED_HOLD:
            self._enter(stop.resume_stage)
        elif self.stage is Stage.RESETTING:
            self._enter(Stage.QUERYING_STATE)
        if stop.request_id is not None:
            self._finished(RequestFinished(stop.request_id, success, message))
        if stop.then_move is not None:
            if success:
                self._moves.waiting.appendleft(stop.then_move)
            else:
                self._moves.refuse(stop.then_move, 'could not replace the running move: '
                                   f'{message}', self._snapshot.world_position_m)
