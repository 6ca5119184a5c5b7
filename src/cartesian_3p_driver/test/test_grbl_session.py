"""Every safety rule of the driver's GrblSession, against the simulator's controller model.

No ROS and no pty: the `bench` fixture (conftest.py) wires the sans-I/O session to the
sans-I/O GrblController on a fake clock. Times below are simulated seconds.
"""

from collections import Counter

import pytest
from cartesian_3p_driver.gcode import MotionConfig
from cartesian_3p_driver.grbl_controller import ControllerSettings, FaultInjection
from cartesian_3p_driver.grbl_protocol import RX_BUFFER_SIZE
from cartesian_3p_driver.grbl_session import Stage
from cartesian_3p_driver.link_events import SessionConfig

PREAMBLE = ['G21 G90 G94']
#: Lines written after each connection: read the settings, then the preamble.
CONNECT = ['$$'] + PREAMBLE
MOVE_100_200_50 = ['G53 G1 Z150.000 F1000.0', 'G53 G1 X100.000 Y200.000 F1500.0',
                   'G53 G1 Z50.000 F1000.0']


def assert_each_line_written_once(bench):
    """Exactly once: the controller got what was logged, and no line twice unless planned."""
    assert bench.received == bench.written
    assert [line for line in bench.commands() if line not in ('!', '~', 'RESET')] \
        == bench.written


# -- connecting -----------------------------------------------------------------------------

def test_banner_then_state_then_preamble_then_ready(bench):
    b = bench()
    b.open()
    assert b.session.stage is not Stage.AWAITING_BANNER   # the banner came with the boot
    b.ready()
    assert b.written == CONNECT
    assert b.session.stage is Stage.READY
    assert 'RESET' not in b.commands()


def test_no_banner_gives_one_soft_reset_then_gives_up(bench):
    b = bench(config=SessionConfig(banner_timeout_s=1.0), controller_present=False)
    b.open()
    b.run_until(b.closed, 'the session giving up')
    assert b.commands() == ['RESET']                      # one soft reset, nothing else
    assert b.written == []
    assert b.snapshot.state == 'Disconnected' and not b.snapshot.connected
    assert 'no Grbl banner' in b.snapshot.link_error


def test_a_silent_controller_answers_the_soft_reset_with_its_banner(bench):
    b = bench(config=SessionConfig(banner_timeout_s=1.0))
    b.controller.output.clear()
    b.session.connection_opened(b.now)                   # opened, but no boot banner
    b.ready()
    assert b.commands() == ['RESET'] + CONNECT
    assert not b.closed()


def test_motion_is_refused_until_the_preamble_is_acknowledged(bench):
    b = bench(deliver_output=False)
    b.open()
    early = b.finished(b.move(0.1, 0.2, 0.05))
    assert early is not None and not early.success
    assert 'not connected' in early.outcome
    b.deliver_output = True
    b.ready()
    job = b.move(0.1, 0.2, 0.05)
    assert b.wait_finished(job).success
    assert b.written == CONNECT + MOVE_100_200_50


# -- moves ----------------------------------------------------------------------------------

def test_a_move_finishes_only_on_idle_at_the_goal(bench):
    b = bench()
    b.open()
    b.ready()
    job = b.move(0.1, 0.2, 0.05)
    b.run_until(lambda: b.session.snapshot.lines_acknowledged == 5, 'every line acknowledged')
    assert b.controller.state == 'Run'                   # every ok came, the move has not
    assert b.finished(job) is None
    result = b.wait_finished(job)
    assert result.success and result.outcome == 'reached'
    assert b.controller.state == 'Idle' and b.controller.position == [100.0, 200.0, 50.0]


def test_idle_away_from_the_goal_fails_the_move(bench):
    b = bench()
    b.open()
    b.ready()
    job = b.move(0.1, 0.2, 0.05)
    b.run_until(lambda: b.controller.state == 'Run', 'the move running')
    b.controller.position = [10.0, 10.0, 10.0]           # someone else moved it
    b.controller._planner.clear()                         # and the planner lost the move
    b.controller._block = None
    result = b.wait_finished(job)
    assert not result.success and 'away from the goal' in result.outcome


@pytest.mark.parametrize(('mode', 'in_flight'), [('send_response', 1),
                                               ('character_counting', 3)])
