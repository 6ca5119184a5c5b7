"""gantry_driver_node against the simulated Grbl over a real pty, in-process with real rclpy.

Each test gets its own simulator (ROS-free, on a pty in tmp_path), driver node, client node
and ROS domain; it waits on conditions only. The simulator runs TIME_SCALE times faster than
real time unless a test needs to catch a move in progress.
"""

import math

import pytest
from cartesian_3p_driver.grbl_controller import ControllerSettings, FaultInjection
from gantry_harness import GantryClient, at, start_simulator

pytestmark = pytest.mark.ros

PREAMBLE = ['G21 G90 G94']
#: Lines written after each connection: read the settings ($$), then the preamble.
CONNECT = ['$$'] + PREAMBLE
MOVE_100_200_50 = ['G53 G1 Z150.000 F1000.0', 'G53 G1 X100.000 Y200.000 F1500.0',
                   'G53 G1 Z50.000 F1000.0']
MOVE_300_0_15 = ['G53 G1 Z150.000 F1000.0', 'G53 G1 X300.000 Y0.000 F1500.0']


def test_best_point_sends_the_expected_lines_and_ends_idle_at_the_target(gantry):
    simulator, client = gantry()
    client.wait_ready()
    client.publish_target(0.1, 0.2, 0.05)
    state = client.wait_state(lambda s: s.state == 'Idle' and at(s.world_position, 0.1, 0.2, 0.05),
                              'Idle at (0.1, 0.2, 0.05)')
    assert at(state.machine_position, 0.1, 0.2, 0.05)     # default: machine mm = world m * 1000
    assert client.sent_lines() == CONNECT + MOVE_100_200_50
    assert client.received_lines() == client.sent_lines()
    assert simulator.controller.position == [100.0, 200.0, 50.0]
    client.wait(lambda: client.joints and client.joints[-1].position[0] == pytest.approx(0.1),
                'joint_states at the target')
    joints = client.joints[-1]
    assert list(joints.name) == ['gantry_x_joint', 'gantry_y_joint', 'gantry_z_joint']
    assert list(joints.position) == pytest.approx([0.1, 0.2, 0.05])
    client.wait(lambda: any(kv.key == 'lines_sent' and kv.value == '5'
                            for msg in client.diagnostics for kv in msg.status[0].values),
                '/diagnostics reporting 5 lines sent')


def test_action_feedback_follows_the_controller_and_result_waits_for_idle(gantry):
    # Slow enough (10x real time, about 2.4 s of wall time) to see the move in progress.
    simulator, client = gantry(time_scale=10.0)
    client.wait_ready()
    handle = client.send_goal(0.1, 0.2, 0.05, feed=3000.0)
    assert handle.accepted
    result = client.result_of(handle)
    assert result.success, result.outcome
    assert result.outcome == 'reached'
    assert at(result.final_position, 0.1, 0.2, 0.05)
    # The result came from the controller's own report: it is Idle at the goal.
    assert simulator.controller.state == 'Idle'
    assert simulator.controller.position == [100.0, 200.0, 50.0]
    states = [feedback.feedback.state for feedback in client.feedback]
    assert 'Run' in states, states
    distances = [feedback.feedback.distance_remaining for feedback in client.feedback]
    assert distances[0] > 0.05 and min(distances) < distances[0]


@pytest.mark.parametrize(('target', 'kwargs', 'reason'), [
    ((math.nan, 0.1, 0.1), {}, 'x is not a finite number'),
    ((0.1, math.inf, 0.1), {}, 'y is not a finite number'),
    ((0.1, 0.1, 0.1), {'frame_id': 'camera'}, "frame_id 'camera' is not 'world'"),
    ((0.1, 0.1, 0.1), {'age_s': 5.0}, 'stale'),
    ((0.1, 0.1, 0.1), {'stamped': False}, 'no time stamp'),
    ((0.45, 0.1, 0.1), {}, 'x=0.4500 m is outside the workspace [0.0000, 0.4000] m'),
    ((0.1, 0.1, -0.01), {}, 'z=-0.0100 m is outside'),
])
def test_bad_best_points_are_rejected_with_their_reason_and_nothing_moves(
        gantry, target, kwargs, reason):
    simulator, client = gantry()
    client.wait_ready()
    client.publish_target(*target, **kwargs)
    state = client.wait_state(lambda s: s.last_rejection, 'a rejection')
    assert reason in state.last_rejection
    assert client.sent_lines() == CONNECT
    assert simulator.controller.position == [0.0, 0.0, 0.0]


def test_bad_action_goals_fail_with_their_reason(gantry):
    _, client = gantry()
    client.wait_ready()
    outside = client.result_of(client.send_goal(0.1, 0.35, 0.0))
    assert not outside.success
    assert 'y=0.3500 m is outside the workspace' in outside.outcome
    wrong_frame = client.result_of(client.send_goal(0.1, 0.1, 0.0, frame_id='map'))
    assert "frame_id 'map'" in wrong_frame.outcome
    assert client.sent_lines() == CONNECT


