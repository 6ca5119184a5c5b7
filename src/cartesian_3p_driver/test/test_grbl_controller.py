"""The simulated Grbl controller's state machine, driven with explicit time (no I/O, no ROS)."""

import pytest
from cartesian_3p_driver.grbl_controller import (
    ALARM_LOCK_MESSAGE,
    BANNER,
    ControllerSettings,
    FaultInjection,
    GrblController,
)
from cartesian_3p_driver.grbl_protocol import parse_status_report


def make(homing: bool = False, **faults) -> GrblController:
    received: list[str] = []
    controller = GrblController(ControllerSettings(homing_enabled=homing),
                                FaultInjection(**faults), on_line_received=received.append)
    controller.received = received  # type: ignore[attr-defined]
    return controller


def drain(controller: GrblController) -> list[str]:
    lines = list(controller.output)
    controller.output.clear()
    return lines


def status(controller: GrblController, now: float):
    controller.receive(b'?', now)
    return parse_status_report(drain(controller)[-1])


def test_banner_at_power_up_and_alarm_lock_with_homing():
    assert drain(make())[1] == BANNER
    assert drain(make(homing=True))[1:] == [BANNER, ALARM_LOCK_MESSAGE]


def test_move_runs_over_time_and_ends_idle_at_target():
    controller = make()
    drain(controller)
    controller.receive(b'G21 G90 G94\nG53 G1 X60.000 F600.0\n', 0.0)
    assert drain(controller) == ['ok', 'ok']
    report = status(controller, 3.0)       # 600 mm/min = 10 mm/s -> 30 mm after 3 s
    assert report.state == 'Run'
    assert report.machine_position_mm[0] == pytest.approx(30.0)
    assert report.feed_mm_min == 600.0
    report = status(controller, 6.5)
    assert (report.state, report.machine_position_mm) == ('Idle', (60.0, 0.0, 0.0))
    assert controller.received == ['G21 G90 G94', 'G53 G1 X60.000 F600.0']


def test_rate_is_capped_by_axis_maximum():
    controller = GrblController(ControllerSettings(homing_enabled=False,
                                                   max_rate_mm_min=[60.0, 60.0, 60.0]))
    controller.receive(b'G1 X10 F6000\n', 0.0)
    assert status(controller, 5.0).machine_position_mm[0] == pytest.approx(5.0)


def test_feed_hold_reaches_hold_0_and_reset_keeps_position_without_alarm():
    controller = make()
    controller.receive(b'G1 X100 F600\n', 0.0)
    controller.receive(b'!', 1.0)
    assert status(controller, 1.01).sub_state == 1
    held = status(controller, 1.5)
    assert (held.state, held.sub_state) == ('Hold', 0)
    stopped_at = held.machine_position_mm
    assert status(controller, 3.0).machine_position_mm == stopped_at
    drain(controller)
    controller.receive(b'\x18', 3.0)
    assert drain(controller)[1] == BANNER
    after = status(controller, 4.0)
    assert (after.state, after.machine_position_mm) == ('Idle', stopped_at)


def test_resume_after_hold_finishes_the_move():
    controller = make()
    controller.receive(b'G1 X10 F600\n!', 0.0)
    controller.receive(b'~', 0.5)
    assert status(controller, 5.0).machine_position_mm == (10.0, 0.0, 0.0)


def test_reset_while_moving_raises_alarm_3_and_locks_gcode():
    controller = make()
    controller.receive(b'G1 X100 F600\n', 0.0)
    drain(controller)
    controller.receive(b'\x18', 1.0)
    out = drain(controller)
    assert out[0] == 'ALARM:3' and BANNER in out and ALARM_LOCK_MESSAGE in out
    controller.receive(b'G1 X0\n', 1.1)
    assert drain(controller) == ['error:9']
    controller.receive(b'$X\n', 1.2)
    assert drain(controller) == ['[MSG:Caution: Unlocked]', 'ok']


def test_homing_replies_ok_only_when_done():
    controller = make(homing=True)
    controller.receive(b'$X\nG1 X30 F6000\n', 0.0)
    controller.receive(b'$H\n', 1.0)
    drain(controller)
    assert status(controller, 1.1).state == 'Home'
    assert 'ok' not in drain(controller)
    controller.advance(5.0)
    assert drain(controller) == ['ok']
    assert status(controller, 5.0).machine_position_mm == (0.0, 0.0, 0.0)


def test_homing_disabled_is_error_5():
    controller = make()
    drain(controller)
    controller.receive(b'$H\n', 0.0)
    assert drain(controller) == ['error:5']


