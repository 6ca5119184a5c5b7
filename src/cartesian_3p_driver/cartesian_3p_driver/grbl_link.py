"""The driver's serial link to a Grbl controller: one I/O thread, protocol and safety rules.

ROS-free (standard library and pyserial). The thread owns the port, the line streamer and
every decision that depends on what the controller said; callers talk to it only through
`submit_*` / `request` (a command queue plus a wake-up pipe, so a new target reaches the wire
without waiting for a poll tick) and hear back through `on_event`, called in the I/O thread.

Why a dedicated thread rather than executor callbacks: pyserial reads and writes are blocking
system calls with timeouts; in a thread of their own they never hold up the ROS executor, and
the protocol state (lines in flight, stop sequences) has a single owner with no locking.

Safety rules enforced here:
- Nothing moves before the banner was seen and the preamble acknowledged.
- Each line is written exactly once; nothing is ever replayed after a fault or a reconnect.
- error:N, ALARM:N, a garbled or missing reply stop streaming, drop the host queue and latch
  a fault that only gantry/unlock or gantry/home clears.
- After a reconnection, motion is refused until the controller was homed again.
- A move is finished only when the controller reports Idle at the goal.
"""

from __future__ import annotations

import contextlib
import itertools
import math
import os
import queue
import select
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import serial

from .gcode import (
    PREAMBLE,
    MotionConfig,
    MovePlan,
    TargetRejectedError,
    Vector3,
    plan_move,
)
from .grbl_protocol import (
    CRITICAL_ALARMS,
    FEED_HOLD,
    SOFT_RESET,
    STATUS_QUERY,
    ProtocolError,
    ReplyKind,
    StatusReport,
    alarm_text,
    classify,
    error_text,
    parse_status_report,
)
from .line_streamer import LineStreamer, StreamingError

DISCONNECTED = 'Disconnected'
#: Status polling while a stop sequence waits for Hold:0 [s].
FAST_POLL_PERIOD_S = 0.05
#: Idle reports away from the goal, after every line was answered, before a move fails.
IDLE_AWAY_REPORTS = 3


@dataclass(frozen=True)
class LinkConfig:
    """How the link talks to the controller.

    Attributes:
        port: Device path or pyserial URL.
        baud: Baud rate [bit/s].
        streaming_mode: 'send_response' or 'character_counting'.
        poll_period_s: Status (`?`) polling period [s].
        banner_timeout_s: Wait for a banner after opening before a soft reset, and after that
            before giving up on the connection [s].
        reply_timeout_s: Longest wait for the ok/error of a line ($H excluded) [s].
        homing_timeout_s: Longest wait for `$H` to finish [s].
        link_timeout_s: No byte at all for this long means the link is dead [s].
        stop_timeout_s: Longest wait for Hold:0 and the banner in a stop sequence [s].
        reconnect_initial_s: First reconnection delay, doubled per failure [s].
        reconnect_max_s: Longest reconnection delay [s].
        new_target_policy: 'queue' or 'replace' for targets arriving during a move.
        max_queued_moves: Most moves waiting behind the active one (queue policy).
        position_tolerance_mm: Distance to the goal accepted as 'at the target' [mm].
        require_homing_at_start: Refuse motion until homed, even on the first connection.
        sent_lines_log: File each written line is appended to ('' = off).
    """

    port: str = 'socket://127.0.0.1:23000'
    baud: int = 115200
    streaming_mode: str = 'send_response'
    poll_period_s: float = 0.2
    banner_timeout_s: float = 2.5
    reply_timeout_s: float = 5.0
    homing_timeout_s: float = 120.0
    link_timeout_s: float = 3.0
    stop_timeout_s: float = 10.0
    reconnect_initial_s: float = 0.5
    reconnect_max_s: float = 5.0
    new_target_policy: str = 'queue'
    max_queued_moves: int = 4
    position_tolerance_mm: float = 0.02
    require_homing_at_start: bool = False
    sent_lines_log: str = ''


@dataclass(frozen=True)
class GantrySnapshot:
    """What the link knows about the gantry; positions [mm] machine, [m] world."""

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


LinkEvent = GantrySnapshot | MoveFeedback | MoveFinished | RequestFinished
REQUESTS = ('home', 'unlock', 'stop')


