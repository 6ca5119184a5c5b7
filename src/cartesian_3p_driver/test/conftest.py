"""Fixtures of the driver's ROS-free tests.

`bench` builds a SessionBench: the driver's GrblSession wired in-process to the simulator's
controller model (GrblController) on a fake clock. No ROS, no pty, no threads: bytes go
straight from the session to the controller and its output straight back, so a test of a
safety rule runs in milliseconds.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import pytest
from cartesian_3p_driver.gcode import MotionConfig
from cartesian_3p_driver.grbl_controller import ControllerSettings, FaultInjection, GrblController
from cartesian_3p_driver.grbl_session import GrblSession
from cartesian_3p_driver.link_events import (
    CloseLink,
    GantrySnapshot,
    LineWritten,
    MoveFinished,
    RequestFinished,
    SessionConfig,
    SessionEvent,
)


@dataclass
class SessionBench:
    """The session, the controller model, the wire between them and a fake clock [s]."""

    config: SessionConfig = field(default_factory=SessionConfig)
    settings: ControllerSettings = field(
        default_factory=lambda: ControllerSettings(homing_enabled=False))
    faults: FaultInjection = field(default_factory=FaultInjection)
    motion: MotionConfig = field(default_factory=MotionConfig)
    now: float = 0.0
    #: False: the controller hears nothing and says nothing (a dead or silent port).
    controller_present: bool = True
    #: False: the controller's output is held back (replies late, or never).
    deliver_output: bool = True

    def __post_init__(self) -> None:
        self.session = GrblSession(self.config, self.motion, 'bench')
        self.controller = GrblController(self.settings, self.faults,
                                         on_line_received=self._on_received)
        self.written: list[str] = []
        self.received: list[str] = []
        self.wire: list[bytes] = []
        self.events: list[SessionEvent] = []
        self._ids = iter(range(1, 1_000_000))

    def _on_received(self, line: str) -> None:
        self.received.append(line)

    # -- driving ------------------------------------------------------------------------------

    def open(self) -> None:
        """Open the port: the controller reboots (as on a DTR reset) and prints its banner."""
        self.session.connection_opened(self.now)
        self.controller.output.clear()
        if self.controller_present:
            self.controller.power_cycle(self.now)
        self.pump()

    def pump(self) -> None:
        """Carry bytes both ways until neither side has anything to say."""
        for _ in range(1000):
            self._collect()
            data = self.session.data_to_send()
            if data:
                self.wire.append(data)
                if self.controller_present:
                    self.controller.receive(data, self.now)
            elif self.controller_present:
                self.controller.advance(self.now)
            output = b''
            if self.deliver_output and self.controller_present:
                output = b''.join(line.encode('utf-8') + b'\r\n'
                                  for line in self.controller.output)
                self.controller.output.clear()
                self.session.receive(output, self.now)
            if not data and not output:
                break
        self._collect()

    def step(self, dt_s: float = 0.01) -> None:
        """Let `dt_s` [s] pass on both sides, then carry the bytes."""
        self.now += dt_s
        self.session.tick(self.now)
        self.pump()

    def run_until(self, predicate: Callable[[], bool], what: str,
                  limit_s: float = 120.0, dt_s: float = 0.01) -> None:
        """Step the clock until `predicate` holds; fail after `limit_s` simulated seconds."""
        end = self.now + limit_s
        while not predicate():
            if self.now > end:
                raise AssertionError(f'{what}: not within {limit_s} s simulated; last '
                                     f'snapshot {self.snapshot}')
            self.step(dt_s)

    def _collect(self) -> None:
        for event in self.session.events():
            self.events.append(event)
            if isinstance(event, LineWritten):
                self.written.append(event.line)

    # -- commands and what came of them -------------------------------------------------------

    def move(self, x: float, y: float, z: float, feed_mm_min: float = 0.0) -> int:
        job_id = next(self._ids)
        self.session.submit_move(job_id, (x, y, z), feed_mm_min, self.now)
        self.pump()
        return job_id

    def request(self, kind: str) -> int:
        request_id = next(self._ids)
        self.session.request(kind, request_id, self.now)
        self.pump()
        return request_id

    def finished(self, job_or_request_id: int) -> MoveFinished | RequestFinished | None:
        for event in self.events:
            if isinstance(event, MoveFinished | RequestFinished) and (
                    getattr(event, 'job_id', None) == job_or_request_id
                    or getattr(event, 'request_id', None) == job_or_request_id):
                return event
        return None

    def wait_finished(self, job_or_request_id: int,
                      limit_s: float = 120.0) -> MoveFinished | RequestFinished:
        self.run_until(lambda: self.finished(job_or_request_id) is not None,
                       f'answer to {job_or_request_id}', limit_s)
        result = self.finished(job_or_request_id)
        assert result is not None
        return result

    def ready(self) -> None:
        self.run_until(lambda: self.snapshot.connected and self.snapshot.state == 'Idle',
                       'connected and Idle')

    @property
    def snapshot(self) -> GantrySnapshot:
        return self.session.snapshot

    def closed(self) -> bool:
        return any(isinstance(event, CloseLink) for event in self.events)

    def logs(self, level: str) -> list[str]:
        return [event.message for event in self.events
                if getattr(event, 'level', None) == level]

    def commands(self) -> list[str]:
        """What was written, in order: each line, and the real-time bytes but `?`."""
        tokens: list[str] = []
        line = bytearray()
        for byte in b''.join(self.wire):
            if byte == 0x0A:
                tokens.append(line.decode('ascii'))
                line.clear()
            elif byte in REALTIME:
                tokens.append(REALTIME[byte])
            elif byte != 0x3F:
                line.append(byte)
        return tokens


REALTIME = {0x21: '!', 0x7E: '~', 0x18: 'RESET'}


@pytest.fixture
def bench() -> Callable[..., SessionBench]:
    """Factory: a SessionBench with the given fields (config, settings, faults, motion)."""

    def build(**fields: Any) -> SessionBench:
        return SessionBench(**fields)

    return build
