"""Capture two cameras and publish them on the standard camera topics, as a camera driver does.

Publishes `left/image_raw`, `left/camera_info`, `right/image_raw`, `right/camera_info` (the
four inputs stereo_sync_node pairs, and what image_proc, RViz and `ros2 bag` expect). Both
frames are grabbed before either is decoded and all four messages carry one stamp (the node
clock at capture), with the calibration of each camera from its ROS camera-calibration YAML.
Capture runs in a thread of its own, so the executor never blocks. At the end of a video file
or image pattern it logs once and stops, or starts again with `loop:=true`.
"""

from __future__ import annotations

import threading
import time
from dataclasses import replace
from typing import Any

import numpy as np
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import CameraInfo, Image
from std_msgs.msg import Header
from stereo_fuzzy_parameters.declaration import StartupError, declare_settings, run_node

from stereo_fuzzy_perception.core.camera_calibration_file import (
    CalibrationFileError,
    read_calibration_yaml,
)
from stereo_fuzzy_perception.core.camera_model import CameraCalibration
from stereo_fuzzy_perception.core.frame_capture import (
    CaptureOpenError,
    DeviceCapture,
    convert_frame,
)
from stereo_fuzzy_perception.nodes import topic_names
from stereo_fuzzy_perception.nodes.conversions import array_to_image, calibration_to_camera_info
from stereo_fuzzy_perception.nodes.stereo_camera_parameters import StereoCameraSettings

ERROR_THROTTLE_S = 5.0
# Reliable, so that both reliable and best-effort subscribers (sensor data QoS) receive it.
CAMERA_OUTPUT = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=5,
                           reliability=ReliabilityPolicy.RELIABLE)


def read_usable_calibration(name: str, path: str, frame_id: str) -> CameraCalibration:
    """Read the calibration file of parameter `name`; refuse one the chain cannot use.

    Raises:
        CalibrationFileError: Naming the parameter, the file and what is wrong with it.
    """
    try:
        calibration = read_calibration_yaml(path)
    except CalibrationFileError as error:
        raise CalibrationFileError(f'{name}: {error}') from None
    problem = calibration.problem()
    if problem:
        raise CalibrationFileError(f'{name}: {path}: unusable calibration: {problem}')
    return replace(calibration, frame_id=frame_id)


class StereoCameraNode(Node):
    """Capture two cameras; publish left|right image_raw and camera_info."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__('stereo_camera_node', **kwargs)
        self.settings = declare_settings(self, StereoCameraSettings, apply=self._apply_settings)
        settings = self.settings
        try:
            self.calibrations = (
                read_usable_calibration('left_calibration_file', settings.left_calibration_file,
                                        settings.left_frame_id),
                read_usable_calibration('right_calibration_file',
                                        settings.right_calibration_file,
                                        settings.right_frame_id))
        except CalibrationFileError as error:
            raise StartupError(str(error), self.get_name()) from None
        self.publishers_by_side = {
            side: (self.create_publisher(Image, image_topic, CAMERA_OUTPUT),
                   self.create_publisher(CameraInfo, info_topic, CAMERA_OUTPUT))
            for side, image_topic, info_topic in (
                ('left', topic_names.LEFT_IMAGE, topic_names.LEFT_CAMERA_INFO),
                ('right', topic_names.RIGHT_IMAGE, topic_names.RIGHT_CAMERA_INFO))}
        self.frames_published = 0
        self.capture_state = 'running'
        try:
            self._capture = DeviceCapture(str(settings.left_device), str(settings.right_device))
        except CaptureOpenError as error:
            raise StartupError(str(error), self.get_name()) from None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._capture_loop, name='stereo_camera',
                                        daemon=True)
        self._thread.start()
        self.get_logger().info(
            f'capturing {settings.left_device} and {settings.right_device} '
            f'at {settings.frame_rate_hz} Hz')

    def _apply_settings(self, settings: StereoCameraSettings) -> None:
        # frame_rate_hz and loop may change while running; the capture thread reads them anew
        self.settings = settings

    def _capture_loop(self) -> None:
        try:
            self._capture_frames()
        except Exception as error:  # the thread must report, not die silently
            if self._stop.is_set() or not self.context.ok():
                return
            self.capture_state = 'failed'
            self.get_logger().error(f'capture stopped: {error}')

    def _capture_frames(self) -> None:
        next_frame = time.monotonic()
        rewound = False
        while not self._stop.is_set():
            frames = self._capture.read()
            if frames is None:
                if not self._capture.is_live and self.settings.loop and not rewound:
                    self._capture.rewind()
                    rewound = True
                    continue
                if not self._capture.is_live:
                    self.capture_state = 'ended'
                    self.get_logger().info(
                        f'end of {self._capture.left_source} / {self._capture.right_source} '
                        f'after {self.frames_published} frames (set loop:=true to start again)')
                    return
                self.get_logger().error(
                    f'cannot read a frame from {self._capture.left_source} or '
                    f'{self._capture.right_source}; retrying',
                    throttle_duration_sec=ERROR_THROTTLE_S)
            else:
                rewound = False
                self._publish(*frames)
            period = 1.0 / self.settings.frame_rate_hz
            next_frame = max(next_frame + period, time.monotonic())
            self._stop.wait(next_frame - time.monotonic())

    def _publish(self, left: np.ndarray, right: np.ndarray) -> None:
        stamp = self.get_clock().now().to_msg()
        encoding = self.settings.encoding
        for side, frame, calibration in zip(('left', 'right'), (left, right), self.calibrations,
                                            strict=True):
            header = Header(stamp=stamp, frame_id=calibration.frame_id)
            image_publisher, info_publisher = self.publishers_by_side[side]
            image_publisher.publish(array_to_image(convert_frame(frame, encoding), encoding,
                                                   header))
            info_publisher.publish(calibration_to_camera_info(calibration, header))
        self.frames_published += 1

    def destroy_node(self) -> None:
        """Stop the capture thread and release the devices, then destroy the node."""
        self._stop.set()
        self._thread.join(timeout=5.0)
        self._capture.release()
        super().destroy_node()


def main(args: list[str] | None = None) -> None:
    """Run the node until shutdown; a wiring mistake ends it with one line (exit 1)."""
    run_node(StereoCameraNode, args)
