"""What the driver's Grbl session is told and what it reports: settings, snapshots, events.

ROS-free, plain data. The session (grbl_session.py) produces these; the serial runner
(grbl_link.py) hands the LinkEvents to the node and handles the RunnerEvents itself.
"""

from __future__ import annotations

from dataclasses import dataclass

from .gcode import Vector3

DISCONNECTED = 'Disconnected'
REQUESTS = ('home', 'unlock', 'stop')


@dataclass(frozen=True)
class SessionConfig:
    """How the session talks to the controller (timeouts, streaming, policies).

    Attributes:
        streaming_mode: 'send_response' or 'character_counting'.
        poll_period_s: Status (`?`) polling period [s].
        banner_timeout_s: Wait for a banner after opening before a soft reset, and after that
            before giving up on the connection [s].
        reply_timeout_s: Longest wait for the ok/error of a line ($H excluded) [s].
        homing_timeout_s: Longest wait for `$H` to finish [s].
        link_timeout_s: No byte at all for this long means the link is dead [s].
        stop_timeout_s: Longest wait for Hold:0 and the banner in a stop sequence [s].
        new_target_policy: 'queue' or 'replace' for targets arriving during a move.
        max_queued_moves: Most moves waiting behind the active one (queue policy).
        position_tolerance_mm: Distance to the goal accepted as 'at the target' [mm].
        require_homing_at_start: Refuse motion until homed, even on the first connection.
    """

    streaming_mode: str = 'send_response'
    poll_period_s: float = 0.2
    banner_timeout_s: float = 2.5
    reply_timeout_s: float = 5.0
    homing_timeout_s: float = 120.0
    link_timeout_s: float = 3.0
    stop_timeout_s: float = 10.0
    new_target_policy: str = 'queue'
    max_queued_moves: int = 4
    position_tolerance_mm: float = 0.02
    require_homing_at_start: bool = False


@dataclass(frozen=True)
class GantrySnapshot:
    """What the session knows about the gantry; positions [mm] machine, [m] world.

    `link_error` is the last reason the port could not be opened or was lost ('' once a
    controller answered); `settings_problem` is why the controller's `$$` settings forbid
    motion ('' when they fit the driver's parameters).
    """

    state: str = DISCONNECTED
    sub_state: int = -1
    connected: bool = False
    homing_required: bool = False
    machine_position_mm: Vector3 | None = None
    world_position_m: Vector3 | None = None
    feed_mm_min: float = 0.0
    pins: str = ''
    last_error_code: int = 0
    last_error_text: str = ''
    last_alarm_code: int = 0
    last_alarm_text: str = ''
    fault: str = ''
    lines_queued: int = 0
    lines_sent: int = 0
    lines_acknowledged: int = 0
    total_lines_sent: int = 0
    reconnections: int = 0
    port: str = ''
    link_state: str = 'closed'
    link_error: str = ''
    settings_problem: str = ''


@dataclass(frozen=True)
class MoveFeedback:
    """Progress of a move: controller-reported position and state."""

    job_id: int
    world_position_m: Vector3
    state: str
    distance_remaining_m: float


@dataclass(frozen=True)
class MoveFinished:
    """A move ended: reached (Idle at the goal) or not, and why."""

    job_id: int
    success: bool
    outcome: str
    world_position_m: Vector3 | None


@dataclass(frozen=True)
class RequestFinished:
    """A home / unlock / stop request ended."""

    request_id: int
    success: bool
    message: str


@dataclass(frozen=True)
class LogRecord:
    """A notable event worth one log line; level is 'info', 'warn' or 'error'."""

    level: str
    message: str


@dataclass(frozen=True)
class LineWritten:
    """A line just handed to the port, exactly once (for the sent-lines log)."""

    line: str


@dataclass(frozen=True)
class CloseLink:
    """The session gave up on this connection: close the port, reconnect with back-off."""

    reason: str


#: Events for the node.
LinkEvent = GantrySnapshot | MoveFeedback | MoveFinished | RequestFinished
#: Events for the serial runner.
RunnerEvent = LogRecord | LineWritten | CloseLink
SessionEvent = LinkEvent | RunnerEvent
