"""Losses nobody counts, issue #15 item 10: a burst through the three perception processes.

stereo_sync_node, correlation_node and fuzzy_best_point_node run as processes; a burst of
camera sets is published far faster than the chain can take it. Afterwards one more set is
sent slowly, so that a loss at the end of the burst shows as a gap before it. Then every pair
the sync node published must be received or counted lost by the correlation node, every pair
received must be processed or dropped by reason, every StereoMatches published must be
received or counted lost by the fuzzy node, and every one received must have a decision.
"""

from __future__ import annotations

import pytest
from hostile_messages import camera_inputs, stereo_pair
from hostile_probe import HostileProbe

pytestmark = pytest.mark.ros

BURST = 300
INPUTS = ('left/image_raw', 'left/camera_info', 'right/image_raw', 'right/camera_info')
CORRELATION_DROPS = ('superseded', 'image_too_large', 'calibration', 'size_mismatch',
                     'encoding', 'matcher_input', 'opencv', 'internal')


def unaccounted(sync: HostileProbe, correlation: HostileProbe, fuzzy: HostileProbe,
                pairs_sent: int | None = None) -> list[str]:
    """Return the accounting identities the latest reports break (empty: all hold).

    `pairs_sent`: StereoPairs the test published itself (None: the sync node's `pairs out`).
    """
    published = sync.counter('pairs out') if pairs_sent is None else pairs_sent
    received = correlation.counter('pair received')
    matched = correlation.counter('pairs processed')
    arrived = fuzzy.counter('matches received')
    identities = {
        'sync: pairs in = out + dropped':
            (sync.counter('pairs in'), sync.counter('pairs out') + sync.counter('pairs dropped')),
        'correlation: received + lost = sync out':
            (received + correlation.counter('pair lost (sequence gaps)')
             + correlation.counter('pair sent before the first received'), published),
        'correlation: processed + dropped + waiting = received':
            (matched + correlation.counter('pairs waiting') + sum(
                correlation.counter(f'dropped {reason}') for reason in CORRELATION_DROPS),
             received),
        'fuzzy: received + lost = correlation processed':
            (arrived + fuzzy.counter('matches lost (sequence gaps)')
             + fuzzy.counter('matches sent before the first received'), matched),
        'fuzzy: made + refused = received':
            (fuzzy.counter('decisions made') + fuzzy.counter('decisions refused'), arrived),
    }
    return [f'{name}: {left} != {right}' for name, (left, right) in identities.items()
            if left != right]


@pytest.mark.timeout(600)
@pytest.mark.parametrize('source', ['camera_sets', 'stereo_pairs'])
def test_every_pair_and_match_is_delivered_or_counted_lost(ros_context, start_ros_process,
                                                           source):
    """A burst of camera sets into the sync node, or of numbered pairs into the correlation."""
    from rclpy.executors import SingleThreadedExecutor
    from sensor_msgs.msg import CameraInfo, Image
    from stereo_fuzzy_perception.nodes import qos

    from stereo_fuzzy_msgs.msg import StereoPair

    sync_process = start_ros_process('stereo_fuzzy_perception', 'stereo_sync_node', '--ros-args',
                                     '-p', 'input_reliability:=reliable')
    correlation_process = start_ros_process(
        'stereo_fuzzy_perception', 'correlation_node', '--ros-args', '-p', 'window_size:=5',
        '-p', 'disparity_range:=16', '-p', 'input_queue_depth:=1')
    fuzzy_process = start_ros_process('stereo_fuzzy_perception', 'fuzzy_best_point_node')
    executor = SingleThreadedExecutor(context=ros_context)
    sync = HostileProbe(ros_context, sync_process, 'stereo_sync_node', executor)
    correlation = HostileProbe(ros_context, correlation_process, 'correlation_node', executor)
    fuzzy = HostileProbe(ros_context, fuzzy_process, 'fuzzy_best_point_node', executor)
    probes = (sync, correlation, fuzzy)
    try:
        publishers = {topic: sync.node.create_publisher(
            Image if 'image' in topic else CameraInfo, topic, qos.RESULTS) for topic in INPUTS}
        pair_publisher = sync.node.create_publisher(StereoPair, 'pair', qos.RESULTS)
        sync.wait(lambda: all(p.get_subscription_count() > 0 for p in publishers.values())
                  and sync.node.count_subscribers('pair') > 0
                  and sync.node.count_subscribers('matches') > 0,
                  'the three nodes to subscribe (numba warm-up)', timeout=180.0)
        # The probe seeing the fuzzy node's subscription does not mean DDS has matched it to the
        # correlation node's writer: both ends say so in /diagnostics.
        sync.wait(lambda: correlation.counter('matches subscribers') >= 1
                  and fuzzy.counter('matches publishers') >= 1,
                  'the correlation and fuzzy nodes to be connected on matches', timeout=180.0)
        pairs_sent = None if source == 'camera_sets' else BURST + 1

        def send(stamp: int) -> None:
            if source == 'camera_sets':
                inputs = camera_inputs(stamp)
                for topic in INPUTS:
                    publishers[topic].publish(inputs[topic])
            else:
                pair_publisher.publish(stereo_pair(stamp, sequence=stamp))

        for stamp in range(1, BURST + 1):  # the burst: no waiting between messages
            send(stamp)
        try:
            # Settled at the correlation node; the fuzzy node may have received nothing yet
            # (under load, matches can all be sent before DDS matched its subscription).
            sync.wait(lambda: correlation.counter('pairs processed') > 0
                      and correlation.counter('pairs waiting') == 0,
                      'the chain to work through the burst', timeout=200.0)
        except AssertionError as error:
            raise AssertionError(f'{error}: {unaccounted(sync, correlation, fuzzy)}; '
                                 f'{correlation.diagnostics}; {fuzzy.diagnostics}') from None
        # One last message, slowly: it carries the next sequence numbers, so a loss at the end
        # of the burst shows as a gap before it.
        arrived_before = fuzzy.counter('matches received')
        send(BURST + 1)
        try:
            sync.wait(lambda: fuzzy.counter('matches received') > arrived_before,
                      'the last message to reach the fuzzy node', timeout=120.0)
        except AssertionError as error:
            raise AssertionError(f'{error}: {unaccounted(sync, correlation, fuzzy, pairs_sent)}'
                                 f'; {correlation.diagnostics}; {fuzzy.diagnostics}; fuzzy node '
                                 f'log:\n{fuzzy_process.output()[-3000:]}') from None
        try:
            sync.wait(lambda: not unaccounted(sync, correlation, fuzzy, pairs_sent),
                      'every count to agree')
        except AssertionError as error:
            raise AssertionError(
                f'{error}: {unaccounted(sync, correlation, fuzzy, pairs_sent)}') from None
        assert correlation.counter('pairs waiting') == 0
        for probe in probes:
            probe.assert_alive()
    finally:
        for probe in probes:
            probe.close()
        executor.shutdown()
