"""The simulator's I/O layer on a real pseudo-terminal (no ROS): the repeating vanish fault."""

from __future__ import annotations

import os
import select
import time
from pathlib import Path

from cartesian_3p_driver.grbl_controller import ControllerSettings, GrblController
from cartesian_3p_driver.grbl_simulator import GrblSimulator, SimulatorOptions

TIMEOUT_S = 10.0


def wait_for(predicate, what: str) -> None:
    deadline = time.monotonic() + TIMEOUT_S
    while not predicate():
        assert time.monotonic() < deadline, f'timed out waiting for {what}'
        time.sleep(0.01)


def read_until(fd: int, text: bytes) -> bytes:
    """Read from the pty until `text` arrived; return everything read."""
    data = b''
    deadline = time.monotonic() + TIMEOUT_S
    while text not in data:
        remaining = deadline - time.monotonic()
        assert remaining > 0, f'timed out waiting for {text!r}, got {data!r}'
        ready, _, _ = select.select([fd], [], [], remaining)
        if ready:
            data += os.read(fd, 4096)
    return data


def test_vanish_every_lines_closes_the_device_again_and_again(tmp_path: Path):
    link = tmp_path / 'tty'
    messages: list[str] = []
    simulator = GrblSimulator(
        GrblController(ControllerSettings(homing_enabled=False)),
        SimulatorOptions(link_path=str(link), time_scale=100.0, vanish_every_lines=2,
                         vanish_duration_s=0.1, boot_delay_s=0.0),
        messages.append)
    simulator.start()
    try:
        for connection in range(1, 3):
            # Each new pty is announced once (the first at start).
            wait_for(lambda count=connection: sum(
                'serving Grbl on' in message for message in messages) == count and link.exists(),
                f'pty number {connection}')
            fd = os.open(link, os.O_RDWR | os.O_NOCTTY)
            try:
                read_until(fd, b'Grbl 1.1')
                os.write(fd, b'G21\n')
                assert b'ok' in read_until(fd, b'ok\r\n')
                os.write(fd, b'G21\n')  # the 2nd, 4th, ... line: gone before the reply
                wait_for(lambda count=connection: sum(
                    'disappears' in message for message in messages) == count,
                    f'vanish number {connection}')
            finally:
                os.close(fd)
        assert simulator.received_lines == ['G21'] * 4
    finally:
        simulator.stop()
