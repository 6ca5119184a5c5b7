"""gantry_driver_node against hostile or mistaken peers and configurations (issue #15, #17).

Real rclpy and the simulated Grbl on a real pty, as in test_gantry_driver.py; the start-up
check runs the installed executable as a process. Every test waits on conditions only.
"""

import os
import subprocess

import pytest
from cartesian_3p_driver.grbl_controller import ControllerSettings
from gantry_harness import TIMEOUT_S, GantryClient
from ros_fixtures import executable_path

pytestmark = pytest.mark.ros

CONNECT = ['$$', 'G21 G90 G94']


def set_parameter_remotely(client, name, value):
    """Set a driver parameter through its set_parameters service, as any peer could."""
    from rcl_interfaces.srv import SetParameters
    from rclpy.parameter import Parameter

    service = client.node.create_client(SetParameters, '/gantry_driver_node/set_parameters')
    client.wait(service.service_is_ready, 'the set_parameters service')
    request = SetParameters.Request(parameters=[Parameter(name, value=value).to_parameter_msg()])
    future = service.call_async(request)
    client.wait(future.done, 'the set_parameters answer')
    return future.result().results[0]


def diagnostics_values(message):
    return {kv.key: kv.value for kv in message.status[0].values}


@pytest.mark.parametrize(('name', 'value'), [
    ('workspace_max_m', [1.0, 1.0, 0.2]),
    ('machine_offset_mm', [-500.0, 0.0, 0.0]),
    ('axis_scale_mm_per_m', [2000.0, 1000.0, 1000.0]),
    ('max_rate_mm_min', [60000.0, 3000.0, 1000.0]),
    ('safe_z_m', 0.0),
    ('min_feed_rate_mm_min', 1.0),
])
def test_safety_parameters_are_read_only_at_run_time(gantry, name, value):
    simulator, client = gantry()
    client.wait_ready()
    result = set_parameter_remotely(client, name, value)
    assert not result.successful
    assert 'read-only' in result.reason or 'read only' in result.reason, result.reason
    client.publish_target(0.9, 0.9, 0.1)
    state = client.wait_state(lambda s: s.last_rejection, 'a rejection')
    assert 'outside the workspace' in state.last_rejection
    assert client.sent_lines() == CONNECT
    assert simulator.controller.position == [0.0, 0.0, 0.0]


def test_goal_slower_than_the_minimum_feed_is_refused_with_the_reason(gantry):
    _, client = gantry()
    client.wait_ready()
    result = client.result_of(client.send_goal(0.1, 0.1, 0.0, feed=1e-12))
    assert not result.success
    assert 'min_feed_rate_mm_min (10 mm/min)' in result.outcome
    assert client.sent_lines() == CONNECT


def test_a_travel_shorter_than_the_workspace_refuses_motion_with_the_reason(gantry):
    settings = ControllerSettings(homing_enabled=False, max_travel_mm=[300.0, 300.0, 200.0])
    simulator, client = gantry(settings=settings)
    state = client.wait_state(lambda s: '$130=300.000' in s.last_error_text,
                              'the settings problem in gantry/state')
    assert state.last_error_code == 0
    client.wait(lambda: client.diagnostics and '$130=300.000'
                in client.diagnostics[-1].status[0].message, 'the problem in /diagnostics')
    result = client.result_of(client.send_goal(0.1, 0.1, 0.0))
    assert not result.success and '$130=300.000' in result.outcome
    assert client.sent_lines() == CONNECT
    assert client.received_lines() == client.sent_lines()


def test_stop_during_homing_resets_at_once_and_leaves_the_controller_in_alarm(gantry):
    from std_srvs.srv import Trigger

    settings = ControllerSettings(homing_enabled=True, homing_rate_mm_min=60.0)
    simulator, client = gantry(settings=settings)
    client.wait_state(lambda s: s.state == 'Alarm', 'the controller booting in Alarm')
    with simulator.lock:
        simulator.controller.position = [300.0, 200.0, 100.0]   # far from home
    home_client = client.services['home']
    client.wait(home_client.service_is_ready, 'gantry/home service')
    home = home_client.call_async(Trigger.Request())
    client.wait_state(lambda s: s.state == 'Home', 'homing running')
    response = client.call('stop')
    assert response.success, response.message
    assert 'homing is incomplete' in response.message
    client.wait(home.done, 'the gantry/home answer')
    assert not home.result().success and 'interrupted' in home.result().message
    state = client.wait_state(lambda s: s.state == 'Alarm' and s.last_alarm_code == 6,
                              'Alarm after the reset during homing')
    assert state.homing_required
    assert client.sent_lines() == ['$$', '$H']
    assert simulator.controller.position != [0.0, 0.0, 0.0]


def test_an_unreachable_port_is_reported_in_diagnostics_with_the_os_error(
        ros_context, tmp_path):
    port = str(tmp_path / 'no_such_tty')
    client = GantryClient(ros_context, tmp_path, {'port': port})
    try:
        client.wait(lambda: any(
            'No such file' in diagnostics_values(message)['last_error']
            for message in client.diagnostics), '/diagnostics with the OS error')
        message = client.diagnostics[-1].status[0]
        assert message.hardware_id == port
        assert message.message != 'closed' and 'No such file' in message.message
        assert client.state.state == 'Disconnected'
    finally:
        client.close()


@pytest.mark.parametrize(('argument', 'named'), [
    ('axis_scale_mm_per_m:=[1e306,1000.0,1000.0]', ['axis_scale_mm_per_m', '1e+306', '<=']),
    ('machine_offset_mm:=[1e308,0.0,0.0]', ['machine_offset_mm', '1e+308', '<=']),
    ('workspace_max_m:=[0.4,0.3]', ['workspace_max_m', '[0.4, 0.3]', '3 values']),
    ('poll_rate_hz:=50.0', ['poll_rate_hz', '50.0', '[0.5, 5.0]']),
])
def test_a_bad_start_up_value_ends_the_node_with_one_fatal_line(ros_domain_id, argument,
                                                               named):
    path = executable_path('cartesian_3p_driver', 'gantry_driver_node')
    environment = dict(os.environ, RCUTILS_COLORIZED_OUTPUT='0')
    finished = subprocess.run([str(path), '--ros-args', '-p', 'port:=/nonexistent',
                               '-p', argument], capture_output=True, text=True,
                              timeout=TIMEOUT_S * 3, env=environment, check=False)
    output = (finished.stdout + finished.stderr).strip()
    assert finished.returncode != 0, output
    assert 'Traceback' not in output
    lines = output.splitlines()
    assert len(lines) == 1 and '[FATAL]' in lines[0], output
    for text in named:
        assert text in lines[0], lines[0]
