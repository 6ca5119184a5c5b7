"""Settings of stereo_sync_node: its parameters' names, defaults, ranges and docs, once."""

from __future__ import annotations

from dataclasses import dataclass

from stereo_fuzzy_parameters.spec import parameter, parameter_specs

DEVICE_FILES = ('left_device', 'right_device', 'left_calibration_file', 'right_calibration_file')


@dataclass(frozen=True)
class StereoSyncSettings:
    """Parameters of stereo_sync_node, typed."""

    source: str = parameter(
        'topics', 'Where pairs come from: camera topics, or two OpenCV capture devices/files',
        choices=('topics', 'devices'), read_only=True)
    # --- topics source
    slop_s: float = parameter(
        0.0, 'Largest stamp span of a paired left/right image + camera_info set [s]; 0 pairs '
        'exact stamps only', 0.0, 1.0)
    queue_size: int = parameter(
        10, 'Unpaired messages kept per input topic; the oldest is dropped beyond it', 1, 1000)
    input_reliability: str = parameter(
        'best_effort', 'Reliability of the four input subscriptions; best_effort also receives '
        'reliable publishers', choices=('best_effort', 'reliable'), read_only=True)
    max_image_pixels: int = parameter(
        4096 * 3072, 'Largest image accepted [px, width x height]; larger sets are dropped as '
        'image_too_large before they are decoded', 1, 32767 * 32767)
    # --- devices source
    left_device: str = parameter(
        '', 'Left capture: device index (0), video file, or image pattern (left_%03d.png)',
        read_only=True, dynamic_typing=True)
    right_device: str = parameter(
        '', 'Right capture: device index, video file, or image pattern', read_only=True,
        dynamic_typing=True)
    left_calibration_file: str = parameter(
        '', 'Left camera calibration, ROS camera-calibration YAML', read_only=True)
    right_calibration_file: str = parameter(
        '', 'Right camera calibration, ROS camera-calibration YAML', read_only=True)
    frame_rate_hz: float = parameter(
        10.0, 'Capture rate of the devices source [Hz]', 0.1, 240.0)
    left_frame_id: str = parameter(
        'left_camera_optical_frame', 'Frame of the left camera (devices source)', read_only=True)
    right_frame_id: str = parameter(
        'right_camera_optical_frame', 'Frame of the right camera (devices source)',
        read_only=True)
    encoding: str = parameter(
        'bgr8', 'Encoding published by the devices source', choices=('bgr8', 'rgb8', 'mono8'),
        read_only=True)
    loop: bool = parameter(
        False, 'At the end of a video file or image pattern, start again instead of stopping')
    # --- diagnostics
    diagnostics_period_s: float = parameter(
        1.0, 'Period of the /diagnostics report [s]', 0.05, 60.0, read_only=True)
    drop_warn_window_s: float = parameter(
        5.0, 'Diagnostics level is WARN while a pair was dropped within this window [s]',
        0.0, 3600.0)

    def problem(self) -> str | None:
        """Return why this combination cannot work, or None.

        The devices source needs both captures and both calibration files.
        """
        if self.source != 'devices':
            return None
        missing = [name for name in DEVICE_FILES if not getattr(self, name)]
        if missing:
            return 'source=devices needs ' + ', '.join(f"{name} (now '')" for name in missing)
        return None


PARAMETERS = parameter_specs(StereoSyncSettings)
