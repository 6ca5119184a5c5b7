"""Settings of stereo_camera_node: its parameters' names, defaults, ranges and docs, once.

ROS-free, so the README table and the node read the same declarations.
"""

from __future__ import annotations

from dataclasses import dataclass

from stereo_fuzzy_parameters.spec import parameter, parameter_specs

from stereo_fuzzy_perception.core.frame_transforms import LEFT_CAMERA_FRAME, RIGHT_CAMERA_FRAME

REQUIRED = ('left_device', 'right_device', 'left_calibration_file', 'right_calibration_file')


@dataclass(frozen=True)
class StereoCameraSettings:
    """Parameters of stereo_camera_node, typed."""

    left_device: str = parameter(
        '', 'Left capture: device index (0), device path, video file, or image pattern '
        '(left_%03d.png); required', read_only=True, dynamic_typing=True)
    right_device: str = parameter(
        '', 'Right capture, likewise; required', read_only=True, dynamic_typing=True)
    left_calibration_file: str = parameter(
        '', 'Left camera calibration, ROS camera-calibration YAML; required', read_only=True)
    right_calibration_file: str = parameter(
        '', 'Right camera calibration, ROS camera-calibration YAML; required', read_only=True)
    frame_rate_hz: float = parameter(10.0, 'Capture rate [Hz]', 0.1, 240.0)
    left_frame_id: str = parameter(
        LEFT_CAMERA_FRAME, 'Frame of the left images and info', read_only=True)
    right_frame_id: str = parameter(
        RIGHT_CAMERA_FRAME, 'Frame of the right images and info', read_only=True)
    encoding: str = parameter(
        'bgr8', 'Encoding of the published images', choices=('bgr8', 'rgb8', 'mono8'),
        read_only=True)
    loop: bool = parameter(
        False, 'At the end of a video file or image pattern, start again instead of stopping')

    def problem(self) -> str | None:
        """Return why the node cannot capture (a capture or calibration file not given)."""
        missing = [name for name in REQUIRED if not getattr(self, name)]
        return 'stereo_camera_node needs ' + ', '.join(missing) if missing else None


PARAMETERS = parameter_specs(StereoCameraSettings)
