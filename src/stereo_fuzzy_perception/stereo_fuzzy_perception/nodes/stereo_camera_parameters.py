"""Parameters of stereo_camera_node: the one place their names, defaults and ranges live.

ROS-free, so the README table, the config file test and the node read the same specs.
"""

from __future__ import annotations

from stereo_fuzzy_parameters.spec import ParameterSpec

from stereo_fuzzy_perception.core.rig_pose import LEFT_CAMERA_FRAME, RIGHT_CAMERA_FRAME

PARAMETERS = [
    ParameterSpec('left_device', '',
                  'Left capture: device index (0), device path, video file, or image pattern '
                  '(left_%03d.png); required', read_only=True),
    ParameterSpec('right_device', '', 'Right capture, likewise; required', read_only=True),
    ParameterSpec('left_calibration_file', '',
                  'Left camera calibration, ROS camera-calibration YAML; required',
                  read_only=True),
    ParameterSpec('right_calibration_file', '',
                  'Right camera calibration, ROS camera-calibration YAML; required',
                  read_only=True),
    ParameterSpec('frame_rate', 10.0, 'Capture rate [Hz]', minimum=0.1, maximum=240.0),
    ParameterSpec('left_frame_id', LEFT_CAMERA_FRAME, 'Frame of the left images and info',
                  read_only=True),
    ParameterSpec('right_frame_id', RIGHT_CAMERA_FRAME, 'Frame of the right images and info',
                  read_only=True),
    ParameterSpec('encoding', 'bgr8', 'Encoding of the published images',
                  choices=('bgr8', 'rgb8', 'mono8'), read_only=True),
    ParameterSpec('loop', False,
                  'At the end of a video file or image pattern, start again instead of stopping'),
]