def test_streaming_keeps_within_the_receive_buffer(bench, mode, in_flight):
    b = bench(config=SessionConfig(streaming_mode=mode, max_queued_moves=20))
    b.open()
    b.ready()
    b.deliver_output = False                              # replies held back
    jobs = [b.move(0.01 * i, 0.01 * i, 0.01 * i) for i in range(1, 4)]
    for _ in range(20):
        b.step()
        assert b.session._streamer.in_flight_bytes <= RX_BUFFER_SIZE
    assert b.session._streamer.in_flight == in_flight
    b.deliver_output = True
    for job in jobs:
        assert b.wait_finished(job).success
    assert b.controller.rx_overflow_bytes == 0
    assert_each_line_written_once(b)


# -- faults ---------------------------------------------------------------------------------

def test_an_error_reply_latches_a_fault_that_only_unlock_clears(bench):
    b = bench(faults=FaultInjection(refuse_line_pattern='X', refuse_error_code=33))
    b.open()
    b.ready()
    result = b.wait_finished(b.move(0.1, 0.2, 0.05))
    assert not result.success and 'error:33' in result.outcome
    assert b.written == CONNECT + MOVE_100_200_50[:2]   # the descent was never sent
    assert b.snapshot.homing_required and b.snapshot.last_error_code == 33
    refused = b.wait_finished(b.move(0.2, 0.1, 0.0))
    assert 'call gantry/unlock or gantry/home' in refused.outcome
    b.controller.set_faults(FaultInjection())
    assert b.wait_finished(b.request('unlock')).success
    assert b.wait_finished(b.move(0.2, 0.1, 0.0)).success
    assert_each_line_written_once(b)


@pytest.mark.parametrize(('faults', 'reason'), [
    (FaultInjection(garble_reply_to_line=4), 'unrecognised reply'),
    (FaultInjection(drop_reply_to_line=4), "no reply to 'G53 G1 X100.000 Y200.000 F1500.0'"),
])
def test_a_garbled_or_missing_reply_latches_a_fault_and_nothing_is_resent(
        bench, faults, reason):
    b = bench(faults=faults, config=SessionConfig(reply_timeout_s=0.5))
    b.open()
    b.ready()
    result = b.wait_finished(b.move(0.1, 0.2, 0.05))
    assert not result.success and reason in result.outcome
    assert b.written == CONNECT + MOVE_100_200_50[:2]
    assert b.snapshot.fault and b.snapshot.homing_required
    b.run_until(lambda: b.controller.state == 'Idle', 'the controller finishing the line')
    assert b.wait_finished(b.request('unlock')).success
    assert b.wait_finished(b.move(0.2, 0.1, 0.0)).success
    assert_each_line_written_once(b)


def test_a_reply_with_no_line_in_flight_latches_a_fault(bench):
    b = bench()
    b.open()
    b.ready()
    b.session.receive(b'ok\r\n', b.now)
    b.pump()
    assert 'replies out of step' in b.snapshot.fault
    assert 'stopped after a fault' in b.wait_finished(b.move(0.1, 0.1, 0.1)).outcome


def test_a_hard_limit_alarm_needs_a_reset_before_unlock(bench):
    b = bench(faults=FaultInjection(alarm_axis='x', alarm_at_mm=50.0, alarm_code=1))
    b.open()
    b.ready()
    result = b.wait_finished(b.move(0.1, 0.2, 0.05))
    assert not result.success and 'ALARM:1' in result.outcome
    assert b.snapshot.last_alarm_code == 1 and b.snapshot.homing_required
    assert 'refused' in b.wait_finished(b.move(0.2, 0.1, 0.0)).outcome
    assert b.wait_finished(b.request('unlock')).success
    commands = b.commands()
    assert commands[commands.index('RESET') + 1] == '$X'   # Grbl wants the reset first
    assert b.wait_finished(b.move(0.2, 0.1, 0.0)).success
    assert_each_line_written_once(b)


# -- reconnecting ---------------------------------------------------------------------------

