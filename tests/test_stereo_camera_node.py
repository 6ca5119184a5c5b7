"""stereo_camera_node with real rclpy: standard camera topics from two captures, paired downstream.

Captures are image patterns written to tmp_path (what a device gives, without a device); the
test waits on messages, never on fixed sleeps.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from camera_captures import write_captures
from ros_waiting import wait_until

pytestmark = pytest.mark.ros

TIMEOUT = 30.0
WIDTH, HEIGHT = 160, 120


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
    probe.create_subscription(StereoPair, 'pair', pairs.append, qos.RESULTS)
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


def start_camera(ros_context, tmp_path, frames: int, **overrides):
    """Write `frames` colour frames per side, start stereo_camera_node on them, add a probe."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter
    from sensor_msgs.msg import CameraInfo, Image
    from stereo_fuzzy_perception.nodes import qos
    from stereo_fuzzy_perception.nodes.stereo_camera_node import StereoCameraNode

    parameters = write_captures(tmp_path, frames)
    for index in range(frames):  # red channel 7: tells bgr8 from rgb8
        for side, offset in (('left', 0), ('right', 100)):
            frame = np.full((HEIGHT, WIDTH, 3), offset + 10 * index, dtype=np.uint8)
            frame[:, :, 2] = 7
            assert cv2.imwrite(str(tmp_path / f'{side}_{index:03d}.png'), frame)
    probe = rclpy.create_node('probe', context=ros_context)
    received: dict[str, list] = {'left/image_raw': [], 'right/image_raw': [],
                                 'right/camera_info': []}
    for topic, messages in received.items():
        kind = Image if topic.endswith('image_raw') else CameraInfo
        probe.create_subscription(kind, topic, messages.append, qos.CAMERA_INPUT)
    camera = StereoCameraNode(context=ros_context, parameter_overrides=[
        Parameter(name, value=value) for name, value in {**parameters, **overrides}.items()])
    executor = SingleThreadedExecutor(context=ros_context)
    for node in (probe, camera):
        executor.add_node(node)
    return camera, received, executor, (camera, probe)


def test_frames_are_published_as_written_in_the_chosen_encoding(ros_context, tmp_path):
    from stereo_fuzzy_perception.nodes.conversions import image_to_array

    camera, received, executor, nodes = start_camera(
        ros_context, tmp_path, frames=3, loop=True, frame_rate_hz=50.0,
        left_frame_id='rig_left_optical', right_frame_id='rig_right_optical')
    try:
        wait_until(lambda: all(len(v) >= 2 for v in received.values()), TIMEOUT,
                   'two frames on each camera topic', executor)
        left, right = received['left/image_raw'][-1], received['right/image_raw'][-1]
        assert left.encoding == 'bgr8'
        assert (left.header.frame_id, right.header.frame_id) == (
            'rig_left_optical', 'rig_right_optical')
        assert received['right/camera_info'][-1].header.frame_id == 'rig_right_optical'
        pixels = image_to_array(left)
        assert pixels.shape == (HEIGHT, WIDTH, 3)
        index = int(pixels[0, 0, 0]) // 10
        assert 0 <= index < 3 and int(pixels[0, 0, 0]) == 10 * index, 'a left frame as written'
        assert int(pixels[0, 0, 2]) == 7, 'bgr8 keeps OpenCV channel order'
        same_stamp = [message for message in received['right/image_raw']
                      if message.header.stamp == left.header.stamp]
        assert same_stamp, 'the right frame captured with this left frame'
        assert int(image_to_array(same_stamp[0])[0, 0, 0]) == 100 + 10 * index, (
            'the right frame of the same index')
    finally:
        executor.shutdown()
        for node in nodes:
            node.destroy_node()


def test_capture_stops_at_the_end_of_the_files(ros_context, tmp_path):
    camera, received, executor, nodes = start_camera(
        ros_context, tmp_path, frames=3, loop=False, frame_rate_hz=50.0, encoding='mono8')
    try:
        wait_until(lambda: camera.capture_state == 'ended', TIMEOUT,
                   'the capture to end after the last file', executor)
        assert camera.frames_published == 3
    finally:
        executor.shutdown()
        for node in nodes:
            node.destroy_node()


def test_device_index_given_as_an_integer_is_accepted(ros_context, tmp_path):
    from rclpy.parameter import Parameter
    from stereo_fuzzy_parameters.declaration import StartupError
    from stereo_fuzzy_perception.nodes.stereo_camera_node import StereoCameraNode

    parameters = write_captures(tmp_path, frames=1)
    parameters.update(left_device=97, right_device=98)  # as `-p left_device:=97` gives it
    # No camera 97 exists here: the node gets as far as opening it, which names the device.
    with pytest.raises(StartupError, match="left_device='97': cannot open the capture"):
        StereoCameraNode(context=ros_context, parameter_overrides=[
            Parameter(name, value=value) for name, value in parameters.items()])


def test_unusable_calibration_file_refuses_to_start_naming_it(ros_context, tmp_path):
    from dataclasses import replace

    from rclpy.parameter import Parameter
    from stereo_fuzzy_parameters.declaration import StartupError
    from stereo_fuzzy_perception.core.camera_calibration_file import (
        read_calibration_yaml,
        write_calibration_yaml,
    )
    from stereo_fuzzy_perception.nodes.stereo_camera_node import StereoCameraNode

    parameters = write_captures(tmp_path, frames=1)
    right = read_calibration_yaml(str(tmp_path / 'right.yaml'))
    write_calibration_yaml(replace(right, distortion_model='fisheye62'), 'right',
                           tmp_path / 'right.yaml')  # readable, but not a model the chain knows
    with pytest.raises(StartupError,
                       match="right_calibration_file: .*distortion model 'fisheye62'"):
        StereoCameraNode(context=ros_context, parameter_overrides=[
            Parameter(name, value=value) for name, value in parameters.items()])


def test_stereo_camera_set_publishes_in_the_namespace_with_a_plain_parameters_file(
        ros_context, start_ros_process, tmp_path):
    """`launch_chain stereo_camera params_file:=my_rig.yaml` as a process: the file's plain
    `stereo_camera_node:` section reaches the node although it runs in /stereo."""
    import rclpy
    import yaml
    from rclpy.executors import SingleThreadedExecutor
    from sensor_msgs.msg import Image
    from stereo_fuzzy_perception.bringup.chain_description import ros_arguments
    from stereo_fuzzy_perception.nodes import qos

    from chain.processes import process_set, source_share_directory

    parameters = {**write_captures(tmp_path, frames=2), 'loop': True, 'frame_rate_hz': 20.0}
    params_file = tmp_path / 'my_rig.yaml'
    params_file.write_text(yaml.safe_dump(
        {'stereo_camera_node': {'ros__parameters': parameters}}))
    processes = process_set('stereo_camera')
    (process,) = processes.processes
    arguments = ros_arguments(process, processes.argument_values(
        {'params_file': str(params_file)}), source_share_directory)
    camera = start_ros_process(process.package, process.executable, *arguments)
    probe = rclpy.create_node('probe', context=ros_context)
    images: list = []
    probe.create_subscription(Image, '/stereo/left/image_raw', images.append, qos.CAMERA_INPUT)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(probe)
    try:
        wait_until(lambda: images or camera.process.poll() is not None, TIMEOUT,
                   'an image on /stereo/left/image_raw', executor)
        assert images, f'stereo_camera_node exited:\n{camera.output()}'
        assert (images[-1].width, images[-1].height) == (WIDTH, HEIGHT)
    finally:
        executor.shutdown()
        probe.destroy_node()
