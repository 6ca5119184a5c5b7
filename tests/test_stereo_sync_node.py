"""stereo_sync_node in-process with real rclpy: pairs published, bad sets dropped and reported.

Each test has a ROS context and domain of its own (ros_context); it waits on graph conditions
and on messages, never on fixed sleeps. The inputs are published reliable and the node is
set to input_reliability=reliable, so no test depends on best-effort delivery, except the one
that checks a best-effort subscription hears a reliable publisher (it republishes until heard).
"""

from __future__ import annotations

import numpy as np
import pytest
from ros_waiting import wait_until

pytestmark = pytest.mark.ros

try:
    from diagnostic_msgs.msg import DiagnosticStatus
except ImportError:  # the workspace is not sourced: conftest.py skips these tests with why
    DiagnosticStatus = None

WIDTH, HEIGHT = 32, 24
FOCAL, BASELINE = 100.0, 0.1  # [px], [m]
TIMEOUT = 30.0  # [s] generous: DDS discovery alone can take about 2 s


def calibration(width: int = WIDTH, height: int = HEIGHT, tx: float = -FOCAL * BASELINE,
                k_zero: bool = False, frame_id: str = ''):
    from stereo_fuzzy_perception.core.camera_model import CameraCalibration

    K = np.array([[FOCAL, 0.0, width / 2], [0.0, FOCAL, height / 2], [0.0, 0.0, 1.0]])
    P = np.hstack([K, [[tx], [0.0], [0.0]]])
    return CameraCalibration(width=width, height=height, K=np.zeros((3, 3)) if k_zero else K,
                             D=np.zeros(5), P=P, frame_id=frame_id)


def stamp_of(ns: int):
    from builtin_interfaces.msg import Time

    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def image_message(stamp_ns: int, frame_id: str, fill: int, encoding: str = 'mono8',
                  width: int = WIDTH, height: int = HEIGHT):
    from sensor_msgs.msg import Image
    from std_msgs.msg import Header

    header = Header(stamp=stamp_of(stamp_ns), frame_id=frame_id)
    if encoding == 'yuv422':  # not supported by the chain: build the message by hand
        return Image(header=header, width=width, height=height, encoding=encoding,
                     step=2 * width, data=bytes([fill]) * (2 * width * height))
    from stereo_fuzzy_perception.nodes.conversions import array_to_image

    gradient = (np.arange(width * height).reshape(height, width) + fill) % 256
    return array_to_image(gradient.astype(np.uint8), encoding, header)


def info_message(stamp_ns: int, frame_id: str, camera):
    from std_msgs.msg import Header
    from stereo_fuzzy_perception.nodes.conversions import calibration_to_camera_info

    return calibration_to_camera_info(camera, Header(stamp=stamp_of(stamp_ns), frame_id=frame_id))


def stereo_set(stamp_ns: int, right_offset_ns: int = 0, **bad):
    """Left/right images and camera_infos; `bad` spoils one part as the parametrised tests ask."""
    right_ns = stamp_ns + right_offset_ns
    left_image = image_message(stamp_ns, 'left_optical', 10, bad.get('encoding', 'mono8'))
    right_image = image_message(right_ns, 'right_optical', 20, bad.get('encoding', 'mono8'),
                                width=bad.get('right_width', WIDTH))
    left_info = info_message(stamp_ns, 'left_optical',
                             calibration(k_zero=bad.get('left_k_zero', False)))
    right_info = info_message(right_ns, 'right_optical', calibration(
        width=bad.get('right_info_width', bad.get('right_width', WIDTH)),
        tx=bad.get('right_tx', -FOCAL * BASELINE)))
    return left_image, left_info, right_image, right_info