def test_after_a_reconnection_only_homing_allows_motion_and_nothing_is_replayed(bench):
    b = bench(settings=ControllerSettings(homing_enabled=True))
    b.open()
    assert b.wait_finished(b.request('home')).success
    b.ready()
    job = b.move(0.1, 0.2, 0.05)
    b.run_until(lambda: len(b.written) >= 5, 'the move streaming')
    b.session.connection_lost('device vanished', b.now)
    b.pump()
    lost = b.finished(job)
    assert lost is not None and 'serial link lost' in lost.outcome
    assert b.snapshot.state == 'Disconnected' and b.snapshot.reconnections == 1
    written_before = list(b.written)
    b.open()
    b.run_until(lambda: b.snapshot.state == 'Alarm', 'the rebooted controller')
    assert b.wait_finished(b.request('unlock')).success
    b.ready()
    refused = b.wait_finished(b.move(0.1, 0.2, 0.05))
    assert 'homing required' in refused.outcome
    assert b.wait_finished(b.request('home')).success
    assert b.wait_finished(b.move(0.1, 0.2, 0.05)).success
    assert b.written[len(written_before):] == ['$$', '$X'] + PREAMBLE + ['$H'] + PREAMBLE \
        + MOVE_100_200_50
    assert Counter(b.written)['G53 G1 X100.000 Y200.000 F1500.0'] == 2   # once per move


def test_homing_is_required_at_start_when_configured(bench):
    b = bench(config=SessionConfig(require_homing_at_start=True),
              settings=ControllerSettings(homing_enabled=True))
    b.open()
    assert b.wait_finished(b.request('unlock')).success
    assert 'homing required' in b.wait_finished(b.move(0.1, 0.1, 0.1)).outcome
    b.controller.settings.homing_rate_mm_min = 3000.0
    assert b.wait_finished(b.request('home')).success
    assert b.wait_finished(b.move(0.1, 0.1, 0.1)).success


# -- stopping -------------------------------------------------------------------------------

def test_stop_holds_waits_for_hold_0_then_resets_and_keeps_the_position(bench):
    b = bench()
    b.open()
    b.ready()
    job = b.move(0.3, 0.0, 0.15)
    b.run_until(lambda: b.controller.state == 'Run', 'the move running')
    stop = b.request('stop')
    assert b.commands()[-1] == '!'
    assert b.wait_finished(stop).success
    assert 'stopped by gantry/stop' in b.finished(job).outcome
    commands = b.commands()
    assert commands[commands.index('!'):] == ['!', 'RESET'] + PREAMBLE
    assert b.snapshot.last_alarm_code == 0      # Hold:0 before the reset: no ALARM:3
    assert 0.0 < b.controller.position[2] < 150.0
    assert b.wait_finished(b.move(0.1, 0.1, 0.1)).success


def test_replace_policy_stops_the_running_move_and_starts_the_new_one(bench):
    b = bench(config=SessionConfig(new_target_policy='replace'))
    b.open()
    b.ready()
    first = b.move(0.3, 0.0, 0.15)
    b.run_until(lambda: b.controller.state == 'Run', 'the move running')
    second = b.move(0.05, 0.05, 0.0)
    assert 'replaced' in b.wait_finished(first).outcome
    assert b.wait_finished(second).success
    assert b.controller.position == [50.0, 50.0, 0.0]
    assert b.snapshot.last_alarm_code == 0


def test_queue_policy_refuses_beyond_max_queued_moves(bench):
    b = bench(config=SessionConfig(max_queued_moves=1))
    b.open()
    b.ready()
    jobs = [b.move(0.1, 0.1, 0.0), b.move(0.2, 0.1, 0.0), b.move(0.3, 0.1, 0.0)]
    assert 'max_queued_moves' in b.wait_finished(jobs[2]).outcome
    assert b.wait_finished(jobs[0]).success and b.wait_finished(jobs[1]).success


def test_a_plan_outside_the_workspace_is_refused_without_writing(bench):
    b = bench(motion=MotionConfig(approach_offset_m=0.05))
    b.open()
    b.ready()
    result = b.wait_finished(b.move(0.1, 0.1, 0.18))
    assert not result.success and 'outside the workspace' in result.outcome
    assert b.written == CONNECT


# -- the controller's own settings ----------------------------------------------------------

