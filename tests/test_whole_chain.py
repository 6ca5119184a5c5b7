"""Replay each committed bag through the whole chain: every node a process, the simulated
gantry on a pseudo-terminal, as the demo runs it (chain/demo.py)."""

from pathlib import Path

import pytest

pytestmark = [pytest.mark.ros, pytest.mark.system]

REPO_ROOT = Path(__file__).resolve().parents[1]
BAGS = sorted(path for path in (REPO_ROOT / 'bags').iterdir()
              if (path / 'metadata.yaml').exists())


def test_committed_bags_exist():
    names = {bag.name for bag in BAGS}
    assert 'demo_scenes' in names, f'bags/ holds {sorted(names)}'


def test_the_demo_waits_for_every_link_of_the_chain(ros_context):
    """The demo plays the bag only once the graph shows each node's endpoints: a node still
    compiling its kernels has none, and the first scene would be lost at that link."""
    import rclpy
    from geometry_msgs.msg import PointStamped
    from rclpy.executors import SingleThreadedExecutor
    from ros_waiting import wait_until

    from chain.demo import CHAIN_LINKS, missing_links
    from stereo_fuzzy_msgs.msg import StereoMatches, StereoPair

    types = {'stereo/pair': StereoPair, 'stereo/matches': StereoMatches,
             'best_point': PointStamped}
    observer = rclpy.create_node('observer', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    nodes = {name: rclpy.create_node(name, context=ros_context)
             for name in ('stereo_sync_node', 'correlation_node', 'fuzzy_best_point_node',
                          'gantry_driver_node')}
    try:
        for publisher, topic, subscriber in CHAIN_LINKS:
            nodes[publisher].create_publisher(types[topic], topic, 10)
            if subscriber != 'gantry_driver_node':  # the driver has not subscribed yet
                nodes[subscriber].create_subscription(types[topic], topic, lambda _: None, 10)
        wait_until(lambda: len(missing_links(observer)) == 1, 30.0,
                   'the graph to show all but the last link', executor)
        assert missing_links(observer) == [
            'fuzzy_best_point_node -> best_point -> gantry_driver_node']

        nodes['gantry_driver_node'].create_subscription(PointStamped, 'best_point',
                                                        lambda _: None, 10)
        wait_until(lambda: not missing_links(observer), 30.0, 'the whole chain', executor)
    finally:
        for node in (*nodes.values(), observer):
            node.destroy_node()
        executor.shutdown()


@pytest.mark.parametrize('bag', BAGS, ids=[bag.name for bag in BAGS])
def test_bag_through_the_whole_chain(ros_domain_id, tmp_path, bag):
    from chain.demo import DEFAULT_PARAMS, DEMO_TOLERANCE_MM, DemoRun, format_table

    run = DemoRun(bag, DEFAULT_PARAMS, tmp_path / 'demo', DEMO_TOLERANCE_MM, rate=0.5,
                  timeout_s=300.0, quiet=True)
    results = run.run()
    table = format_table(results)

    assert results, 'no object with ground truth was seen: the bag did not play'
    for result in results:
        assert result.best_point is not None, f'object {result.index}: {result.status}\n{table}'
        assert result.error_mm <= DEMO_TOLERANCE_MM, (
            f'object {result.index} best point {result.error_mm:.2f} mm from its ground truth '
            f'(tolerance {DEMO_TOLERANCE_MM} mm)\n{table}')
        assert result.final_position is not None, (
            f'object {result.index}: the gantry was never Idle at {result.commanded}\n{table}')
        assert result.gcode_lines, f'object {result.index}: no G-code was sent for it\n{table}'

    sent = run.sent_log.read_text().splitlines()
    received = run.received_log.read_text().splitlines()
    assert sent == received, (
        'the G-code the simulator received differs from what the driver sent:\n'
        f'sent {len(sent)} lines, received {len(received)}')

    errors = {process.name: process.error_lines() for process in run.group.processes}
    assert not any(errors.values()), f'nodes logged errors: {errors}'
    assert all(code == 0 for code in run.exit_codes.values()), (
        f'processes did not exit cleanly: {run.exit_codes}')
    pictures = sorted((tmp_path / 'demo').glob('object_*.png'))
    assert len(pictures) == len(results), 'a picture per object was expected'