def test_soft_limit_raises_critical_alarm_2_and_needs_reset():
    controller = GrblController(ControllerSettings(homing_enabled=True, soft_limits=True))
    controller.receive(b'$X\n', 0.0)
    drain(controller)
    controller.receive(b'G53 G1 X500 F1000\nG4 P0\n', 0.1)
    assert drain(controller) == ['ALARM:2', '[MSG:Reset to continue]']
    controller.receive(b'$X\n', 0.2)
    assert drain(controller) == []              # nothing is processed until a reset
    controller.receive(b'\x18', 0.3)
    assert ALARM_LOCK_MESSAGE in drain(controller)


@pytest.mark.parametrize(('line', 'reply'), [
    ('G1 X1', 'error:22'),                  # feed never set
    ('G7 X1', 'error:20'),                  # unsupported G code
    ('X1 X2', 'error:25'),                  # repeated word
    ('G0 G1 X1', 'error:21'),               # two motion modes
    ('G4', 'error:28'),                     # dwell without P
    ('*12', 'error:1'),                     # not a word
    ('X', 'error:2'),                       # letter without number
    ('$Q', 'error:3'),
    ('G0 X' + '1' * 80, 'error:11'),
    ('N0 G0 X1', 'error:27'),
    ('', 'ok'),
    ('g0 x1 (comment) ; rest', 'ok'),
])
def test_parser_replies(line, reply):
    controller = make()
    drain(controller)
    controller.receive(line.encode() + b'\n', 0.0)
    assert drain(controller) == [reply]


def test_inches_and_relative_modes():
    controller = make()
    controller.receive(b'G20 G91 G0 X1\nG0 X1\n', 0.0)
    assert status(controller, 10.0).machine_position_mm == (pytest.approx(50.8), 0.0, 0.0)


def test_dwell_reply_waits_for_motion_and_dwell():
    controller = make()
    controller.receive(b'G1 X10 F600\nG4 P0.5\n', 0.0)
    assert drain(controller)[-1] == 'ok'    # the G1
    controller.advance(1.2)
    assert drain(controller) == []
    controller.advance(1.6)
    assert drain(controller) == ['ok']


def test_rx_buffer_drops_bytes_beyond_127_and_planner_holds_16_blocks():
    controller = make()
    drain(controller)
    lines = b''.join(b'G1 X%d F60\n' % i for i in range(1, 30))
    controller.receive(lines, 0.0)
    assert controller.rx_overflow_bytes > 0
    assert drain(controller).count('ok') == 16
    assert controller.rx_used == 127


def test_faults_drop_garble_and_refuse_replies():
    controller = make(drop_reply_to_line=1, garble_reply_to_line=2,
                      refuse_line_pattern='Y', refuse_error_code=33)
    drain(controller)
    controller.receive(b'G4 P0\nG21\nG0 Y1\nG21\n', 0.0)
    controller.advance(0.1)
    assert drain(controller) == ['o\ufffdk', 'error:33', 'ok']


def test_alarm_trip_point_stops_motion_and_reports_the_pin():
    controller = make(alarm_axis='x', alarm_at_mm=20.0, alarm_code=1)
    drain(controller)
    controller.receive(b'G1 X50 F600\n', 0.0)
    controller.advance(5.0)
    assert drain(controller) == ['ok', 'ALARM:1', '[MSG:Reset to continue]']
    report = status(controller, 6.0)
    assert (report.state, report.pins, report.machine_position_mm[0]) == ('Alarm', 'X', 20.0)


def test_wpos_reports_carry_wco_intermittently():
    controller = GrblController(ControllerSettings(homing_enabled=False,
                                                   report_machine_position=False),
                                work_offset_mm=(10.0, 0.0, 0.0))
    first = status(controller, 0.0)
    assert first.work_position_mm == (-10.0, 0.0, 0.0)
    assert first.resolve_machine_position(None) == (0.0, 0.0, 0.0)
    assert status(controller, 0.1).work_offset_mm is None


def test_a_reset_during_homing_raises_alarm_6_and_stays_in_alarm():
    controller = GrblController(ControllerSettings(homing_enabled=True))
    controller.position = [50.0, 50.0, 50.0]
    controller.receive(b'$H\n', 0.0)
    controller.advance(0.1)
    assert controller.state == 'Home'
    controller.output.clear()
    controller.receive(b'\x18', 0.2)
    assert list(controller.output)[:1] == ['ALARM:6']
    assert 'ok' not in controller.output                 # $H is never answered
    assert controller.state == 'Alarm'
