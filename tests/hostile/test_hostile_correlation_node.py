"""correlation_node as a process, attacked as a hostile peer on the ROS domain would.

Issue #15 items 6, 9 and 10 against the installed executable: clearing max_rate_hz frees a
waiting pair at once; pairs with unusable calibrations or oversized images are dropped under
their own reason; gaps in StereoPair sequence numbers are counted; every StereoMatches carries
its own sequence and its pair's; and random values on every parameter are refused with a
reason or leave the node matching.
"""

from __future__ import annotations

import pytest
from hostile_messages import spoiled_right_cameras, stereo_pair
from hostile_probe import HostileProbe
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

pytestmark = pytest.mark.ros

NODE = 'correlation_node'


class CorrelationTarget(HostileProbe):
    """The probe plus a StereoPair publisher and a StereoMatches recorder."""

    def __init__(self, context, process):
        super().__init__(context, process, NODE)
        from stereo_fuzzy_perception.nodes import qos

        from stereo_fuzzy_msgs.msg import StereoMatches, StereoPair

        self.matches: list = []
        self.publisher = self.node.create_publisher(StereoPair, 'pair', qos.RESULTS)
        self.node.create_subscription(StereoMatches, 'matches', self.matches.append,
                                      qos.RESULTS)
        self.wait(lambda: self.publisher.get_subscription_count() > 0,
                  f'{NODE} to subscribe pair (numba warm-up)', timeout=180.0)
        self.wait(lambda: self.node.count_publishers('matches') > 0,
                  'the matches publisher')


@pytest.fixture
def target(ros_context, start_ros_process):
    process = start_ros_process('stereo_fuzzy_perception', NODE, '--ros-args',
                                '-p', 'window_size:=5', '-p', 'disparity_range:=16',
                                '-p', 'input_queue_depth:=30')
    probe = CorrelationTarget(ros_context, process)
    yield probe
    probe.close()
    assert process.interrupt() == 0, process.output()[-3000:]


def test_clearing_max_rate_frees_a_waiting_pair_at_once(target):
    assert target.set_parameter('max_rate_hz', 0.001) == (True, '')
    target.publisher.publish(stereo_pair(1, sequence=1))
    target.wait(lambda: len(target.matches) == 1, 'the first pair (no wait before it)')
    target.publisher.publish(stereo_pair(2, sequence=2))
    target.wait_diagnostic('pair received', 2)
    assert len(target.matches) == 1  # the second waits for the 1000 s period of 0.001 Hz
    assert target.set_parameter('max_rate_hz', 0.0) == (True, '')
    # Before the fix it stayed blocked until the old deadline, 1000 s later.
    target.wait(lambda: len(target.matches) == 2, 'the waiting pair once the rate is cleared')
    assert [m.sequence for m in target.matches] == [1, 2]
    assert [m.pair_sequence for m in target.matches] == [1, 2]


def test_unusable_calibrations_and_oversized_images_are_dropped_by_reason(target):
    spoiled = spoiled_right_cameras()
    for index, (_, right) in enumerate(spoiled):
        target.publisher.publish(stereo_pair(10 + index, sequence=1 + index, right=right))
    target.wait_diagnostic('dropped calibration', len(spoiled))
    target.publisher.publish(stereo_pair(30, sequence=len(spoiled) + 1, size=(40000, 8)))
    target.wait_diagnostic('dropped image_too_large', 1)
    assert target.set_parameter('max_image_pixels', 1000) == (True, '')
    target.publisher.publish(stereo_pair(31, sequence=len(spoiled) + 2))
    target.wait_diagnostic('dropped image_too_large', 2)
    target.wait_diagnostic('pairs processed', 0)
    assert target.matches == []
    assert target.counter('dropped internal') == 0 and target.counter('dropped opencv') == 0
    target.assert_alive()


def test_every_pair_is_accounted_for_and_gaps_are_counted(target):
    sequences = [1, 2, 3, 7, 8, 12]
    for sequence in sequences:
        target.publisher.publish(stereo_pair(sequence, sequence=sequence))
    target.wait_diagnostic('pair lost (sequence gaps)', 6)
    target.wait(lambda: target.counter('pairs processed')
                + sum(target.counter(f'dropped {reason}') for reason in (
                    'superseded', 'image_too_large', 'calibration', 'size_mismatch',
                    'encoding', 'matcher_input', 'opencv', 'internal'))
                + target.counter('pairs waiting') == len(sequences),
                'received = processed + dropped + waiting')
    assert target.counter('pair received') == len(sequences)
    target.wait(lambda: len(target.matches) == target.counter('pairs processed'),
                'every processed pair to arrive as matches')
    numbers = [m.sequence for m in target.matches]
    assert numbers == list(range(1, len(numbers) + 1))


PARAMETER_NAMES = ['method', 'window_size', 'min_disparity', 'disparity_range', 'min_score',
                   'texture_threshold', 'uniqueness_ratio', 'lr_check_max_diff', 'subpixel',
                   'preprocess', 'roi.x', 'roi.width', 'point_stride', 'max_rate_hz',
                   'input_queue_depth', 'max_image_pixels', 'input_reliability', 'unknown']
VALUES = st.one_of(
    st.booleans(), st.integers(-2**63, 2**63 - 1), st.integers(-3, 40),
    st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=10),
    st.sampled_from(['zncc', 'plain', 'edges', 'binary', 'none']),
    st.lists(st.integers(-5, 5), max_size=3), st.lists(st.floats(), max_size=3))


@settings(max_examples=80, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(name=st.sampled_from(PARAMETER_NAMES), value=VALUES)
def test_random_parameter_values_are_refused_with_a_reason_or_usable(target, name, value):
    successful, reason = target.set_parameter(name, value)
    assert successful or reason, f'{name}={value!r} refused without a reason'
    target.assert_alive()
    if successful:  # accepted: the next pair must still be processed or dropped by reason
        target.set_parameter('max_rate_hz', 0.0)
        target.set_parameter('max_image_pixels', 4096 * 3072)
        before = target.counter('pair received')
        target.publisher.publish(stereo_pair(before + 1))
        target.wait_diagnostic('pair received', before + 1)
        target.wait(lambda: target.counter('pairs waiting') == 0, 'the pair to be handled')
