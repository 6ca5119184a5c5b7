"""The simulator's I/O layer: a GrblController behind a pseudo-terminal and a TCP port.

ROS-free (standard library only). One thread owns the pty master, the TCP sockets and the
controller; nothing else touches them, so the controller needs no locking beyond the options.

Like an Arduino running Grbl, the simulated controller reboots (banner, Alarm if homing is
enabled) whenever a host opens the port: the pty master sees the slave open (its POLLHUP
clears), the TCP listener accepts a client.
"""

from __future__ import annotations

import contextlib
import os
import select
import socket
import threading
import time
import tty
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from .grbl_controller import GrblController

#: Longest the I/O loop sleeps when nothing arrives [s]; motion advances at least this often.
TICK_S = 0.004


@dataclass
class SimulatorOptions:
    """How the simulator is wired and which I/O faults it injects.

    Attributes:
        link_path: Create a symlink to the pty device here ('' = none).
        tcp_port: Also serve the controller on 127.0.0.1:tcp_port (0 = off).
        time_scale: Simulated seconds per wall-clock second (motion, dwell, homing).
        reply_delay_s: Delay each ok/error reply by this wall-clock time [s].
        boot_delay_s: Time from a host opening the port to the banner [s].
        vanish_on_line: Close the pty (and TCP client) right after receiving this line,
            before answering it, counted from the start (0 = never); one-shot.
        vanish_every_lines: Vanish likewise after every n-th received line (lines n, 2n, ...;
            0 = never): a controller that keeps disappearing, for soak runs.
        vanish_duration_s: Time until a new pty (same link_path) appears [s].
        received_lines_log: Append every received line to this file ('' = off).
    """

    link_path: str = ''
    tcp_port: int = 0
    time_scale: float = 1.0
    reply_delay_s: float = 0.0
    boot_delay_s: float = 0.05
    vanish_on_line: int = 0
    vanish_every_lines: int = 0
    vanish_duration_s: float = 1.0
    received_lines_log: str = ''


