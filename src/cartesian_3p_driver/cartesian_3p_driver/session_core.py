"""The state of a Grbl session and its primitives: stages, latches, outputs, snapshots.

ROS-free and I/O-free. GrblSession (grbl_session.py) builds on this with the protocol rules;
SessionRequests (session_requests.py) holds the commands and the home/unlock/stop sequences.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, replace
from enum import Enum
from typing import Any

from .gcode import MotionConfig
from .grbl_protocol import STATUS_QUERY, StatusReport
from .grbl_settings_check import MachineSettings
from .line_streamer import LineStreamer
from .link_events import (
    DISCONNECTED,
    GantrySnapshot,
    LineWritten,
    LinkEvent,
    LogRecord,
    MoveFinished,
    RequestFinished,
    SessionConfig,
    SessionEvent,
)
from .move_queue import Move, MoveQueue

FAST_POLL_PERIOD_S = 0.05


class Stage(Enum):
    """Where the conversation with the controller stands."""

    CLOSED = 'closed'
    AWAITING_BANNER = 'waiting for banner'
    AWAITING_BANNER_AFTER_RESET = 'no banner: soft reset sent, waiting for banner'
    QUERYING_STATE = 'banner seen'
    READING_SETTINGS = 'reading the controller settings ($$)'
    STATE_KNOWN = 'state known, preamble not sent'
    SENDING_PREAMBLE = 'preamble sent'
    READY = 'ready'
    SYSTEM_COMMAND = 'home/unlock running'
    FEED_HOLD = 'stopping: feed hold, waiting for Hold:0'
    RESETTING = 'soft reset sent, waiting for banner'


#: Stages in which the controller's state is known since the last banner and nothing of
#: ours is pending: a home/unlock may be sent from these.
SETTLED_STAGES = (Stage.STATE_KNOWN, Stage.SENDING_PREAMBLE, Stage.READY)
#: Allowed transitions; `_enter` refuses anything else (a bug, not a controller fault).
_TRANSITIONS: dict[Stage, tuple[Stage, ...]] = {
    Stage.CLOSED: (Stage.AWAITING_BANNER,),
    Stage.AWAITING_BANNER: (Stage.AWAITING_BANNER_AFTER_RESET, Stage.QUERYING_STATE),
    Stage.AWAITING_BANNER_AFTER_RESET: (Stage.QUERYING_STATE,),
    Stage.QUERYING_STATE: (Stage.STATE_KNOWN, Stage.READING_SETTINGS),
    Stage.READING_SETTINGS: (Stage.STATE_KNOWN,),
    Stage.STATE_KNOWN: (Stage.SENDING_PREAMBLE,),
    Stage.SENDING_PREAMBLE: (Stage.READY,),
    Stage.READY: (),
    Stage.SYSTEM_COMMAND: (Stage.QUERYING_STATE,) + SETTLED_STAGES,
    Stage.FEED_HOLD: (Stage.RESETTING,) + SETTLED_STAGES,
    Stage.RESETTING: (Stage.QUERYING_STATE,),
}
#: From any stage but CLOSED: a banner, a stop, a home/unlock (or the reset it needs first).
_ALWAYS = (Stage.CLOSED, Stage.QUERYING_STATE, Stage.FEED_HOLD, Stage.SYSTEM_COMMAND,
           Stage.RESETTING)


class Lockout(Enum):
    """The fault latch: motion stays refused until gantry/unlock or gantry/home."""

    NONE = 'none'
    FAULT = 'fault'
    #: Grbl waits for a soft reset before it accepts $X / $H (hard or soft limit alarm).
    FAULT_RESET_FIRST = 'fault, soft reset before unlocking'


@dataclass
class SystemCommand:
    """A pending home ($H) or unlock ($X) request."""

    request_id: int
    kind: str
    line: str
    resume_stage: Stage = Stage.STATE_KNOWN


@dataclass
class StopSequence:
    """A running stop: feed hold, Hold:0, soft reset, banner, preamble acknowledged."""

    reason: str
    deadline: float
    resume_stage: Stage
    request_id: int | None = None
    then_move: Move | None = None
    #: Set when the stop is a bare soft reset: it is over at the banner, with this message.
    done_at_banner: str = ''


class _Output:
    """Bytes waiting to be written; the line streamer's port."""

    def __init__(self) -> None:
        self.data = bytearray()

    def write(self, data: bytes) -> int:
        self.data.extend(data)
        return len(data)