@dataclass
class _Job:
    job_id: int
    target_m: Vector3
    feed_mm_min: float
    plan: MovePlan | None = None
    lines_left: int = 0
    acked_at: float | None = None
    idle_away: int = 0


@dataclass
class _SystemCommand:
    request_id: int
    kind: str
    line: str
    sent: bool = False


@dataclass
class _StopSequence:
    reason: str
    stage: str = 'hold'          # 'hold': waiting for Hold:0; 'reset': waiting for the banner
    deadline: float = 0.0
    request_id: int | None = None
    then_job: _Job | None = None


@dataclass
class _Connection:
    port: Any
    streamer: LineStreamer
    opened_at: float
    banner_seen: bool = False
    soft_reset_sent: bool = False
    state_known: bool = False
    preamble_sent: bool = False
    ready: bool = False
    needs_reset: bool = False
    reset_requested: bool = False
    rx: bytearray = field(default_factory=bytearray)
    last_rx_at: float = 0.0
    last_poll_at: float = 0.0
    waiting_since: float | None = None


class GrblLink:
    """Serial link to a Grbl controller, run by a thread of its own.

    Args:
        config: Link settings.
        motion: Motion planning settings (transform, limits, approach, feeds).
        on_event: Receives every LinkEvent, called in the I/O thread; must not block.
        log: Receives (level, message) for notable events, in the I/O thread; level is
            'info', 'warn' or 'error'. Called once per event, never per poll.
        open_port: Opens the port (pyserial's serial_for_url by default); for tests.
    """

    def __init__(self, config: LinkConfig, motion: MotionConfig,
                 on_event: Callable[[LinkEvent], None],
                 log: Callable[[str, str], None] = lambda level, message: None,
                 open_port: Callable[[str, int], Any] | None = None) -> None:
        self.config = config
        self.motion = motion
        self._on_event = on_event
        self._log = log
        self._open_port = open_port or self._serial_for_url
        self._commands: queue.SimpleQueue[tuple[str, Any]] = queue.SimpleQueue()
        self._wake_r, self._wake_w = os.pipe()
        os.set_blocking(self._wake_r, False)
        os.set_blocking(self._wake_w, False)
        self._ids = itertools.count(1)
        self._stop_event = threading.Event()
        self._thread = threading.Thread(target=self._run, name='grbl_link', daemon=True)
        self._sent_log = (open(config.sent_lines_log, 'a', encoding='ascii')  # noqa: SIM115
                          if config.sent_lines_log else None)
        # I/O-thread state
        self._conn: _Connection | None = None
        self._next_attempt = 0.0
        self._failures = 0
        self._snapshot = GantrySnapshot(port=config.port)
        # Set at start (if configured) and by every reconnection; only $H clears it.
        self._needs_homing = config.require_homing_at_start
        self._total_sent = 0
        self._report: StatusReport | None = None
        self._wco: Vector3 | None = None
        self._jobs: deque[_Job] = deque()
        self._active: _Job | None = None
        self._system: _SystemCommand | None = None
        self._stop_sequence: _StopSequence | None = None
        # A home/unlock that succeeded, answered once the preamble is acknowledged again.
        self._done_when_ready: RequestFinished | None = None
        self._fault = ''

    # -- public API (any thread) --------------------------------------------------------------

    def start(self) -> None:
        """Start the I/O thread."""
        self._thread.start()

    def close(self) -> None:
        """Stop the I/O thread and close the port."""
        self._stop_event.set()
        self._wake()
        if self._thread.is_alive():
            self._thread.join(5.0)
        if self._conn is not None:
            with contextlib.suppress(Exception):
                self._conn.port.close()
            self._conn = None
        if self._sent_log is not None:
            self._sent_log.close()
            self._sent_log = None
        for fd in (self._wake_r, self._wake_w):
            with contextlib.suppress(OSError):
                os.close(fd)

    def submit_move(self, target_m: Vector3, feed_mm_min: float = 0.0) -> int:
        """Ask for a move to a validated world target [m]; return its job id.

        The outcome arrives as a MoveFinished event with that id.
        """
        job_id = next(self._ids)
        self._commands.put(('move', _Job(job_id, target_m, feed_mm_min)))
        self._wake()
        return job_id

    def cancel_move(self, job_id: int) -> None:
        """Cancel a move: dropped if waiting, stopped (feed hold, reset) if running."""
        self._commands.put(('cancel', job_id))
        self._wake()

    def request(self, kind: str) -> int:
        """Ask for 'home' ($H), 'unlock' ($X) or 'stop' (feed hold, soft reset); return its id.

        The outcome arrives as a RequestFinished event with that id.
        """
        if kind not in REQUESTS:
            raise ValueError(f'request {kind!r} is not one of {", ".join(REQUESTS)}')
        request_id = next(self._ids)
        self._commands.put((kind, request_id))
        self._wake()
        return request_id

    def _wake(self) -> None:
        with contextlib.suppress(BlockingIOError, OSError):
            os.write(self._wake_w, b'.')

    # -- the I/O thread -----------------------------------------------------------------------

    @staticmethod
    def _serial_for_url(port: str, baud: int) -> Any:
        return serial.serial_for_url(port, baudrate=baud, timeout=0, write_timeout=1.0)

    def _run(self) -> None:
        self._emit_snapshot()
        while not self._stop_event.is_set():
            try:
                self._iterate()
            except (serial.SerialException, OSError) as error:
                self._lost_connection(f'serial error: {error}')
            except Exception as error:  # a bug must not kill the link silently
                self._log('error', f'gantry link: unexpected {error!r}; reconnecting')
                self._lost_connection(f'internal error: {error!r}')

    def _iterate(self) -> None:
        now = time.monotonic()
        if self._conn is None and now >= self._next_attempt:
            self._connect(now)
        conn = self._conn
        fds = [self._wake_r]
        if conn is not None:
            fds.append(conn.port.fileno())
        readable, _, _ = select.select(fds, [], [], self._wait_time(now))
        if self._wake_r in readable:
            with contextlib.suppress(BlockingIOError):
                os.read(self._wake_r, 4096)
        if conn is not None and conn is self._conn:
            data = conn.port.read(4096)
            if data:
                conn.last_rx_at = time.monotonic()
                conn.rx.extend(data)
                self._handle_rx(conn)
        self._handle_commands()
        if self._conn is not None:
            self._check_timers(time.monotonic())
        if self._conn is not None:
            self._progress()

    def _wait_time(self, now: float) -> float:
        conn = self._conn
        if conn is None:
            return max(0.0, min(self._next_attempt - now, 0.5))
        period = (FAST_POLL_PERIOD_S if self._stop_sequence is not None
                  else self.config.poll_period_s)
        return max(0.0, min(conn.last_poll_at + period - now, 0.05))

    def _connect(self, now: float) -> None:
        try:
            port = self._open_port(self.config.port, self.config.baud)
        except (serial.SerialException, OSError, ValueError) as error:
            delay = min(self.config.reconnect_initial_s * 2 ** self._failures,
                        self.config.reconnect_max_s)
            if self._failures == 0:
                self._log('warn', f'gantry link: cannot open {self.config.port} ({error}); '
                                  f'retrying with back-off up to {self.config.reconnect_max_s} s')
            self._failures += 1
            self._next_attempt = now + delay
            return
        streamer = LineStreamer(port, self.config.streaming_mode, on_sent=self._record_sent)
        self._conn = _Connection(port, streamer, opened_at=now, last_rx_at=now, last_poll_at=now)
        self._log('info', f'gantry link: opened {self.config.port}, waiting for the banner')
        self._emit_snapshot(link_state='waiting for banner')

    def _record_sent(self, line: str) -> None:
        self._total_sent += 1
        if self._sent_log is not None:
            self._sent_log.write(line + '\n')
            self._sent_log.flush()

    def _write(self, data: bytes) -> None:
        assert self._conn is not None
        self._conn.port.write(data)

    def _lost_connection(self, reason: str) -> None:
        conn = self._conn
        self._conn = None
        had_controller = conn is not None and conn.banner_seen
        if conn is not None:
            with contextlib.suppress(Exception):
                conn.port.close()
            self._log('error', f'gantry link: {reason}; controller disconnected, retrying '
                               'with back-off; homing will be required')
        now = time.monotonic()
        delay = min(self.config.reconnect_initial_s * 2 ** self._failures,
                    self.config.reconnect_max_s)
        self._failures += 1
        self._next_attempt = now + delay
        self._report = None
        outcome = f'serial link lost ({reason})'
        self._fail_all_moves(outcome)
        self._finish_system(False, outcome)
        if self._stop_sequence is not None:
            if self._stop_sequence.request_id is not None:
                self._finished(RequestFinished(self._stop_sequence.request_id, False, outcome))
            self._stop_sequence = None
        if had_controller:
            self._needs_homing = True
            self._snapshot = replace(self._snapshot,
                                     reconnections=self._snapshot.reconnections + 1)
        self._emit_snapshot(state=DISCONNECTED, sub_state=-1, connected=False, feed_mm_min=0.0,
                            link_state=f'disconnected: {reason}')

    # -- incoming lines -----------------------------------------------------------------------

    def _handle_rx(self, conn: _Connection) -> None:
        while self._conn is conn:
            cut = [i for i in (conn.rx.find(b'\n'), conn.rx.find(b'\r')) if i >= 0]
            if not cut:
                return
            index = min(cut)
            raw = bytes(conn.rx[:index])
            del conn.rx[:index + 1]
            text = raw.decode('ascii', errors='replace').strip()
            if text:
                self._handle_line(conn, text)

    def _handle_line(self, conn: _Connection, text: str) -> None:
        reply = classify(text)
        if reply.kind is ReplyKind.BANNER:
            self._on_banner(conn, text)
        elif not conn.banner_seen:
            return  # noise before the banner (boot loader, a half line)
        elif reply.kind is ReplyKind.STATUS:
            try:
                report = parse_status_report(text)
            except ProtocolError as error:
                self._log('warn', f'gantry link: ignoring malformed status report: {error}')
                return
            self._on_status(conn, report)
        elif reply.kind in (ReplyKind.OK, ReplyKind.ERROR):
            self._on_reply(conn, reply.kind is ReplyKind.OK, reply.code)
        elif reply.kind is ReplyKind.ALARM:
            self._on_alarm(conn, reply.code)
        elif reply.kind is ReplyKind.MESSAGE:
            if 'Reset to continue' in text:
                conn.needs_reset = True
            self._log('info', f'gantry controller: {text}')
        elif reply.kind is ReplyKind.UNKNOWN:
            line = conn.streamer.oldest_in_flight()
            if line is None:
                self._log('warn', f'gantry link: ignoring unrecognised line {text!r}')
                return
            conn.streamer.forget_in_flight()
            self._set_fault(conn, f'unrecognised reply {text!r} while waiting for the reply '
                                  f'to {line!r}; streaming stopped')

    def _on_banner(self, conn: _Connection, text: str) -> None:
        first = not conn.banner_seen
        conn.banner_seen = True
        expected = conn.reset_requested or (
            self._stop_sequence is not None and self._stop_sequence.stage == 'reset')
        conn.state_known = conn.preamble_sent = conn.ready = conn.needs_reset = False
        conn.reset_requested = False
        conn.waiting_since = None
        lost = conn.streamer.forget_in_flight() + conn.streamer.drop_queue()
        self._failures = 0
        if first:
            self._log('info', f'gantry link: controller says {text!r}')
        elif expected:
            self._log('info', 'gantry link: controller reset as requested')
        else:
            self._log('warn', f'gantry link: unexpected controller reset ({text!r}); '
                              f'{len(lost)} unanswered line(s) discarded, none re-sent')
            self._fail_all_moves('controller reset unexpectedly')
            self._finish_system(False, 'controller reset unexpectedly')
        if self._system is not None:
            self._system.sent = False
        if self._stop_sequence is not None and self._stop_sequence.stage == 'reset':
            self._stop_sequence.stage = 'ready'
        self._query_status(conn)
        self._emit_snapshot(connected=False, link_state='banner seen')

    def _query_status(self, conn: _Connection) -> None:
        conn.last_poll_at = time.monotonic()
        self._write(STATUS_QUERY)

    def _on_status(self, conn: _Connection, report: StatusReport) -> None:
        if report.work_offset_mm is not None:
            self._wco = report.work_offset_mm
        self._report = report
        conn.state_known = True
        machine = report.resolve_machine_position(self._wco)
        world = self.motion.transform.to_world(machine) if machine is not None else None
        self._snapshot = replace(
            self._snapshot, state=report.state, sub_state=report.sub_state,
            machine_position_mm=machine, world_position_m=world,
            feed_mm_min=report.feed_mm_min or 0.0, pins=report.pins)
        stop = self._stop_sequence
        if stop is not None and stop.stage == 'hold':
            if report.state == 'Alarm':
                self._end_stop_sequence(False, 'controller raised an alarm during the stop')
            elif report.state == 'Hold' and report.sub_state == 0:
                # Only Hold:0 (a feed hold in Idle gives Hold:0 too): a stale Idle report
                # from before the `!` must not trigger a reset while a block starts.
                stop.stage = 'reset'
                conn.reset_requested = True
                stop.deadline = time.monotonic() + self.config.stop_timeout_s
                self._write(SOFT_RESET)
        job = self._active
        # world is derived from machine: both are None or neither (narrowed for mypy).
        if (job is not None and job.plan is not None and world is not None
                and machine is not None):
            self._on_job_status(job, report, machine, world)
        self._emit_snapshot()

    def _on_job_status(self, job: _Job, report: StatusReport, machine: Vector3,
                       world: Vector3) -> None:
        assert job.plan is not None
        goal = job.plan.goal_machine_mm
        distance_mm = math.dist(machine, goal)
        distance_m = math.dist(world, job.plan.goal_world_m)
        self._on_event(MoveFeedback(job.job_id, world, report.state, distance_m))
        if job.lines_left > 0 or job.acked_at is None:
            return
        if report.state != 'Idle':
            job.idle_away = 0
            return
        if distance_mm <= self.config.position_tolerance_mm:
            self._active = None
            self._finished(MoveFinished(job.job_id, True, 'reached', world))
            return
        job.idle_away += 1
        if job.idle_away >= IDLE_AWAY_REPORTS:
            self._active = None
            self._finished(MoveFinished(
                job.job_id, False, f'controller idle {distance_mm:.3f} mm away from the '
                                   'goal after every line was acknowledged', world))

    def _on_reply(self, conn: _Connection, ok: bool, code: int) -> None:
        try:
            line = conn.streamer.acknowledge()
        except StreamingError:
            if self._fault:
                self._log('warn', 'gantry link: ignoring a reply after the fault')
                return
            self._set_fault(conn, f"{'ok' if ok else f'error:{code}'} arrived with no line "
                                  'in flight (replies out of step); streaming stopped')
            return
        conn.waiting_since = time.monotonic() if conn.streamer.in_flight else None
        system = self._system
        if system is not None and system.sent and line == system.line:
            if ok:
                self._on_system_ok(conn, system)
            else:
                self._system = None
                self._finished(RequestFinished(system.request_id, False,
                                               f'{line} refused: error:{code} '
                                               f'({error_text(code)})'))
                self._emit_snapshot(last_error_code=code, last_error_text=error_text(code))
            return
        if not ok:
            meaning = error_text(code)
            self._emit_snapshot(last_error_code=code, last_error_text=meaning)
            self._set_fault(conn, f'error:{code} ({meaning}) for line {line!r}; streaming '
                                  'stopped')
            return
        if line in PREAMBLE and conn.preamble_sent and not conn.ready \
                and not conn.streamer.in_flight and not conn.streamer.queued:
            conn.ready = True
            self._log('info', 'gantry link: controller ready (preamble acknowledged)')
            self._on_ready(conn)
            self._emit_snapshot()
            return
        job = self._active
        if job is not None and job.lines_left > 0:
            job.lines_left -= 1
            if job.lines_left == 0:
                job.acked_at = time.monotonic()
        self._emit_snapshot()

    def _on_alarm(self, conn: _Connection, code: int) -> None:
        meaning = alarm_text(code)
        if code in CRITICAL_ALARMS:
            conn.needs_reset = True
        forgotten = conn.streamer.forget_in_flight()
        conn.waiting_since = None
        self._emit_snapshot(last_alarm_code=code, last_alarm_text=meaning)
        if self._system is not None and self._system.sent:
            system, self._system = self._system, None
            self._finished(RequestFinished(system.request_id, False,
                                           f'{system.line} ended in ALARM:{code} ({meaning})'))
        self._set_fault(conn, f'ALARM:{code} ({meaning}); {len(forgotten)} unanswered line(s) '
                              'discarded', stop_motion=False)

    def _set_fault(self, conn: _Connection, reason: str, stop_motion: bool = True) -> None:
        """Latch a fault: drop the queue, fail the moves, stop buffered lines from running."""
        self._fault = reason
        self._log('error', f'gantry link: {reason}; call gantry/unlock or gantry/home')
        dropped = conn.streamer.drop_queue()
        if dropped:
            self._log('warn', f'gantry link: dropped {len(dropped)} queued line(s)')
        self._fail_all_moves(reason)
        if stop_motion and conn.streamer.in_flight and self._stop_sequence is None:
            # Character counting: lines already in Grbl's buffer would still run.
            self._begin_stop_sequence(f'fault: {reason}')
        self._emit_snapshot()

    # -- outgoing -----------------------------------------------------------------------------

    def _on_ready(self, conn: _Connection) -> None:
        if self._done_when_ready is not None:
            done, self._done_when_ready = self._done_when_ready, None
            self._finished(done)
        stop = self._stop_sequence
        if stop is not None and stop.stage == 'ready':
            self._end_stop_sequence(True, 'stopped')

    def _progress(self) -> None:
        """Send what may be sent now: preamble, system commands, the next move's lines."""
        conn = self._conn
        assert conn is not None
        report = self._report
        if conn.banner_seen and conn.state_known and not conn.preamble_sent \
                and report is not None and report.state != 'Alarm' \
                and not conn.streamer.in_flight and self._system is None:
            conn.preamble_sent = True
            conn.streamer.enqueue(PREAMBLE)
        system = self._system
        if system is not None and not system.sent and conn.banner_seen and conn.state_known \
                and not conn.streamer.in_flight and self._stop_sequence is None:
            if conn.needs_reset:
                # After a hard/soft-limit alarm Grbl accepts $X/$H only after a reset.
                conn.needs_reset = False
                conn.state_known = False
                conn.reset_requested = True
                self._write(SOFT_RESET)
            else:
                system.sent = True
                conn.streamer.enqueue([system.line])
        if self._active is None and self._jobs and self._may_move(conn) is None:
            self._start_job(conn, self._jobs.popleft())
        if conn.streamer.pump() and conn.waiting_since is None:
            conn.waiting_since = time.monotonic()

    def _may_move(self, conn: _Connection | None) -> str | None:
        """Return why no move may start now, or None."""
        if conn is None or not conn.banner_seen:
            return 'not connected to the controller'
        if self._needs_homing:
            return 'homing required (after a reconnection or at start): call gantry/home'
        if self._fault:
            return f'stopped after a fault ({self._fault}): call gantry/unlock or gantry/home'
        if self._report is not None and self._report.state == 'Alarm':
            return 'controller in Alarm: call gantry/home or gantry/unlock'
        if not conn.ready:
            return 'controller not ready yet (preamble not acknowledged)'
        if self._system is not None or self._stop_sequence is not None:
            return 'busy with a home/unlock/stop request'
        return None

    def _start_job(self, conn: _Connection, job: _Job) -> None:
        current = self._snapshot.world_position_m
        try:
            job.plan = plan_move(job.target_m, current, job.feed_mm_min, self.motion)
        except TargetRejectedError as error:
            self._finished(MoveFinished(job.job_id, False, error.reason, current))
            return
        self._active = job
        job.lines_left = len(job.plan.lines)
        conn.streamer.enqueue(job.plan.lines)
        self._log('info', f'gantry link: move {job.job_id} to {job.target_m} m: '
                          f'{len(job.plan.lines)} line(s)')

    def _on_system_ok(self, conn: _Connection, system: _SystemCommand) -> None:
        self._system = None
        self._fault = ''
        if system.kind == 'home':
            message = 'homed'
            self._needs_homing = False
        else:
            message = 'unlocked'
            if self._needs_homing:
                message += '; motion stays refused until gantry/home (position not trusted)'
        # $X / $H leave Alarm; (re)send the preamble so modes are known whatever happened.
        conn.preamble_sent = conn.ready = False
        conn.state_known = False
        self._query_status(conn)
        self._done_when_ready = RequestFinished(system.request_id, True, message)
        self._emit_snapshot()

    def _begin_stop_sequence(self, reason: str, request_id: int | None = None,
                             then_job: _Job | None = None) -> None:
        conn = self._conn
        assert conn is not None
        conn.streamer.drop_queue()
        self._stop_sequence = _StopSequence(reason, 'hold',
                                            time.monotonic() + self.config.stop_timeout_s,
                                            request_id, then_job)
        self._write(FEED_HOLD)
        self._query_status(conn)

    def _end_stop_sequence(self, success: bool, message: str) -> None:
        stop, self._stop_sequence = self._stop_sequence, None
        if stop is None:
            return
        if stop.request_id is not None:
            self._finished(RequestFinished(stop.request_id, success, message))
        if stop.then_job is not None:
            if success:
                self._jobs.appendleft(stop.then_job)
            else:
                self._finished(MoveFinished(stop.then_job.job_id, False,
                                            f'could not replace the running move: {message}',
                                            self._snapshot.world_position_m))

    # -- commands from other threads ----------------------------------------------------------

    def _handle_commands(self) -> None:
        while True:
            try:
                kind, payload = self._commands.get_nowait()
            except queue.Empty:
                return
            if kind == 'move':
                self._command_move(payload)
            elif kind == 'cancel':
                self._command_cancel(payload)
            elif kind == 'stop':
                self._command_stop(payload)
            else:
                self._command_system(kind, payload)

    def _command_move(self, job: _Job) -> None:
        conn = self._conn
        reason = self._may_move(conn)
        busy_only = reason is not None and reason.startswith('busy') \
            and self._stop_sequence is not None and self._stop_sequence.then_job is not None
        if reason is not None and not busy_only:
            self._finished(MoveFinished(job.job_id, False, f'refused: {reason}',
                                        self._snapshot.world_position_m))
            return
        assert conn is not None
        if self._active is None and not busy_only:
            self._jobs.append(job)
            return
        if self.config.new_target_policy == 'replace':
            stop = self._stop_sequence
            if stop is not None and stop.then_job is not None:
                replaced, stop.then_job = stop.then_job, job
                self._finished(MoveFinished(replaced.job_id, False,
                                            'replaced by a newer target',
                                            self._snapshot.world_position_m))
                return
            self._fail_all_moves('replaced by a newer target')
            self._begin_stop_sequence('replaced by a newer target', then_job=job)
            return
        if len(self._jobs) >= self.config.max_queued_moves:
            self._finished(MoveFinished(job.job_id, False,
                                        f'refused: {len(self._jobs)} moves already queued '
                                        f'(max_queued_moves)', self._snapshot.world_position_m))
            return
        self._jobs.append(job)

    def _command_cancel(self, job_id: int) -> None:
        for job in list(self._jobs):
            if job.job_id == job_id:
                self._jobs.remove(job)
                self._finished(MoveFinished(job_id, False, 'cancelled',
                                            self._snapshot.world_position_m))
                return
        if self._active is not None and self._active.job_id == job_id and self._conn:
            self._fail_all_moves('cancelled')
            if self._stop_sequence is None:
                self._begin_stop_sequence('move cancelled')

    def _command_stop(self, request_id: int) -> None:
        conn = self._conn
        if conn is None or not conn.banner_seen:
            self._finished(RequestFinished(request_id, False, 'not connected to the controller'))
            return
        self._fail_all_moves('stopped by gantry/stop')
        if self._stop_sequence is not None:
            if self._stop_sequence.request_id is not None:
                self._finished(RequestFinished(request_id, False, 'a stop is already running'))
                return
            self._stop_sequence.request_id = request_id
            self._stop_sequence.then_job = None
            return
        self._begin_stop_sequence('gantry/stop', request_id=request_id)

    def _command_system(self, kind: str, request_id: int) -> None:
        conn = self._conn
        reason = None
        if conn is None or not conn.banner_seen:
            reason = 'not connected to the controller'
        elif self._system is not None or self._stop_sequence is not None:
            reason = 'busy with another home/unlock/stop request'
        elif self._active is not None or self._jobs:
            reason = 'a move is running: call gantry/stop first'
        if reason is not None:
            self._finished(RequestFinished(request_id, False, reason))
            return
        self._system = _SystemCommand(request_id, kind, '$H' if kind == 'home' else '$X')

    # -- timers -------------------------------------------------------------------------------

    def _check_timers(self, now: float) -> None:
        conn = self._conn
        assert conn is not None
        config = self.config
        if not conn.banner_seen:
            if now - conn.opened_at > config.banner_timeout_s and not conn.soft_reset_sent:
                conn.soft_reset_sent = True
                conn.opened_at = now
                self._log('info', 'gantry link: no banner yet, sending a soft reset')
                self._write(SOFT_RESET)
            elif now - conn.opened_at > config.banner_timeout_s:
                raise serial.SerialException(
                    f'no Grbl banner within {2 * config.banner_timeout_s:.1f} s')
            return
        homing = self._system is not None and self._system.sent and self._system.kind == 'home'
        if not homing and now - conn.last_rx_at > config.link_timeout_s:
            raise serial.SerialException(f'no data from the controller for '
                                         f'{config.link_timeout_s:.1f} s')
        if conn.waiting_since is not None and conn.streamer.in_flight:
            limit = config.homing_timeout_s if homing else config.reply_timeout_s
            if now - conn.waiting_since > limit:
                line = conn.streamer.oldest_in_flight()
                conn.streamer.forget_in_flight()
                conn.waiting_since = None
                if self._system is not None and self._system.sent:
                    system, self._system = self._system, None
                    self._finished(RequestFinished(system.request_id, False,
                                                   f'no reply to {line!r} within {limit:.1f} s'))
                self._set_fault(conn, f'no reply to {line!r} within {limit:.1f} s (lost '
                                      'reply?); streaming stopped, nothing re-sent')
        stop = self._stop_sequence
        if stop is not None and now > stop.deadline:
            self._end_stop_sequence(False, f'controller did not reach Hold:0 and reset within '
                                           f'{config.stop_timeout_s:.1f} s')
        period = FAST_POLL_PERIOD_S if stop is not None else config.poll_period_s
        if now - conn.last_poll_at >= period and not homing:
            self._query_status(conn)
        elif homing and now - conn.last_poll_at >= max(period, 1.0):
            self._query_status(conn)  # Grbl may not answer while homing; harmless

    # -- events -------------------------------------------------------------------------------

    def _fail_all_moves(self, outcome: str) -> None:
        position = self._snapshot.world_position_m
        jobs = ([self._active] if self._active is not None else []) + list(self._jobs)
        self._active = None
        self._jobs.clear()
        for job in jobs:
            self._finished(MoveFinished(job.job_id, False, outcome, position))

    def _finish_system(self, success: bool, message: str) -> None:
        if self._done_when_ready is not None:
            done, self._done_when_ready = self._done_when_ready, None
            self._finished(replace(done, success=False, message=f'{done.message}, but then '
                                                                f'{message}'))
        if self._system is not None:
            system, self._system = self._system, None
            self._finished(RequestFinished(system.request_id, success, message))

    def _finished(self, event: MoveFinished | RequestFinished) -> None:
        self._on_event(event)

    def _emit_snapshot(self, **changes: Any) -> None:
        conn = self._conn
        streamer = conn.streamer if conn is not None else None
        snapshot = replace(self._snapshot, **changes)
        link_state = changes.get('link_state', snapshot.link_state)
        if conn is not None and conn.ready and 'link_state' not in changes:
            link_state = 'ready'
        snapshot = replace(
            snapshot,
            connected=bool(conn is not None and conn.ready),
            fault=self._fault,
            lines_queued=(streamer.queued if streamer else 0) + sum(
                len(job.plan.lines) if job.plan else 0 for job in self._jobs),
            lines_sent=streamer.lines_sent if streamer else 0,
            lines_acknowledged=streamer.lines_acknowledged if streamer else 0,
            total_lines_sent=self._total_sent,
            link_state=link_state)
        if conn is None:
            snapshot = replace(snapshot, state=DISCONNECTED, sub_state=-1)
        # As published: motion is refused until gantry/home (or gantry/unlock) succeeds.
        snapshot = replace(snapshot, homing_required=(
            self._needs_homing or bool(self._fault) or snapshot.state == 'Alarm'))
        self._snapshot = snapshot
        self._on_event(snapshot)