class SyncHarness:
    """The node under test, a feeder node with the four inputs, and the outputs it collects."""

    def __init__(self, context, **parameters) -> None:
        import rclpy
        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.parameter import Parameter
        from sensor_msgs.msg import CameraInfo, Image
        from stereo_fuzzy_perception.nodes import qos
        from stereo_fuzzy_perception.nodes.stereo_sync_node import INPUT_TOPICS, StereoSyncNode

        from stereo_fuzzy_msgs.msg import StereoPair

        parameters.setdefault('input_reliability', 'reliable')
        parameters.setdefault('diagnostics_period_s', 0.2)
        overrides = [Parameter(name, value=value) for name, value in parameters.items()]
        self.node = StereoSyncNode(context=context, parameter_overrides=overrides)
        self.feeder = rclpy.create_node('stereo_feeder', context=context)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)
        self.executor.add_node(self.feeder)
        self.publishers = [
            self.feeder.create_publisher(Image if 'image' in topic else CameraInfo, topic,
                                         qos.RESULTS)
            for topic in INPUT_TOPICS
        ]
        self.pairs: list[StereoPair] = []
        self.statuses: list = []
        self.feeder.create_subscription(StereoPair, 'pair', self.pairs.append, qos.RESULTS)
        self.feeder.create_subscription(
            DiagnosticArray, '/diagnostics',
            lambda array: self.statuses.extend(
                status for status in array.status if status.name.startswith('stereo_sync_node')),
            qos.DIAGNOSTICS)

    def wait_for_graph(self) -> None:
        for publisher in self.publishers:
            self.wait(lambda p=publisher: p.get_subscription_count() > 0,
                      f'stereo_sync_node subscribed to {publisher.topic_name}')
        self.wait(lambda: self.node.pair_publisher.get_subscription_count() > 0,
                  'the test subscribed to pair')
        self.wait(lambda: self.node.diagnostics_publisher.get_subscription_count() > 0,
                  'the test subscribed to /diagnostics')

    def wait(self, predicate, what: str) -> None:
        wait_until(predicate, TIMEOUT, what, self.executor)

    def publish(self, messages) -> None:
        for publisher, message in zip(self.publishers, messages, strict=True):
            publisher.publish(message)

    def diagnostic(self, key: str) -> str | None:
        """The latest value reported under `key`, or None before the first report."""
        if not self.statuses:
            return None
        return {value.key: value.value for value in self.statuses[-1].values}.get(key)

    def wait_for_diagnostic(self, key: str, accept, what: str) -> None:
        self.wait(lambda: self.diagnostic(key) is not None and accept(self.diagnostic(key)),
                  f'/diagnostics {key!r} {what} (last: {self.diagnostic(key)!r})')

    def close(self) -> None:
        self.node.destroy_node()
        self.feeder.destroy_node()
        self.executor.shutdown()


@pytest.fixture
def make_harness(ros_context):
    made: list[SyncHarness] = []

    def make(**parameters) -> SyncHarness:
        harness = SyncHarness(ros_context, **parameters)
        made.append(harness)
        return harness

    yield make
    for harness in made:
        harness.close()


def stamp_ns_of(message) -> int:
    return message.header.stamp.sec * 1_000_000_000 + message.header.stamp.nanosec


def test_matching_images_and_camera_infos_make_one_stereo_pair(make_harness):
    harness = make_harness()
    harness.wait_for_graph()
    sent = stereo_set(1_500_000_000)
    harness.publish(sent)
    harness.wait(lambda: harness.pairs, 'a StereoPair')
    pair = harness.pairs[0]
    left_image, left_info, right_image, right_info = sent
    assert stamp_ns_of(pair) == 1_500_000_000, 'header stamp must be the left image stamp'
    assert pair.header.frame_id == 'left_optical', 'frame_id must be the left camera frame'
    assert pair.left_image == left_image
    assert pair.right_image == right_image
    assert pair.left_info == left_info
    assert pair.right_info == right_info
    assert pair.right_info.p[3] == pytest.approx(-FOCAL * BASELINE)
    harness.wait_for_diagnostic('pairs out', lambda value: value == '1', 'to be 1')
    assert harness.statuses[-1].level == DiagnosticStatus.OK, 'no drops: level OK'


def test_exact_mode_ignores_a_near_set_and_approximate_mode_pairs_it(make_harness):
    from rclpy.parameter import Parameter

    harness = make_harness(slop_s=0.0)
    harness.wait_for_graph()
    harness.publish(stereo_set(1_000_000_000, right_offset_ns=5_000_000))
    harness.publish(stereo_set(2_000_000_000))
    harness.wait(lambda: harness.pairs, 'the exact pair at 2 s')
    assert [stamp_ns_of(pair) for pair in harness.pairs] == [2_000_000_000], (
        'slop_s 0 must not pair left 1.000 s with right 1.005 s')

    result = harness.node.set_parameters([Parameter('slop_s', value=0.02)])[0]
    assert result.successful, result.reason
    harness.publish(stereo_set(3_000_000_000, right_offset_ns=5_000_000))
    harness.wait(lambda: len(harness.pairs) == 2, 'the approximate pair at 3 s')
    pair = harness.pairs[1]
    assert stamp_ns_of(pair) == 3_000_000_000
    assert stamp_ns_of(pair.right_image) == 3_005_000_000
    assert stamp_ns_of(pair.right_info) == 3_005_000_000


