"""The foundation: interfaces built by colcon cross processes over DDS; executables start like
`ros2 run` with --ros-args and stop cleanly on SIGINT."""

import subprocess
import sys
from pathlib import Path

import pytest
from ros_fixtures import REPO_ROOT
from ros_waiting import wait_for_node, wait_until

pytestmark = pytest.mark.ros

# (package, executable, a parameter override the test reads back)
EXECUTABLES = [
    ('stereo_fuzzy_perception', 'stereo_sync_node', ('slop_s', 0.02)),
    ('stereo_fuzzy_perception', 'correlation_node', ('window_size', 11)),
    ('stereo_fuzzy_perception', 'fuzzy_best_point_node', ('selector', 'centroid')),
    ('cartesian_3p_driver', 'gantry_driver_node', ('poll_rate_hz', 2.0)),
    ('cartesian_3p_driver', 'fake_gantry', ('reply_delay_s', 0.25)),
]


def test_custom_message_round_trips_between_processes(ros_context):
    import rclpy
    from rclpy.executors import SingleThreadedExecutor

    from stereo_fuzzy_msgs.msg import FuzzyDecision

    sys.path.insert(0, str(Path(__file__).parent / 'support'))
    from publish_fuzzy_decision import known_decision

    node = rclpy.create_node('decision_listener', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    received: list[FuzzyDecision] = []
    node.create_subscription(FuzzyDecision, 'decision', received.append, 10)
    publisher = subprocess.Popen(
        [sys.executable, str(REPO_ROOT / 'tests' / 'support' / 'publish_fuzzy_decision.py')])
    try:
        wait_until(lambda: received, 30.0, 'a FuzzyDecision from the other process', executor)
    finally:
        node.destroy_node()
        executor.shutdown()
        publisher.wait(15.0)
    assert received[0] == known_decision()
    assert publisher.returncode == 0


@pytest.mark.parametrize(('package', 'executable', 'override'), EXECUTABLES,
                         ids=[entry[1] for entry in EXECUTABLES])
def test_executable_starts_with_ros_args_and_stops_on_sigint(
        ros_context, start_ros_process, package, executable, override):
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter_client import AsyncParameterClient

    name, value = override
    renamed = f'{executable}_under_test'
    process = start_ros_process(
        package, executable, '--ros-args', '-p', f'{name}:={value}', '-r', f'__node:={renamed}')
    probe = rclpy.create_node('graph_probe', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(probe)
    try:
        wait_for_node(probe, renamed, 30.0, executor)
        client = AsyncParameterClient(probe, renamed)
        wait_until(lambda: client.services_are_ready(), 30.0,
                   f'parameter services of {renamed}', executor)
        future = client.get_parameters([name])
        executor.spin_until_future_complete(future, timeout_sec=10.0)
        assert future.done(), f'{renamed} did not answer get_parameters'
        from rclpy.parameter import parameter_value_to_python
        assert parameter_value_to_python(future.result().values[0]) == value
        assert process.process.poll() is None, process.output()
    finally:
        probe.destroy_node()
        executor.shutdown()
    assert process.interrupt() == 0, process.output()
