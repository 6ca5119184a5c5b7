"""stereo_sync_node as a process, attacked as a hostile peer on the ROS domain would.

Issue #15 items 9 and 10 against the installed executable: every unusable calibration is
dropped as `uncalibrated` and never published; images beyond the size limits are dropped as
`image_too_large` before anything is decoded; published pairs are numbered 1, 2, 3, ...; random
values on every parameter are refused with a reason or leave the node pairing.
"""

from __future__ import annotations

import pytest
from hostile_messages import camera_inputs, spoiled_right_cameras
from hostile_probe import HostileProbe
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

pytestmark = pytest.mark.ros

NODE = 'stereo_sync_node'
INPUTS = ('left/image_raw', 'left/camera_info', 'right/image_raw', 'right/camera_info')


class SyncTarget(HostileProbe):
    """The probe plus publishers of the four camera inputs and a StereoPair recorder."""

    def __init__(self, context, process):
        super().__init__(context, process, NODE)
        from sensor_msgs.msg import CameraInfo, Image
        from stereo_fuzzy_perception.nodes import qos

        from stereo_fuzzy_msgs.msg import StereoPair

        self.pairs: list = []
        self.node.create_subscription(StereoPair, 'pair', self.pairs.append, qos.RESULTS)
        self.publishers = {
            topic: self.node.create_publisher(Image if 'image' in topic else CameraInfo, topic,
                                              qos.RESULTS)
            for topic in INPUTS}
        self.wait(lambda: all(publisher.get_subscription_count() > 0
                              for publisher in self.publishers.values())
                  and self.node.count_publishers('pair') > 0,
                  f'{NODE} and the probe to discover each other')
        self.wait(lambda: self.diagnostic_value('pairs in') is not None, 'a first report')

    def send(self, inputs: dict) -> None:
        """Publish one set and wait until the node took it in (its inputs are 5 deep)."""
        before = self.counter('received right/camera_info')
        for topic in INPUTS:
            self.publishers[topic].publish(inputs[topic])
        self.wait_diagnostic('received right/camera_info', before + 1)


@pytest.fixture
def target(ros_context, start_ros_process):
    process = start_ros_process('stereo_fuzzy_perception', NODE, '--ros-args',
                                '-p', 'input_reliability:=reliable', '-p', 'queue_size:=50')
    probe = SyncTarget(ros_context, process)
    yield probe
    probe.close()
    assert process.interrupt() == 0, process.output()[-3000:]


def test_unusable_calibrations_are_dropped_and_never_published(target):
    spoiled = spoiled_right_cameras()
    for index, (_, right) in enumerate(spoiled):
        target.send(camera_inputs(100 + index, right=right))
    target.wait_diagnostic('dropped uncalibrated', len(spoiled))
    target.send(camera_inputs(200))
    target.wait(lambda: target.pairs, 'the good pair')
    assert [pair.header.stamp.sec for pair in target.pairs] == [200]
    assert target.pairs[0].sequence == 1


def test_images_beyond_the_size_limits_are_dropped_before_decoding(target):
    target.send(camera_inputs(1, size=(40000, 8)))
    target.wait_diagnostic('dropped image_too_large', 1)
    assert target.set_parameter('max_image_pixels', 1000) == (True, '')
    target.send(camera_inputs(2))
    target.wait_diagnostic('dropped image_too_large', 2)
    assert target.set_parameter('max_image_pixels', 4096 * 3072) == (True, '')
    target.send(camera_inputs(3))
    target.wait(lambda: target.pairs, 'the pair within the limit')
    assert [(pair.header.stamp.sec, pair.sequence) for pair in target.pairs] == [(3, 1)]
    target.wait_diagnostic('pairs in', 3)
    target.wait_diagnostic('pairs out', 1)


# 'source' and 'left_device' were parameters once (the node captured devices): now undeclared.
PARAMETER_NAMES = ['slop_s', 'queue_size', 'input_reliability', 'diagnostics_period_s',
                   'drop_warn_window_s', 'max_image_pixels', 'source', 'left_device', 'unknown']
VALUES = st.one_of(
    st.booleans(), st.integers(-2**63, 2**63 - 1), st.integers(-3, 2000),
    st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=10),
    st.sampled_from(['/dev/zero', 'devices', 'topics', 'reliable']),
    st.lists(st.integers(-5, 5), max_size=3), st.lists(st.text(max_size=3), max_size=3))


@settings(max_examples=80, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(name=st.sampled_from(PARAMETER_NAMES), value=VALUES)
def test_random_parameter_values_are_refused_with_a_reason_or_usable(target, name, value):
    successful, reason = target.set_parameter(name, value)
    assert successful or reason, f'{name}={value!r} refused without a reason'
    target.assert_alive()
    if successful:  # accepted: the next set must still be paired or dropped by reason
        target.set_parameter('max_image_pixels', 4096 * 3072)
        target.set_parameter('slop_s', 0.0)
        before = target.counter('pairs in')
        target.send(camera_inputs(1000 + before))
        target.wait_diagnostic('pairs in', before + 1)
        target.assert_alive()