def test_approximate_mode_pairs_the_closest_right_image(make_harness):
    harness = make_harness(slop_s=0.02)
    harness.wait_for_graph()
    left_image, left_info, _, _ = stereo_set(5_000_000_000)
    far = stereo_set(5_000_000_000, right_offset_ns=15_000_000)
    near = stereo_set(5_000_000_000, right_offset_ns=-3_000_000)
    # Both right candidates (with their infos) first, then the left image completes a set.
    for message, publisher in ((far[2], 2), (far[3], 3), (near[2], 2), (near[3], 3),
                               (left_info, 1)):
        harness.publishers[publisher].publish(message)
    # Wait until the node holds all five before the left image arrives.
    harness.wait(lambda: sum(harness.node.statistics.received.values()) == 5,
                 'the node to receive five messages')
    harness.publishers[0].publish(left_image)
    harness.wait(lambda: harness.pairs, 'a StereoPair')
    assert stamp_ns_of(harness.pairs[0].right_image) == 4_997_000_000


def test_best_effort_subscription_hears_a_reliable_publisher(make_harness):
    harness = make_harness(input_reliability='best_effort')
    harness.wait_for_graph()
    stamp = 7_000_000_000

    def published_and_received() -> bool:
        nonlocal stamp
        if harness.pairs:
            return True
        stamp += 1_000_000  # republish until heard: best effort may lose the first ones
        harness.publish(stereo_set(stamp))
        return False

    harness.wait(published_and_received, 'a StereoPair from best-effort inputs')
    assert stamp_ns_of(harness.pairs[0].right_image) == stamp_ns_of(harness.pairs[0])


BAD_SETS = {
    'unsupported_encoding': {'encoding': 'yuv422'},
    'size_mismatch': {'right_width': WIDTH - 2},
    'uncalibrated': {'left_k_zero': True},
    'right_tx_not_negative': {'right_tx': 0.0},
}


@pytest.mark.parametrize(('reason', 'bad'), [
    *BAD_SETS.items(),
    ('size_mismatch', {'right_info_width': WIDTH + 8}),
], ids=[*BAD_SETS, 'image_vs_camera_info_size'])
def test_bad_set_is_dropped_counted_by_reason_and_a_good_pair_follows(make_harness, reason, bad):
    harness = make_harness(slop_s=0.01)
    harness.wait_for_graph()
    harness.publish(stereo_set(10_000_000_000, **bad))
    harness.wait_for_diagnostic(f'dropped {reason}', lambda value: value == '1', 'to be 1')
    status = harness.statuses[-1]
    assert status.level == DiagnosticStatus.WARN, (
        f'a recent drop must make the level WARN, got {status.level}')
    assert reason in status.message
    assert harness.diagnostic('pairs dropped') == '1'
    others = [key for key, value in ((v.key, v.value) for v in status.values)
              if key.startswith('dropped ') and key != f'dropped {reason}' and value != '0']
    assert others == [], f'only {reason} must be counted'

    harness.publish(stereo_set(11_000_000_000))
    harness.wait(lambda: harness.pairs, 'the good pair after the bad one')
    assert [stamp_ns_of(pair) for pair in harness.pairs] == [11_000_000_000]
    harness.wait_for_diagnostic('pairs out', lambda value: value == '1', 'to be 1')
    assert harness.diagnostic('pairs in') == '2'


def test_images_without_camera_info_are_reported_missing(make_harness):
    harness = make_harness(queue_size=2)
    harness.wait_for_graph()
    sets = [stereo_set(20_000_000_000 + index * 100_000_000) for index in range(4)]
    # The right camera_infos first, so the right images always find one queued.
    for _, _, _, right_info in sets:
        harness.publishers[3].publish(right_info)
    harness.wait(lambda: harness.node.statistics.received['right/camera_info'] == 4,
                 'the node to receive the right camera_infos')
    for left_image, _, right_image, _ in sets:  # and no left camera_info at all
        harness.publishers[0].publish(left_image)
        harness.publishers[2].publish(right_image)
    harness.wait_for_diagnostic('dropped missing_camera_info', lambda value: value == '2',
                                'to count the two left images evicted without camera_info')
    assert harness.pairs == []
    assert harness.statuses[-1].level == DiagnosticStatus.WARN
    assert 'missing_camera_info' in harness.statuses[-1].message
    assert harness.statuses[-1].hardware_id == 'stereo_sync_node', (
        'hardware_id names the node when it reads topics')
    # The right images had their camera_info: unpaired, not missing calibration.
    harness.wait_for_diagnostic('unpaired right/image_raw', lambda value: value == '2',
                                'to count the two right images evicted without a left partner')
    assert harness.diagnostic('dropped missing_camera_info') == '2'