def test_approach_offset_that_leaves_the_workspace_is_rejected(gantry):
    _, client = gantry({'approach_offset_m': 0.05})
    client.wait_ready()
    client.publish_target(0.1, 0.1, 0.18)
    state = client.wait_state(lambda s: s.last_rejection, 'a rejection')
    assert 'z=0.2300 m is outside' in state.last_rejection
    assert client.sent_lines() == CONNECT


def test_error_reply_stops_streaming_and_requires_unlock(gantry):
    faults = FaultInjection(refuse_line_pattern='X', refuse_error_code=33)
    simulator, client = gantry(faults=faults)
    client.wait_ready()
    result = client.result_of(client.send_goal(0.1, 0.2, 0.05))
    assert not result.success
    assert 'error:33' in result.outcome and 'invalid target' in result.outcome
    state = client.wait_state(lambda s: s.last_error_code == 33, 'error 33 in the state')
    assert 'invalid target' in state.last_error_text
    assert state.homing_required
    # Streaming stopped at the refused line: the descent was never sent.
    assert client.sent_lines() == CONNECT + MOVE_100_200_50[:2]
    refused = client.result_of(client.send_goal(0.2, 0.1, 0.0))
    assert 'call gantry/unlock or gantry/home' in refused.outcome
    assert client.sent_lines() == CONNECT + MOVE_100_200_50[:2]
    simulator.controller.set_faults(FaultInjection())
    assert client.call('unlock').success
    result = client.result_of(client.send_goal(0.2, 0.1, 0.0))
    assert result.success, result.outcome
    assert client.received_lines() == client.sent_lines()


def test_alarm_at_a_position_stops_and_unlock_resets_first(gantry):
    faults = FaultInjection(alarm_axis='x', alarm_at_mm=50.0, alarm_code=1)
    simulator, client = gantry(faults=faults)
    client.wait_ready()
    result = client.result_of(client.send_goal(0.1, 0.2, 0.05))
    assert not result.success
    assert 'ALARM:1' in result.outcome and 'Hard limit' in result.outcome
    state = client.wait_state(lambda s: s.state == 'Alarm' and s.pins == 'X',
                              'Alarm with the X limit pin')
    assert state.last_alarm_code == 1 and state.homing_required
    assert simulator.controller.position[0] == 50.0
    refused = client.result_of(client.send_goal(0.2, 0.1, 0.0))
    assert not refused.success and 'refused' in refused.outcome
    response = client.call('unlock')
    assert response.success, response.message
    assert client.sent_lines()[-1] == '$X' or client.sent_lines()[-2] == '$X'
    client.wait_ready()
    result = client.result_of(client.send_goal(0.2, 0.1, 0.0))
    assert result.success, result.outcome


def test_stop_holds_then_resets_and_keeps_the_position(gantry):
    simulator, client = gantry(time_scale=2.0)
    client.wait_ready()
    handle = client.send_goal(0.3, 0.0, 0.15)   # lift to 150 mm at 1000 mm/min: ~4.5 s
    client.wait_state(lambda s: s.state == 'Run', 'Run')
    response = client.call('stop')
    assert response.success, response.message
    result = client.result_of(handle)
    assert not result.success and 'stopped by gantry/stop' in result.outcome
    state = client.wait_ready()
    assert state.last_alarm_code == 0            # Hold:0 before the reset: no ALARM:3
    stopped_at = list(simulator.controller.position)
    assert 0.0 < stopped_at[2] < 150.0 and stopped_at[0] == 0.0
    assert at(state.machine_position, *(v / 1000.0 for v in stopped_at))
    # The move's lines were all planned at once; after the reset only the preamble was sent.
    sent = client.sent_lines()
    assert sent[-1:] == PREAMBLE and sent[2:-1] == MOVE_300_0_15[:len(sent) - 3]
    assert client.received_lines() == sent


def test_replace_policy_feed_holds_and_starts_the_new_move(gantry):
    simulator, client = gantry({'new_target_policy': 'replace'}, time_scale=2.0)
    client.wait_ready()
    first = client.send_goal(0.3, 0.0, 0.15)
    client.wait_state(lambda s: s.state == 'Run', 'Run')
    simulator.set_time_scale(200.0)
    second = client.send_goal(0.05, 0.05, 0.0)
    first_result = client.result_of(first)
    assert not first_result.success and 'replaced' in first_result.outcome
    second_result = client.result_of(second)
    assert second_result.success, second_result.outcome
    assert simulator.controller.position == [50.0, 50.0, 0.0]
    assert client.state.last_alarm_code == 0
    assert client.received_lines() == client.sent_lines()


def test_queue_policy_runs_moves_one_after_another(gantry):
    _, client = gantry()
    client.wait_ready()
    handles = [client.send_goal(0.1, 0.1, 0.0), client.send_goal(0.2, 0.1, 0.0),
               client.send_goal(0.3, 0.2, 0.1)]
    results = [client.result_of(handle) for handle in handles]
    assert [result.success for result in results] == [True, True, True]
    assert at(results[-1].final_position, 0.3, 0.2, 0.1)
    xy_lines = [line for line in client.sent_lines() if ' X' in line]
    assert xy_lines == ['G53 G1 X100.000 Y100.000 F1500.0', 'G53 G1 X200.000 Y100.000 F1500.0',
                        'G53 G1 X300.000 Y200.000 F1500.0']


