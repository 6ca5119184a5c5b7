"""Parameters of stereo_sync_node: the one place their names, defaults, ranges and docs live."""

from __future__ import annotations

from stereo_fuzzy_parameters.spec import ParameterSpec, ParameterValue

PARAMETERS = [
    ParameterSpec('source', 'topics',
                  'Where pairs come from: camera topics, or two OpenCV capture devices/files',
                  choices=('topics', 'devices'), read_only=True),
    # --- topics source
    ParameterSpec('slop', 0.0,
                  'Largest stamp span of a paired left/right image + camera_info set [s]; '
                  '0 pairs exact stamps only',
                  minimum=0.0, maximum=1.0),
    ParameterSpec('queue_size', 10,
                  'Unpaired messages kept per input topic; the oldest is dropped beyond it',
                  minimum=1, maximum=1000),
    ParameterSpec('input_reliability', 'best_effort',
                  'Reliability of the four input subscriptions; best_effort also receives '
                  'reliable publishers',
                  choices=('best_effort', 'reliable'), read_only=True),
    ParameterSpec('max_image_pixels', 4096 * 3072,
                  'Largest image accepted [px, width x height]; larger pairs are dropped as '
                  'image_too_large before they are decoded', minimum=1, maximum=32767 * 32767),
    # --- devices source
    ParameterSpec('left_device', '',
                  'Left capture: device index (0), video file, or image pattern (left_%03d.png)',
                  read_only=True),
    ParameterSpec('right_device', '',
                  'Right capture: device index, video file, or image pattern', read_only=True),
    ParameterSpec('left_calibration_file', '',
                  'Left camera calibration, ROS camera-calibration YAML', read_only=True),
    ParameterSpec('right_calibration_file', '',
                  'Right camera calibration, ROS camera-calibration YAML', read_only=True),
    ParameterSpec('frame_rate', 10.0, 'Capture rate of the devices source [Hz]',
                  minimum=0.1, maximum=240.0),
    ParameterSpec('left_frame_id', 'left_camera_optical_frame',
                  'Frame of the left camera (devices source)', read_only=True),
    ParameterSpec('right_frame_id', 'right_camera_optical_frame',
                  'Frame of the right camera (devices source)', read_only=True),
    ParameterSpec('encoding', 'bgr8', 'Encoding published by the devices source',
                  choices=('bgr8', 'rgb8', 'mono8'), read_only=True),
    ParameterSpec('loop', False,
                  'At the end of a video file or image pattern, start again instead of stopping'),
    # --- diagnostics
    ParameterSpec('diagnostics_period', 1.0, 'Period of the /diagnostics report [s]',
                  minimum=0.05, maximum=60.0, read_only=True),
    ParameterSpec('drop_warn_window', 5.0,
                  'Diagnostics level is WARN while a pair was dropped within this window [s]',
                  minimum=0.0, maximum=3600.0),
]

DEFAULTS: dict[str, ParameterValue] = {spec.name: spec.default for spec in PARAMETERS}


def check_parameters(values: dict[str, ParameterValue]) -> str | None:
    """Return why this combination of parameters cannot work, or None.

    The devices source needs both captures and both calibration files.
    """
    if values['source'] != 'devices':
        return None
    missing = [name for name in ('left_device', 'right_device', 'left_calibration_file',
                                 'right_calibration_file') if not values[name]]
    if missing:
        return 'source=devices needs ' + ', '.join(missing)
    return None
