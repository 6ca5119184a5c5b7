"""Read and write camera calibration files in the standard ROS camera-calibration YAML format.

The format camera_calibration (cameracalibrator) saves and camera_calibration_parsers /
camera_info_manager load::

    image_width: 640
    image_height: 480
    camera_name: left
    camera_matrix: {rows: 3, cols: 3, data: [fx, 0, cx, 0, fy, cy, 0, 0, 1]}
    distortion_model: plumb_bob
    distortion_coefficients: {rows: 1, cols: 5, data: [k1, k2, t1, t2, k3]}
    rectification_matrix: {rows: 3, cols: 3, data: [...]}
    projection_matrix: {rows: 3, cols: 4, data: [...]}

ROS-free: PyYAML and numpy only. `camera_name` is optional on reading, and a missing
`distortion_model` means plumb_bob, as in camera_calibration_parsers.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import yaml

from stereo_fuzzy_perception.core.camera_model import CameraCalibration
from stereo_fuzzy_perception.core.yaml_file import read_yaml_file


class CalibrationFileError(ValueError):
    """A calibration file that cannot be read, naming the file and the bad or missing key."""


# key -> (rows, cols) it must have; None means any count (distortion: 1 x N).
_MATRICES: dict[str, tuple[int, int | None]] = {
    'camera_matrix': (3, 3),
    'distortion_coefficients': (1, None),
    'rectification_matrix': (3, 3),
    'projection_matrix': (3, 4),
}


def read_calibration_yaml(path: str | Path) -> CameraCalibration:
    """Read one camera's calibration from a ROS camera-calibration YAML file.

    The calibration's frame_id is left empty: frames are wiring, set by the caller.

    Args:
        path: The YAML file.

    Returns:
        The calibration (not validated for use: see CameraCalibration.problem()).

    Raises:
        CalibrationFileError: When the file cannot be read or parsed, or a key is missing or
            holds a value of the wrong kind or shape; the message names the file and the key.
    """
    path = Path(path)
    document = read_yaml_file(path, CalibrationFileError, 'calibration file')
    if not isinstance(document, dict):
        raise CalibrationFileError(
            f'{path}: expected a mapping with image_width, image_height, camera_matrix, ...; '
            f'got {type(document).__name__}')
    width = _positive_int(document, 'image_width', path)
    height = _positive_int(document, 'image_height', path)
    distortion_model = document.get('distortion_model', 'plumb_bob')
    if not isinstance(distortion_model, str) or not distortion_model:
        raise CalibrationFileError(
            f'{path}: distortion_model must be a non-empty string, got {distortion_model!r}')
    matrices = {key: _matrix(document, key, path) for key in _MATRICES}
    return CameraCalibration(
        width=width,
        height=height,
        K=matrices['camera_matrix'],
        D=matrices['distortion_coefficients'].ravel(),
        R=matrices['rectification_matrix'],
        P=matrices['projection_matrix'],
        distortion_model=distortion_model,
    )


def write_calibration_yaml(calibration: CameraCalibration, camera_name: str,
                           path: str | Path) -> None:
    """Write `calibration` to `path` in the ROS camera-calibration YAML format.

    Args:
        calibration: The camera's calibration.
        camera_name: Stored as `camera_name` (camera_info_manager checks it on loading).
        path: The file to write (overwritten).
    """
    def matrix(values: np.ndarray, rows: int, cols: int) -> dict[str, Any]:
        return {'rows': rows, 'cols': cols,
                'data': [float(value) for value in np.asarray(values, dtype=float).ravel()]}

    distortion = np.asarray(calibration.D, dtype=float).ravel()
    document = {
        'image_width': int(calibration.width),
        'image_height': int(calibration.height),
        'camera_name': camera_name,
        'camera_matrix': matrix(calibration.K, 3, 3),
        'distortion_model': calibration.distortion_model,
        'distortion_coefficients': matrix(distortion, 1, distortion.size),
        'rectification_matrix': matrix(calibration.R, 3, 3),
        'projection_matrix': matrix(calibration.P, 3, 4),
    }
    Path(path).write_text(yaml.safe_dump(document, sort_keys=False, default_flow_style=None))


def _positive_int(document: dict[str, Any], key: str, path: Path) -> int:
    if key not in document:
        raise CalibrationFileError(f'{path}: missing key {key!r}')
    value = document[key]
    if isinstance(value, bool) or not isinstance(value, int) or value <= 0:
        raise CalibrationFileError(f'{path}: {key} must be a positive integer [px], got {value!r}')
    return value


def _matrix(document: dict[str, Any], key: str, path: Path) -> np.ndarray:
    if key not in document:
        raise CalibrationFileError(f'{path}: missing key {key!r}')
    entry = document[key]
    if not isinstance(entry, dict):
        raise CalibrationFileError(
            f'{path}: {key} must be a mapping with rows, cols and data, got {entry!r}')
    for part in ('rows', 'cols', 'data'):
        if part not in entry:
            raise CalibrationFileError(f'{path}: missing key {key}.{part!r}')
    rows, cols, data = entry['rows'], entry['cols'], entry['data']
    expected_rows, expected_cols = _MATRICES[key]
    if rows != expected_rows or (expected_cols is not None and cols != expected_cols):
        shape = f'{expected_rows}x{expected_cols if expected_cols is not None else "N"}'
        raise CalibrationFileError(f'{path}: {key} is {rows}x{cols}, expected {shape}')
    if not isinstance(cols, int) or isinstance(cols, bool) or cols < 0:
        raise CalibrationFileError(f'{path}: {key}.cols must be a non-negative integer')
    if not isinstance(data, list) or len(data) != rows * cols:
        count = len(data) if isinstance(data, list) else type(data).__name__
        raise CalibrationFileError(
            f'{path}: {key}.data must be a list of rows*cols = {rows * cols} numbers, '
            f'got {count}')
    try:
        values = np.array(data, dtype=float)
    except (TypeError, ValueError) as error:
        raise CalibrationFileError(f'{path}: {key}.data holds a non-number ({error})') from error
    if not np.all(np.isfinite(values)):
        raise CalibrationFileError(f'{path}: {key}.data holds NaN or infinity')
    return values.reshape(rows, cols)
