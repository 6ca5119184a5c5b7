"""Stream G-code lines to a Grbl controller: send-response or character counting.

ROS-free. The streamer owns the host queue and the lines in flight (written, not yet answered
with `ok` / `error:N`). Every line is written exactly once: nothing is ever re-sent, whatever
happens to its reply; after a fault the host queue is dropped instead.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Iterable
from typing import Protocol

from .grbl_protocol import MAX_LINE_LENGTH, RX_BUFFER_SIZE

STREAMING_MODES = ('send_response', 'character_counting')


class SupportsWrite(Protocol):
    """The part of a pyserial port the streamer uses."""

    def write(self, data: bytes) -> int | None:
        """Write bytes to the controller."""


class StreamingError(RuntimeError):
    """A reply arrived with no line in flight, or a line cannot be sent at all."""


class LineStreamer:
    """Host queue and flow control for lines sent to a Grbl controller.

    `send_response` keeps one line in flight and waits for its reply (Grbl's recommended
    protocol). `character_counting` keeps sending while the unanswered bytes, newlines
    included, fit in the controller's receive buffer.

    Args:
        port: Where lines are written (a pyserial port).
        mode: One of STREAMING_MODES.
        rx_buffer_size: Usable receive-buffer bytes of the controller [bytes].
        on_sent: Called with each line just before it is written (the sent-lines log).
    """

    def __init__(self, port: SupportsWrite, mode: str = 'send_response',
                 rx_buffer_size: int = RX_BUFFER_SIZE,
                 on_sent: Callable[[str], None] | None = None) -> None:
        if mode not in STREAMING_MODES:
            raise ValueError(f'streaming mode {mode!r} is not one of {", ".join(STREAMING_MODES)}')
        self._port = port
        self.mode = mode
        self.rx_buffer_size = rx_buffer_size
        self._on_sent = on_sent
        self._queue: deque[str] = deque()
        self._in_flight: deque[str] = deque()
        self._in_flight_bytes = 0
        self.lines_sent = 0
        self.lines_acknowledged = 0

    @property
    def queued(self) -> int:
        """Lines waiting on the host."""
        return len(self._queue)

    @property
    def in_flight(self) -> int:
        """Lines written and not yet answered."""
        return len(self._in_flight)

    @property
    def in_flight_bytes(self) -> int:
        """Bytes written and not yet answered, newlines included [bytes]."""
        return self._in_flight_bytes

    @property
    def idle(self) -> bool:
        """True when nothing is queued and nothing is waiting for a reply."""
        return not self._queue and not self._in_flight

    def oldest_in_flight(self) -> str | None:
        """Return the line the next reply belongs to, if any."""
        return self._in_flight[0] if self._in_flight else None

    def enqueue(self, lines: Iterable[str]) -> None:
        """Append lines to the host queue after checking each can be sent.

        Raises:
            StreamingError: For a line with a line break, non-ASCII text, or longer than the
                controller accepts; then nothing is queued.
        """
        checked = []
        for line in lines:
            if '\n' in line or '\r' in line:
                raise StreamingError(f'line {line!r} contains a line break')
            if not line.isascii():
                raise StreamingError(f'line {line!r} is not ASCII')
            if len(line) > MAX_LINE_LENGTH or len(line) + 1 > self.rx_buffer_size:
                raise StreamingError(f'line {line!r} is longer than {MAX_LINE_LENGTH} characters')
            checked.append(line)
        self._queue.extend(checked)

    def _may_send(self, line: str) -> bool:
        if self.mode == 'send_response':
            return not self._in_flight
        return self._in_flight_bytes + len(line) + 1 <= self.rx_buffer_size

    def pump(self) -> int:
        """Write as many queued lines as the flow control allows; return how many."""
        written = 0
        while self._queue and self._may_send(self._queue[0]):
            line = self._queue.popleft()
            # Counted as sent before the write: if the write fails half-way the line may have
            # reached the controller, and it must never be written a second time.
            self._in_flight.append(line)
            self._in_flight_bytes += len(line) + 1
            self.lines_sent += 1
            if self._on_sent is not None:
                self._on_sent(line)
            self._port.write(line.encode('ascii') + b'\n')
            written += 1
        return written

    def acknowledge(self) -> str:
        """Account for one `ok` / `error:N`: pop and return the line it answers.

        Raises:
            StreamingError: When no line is in flight (a reply the host cannot place).
        """
        if not self._in_flight:
            raise StreamingError('reply received with no line in flight')
        line = self._in_flight.popleft()
        self._in_flight_bytes -= len(line) + 1
        self.lines_acknowledged += 1
        return line

    def drop_queue(self) -> list[str]:
        """Drop every line still on the host and return them."""
        dropped = list(self._queue)
        self._queue.clear()
        return dropped

    def forget_in_flight(self) -> list[str]:
        """Forget the unanswered lines (the controller was reset or lost); return them."""
        forgotten = list(self._in_flight)
        self._in_flight.clear()
        self._in_flight_bytes = 0
        return forgotten
