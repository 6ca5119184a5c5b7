"""The driver's serial link: one I/O thread feeding a GrblSession from a pyserial port.

ROS-free (standard library and pyserial). Every protocol and safety rule lives in the
sans-I/O session (grbl_session.py); this runner only owns what touches the operating system:
the port, the thread, the wake-up pipe, the sent-lines log and the reconnection back-off.
Callers talk to it through `submit_move` / `cancel_move` / `request` (a command queue plus a
wake-up pipe, so a new target reaches the wire without waiting for a poll tick) and hear back
through `on_event`, called in the I/O thread.

Why a dedicated thread rather than executor callbacks: pyserial reads and writes are blocking
system calls with timeouts; in a thread of their own they never hold up the ROS executor, and
the session has a single owner with no locking.
"""

from __future__ import annotations

import contextlib
import itertools
import os
import queue
import select
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import serial

from .gcode import MotionConfig, Vector3
from .grbl_session import GrblSession
from .link_events import (
    REQUESTS,
    CloseLink,
    LineWritten,
    LinkEvent,
    LogRecord,
    SessionConfig,
)

#: Least time between two reminders that the port still cannot be opened [s].
RETRY_REMINDER_PERIOD_S = 30.0


@dataclass(frozen=True)
class LinkConfig:
    """Where the link connects and how it retries; the session settings ride along.

    Attributes:
        port: Device path or pyserial URL.
        baud: Baud rate [bit/s].
        reconnect_initial_s: First reconnection delay, doubled per failure [s].
        reconnect_max_s: Longest reconnection delay [s].
        sent_lines_log: File each written line is appended to ('' = off).
        session: Protocol settings for the session.
    """

    port: str = 'socket://127.0.0.1:23000'
    baud: int = 115200
    reconnect_initial_s: float = 0.5
    reconnect_max_s: float = 5.0
    sent_lines_log: str = ''
    session: SessionConfig = field(default_factory=SessionConfig)


class ReconnectSchedule:
    """Exponential back-off between connection attempts, and when to remind the operator.

    Args:
        initial_s: First delay [s].
        maximum_s: Longest delay [s].
        reminder_period_s: Least time between two log reminders of a lasting failure [s].
    """

    def __init__(self, initial_s: float, maximum_s: float,
                 reminder_period_s: float = RETRY_REMINDER_PERIOD_S) -> None:
        self.initial_s = initial_s
        self.maximum_s = maximum_s
        self.reminder_period_s = reminder_period_s
        self.failures = 0
        self.next_attempt = 0.0
        self._reminded_at: float | None = None

    def failed(self, now: float) -> bool:
        """Count a failed or lost connection at `now` [s]; return whether to log it."""
        delay = min(self.initial_s * 2 ** min(self.failures, 60), self.maximum_s)
        self.failures += 1
        self.next_attempt = now + delay
        if self._reminded_at is None or now - self._reminded_at >= self.reminder_period_s:
            self._reminded_at = now
            return True
        return False

    def succeeded(self) -> None:
        """A controller answered: start again from the first delay, log the next failure."""
        self.failures = 0
        self._reminded_at = None


