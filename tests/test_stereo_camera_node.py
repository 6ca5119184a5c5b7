"""stereo_camera_node with real rclpy: standard camera topics from two captures, paired downstream.

Captures are image patterns written to tmp_path (what a device gives, without a device); the
test waits on messages, never on fixed sleeps.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
from ros_waiting import wait_until

pytestmark = pytest.mark.ros

TIMEOUT = 30.0
WIDTH, HEIGHT = 160, 120


def write_captures(directory: Path, frames: int) -> dict[str, object]:
    from stereo_fuzzy_perception.core.camera_calibration_file import write_calibration_yaml
    from stereo_fuzzy_perception.core.rig_geometry import StereoRig
    from stereo_fuzzy_perception.simulation.scene_model import SimulatedCamera
    from stereo_fuzzy_perception.simulation.scene_renderer import stereo_calibration

    for index in range(frames):
        for side, offset in (('left', 0), ('right', 100)):
            frame = np.full((HEIGHT, WIDTH, 3), offset + 10 * index, dtype=np.uint8)
            assert cv2.imwrite(str(directory / f'{side}_{index:03d}.png'), frame)
    calibration = stereo_calibration(SimulatedCamera(width=WIDTH, height=HEIGHT), StereoRig())
    write_calibration_yaml(calibration.left, 'left', directory / 'left.yaml')
    write_calibration_yaml(calibration.right, 'right', directory / 'right.yaml')
    return {'left_device': str(directory / 'left_%03d.png'),
            'right_device': str(directory / 'right_%03d.png'),
            'left_calibration_file': str(directory / 'left.yaml'),
            'right_calibration_file': str(directory / 'right.yaml')}


def test_camera_topics_carry_one_stamp_and_stereo_sync_pairs_them(ros_context, tmp_path):
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter
    from sensor_msgs.msg import CameraInfo, Image
    from stereo_fuzzy_perception.nodes import qos
    from stereo_fuzzy_perception.nodes.stereo_camera_node import StereoCameraNode
    from stereo_fuzzy_perception.nodes.stereo_sync_node import StereoSyncNode

    from stereo_fuzzy_msgs.msg import StereoPair

    parameters = write_captures(tmp_path, frames=3)
    probe = rclpy.create_node('probe', context=ros_context)
    received: dict[str, list] = {topic: [] for topic in (
        'left/image_raw', 'left/camera_info', 'right/image_raw', 'right/camera_info')}
    for topic in received:
        kind = Image if topic.endswith('image_raw') else CameraInfo
        probe.create_subscription(kind, topic, received[topic].append, qos.CAMERA_INPUT)
    pairs: list = []
    probe.create_subscription(StereoPair, 'stereo/pair', pairs.append, qos.RESULTS)
    sync = StereoSyncNode(context=ros_context)
    camera = StereoCameraNode(context=ros_context, parameter_overrides=[
        Parameter(name, value=value) for name, value in
        {**parameters, 'loop': True, 'frame_rate_hz': 20.0, 'encoding': 'mono8'}.items()])
    executor = SingleThreadedExecutor(context=ros_context)
    for node in (probe, sync, camera):
        executor.add_node(node)
    try:
        wait_until(lambda: len(pairs) >= 2 and all(len(v) >= 2 for v in received.values()),
                   TIMEOUT, 'camera topics and two StereoPairs', executor)
        left, right = received['left/image_raw'][-1], received['right/image_raw'][-1]
        assert left.encoding == 'mono8' and (left.width, left.height) == (WIDTH, HEIGHT)
        assert left.header.frame_id == 'left_camera_optical_frame'
        assert right.header.frame_id == 'right_camera_optical_frame'
        stamps = {topic: {(m.header.stamp.sec, m.header.stamp.nanosec) for m in messages}
                  for topic, messages in received.items()}
        assert stamps['left/image_raw'] & stamps['right/camera_info'], 'one stamp for all four'
        assert received['right/camera_info'][-1].p[3] < 0.0
        pair = pairs[-1]
        assert pair.left_image.header.stamp == pair.right_image.header.stamp
    finally:
        executor.shutdown()
        for node in (camera, sync, probe):
            node.destroy_node()


def test_missing_capture_refuses_to_start_naming_it(ros_context):
    from stereo_fuzzy_perception.nodes.stereo_camera_node import StereoCameraNode

    with pytest.raises(ValueError, match='stereo_camera_node needs left_device, right_device'):
        StereoCameraNode(context=ros_context)
