"""Send-response and character-counting flow control over a recording port (no ROS)."""

import pytest
from cartesian_3p_driver.line_streamer import LineStreamer, StreamingError


class RecordingPort:
    def __init__(self) -> None:
        self.writes: list[bytes] = []

    def write(self, data: bytes) -> int:
        self.writes.append(data)
        return len(data)


def test_send_response_keeps_one_line_in_flight():
    port = RecordingPort()
    logged: list[str] = []
    streamer = LineStreamer(port, 'send_response', on_sent=logged.append)
    streamer.enqueue(['G21 G90 G94', 'G53 G1 Z10.000 F100.0'])
    assert streamer.pump() == 1
    assert streamer.pump() == 0
    assert port.writes == [b'G21 G90 G94\n']
    assert streamer.acknowledge() == 'G21 G90 G94'
    assert streamer.pump() == 1
    assert streamer.acknowledge() == 'G53 G1 Z10.000 F100.0'
    assert streamer.idle
    assert logged == ['G21 G90 G94', 'G53 G1 Z10.000 F100.0']
    assert (streamer.lines_sent, streamer.lines_acknowledged) == (2, 2)


def test_character_counting_fills_but_never_overflows_the_rx_buffer():
    port = RecordingPort()
    streamer = LineStreamer(port, 'character_counting', rx_buffer_size=127)
    line = 'G53 G1 X100.000 Y100.000 F1000.0'  # 32 characters + newline = 33 bytes
    streamer.enqueue([line] * 10)
    assert streamer.pump() == 3          # 99 bytes; a fourth would make 132 > 127
    assert streamer.in_flight_bytes == 99
    streamer.acknowledge()
    assert streamer.pump() == 1
    assert sum(len(data) for data in port.writes) == 4 * 33
    assert streamer.queued == 6


def test_reply_without_line_in_flight_is_an_error():
    streamer = LineStreamer(RecordingPort())
    with pytest.raises(StreamingError, match='no line in flight'):
        streamer.acknowledge()


@pytest.mark.parametrize('line', ['G0 X1\nG0 X2', 'G0 X' + '1' * 90, 'G0 X1 (é)'])
def test_unsendable_lines_are_refused_and_nothing_is_queued(line):
    streamer = LineStreamer(RecordingPort())
    with pytest.raises(StreamingError):
        streamer.enqueue(['G21', line])
    assert streamer.queued == 0


def test_drop_and_forget_never_resend():
    port = RecordingPort()
    streamer = LineStreamer(port, 'character_counting')
    streamer.enqueue(['G4 P0.1', 'G4 P0.2', 'G4 P0.3'])
    streamer.pump()
    assert streamer.forget_in_flight() == ['G4 P0.1', 'G4 P0.2', 'G4 P0.3']
    streamer.enqueue(['G4 P0.4'])
    streamer.pump()
    assert port.writes == [b'G4 P0.1\n', b'G4 P0.2\n', b'G4 P0.3\n', b'G4 P0.4\n']
    streamer.enqueue(['G4 P0.5'])
    assert streamer.drop_queue() == ['G4 P0.5']
    assert streamer.lines_sent == 4


def test_unknown_mode_is_refused():
    with pytest.raises(ValueError, match='streaming mode'):
        LineStreamer(RecordingPort(), 'fire_and_forget')
