"""Image-pattern captures and calibration files for stereo_camera_node, written to a folder."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np


def write_captures(directory: Path, frames: int, width: int = 160,
                   height: int = 120) -> dict[str, object]:
    """Write left_%03d.png / right_%03d.png and both calibration files; return the parameters.

    Frame `index` is grey `10 * index` on the left and `100 + 10 * index` on the right, so a
    test can tell which frames travelled together.
    """
    from stereo_fuzzy_perception.core.camera_calibration_file import write_calibration_yaml
    from stereo_fuzzy_perception.core.rig_geometry import StereoRig
    from stereo_fuzzy_perception.simulation.scene_model import SimulatedCamera
    from stereo_fuzzy_perception.simulation.scene_renderer import stereo_calibration

    for index in range(frames):
        for side, offset in (('left', 0), ('right', 100)):
            frame = np.full((height, width, 3), offset + 10 * index, dtype=np.uint8)
            assert cv2.imwrite(str(directory / f'{side}_{index:03d}.png'), frame)
    calibration = stereo_calibration(SimulatedCamera(width=width, height=height), StereoRig())
    write_calibration_yaml(calibration.left, 'left', directory / 'left.yaml')
    write_calibration_yaml(calibration.right, 'right', directory / 'right.yaml')
    return {'left_device': str(directory / 'left_%03d.png'),
            'right_device': str(directory / 'right_%03d.png'),
            'left_calibration_file': str(directory / 'left.yaml'),
            'right_calibration_file': str(directory / 'right.yaml')}