class SessionCore:
    """Stage, latches, queues and outputs of a session, and the primitives that change them.

    Args:
        config: Protocol settings (timeouts, streaming mode, policies).
        motion: Motion planning settings (transform, limits, approach, feeds).
        port_name: The port, as shown in snapshots and diagnostics.
    """

    def __init__(self, config: SessionConfig, motion: MotionConfig, port_name: str = '') -> None:
        self.config = config
        self.motion = motion
        self.stage = Stage.CLOSED
        self.lockout = Lockout.NONE
        self.fault_reason = ''
        # Set at start (if configured) and by every reconnection; only $H clears it.
        self.homing_required = config.require_homing_at_start
        # The controller's $$ settings, read once per connection, and why they forbid motion.
        self.machine_settings: MachineSettings | None = None
        self.settings_problem = ''
        self._setting_values: dict[int, float] = {}
        self._out = _Output()
        self._events: deque[SessionEvent] = deque()
        self._streamer = self._new_streamer()
        self._rx = bytearray()
        self._snapshot = GantrySnapshot(port=port_name)
        self._closed_reason = ''
        self._total_sent = 0
        self._report: StatusReport | None = None
        self._wco: tuple[float, float, float] | None = None
        self._opened_at = self._last_rx_at = self._last_poll_at = 0.0
        self._waiting_since: float | None = None
        self._moves = MoveQueue(self._emit)
        self._system: SystemCommand | None = None
        self._stop: StopSequence | None = None
        # A home/unlock that succeeded, answered once the preamble is acknowledged again.
        self._done_when_ready: RequestFinished | None = None

    # -- outputs ------------------------------------------------------------------------------

    def data_to_send(self) -> bytes:
        """Return (and forget) the bytes to write to the controller, in order."""
        data = bytes(self._out.data)
        self._out.data.clear()
        return data

    def events(self) -> list[SessionEvent]:
        """Return (and forget) the events since the last call, in order."""
        events = list(self._events)
        self._events.clear()
        return events

    @property
    def snapshot(self) -> GantrySnapshot:
        """The last snapshot emitted."""
        return self._snapshot

    @property
    def is_open(self) -> bool:
        """True while a port is open (from connection_opened to connection_lost)."""
        return self.stage is not Stage.CLOSED

    @property
    def controller_seen(self) -> bool:
        """True once a banner arrived on this connection."""
        return self.stage not in (Stage.CLOSED, Stage.AWAITING_BANNER,
                                  Stage.AWAITING_BANNER_AFTER_RESET)

    def next_timer_s(self, now: float) -> float:
        """Return how soon `tick` has work to do (polling, timeouts) [s]."""
        if self.stage is Stage.CLOSED:
            return 0.5
        period = FAST_POLL_PERIOD_S if self._stop is not None else self.config.poll_period_s
        return max(0.0, min(self._last_poll_at + period - now, 0.05))

    # -- stages -------------------------------------------------------------------------------

    def _enter(self, stage: Stage) -> None:
        if stage not in _ALWAYS and stage not in _TRANSITIONS[self.stage]:
            raise RuntimeError(f'gantry session: no transition from {self.stage.name} to '
                               f'{stage.name}')
        self.stage = stage

    def _homing(self) -> bool:
        return self.stage is Stage.SYSTEM_COMMAND and self._system is not None \
            and self._system.kind == 'home'

    def _query_status(self, now: float) -> None:
        self._last_poll_at = now
        self._out.write(STATUS_QUERY)

    def _new_streamer(self) -> LineStreamer:
        return LineStreamer(self._out, self.config.streaming_mode, on_sent=self._record_sent)

    def _record_sent(self, line: str) -> None:
        self._total_sent += 1
        self._events.append(LineWritten(line))

    def _log(self, level: str, message: str) -> None:
        self._events.append(LogRecord(level, message))

    def _emit(self, event: LinkEvent) -> None:
        self._events.append(event)

    def _emit_snapshot(self, **changes: Any) -> None:
        streamer = self._streamer
        snapshot = replace(self._snapshot, **changes)
        is_open = self.stage is not Stage.CLOSED
        link_state = self.stage.value if is_open else (self._closed_reason or 'closed')
        snapshot = replace(
            snapshot,
            connected=self._connected(),
            fault=self.fault_reason or (
                f'controller settings refuse motion: {self.settings_problem}'
                if self.settings_problem else ''),
            settings_problem=self.settings_problem,
            lines_queued=(streamer.queued if is_open else 0) + self._moves.waiting_lines(),
            lines_sent=streamer.lines_sent if is_open else 0,
            lines_acknowledged=streamer.lines_acknowledged if is_open else 0,
            total_lines_sent=self._total_sent,
            link_state=link_state)
        if not is_open:
            snapshot = replace(snapshot, state=DISCONNECTED, sub_state=-1)
        # As published: motion is refused until gantry/home (or gantry/unlock) succeeds.
        snapshot = replace(snapshot, homing_required=(
            self.homing_required or self.lockout is not Lockout.NONE
            or snapshot.state == 'Alarm'))
        self._snapshot = snapshot
        self._emit(snapshot)

    def _connected(self) -> bool:
        """Banner seen and preamble acknowledged since (as the message defines `connected`)."""
        if self.stage is Stage.READY:
            return True
        resume = (self._system.resume_stage if self.stage is Stage.SYSTEM_COMMAND
                  and self._system is not None else
                  self._stop.resume_stage if self.stage is Stage.FEED_HOLD
                  and self._stop is not None else None)
        return resume is Stage.READY

    def _finished(self, event: MoveFinished | RequestFinished) -> None:
        self._emit(event)

    def _may_move(self) -> str | None:
        """Return why no move may start now, or None."""
        if not self.controller_seen:
            return 'not connected to the controller'
        if self.homing_required:
            return 'homing required (after a reconnection or at start): call gantry/home'
        if self.lockout is not Lockout.NONE:
            return (f'stopped after a fault ({self.fault_reason}): call gantry/unlock or '
                    'gantry/home')
        if self._report is not None and self._report.state == 'Alarm':
            return 'controller in Alarm: call gantry/home or gantry/unlock'
        if self.settings_problem:
            return (f'controller settings refuse motion: {self.settings_problem}; fix the '
                    'parameters or the controller, then reconnect')
        if self._system is not None or self._stop is not None:
            return 'busy with a home/unlock/stop request'
        if self.stage is not Stage.READY:
            return 'controller not ready yet (preamble not acknowledged)'
        return None
    def _fail_all_moves(self, outcome: str) -> None:
        self._moves.fail_all(outcome, self._snapshot.world_position_m)

    def _progress(self, now: float) -> None:
        """Send what may be sent now (GrblSession)."""
        raise NotImplementedError
