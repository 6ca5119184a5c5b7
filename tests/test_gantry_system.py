"""The gantry executables as processes, configured from their YAML files, over a real pty:
a best point published on the graph ends with the simulated gantry Idle at the target."""

import math

import pytest
from ros_fixtures import REPO_ROOT
from ros_waiting import wait_until

pytestmark = pytest.mark.ros

CONFIG = REPO_ROOT / 'src' / 'cartesian_3p_driver' / 'config'


def test_best_point_to_idle_at_target_across_processes(ros_context, start_ros_process, tmp_path):
    import rclpy
    from geometry_msgs.msg import PointStamped
    from rclpy.executors import SingleThreadedExecutor

    from cartesian_3p_driver import qos
    from stereo_fuzzy_msgs.msg import GantryState

    link = tmp_path / 'gantry_tty'
    sent_log, received_log = tmp_path / 'sent.log', tmp_path / 'received.log'
    simulator = start_ros_process(
        'cartesian_3p_driver', 'fake_gantry', '--ros-args',
        '--params-file', str(CONFIG / 'fake_gantry.yaml'),
        '-p', f'link_path:={link}', '-p', 'tcp_port:=0', '-p', 'time_scale:=100.0',
        '-p', 'homing_enabled:=false', '-p', f'received_lines_log:={received_log}')
    driver = start_ros_process(
        'cartesian_3p_driver', 'gantry_driver_node', '--ros-args',
        '--params-file', str(CONFIG / 'gantry_driver_node.yaml'),
        '-p', f'port:={link}', '-p', f'sent_lines_log:={sent_log}',
        '-p', 'reconnect_max_s:=0.5')
    node = rclpy.create_node('gantry_system_probe', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    states: list[GantryState] = []
    node.create_subscription(GantryState, 'gantry/state', states.append, qos.DRIVER_STATE)
    publisher = node.create_publisher(PointStamped, 'best_point', qos.COMMANDS)
    try:
        wait_until(lambda: states and states[-1].connected, 60.0,
                   'the driver connected to fake_gantry', executor)
        wait_until(lambda: publisher.get_subscription_count() > 0, 30.0,
                   'the driver subscribed to best_point', executor)
        target = PointStamped()
        target.header.frame_id = 'world'
        target.header.stamp = node.get_clock().now().to_msg()
        target.point.x, target.point.y, target.point.z = 0.25, 0.15, 0.02
        publisher.publish(target)

        def at_target() -> bool:
            if not states or states[-1].state != 'Idle':
                return False
            p = states[-1].world_position
            return math.dist((p.x, p.y, p.z), (0.25, 0.15, 0.02)) < 1e-4

        wait_until(at_target, 30.0, 'gantry/state Idle at the target', executor)
        assert any(state.state == 'Run' for state in states)
    finally:
        node.destroy_node()
        executor.shutdown()
    assert driver.interrupt() == 0, driver.output()
    assert simulator.interrupt() == 0, simulator.output()
    sent = sent_log.read_text().splitlines()
    assert sent == ['$$', 'G21 G90 G94', 'G53 G1 Z150.000 F1000.0',
                    'G53 G1 X250.000 Y150.000 F1500.0', 'G53 G1 Z20.000 F1000.0']
    assert received_log.read_text().splitlines() == sent
    assert 'fake_gantry serving Grbl on /dev/pts/' in simulator.output()