class GrblSimulator:
    """Run a GrblController on a pseudo-terminal (and optionally TCP) in a thread of its own.

    Args:
        controller: The controller state machine; its on_line_received hook is taken over.
        options: Wiring and I/O faults.
        log: Called with one-line messages worth an info log (device path, faults).
    """

    def __init__(self, controller: GrblController, options: SimulatorOptions,
                 log: Callable[[str], None] = lambda message: None) -> None:
        self.controller = controller
        self.options = options
        self._log = log
        self.received_lines: list[str] = []
        controller.on_line_received = self._on_line_received
        self._lines_log = (open(options.received_lines_log, 'a', encoding='ascii',  # noqa: SIM115
                                errors='replace')
                           if options.received_lines_log else None)
        self._master: int | None = None
        self.device_path = ''
        self._pty_connected = False
        self._listener: socket.socket | None = None
        self._client: socket.socket | None = None
        self._boot_at: float | None = None
        self._vanish_requested = False
        self._vanished_until: float | None = None
        self._pending: deque[tuple[float, bytes]] = deque()
        self._t0 = time.monotonic()
        self._sim_offset = 0.0
        self._scale_changed_at = self._t0
        self._stop = threading.Event()
        self.lock = threading.Lock()
        self._thread = threading.Thread(target=self._run, name='grbl_simulator', daemon=True)
        self._open_pty()
        if options.tcp_port:
            self._open_listener(options.tcp_port)

    # -- set-up -------------------------------------------------------------------------------

    def _open_pty(self) -> None:
        master, slave = os.openpty()
        tty.setraw(slave)
        self.device_path = os.ttyname(slave)
        # Close our copy of the slave: the master then reports POLLHUP until a host opens
        # the device, which is how the simulator notices a connection (an Arduino's DTR reset).
        os.close(slave)
        os.set_blocking(master, False)
        self._master = master
        self._pty_connected = False
        if self.options.link_path:
            link = Path(self.options.link_path)
            if link.exists() and not link.is_symlink():
                raise FileExistsError(f'link_path {link} exists and is not a symlink')
            temporary = link.with_name(f'.{link.name}.{os.getpid()}')
            with contextlib.suppress(FileNotFoundError):
                temporary.unlink()
            temporary.symlink_to(self.device_path)
            os.replace(temporary, link)
        self._log(f'fake_gantry serving Grbl on {self.device_path}'
                  + (f' (link {self.options.link_path})' if self.options.link_path else ''))

    def _open_listener(self, port: int) -> None:
        listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            listener.bind(('127.0.0.1', port))
        except OSError as error:
            listener.close()
            self._log(f'fake_gantry cannot listen on TCP port {port} ({error}); pty only')
            return
        listener.listen(1)
        listener.setblocking(False)
        self._listener = listener
        self._log(f'fake_gantry serving Grbl on socket://127.0.0.1:{port}')

    def start(self) -> None:
        """Start the I/O thread."""
        self._thread.start()

    def stop(self) -> None:
        """Stop the I/O thread and close everything (the symlink is removed)."""
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(5.0)
        self._close_pty()
        for sock in (self._client, self._listener):
            if sock is not None:
                sock.close()
        self._client = self._listener = None
        if self._lines_log is not None:
            self._lines_log.close()
            self._lines_log = None

    def _close_pty(self) -> None:
        if self._master is not None:
            os.close(self._master)
            self._master = None
        self._pty_connected = False
        if self.options.link_path:
            link = Path(self.options.link_path)
            if link.is_symlink():
                link.unlink()

    # -- time ---------------------------------------------------------------------------------

    def sim_time(self) -> float:
        """Simulated time since start [s] (wall time multiplied by the time scale)."""
        now = time.monotonic()
        return self._sim_offset + (now - self._scale_changed_at) * self.options.time_scale

    def set_time_scale(self, time_scale: float) -> None:
        """Change the time scale from now on without a jump in simulated time."""
        with self.lock:
            now = time.monotonic()
            self._sim_offset += (now - self._scale_changed_at) * self.options.time_scale
            self._scale_changed_at = now
            self.options.time_scale = time_scale

    # -- the loop -----------------------------------------------------------------------------

    def _on_line_received(self, line: str) -> None:
        self.received_lines.append(line)
        if self._lines_log is not None:
            self._lines_log.write(line + '\n')
            self._lines_log.flush()
        number = self.controller.lines_received
        every = self.options.vanish_every_lines
        if (self.options.vanish_on_line and number == self.options.vanish_on_line) \
                or (every > 0 and number % every == 0):
            self._vanish_requested = True

    def _host_connected(self) -> bool:
        return self._pty_connected or self._client is not None

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                self._iterate()
            except Exception as error:  # keep the simulator alive, and say why
                self._log(f'fake_gantry I/O error: {error!r}')
                time.sleep(0.1)

    def _iterate(self) -> None:
        now = time.monotonic()
        if self._vanished_until is not None:
            if now < self._vanished_until:
                time.sleep(TICK_S)
                return
            self._vanished_until = None
            self._open_pty()
        self._check_pty_connection(now)
        poller = select.poll()
        if self._master is not None and self._pty_connected:
            poller.register(self._master, select.POLLIN)
        if self._listener is not None:
            poller.register(self._listener, select.POLLIN)
        if self._client is not None:
            poller.register(self._client, select.POLLIN)
        timeout = TICK_S
        if self._pending:
            timeout = min(timeout, max(0.0, self._pending[0][0] - now))
        events = poller.poll(timeout * 1000.0)
        with self.lock:
            for fd, event in events:
                self._handle_event(fd, event)
            if self._boot_at is not None and time.monotonic() >= self._boot_at:
                self._boot_at = None
                self._pending.clear()
                self.controller.power_cycle(self.sim_time())
            self.controller.advance(self.sim_time())
            self._queue_output()
        if self._vanish_requested:
            # Gone before answering the line: what the host wrote after it would be lost in a
            # closed pty, and whether it got that far would depend on timing.
            self._vanish_requested = False
            self.options.vanish_on_line = 0
            self._vanish()
            return
        self._flush_output()

    def _check_pty_connection(self, now: float) -> None:
        if self._master is None:
            return
        probe = select.poll()
        probe.register(self._master, select.POLLIN)
        hung_up = any(event & select.POLLHUP for _, event in probe.poll(0))
        if hung_up and self._pty_connected:
            self._pty_connected = False
            self._log('fake_gantry: host closed the pty')
        elif not hung_up and not self._pty_connected:
            self._pty_connected = True
            self.controller.output.clear()
            self._boot_at = now + self.options.boot_delay_s
            self._log('fake_gantry: host opened the pty, rebooting')
        if hung_up:
            time.sleep(TICK_S)

    def _handle_event(self, fd: int, event: int) -> None:
        if self._listener is not None and fd == self._listener.fileno():
            client, _ = self._listener.accept()
            if self._client is not None:
                client.close()
                return
            client.setblocking(False)
            client.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            self._client = client
            self._boot_at = time.monotonic() + self.options.boot_delay_s
            self._log('fake_gantry: TCP client connected, rebooting')
            return
        if self._client is not None and fd == self._client.fileno():
            try:
                data = self._client.recv(4096)
            except OSError:
                data = b''
            if not data:
                self._client.close()
                self._client = None
                self._log('fake_gantry: TCP client disconnected')
                return
            self.controller.receive(data, self.sim_time())
            return
        if fd == self._master:
            try:
                data = os.read(fd, 4096)
            except (BlockingIOError, InterruptedError):
                return
            except OSError:
                data = b''
            if data:
                self.controller.receive(data, self.sim_time())

    def _queue_output(self) -> None:
        now = time.monotonic()
        last_due = self._pending[-1][0] if self._pending else now
        while self.controller.output:
            text = self.controller.output.popleft()
            if not self._host_connected():
                continue
            is_reply = text == 'ok' or text.startswith('error:') or text == 'o\ufffdk'
            due = max(last_due, now + (self.options.reply_delay_s if is_reply else 0.0))
            self._pending.append((due, text.encode('utf-8') + b'\r\n'))
            last_due = due

    def _flush_output(self) -> None:
        now = time.monotonic()
        data = b''
        while self._pending and self._pending[0][0] <= now:
            data += self._pending.popleft()[1]
        if not data:
            return
        if self._master is not None and self._pty_connected:
            with contextlib.suppress(BlockingIOError, OSError):
                os.write(self._master, data)
        if self._client is not None:
            with contextlib.suppress(OSError):
                self._client.sendall(data)

    def _vanish(self) -> None:
        self._log(f'fake_gantry: fault injection, device disappears for '
                  f'{self.options.vanish_duration_s} s')
        self._close_pty()
        if self._client is not None:
            self._client.close()
            self._client = None
        self._pending.clear()
        self._vanished_until = time.monotonic() + self.options.vanish_duration_s