def test_settings_are_read_once_per_connection_and_a_short_travel_refuses_motion(bench):
    b = bench(settings=ControllerSettings(homing_enabled=False,
                                          max_travel_mm=[300.0, 300.0, 200.0]))
    b.open()
    b.run_until(lambda: b.snapshot.settings_problem, 'the settings checked')
    assert '$130=300.000' in b.snapshot.settings_problem
    assert 'controller settings refuse motion' in b.snapshot.fault
    refused = b.wait_finished(b.move(0.1, 0.1, 0.1))
    assert not refused.success and '$130=300.000' in refused.outcome
    assert b.written == CONNECT                           # the preamble still goes out
    assert len([log for log in b.logs('error') if '$130' in log]) == 1   # logged once
    assert b.wait_finished(b.request('unlock')).success  # unlocking does not help
    assert 'controller settings' in b.wait_finished(b.move(0.1, 0.1, 0.1)).outcome
    assert b.written.count('$$') == 1


def test_a_rate_above_the_controller_maximum_refuses_motion(bench):
    b = bench(settings=ControllerSettings(homing_enabled=False,
                                          max_rate_mm_min=[6000.0, 2000.0, 3000.0]))
    b.open()
    b.run_until(lambda: b.snapshot.settings_problem, 'the settings checked')
    assert 'max_rate_mm_min for Y is 3000 mm/min' in b.snapshot.settings_problem
    assert '$111=2000.000' in b.snapshot.settings_problem


def test_a_negative_space_machine_fits_its_travel(bench):
    # Stock Grbl after homing: machine X from -400 to 0 holds world x from 0 to 0.4 m.
    from cartesian_3p_driver.gcode import MachineTransform
    motion = MotionConfig(transform=MachineTransform(offset_mm=(-400.0, -300.0, -200.0)))
    b = bench(motion=motion)
    b.open()
    b.ready()
    assert b.snapshot.settings_problem == ''


def test_settings_missing_from_the_reply_refuse_motion(bench):
    b = bench()
    b.controller.settings.as_dollar_lines = lambda: ['$10=1']
    b.open()
    b.run_until(lambda: b.snapshot.settings_problem, 'the settings checked')
    assert 'did not report $20, $110' in b.snapshot.settings_problem


# -- stop during homing, feeds ---------------------------------------------------------------

def test_stop_during_homing_resets_at_once_and_homing_stays_required(bench):
    b = bench(settings=ControllerSettings(homing_enabled=True, homing_rate_mm_min=10.0))
    b.open()
    b.controller.position = [100.0, 100.0, 100.0]
    home = b.request('home')
    b.run_until(lambda: b.controller.state == 'Home', 'homing running')
    stop = b.request('stop')
    assert b.commands()[-1] == 'RESET'                    # no feed hold: Grbl ignores it here
    result = b.wait_finished(stop)
    assert result.success and 'homing is incomplete' in result.message
    assert 'interrupted by gantry/stop' in b.finished(home).message
    b.run_until(lambda: b.snapshot.state == 'Alarm', 'Alarm reported')
    assert b.snapshot.last_alarm_code == 6 and b.snapshot.homing_required
    assert '!' not in b.commands()
    assert b.wait_finished(b.request('unlock')).success
    assert 'homing required' in b.wait_finished(b.move(0.1, 0.1, 0.1)).outcome
    b.controller.settings.homing_rate_mm_min = 3000.0
    assert b.wait_finished(b.request('home')).success
    assert b.wait_finished(b.move(0.1, 0.1, 0.1)).success
    assert_each_line_written_once(b)


@pytest.mark.parametrize('feed', [1e-12, 9.9, -5.0, float('nan'), float('inf')])
def test_feeds_below_the_minimum_are_refused_without_writing(bench, feed):
    b = bench()
    b.open()
    b.ready()
    result = b.wait_finished(b.move(0.1, 0.1, 0.1, feed_mm_min=feed))
    assert not result.success and 'min_feed_rate_mm_min' in result.outcome
    assert b.written == CONNECT


def test_the_minimum_feed_itself_and_zero_for_the_default_are_accepted(bench):
    b = bench(motion=MotionConfig(min_feed_mm_min=600.0))
    b.open()
    b.ready()
    assert b.wait_finished(b.move(0.01, 0.0, 0.15, feed_mm_min=600.0)).success
    first = [line.split()[-1] for line in b.written[len(CONNECT):]]
    assert set(first) == {'F600.0'}
    assert b.wait_finished(b.move(0.02, 0.0, 0.15)).success
    assert b.written[-1].endswith('F1500.0')
