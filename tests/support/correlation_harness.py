"""correlation_node's test harness: synthetic rectified pairs and the node with a probe node.

Shared by tests/test_correlation_node.py and tests/test_correlation_area_tracking.py.
"""

from __future__ import annotations

import hostile_messages
import numpy as np
from ros_waiting import wait_until

WIDTH, HEIGHT = 160, 120
FOCAL, BASELINE = 200.0, 0.1  # [px], [m]
SHIFT = 8  # [px] disparity of the synthetic pair
TIMEOUT = 60.0  # [s] generous: DDS discovery, and a numba compile when its cache is cold


def camera(width: int = WIDTH, height: int = HEIGHT, tx: float = -FOCAL * BASELINE,
           k_zero: bool = False):
    from stereo_fuzzy_perception.core.camera_model import CameraCalibration

    K = np.array([[FOCAL, 0.0, width / 2], [0.0, FOCAL, height / 2], [0.0, 0.0, 1.0]])
    P = np.hstack([K, [[tx], [0.0], [0.0]]])
    return CameraCalibration(width=width, height=height, K=np.zeros((3, 3)) if k_zero else K,
                             D=np.zeros(5), P=P, frame_id='left_camera_optical_frame')


def textured_pair(width: int = WIDTH, height: int = HEIGHT) -> tuple[np.ndarray, np.ndarray]:
    """A rectified pair with a constant disparity SHIFT: left x matches right x - SHIFT."""
    return hostile_messages.textured_pair(width, height, SHIFT)


def stereo_pair(stamp_sec: int = 1, encoding: str = 'mono8', right_width: int = WIDTH,
                left_k_zero: bool = False, right_tx: float = -FOCAL * BASELINE):
    from sensor_msgs.msg import Image
    from std_msgs.msg import Header
    from stereo_fuzzy_perception.nodes.conversions import (
        array_to_image,
        calibration_to_camera_info,
    )

    from stereo_fuzzy_msgs.msg import StereoPair

    header = Header(frame_id='left_camera_optical_frame')
    header.stamp.sec = stamp_sec
    left, right = textured_pair()
    if right_width != WIDTH:
        right = textured_pair(width=right_width)[1]
    pair = StereoPair(header=header)
    if encoding == 'yuv422':
        pair.left_image = Image(header=header, width=WIDTH, height=HEIGHT, encoding=encoding,
                                step=2 * WIDTH, data=bytes(2 * WIDTH * HEIGHT))
        pair.right_image = pair.left_image
    else:
        pair.left_image = array_to_image(left, encoding, header)
        pair.right_image = array_to_image(right, encoding, header)
    pair.left_info = calibration_to_camera_info(camera(k_zero=left_k_zero, tx=0.0), header)
    pair.right_info = calibration_to_camera_info(camera(width=right_width, tx=right_tx), header)
    return pair


class Harness:
    """The node under test plus a probe node that publishes pairs and collects outputs."""

    def __init__(self, context, **overrides):
        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.parameter import Parameter
        from stereo_fuzzy_perception.nodes import qos
        from stereo_fuzzy_perception.nodes.correlation_node import CorrelationNode

        from stereo_fuzzy_msgs.msg import StereoMatches, StereoPair

        parameters = [Parameter(name, value=value) for name, value in overrides.items()]
        self.node = CorrelationNode(context=context, parameter_overrides=parameters)
        self.probe = __import__('rclpy').create_node('correlation_probe', context=context)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)
        self.executor.add_node(self.probe)
        self.matches: list = []
        self.diagnostics: list = []
        self.publisher = self.probe.create_publisher(StereoPair, 'pair', qos.RESULTS)
        self.probe.create_subscription(StereoMatches, 'matches', self.matches.append,
                                       qos.RESULTS)
        self.probe.create_subscription(DiagnosticArray, '/diagnostics', self.diagnostics.append,
                                       qos.DIAGNOSTICS)
        # Another harness in the same context also subscribes to the pairs: a count above zero
        # can be that one's node, so wait until every subscriber the graph knows is matched.
        topic = self.publisher.topic_name
        wait_until(lambda: 0 < self.probe.count_subscribers(topic)
                   <= self.publisher.get_subscription_count()
                   and 0 < self.probe.count_publishers(topic)
                   <= self.node.pair_subscription.get_publisher_count()
                   and self.node.matches_publisher.get_subscription_count() > 0,
                   TIMEOUT, 'the probe and the node to discover each other', self.executor)

    def publish_and_wait_processed(self, pair) -> None:
        before = self.node.processed + sum(self.node.dropped.values())
        self.publisher.publish(pair)
        wait_until(lambda: self.node.processed + sum(self.node.dropped.values()) > before,
                   TIMEOUT, 'the node to process or drop the pair', self.executor)

    def latest_values(self) -> dict[str, str]:
        status = self.diagnostics[-1].status[0]
        return {item.key: item.value for item in status.values}

    def close(self) -> None:
        self.node.destroy_node()
        self.probe.destroy_node()
        self.executor.shutdown()


# A rig 2.5 m straight above the workspace sees its floor at f B / Z = 8 px, the pair's SHIFT.
OVERHEAD_RIG = {'rig.alpha_deg': 0.0, 'rig.theta_deg': 0.0, 'rig.x0_m': 0.2, 'rig.y0_m': 0.15,
                'rig.z0_m': FOCAL * BASELINE / SHIFT, 'rig.baseline_m': BASELINE,
                'rig.vergence_deg': 0.0}
