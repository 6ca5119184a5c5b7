"""ROS camera-calibration YAML files: round trip, the standard layout, errors that name the key."""

import re

import numpy as np
import pytest
import yaml
from stereo_fuzzy_perception.core.camera_calibration_file import (
    CalibrationFileError,
    read_calibration_yaml,
    write_calibration_yaml,
)
from stereo_fuzzy_perception.core.camera_model import CameraCalibration

# As cameracalibrator writes it (values from a real narrow-stereo right camera, shortened).
STANDARD_FILE = """\
image_width: 640
image_height: 480
camera_name: narrow_stereo/right
camera_matrix:
  rows: 3
  cols: 3
  data: [430.2, 0, 306.7, 0, 430.9, 238.1, 0, 0, 1]
distortion_model: plumb_bob
distortion_coefficients:
  rows: 1
  cols: 5
  data: [-0.33, 0.11, 0.0005, -0.0002, 0]
rectification_matrix:
  rows: 3
  cols: 3
  data: [0.999, 0.01, -0.02, -0.01, 0.999, 0.003, 0.02, -0.003, 0.999]
projection_matrix:
  rows: 3
  cols: 4
  data: [295.5, 0, 285.5, -26.7, 0, 295.5, 223.4, 0, 0, 0, 1, 0]
"""


def right_camera() -> CameraCalibration:
    return CameraCalibration(
        width=752, height=480,
        K=np.array([[700.0, 0.0, 376.5], [0.0, 701.25, 240.0], [0.0, 0.0, 1.0]]),
        D=np.array([-0.1, 0.02, 0.001, -0.002, 0.0003]),
        R=np.array([[1.0, 0.001, 0.0], [-0.001, 1.0, 0.0], [0.0, 0.0, 1.0]]),
        P=np.array([[690.0, 0.0, 370.0, -82.8], [0.0, 690.0, 241.0, 0.0], [0.0, 0.0, 1.0, 0.0]]),
    )


def test_round_trip_keeps_every_field(tmp_path):
    path = tmp_path / 'right.yaml'
    write_calibration_yaml(right_camera(), 'rig/right', path)
    assert read_calibration_yaml(path).same_as(right_camera())


def test_round_trip_of_a_rational_polynomial_model_keeps_eight_coefficients(tmp_path):
    path = tmp_path / 'wide.yaml'
    camera = CameraCalibration(width=64, height=48, K=np.diag([50.0, 50.0, 1.0]),
                               D=np.arange(8) / 100.0, P=np.eye(3, 4) * 50.0,
                               distortion_model='rational_polynomial')
    write_calibration_yaml(camera, 'wide', path)
    assert read_calibration_yaml(path).same_as(camera)


def test_written_file_has_the_standard_keys_and_matrix_layout(tmp_path):
    path = tmp_path / 'right.yaml'
    write_calibration_yaml(right_camera(), 'rig/right', path)
    document = yaml.safe_load(path.read_text())
    assert list(document) == [
        'image_width', 'image_height', 'camera_name', 'camera_matrix', 'distortion_model',
        'distortion_coefficients', 'rectification_matrix', 'projection_matrix']
    assert document['camera_name'] == 'rig/right'
    assert document['projection_matrix']['rows'] == 3
    assert document['projection_matrix']['cols'] == 4
    assert document['projection_matrix']['data'][3] == -82.8
    assert document['distortion_coefficients'] == {
        'rows': 1, 'cols': 5, 'data': [-0.1, 0.02, 0.001, -0.002, 0.0003]}


def test_reads_a_file_as_cameracalibrator_writes_it(tmp_path):
    path = tmp_path / 'narrow_right.yaml'
    path.write_text(STANDARD_FILE)
    camera = read_calibration_yaml(path)
    assert (camera.width, camera.height) == (640, 480)
    assert camera.K[0, 0] == 430.2 and camera.K[1, 2] == 238.1
    assert camera.D.shape == (5,)
    assert camera.P.shape == (3, 4) and camera.P[0, 3] == -26.7
    assert camera.distortion_model == 'plumb_bob'
    assert camera.problem() is None


def test_missing_distortion_model_means_plumb_bob(tmp_path):
    path = tmp_path / 'no_model.yaml'
    path.write_text(STANDARD_FILE.replace('distortion_model: plumb_bob\n', ''))
    assert read_calibration_yaml(path).distortion_model == 'plumb_bob'


@pytest.mark.parametrize('key', [
    'image_width', 'image_height', 'camera_matrix', 'distortion_coefficients',
    'rectification_matrix', 'projection_matrix'])
def test_missing_key_is_named_with_the_file(tmp_path, key):
    document = yaml.safe_load(STANDARD_FILE)
    del document[key]
    path = tmp_path / f'without_{key}.yaml'
    path.write_text(yaml.safe_dump(document))
    with pytest.raises(CalibrationFileError) as raised:
        read_calibration_yaml(path)
    assert str(path) in str(raised.value)
    assert f'missing key {key!r}' in str(raised.value)


@pytest.mark.parametrize(('edit', 'named'), [
    (lambda d: d['camera_matrix'].pop('data'), "missing key camera_matrix.'data'"),
    (lambda d: d['projection_matrix'].update(cols=3, data=[0.0] * 9),
     'projection_matrix is 3x3, expected 3x4'),
    (lambda d: d['camera_matrix'].update(data=[1.0] * 8),
     'camera_matrix.data must be a list of rows*cols = 9 numbers, got 8'),
    (lambda d: d['rectification_matrix'].update(data=['a'] * 9),
     'rectification_matrix.data holds a non-number'),
    (lambda d: d.update(image_width=-640), 'image_width must be a positive integer'),
    (lambda d: d.update(image_height='480'), 'image_height must be a positive integer'),
    (lambda d: d.update(distortion_coefficients=[0.0] * 5),
     'distortion_coefficients must be a mapping'),
])
def test_bad_value_is_named_with_the_file(tmp_path, edit, named):
    document = yaml.safe_load(STANDARD_FILE)
    edit(document)
    path = tmp_path / 'bad.yaml'
    path.write_text(yaml.safe_dump(document))
    with pytest.raises(CalibrationFileError, match='^' + re.escape(f'{path}: ')) as raised:
        read_calibration_yaml(path)
    assert named in str(raised.value)


def test_unreadable_or_unparsable_files_are_named(tmp_path):
    missing = tmp_path / 'absent.yaml'
    with pytest.raises(CalibrationFileError, match='absent.yaml: cannot read'):
        read_calibration_yaml(missing)
    broken = tmp_path / 'broken.yaml'
    broken.write_text('image_width: [640\n')
    with pytest.raises(CalibrationFileError, match='broken.yaml: not valid YAML'):
        read_calibration_yaml(broken)
    scalar = tmp_path / 'scalar.yaml'
    scalar.write_text('42\n')
    with pytest.raises(CalibrationFileError, match='scalar.yaml: expected a mapping'):
        read_calibration_yaml(scalar)