@pytest.mark.parametrize(('fault', 'reason'), [
    (FaultInjection(drop_reply_to_line=4), "no reply to 'G53 G1 X100.000 Y200.000 F1500.0'"),
    (FaultInjection(garble_reply_to_line=4), 'unrecognised reply'),
])
def test_lost_or_garbled_reply_stops_and_nothing_is_lost_or_sent_twice(gantry, fault, reason):
    simulator, client = gantry({'reply_timeout_s': 0.5}, faults=fault, reply_delay_s=0.01)
    client.wait_ready()
    result = client.result_of(client.send_goal(0.1, 0.2, 0.05))
    assert not result.success
    assert reason in result.outcome
    state = client.wait_state(lambda s: s.homing_required, 'the fault latched')
    assert not state.connected or state.homing_required
    assert client.sent_lines() == CONNECT + MOVE_100_200_50[:2]
    assert client.received_lines() == client.sent_lines()
    assert client.call('unlock').success
    assert client.result_of(client.send_goal(0.2, 0.1, 0.0)).success
    assert client.received_lines() == client.sent_lines()


def test_character_counting_streams_moves_with_delayed_replies(gantry):
    simulator, client = gantry({'streaming_mode': 'character_counting',
                                'max_queued_moves': 10}, reply_delay_s=0.02)
    client.wait_ready()
    targets = [(0.05 * i, 0.03 * i, 0.01 * i) for i in range(1, 6)]
    handles = [client.send_goal(*target) for target in targets]
    results = [client.result_of(handle) for handle in handles]
    assert all(result.success for result in results), [r.outcome for r in results]
    assert simulator.controller.rx_overflow_bytes == 0
    assert len(client.sent_lines()) == len(CONNECT) + 3 * len(targets)
    assert client.received_lines() == client.sent_lines()


def test_reconnect_after_the_device_vanishes_requires_homing_and_replays_nothing(gantry):
    # Lines: 1 $$, 2 $H, 3 preamble, 4 lift, 5 XY: the pty disappears right after the XY line.
    simulator, client = gantry(homing=True, vanish_on_line=5, vanish_duration_s=0.5,
                               time_scale=20.0)
    client.wait_state(lambda s: s.state == 'Alarm', 'the controller booting in Alarm')
    assert client.call('home').success
    client.wait_ready()
    result = client.result_of(client.send_goal(0.1, 0.2, 0.05))
    assert not result.success and 'serial link lost' in result.outcome
    client.wait_state(lambda s: s.state == 'Alarm' and s.homing_required,
                      'reconnected to a rebooted controller')
    assert any(s.state == 'Disconnected' and not s.connected for s in client.states)
    # What went out before the device vanished (the new connection's $$ may follow already).
    sent_before = client.sent_lines()[:5]
    assert sent_before == ['$$', '$H'] + PREAMBLE + MOVE_100_200_50[:2]
    refused = client.result_of(client.send_goal(0.1, 0.2, 0.05))
    assert 'controller in Alarm' in refused.outcome or 'homing required' in refused.outcome
    # Unlocking is not enough after a reconnection: the position is not trusted.
    assert client.call('unlock').success
    client.wait_ready()
    refused = client.result_of(client.send_goal(0.1, 0.2, 0.05))
    assert 'homing required' in refused.outcome
    assert client.call('home').success
    client.wait_ready()
    result = client.result_of(client.send_goal(0.1, 0.2, 0.05))
    assert result.success, result.outcome
    sent = client.sent_lines()
    assert sent[:len(sent_before)] == sent_before
    assert sent[len(sent_before):] == (['$$', '$X'] + PREAMBLE + ['$H'] + PREAMBLE
                                      + MOVE_100_200_50)
    assert client.received_lines() == sent


def test_disconnected_until_a_controller_appears_then_connects(ros_context, tmp_path):
    client = GantryClient(ros_context, tmp_path)
    simulator = None
    try:
        state = client.wait_state(lambda s: s.state == 'Disconnected', 'Disconnected')
        assert not state.connected
        assert client.sent_lines() == []
        # The driver keeps retrying with back-off; a controller appearing later is found.
        simulator = start_simulator(tmp_path)
        state = client.wait_ready()
        assert not state.homing_required          # never connected before: no homing needed
        assert client.sent_lines() == CONNECT
    finally:
        client.close()
        if simulator is not None:
            simulator.stop()


def test_wpos_reports_with_wco_give_the_machine_position(gantry):
    settings = ControllerSettings(homing_enabled=False, report_machine_position=False)
    simulator, client = gantry(settings=settings, work_offset_mm=(10.0, 20.0, 5.0))
    client.wait_ready()
    client.publish_target(0.1, 0.2, 0.05)
    state = client.wait_state(lambda s: s.state == 'Idle' and at(s.world_position, 0.1, 0.2, 0.05),
                              'Idle at the target, from WPos + WCO')
    assert at(state.machine_position, 0.1, 0.2, 0.05)
