"""Unusable calibrations are named by CameraCalibration.problem() before they are used.

Issue #15 item 9: NaN in D or R, a D of the wrong length for its model, an unknown distortion
model, a zero projection focal length, a principal point outside the image, binning or an ROI:
each is refused with its reason (the sync node drops such pairs as `uncalibrated`, the
correlation node as `calibration`), and the property test holds for any change of any number.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from stereo_fuzzy_perception.core.camera_model import CameraCalibration, StereoCalibration
from stereo_fuzzy_perception.core.matching.rectification import rectification_maps
from stereo_fuzzy_perception.core.rig_geometry import StereoRig
from stereo_fuzzy_perception.simulation.synthetic_scenes import rectified_calibration

LEFT, RIGHT = rectified_calibration(StereoRig())


def changed(matrix_name: str, index: tuple[int, ...], value: float) -> CameraCalibration:
    matrix = np.array(getattr(RIGHT, matrix_name), dtype=float)
    matrix[index] = value
    return replace(RIGHT, **{matrix_name: matrix})


def test_the_simulated_rig_is_usable():
    assert LEFT.problem() is None and RIGHT.problem() is None
    assert StereoCalibration(LEFT, RIGHT).problem() is None


@pytest.mark.parametrize(('calibration', 'message'), [
    (changed('D', (1,), math.nan), 'D holds NaN'),
    (changed('R', (0, 1), math.nan), 'R holds NaN'),
    (changed('R', (0, 1), 0.5), 'R is not a rotation'),
    (replace(RIGHT, D=np.zeros(7)), 'D has 7 coefficients; plumb_bob takes 0 or 4 or 5'),
    (replace(RIGHT, distortion_model='rational_polynomial'), 'rational_polynomial takes 0 or 8'),
    (replace(RIGHT, distortion_model='fisheye62'), "distortion model 'fisheye62' is not one"),
    (changed('P', (0, 0), 0.0), 'projection focal lengths'),
    (changed('K', (1, 1), -1.0), 'focal lengths'),
    (changed('K', (0, 2), 5000.0), 'K principal point'),
    (changed('P', (1, 2), -3.0), 'P principal point'),
    (changed('K', (2, 2), 2.0), 'last row'),
    (replace(RIGHT, binning_x=2, binning_y=2), 'binning 2x2 is not supported'),
    (replace(RIGHT, roi=(10, 10, 100, 100)), 'ROI (10, 10, 100, 100)'),
    (replace(RIGHT, width=40000, height=8), 'a side above 32767'),
    (replace(RIGHT, K=np.zeros((2, 2))), 'K has shape'),
])
def test_unusable_calibrations_are_named(calibration, message):
    problem = calibration.problem()
    assert problem is not None and message in problem, problem
    stereo = StereoCalibration(LEFT, calibration).problem()
    assert stereo is not None and stereo.startswith('right camera_info: ')


def test_a_full_image_roi_and_binning_one_are_accepted():
    assert replace(RIGHT, roi=(0, 0, RIGHT.width, RIGHT.height), binning_x=1,
                   binning_y=1).problem() is None


NUMBERS = st.floats(allow_nan=True, allow_infinity=True) | st.sampled_from(
    [0.0, -1.0, 1e-300, 1e300, 320.0, 640.0, 641.0])


@settings(max_examples=300, deadline=None)
@given(st.sampled_from(['K', 'D', 'R', 'P']), st.integers(0, 11), NUMBERS,
       st.sampled_from(['plumb_bob', 'rational_polynomial', 'equidistant', '', 'x']),
       st.integers(0, 8))
def test_any_calibration_is_refused_with_a_reason_or_can_be_rectified(name, flat_index, value,
                                                                     model, d_length):
    matrix = np.array(getattr(RIGHT, name), dtype=float)
    if name == 'D':
        matrix = np.zeros(d_length)
    if matrix.size:
        matrix.flat[flat_index % matrix.size] = value
    calibration = replace(RIGHT, **{name: matrix}, distortion_model=model or 'plumb_bob')
    problem = calibration.problem()
    if problem is not None:
        assert isinstance(problem, str) and problem
        return
    maps = rectification_maps(calibration)  # OpenCV must accept what problem() accepts
    if maps.map_x is not None:
        assert maps.map_x.shape[:2] == (calibration.height, calibration.width)