class GrblLink:
    """Serial link to a Grbl controller, run by a thread of its own.

    Args:
        config: Port, retry and session settings.
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
        self.session = GrblSession(config.session, motion, config.port)
        self._port: Any = None
        self._schedule = ReconnectSchedule(config.reconnect_initial_s, config.reconnect_max_s)

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
        self._close_port()
        if self._sent_log is not None:
            self._sent_log.close()
            self._sent_log = None
        for fd in (self._wake_r, self._wake_w):
            with contextlib.suppress(OSError):
                os.close(fd)

    def reconfigure(self, config: LinkConfig, motion: MotionConfig) -> None:
        """Use new settings from the next decision on (the port and log stay as opened)."""
        # Each is replaced whole; the I/O thread reads them per decision.
        self.config = config
        self.session.config = config.session
        self.session.motion = motion
        self._schedule.initial_s = config.reconnect_initial_s
        self._schedule.maximum_s = config.reconnect_max_s

    def submit_move(self, target_m: Vector3, feed_mm_min: float = 0.0) -> int:
        """Ask for a move to a validated world target [m]; return its job id.

        The outcome arrives as a MoveFinished event with that id.
        """
        job_id = next(self._ids)
        self._commands.put(('move', (job_id, target_m, feed_mm_min)))
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
        self._flush()
        self._on_event(self.session.snapshot)
        while not self._stop_event.is_set():
            try:
                self._iterate()
            except (serial.SerialException, OSError) as error:
                self._lost(f'serial error: {error}')
            except Exception as error:  # a bug must not kill the link silently
                self._log('error', f'gantry link: unexpected {error!r}; reconnecting')
                self._lost(f'internal error: {error!r}')

    def _iterate(self) -> None:
        session = self.session
        now = time.monotonic()
        if self._port is None and now >= self._schedule.next_attempt:
            self._connect(now)
        fds = [self._wake_r]
        if self._port is not None:
            fds.append(self._port.fileno())
            timeout = session.next_timer_s(now)
        else:
            timeout = max(0.0, min(self._schedule.next_attempt - now, 0.5))
        readable, _, _ = select.select(fds, [], [], timeout)
        if self._wake_r in readable:
            with contextlib.suppress(BlockingIOError):
                os.read(self._wake_r, 4096)
        if self._port is not None:
            data = self._port.read(4096)
            if data:
                session.receive(data, time.monotonic())
                if session.controller_seen:
                    self._schedule.succeeded()
                self._flush()
        self._handle_commands()
        if self._port is not None:
            session.tick(time.monotonic())
            self._flush()

    def _handle_commands(self) -> None:
        while True:
            try:
                kind, payload = self._commands.get_nowait()
            except queue.Empty:
                return
            now = time.monotonic()
            if kind == 'move':
                job_id, target_m, feed_mm_min = payload
                self.session.submit_move(job_id, target_m, feed_mm_min, now)
            elif kind == 'cancel':
                self.session.cancel_move(payload, now)
            else:
                self.session.request(kind, payload, now)
            self._flush()

    def _flush(self) -> None:
        """Hand the session's events out, then write its bytes.

        Lines are logged before they are written: a line that may have reached the
        controller is in the log, and it is never written again.
        """
        for event in self.session.events():
            if isinstance(event, LineWritten):
                self._record_sent(event.line)
            elif isinstance(event, LogRecord):
                self._log(event.level, event.message)
            elif isinstance(event, CloseLink):
                self._close_port()
                self._schedule.failed(time.monotonic())
            else:
                self._on_event(event)
        data = self.session.data_to_send()
        if data and self._port is not None:
            self._port.write(data)

    def _connect(self, now: float) -> None:
        try:
            self._port = self._open_port(self.config.port, self.config.baud)
        except (serial.SerialException, OSError, ValueError) as error:
            reason = f'cannot open {self.config.port}: {error}'
            if self._schedule.failed(now):
                self._log('warn', f'gantry link: {reason}; retrying every '
                                  f'{self.config.reconnect_max_s} s at most')
            self.session.connection_failed(reason)
            self._flush()
            return
        self.session.connection_opened(now)
        self._log('info', f'gantry link: opened {self.config.port}, waiting for the banner')
        self._flush()

    def _record_sent(self, line: str) -> None:
        if self._sent_log is not None:
            self._sent_log.write(line + '\n')
            self._sent_log.flush()

    def _close_port(self) -> None:
        port, self._port = self._port, None
        if port is not None:
            with contextlib.suppress(Exception):
                port.close()

    def _lost(self, reason: str) -> None:
        self._close_port()
        self._schedule.failed(time.monotonic())
        self.session.connection_lost(reason, time.monotonic())
        self._flush()
