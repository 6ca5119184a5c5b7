"""Odd image shapes through the correlation stage: a result or a named error, never another.

Issue #15 item 9: 40000 x 8 images ended as an 'internal' drop with an OpenCV traceback. Now
sizes OpenCV cannot remap are refused by CameraCalibration.problem(), and for any small shape,
calibration distortion and matcher window the pipeline returns points or raises one of the
errors correlation_node maps to its own drop reason (calibration, size_mismatch,
matcher_input, opencv), never another exception (which would be 'internal').
"""

from __future__ import annotations

import cv2
import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from stereo_fuzzy_perception.core.camera_model import (
    CalibrationError,
    CameraCalibration,
    StereoCalibration,
)
from stereo_fuzzy_perception.core.matching.rectification import RectificationError
from stereo_fuzzy_perception.core.matching.stereo_matching import StereoMatchingPipeline
from stereo_fuzzy_perception.core.matching.window_matcher import (
    MatcherConfig,
    MatcherInputError,
)

NAMED_ERRORS = (CalibrationError, RectificationError, MatcherInputError, cv2.error)


def camera(width: int, height: int, distortion: float, tx: float) -> CameraCalibration:
    K = np.array([[50.0, 0.0, width / 2], [0.0, 50.0, height / 2], [0.0, 0.0, 1.0]])
    return CameraCalibration(width=width, height=height, K=K,
                             D=np.array([distortion, 0.0, 0.0, 0.0, 0.0]),
                             P=np.hstack([K, [[tx], [0.0], [0.0]]]))


def test_a_side_beyond_opencvs_remap_limit_is_a_calibration_error():
    calibration = StereoCalibration(camera(40000, 8, 0.1, 0.0), camera(40000, 8, 0.1, -5.0))
    assert 'a side above 32767' in (calibration.problem() or '')


@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(1, 48), st.integers(1, 48), st.sampled_from([0.0, 0.1, -0.3]),
       st.sampled_from([3, 5, 9, 31]), st.integers(1, 64), st.booleans())
def test_any_small_shape_gives_points_or_a_named_error(width, height, distortion, window,
                                                       disparities, same_size):
    rng = np.random.default_rng(width * 100 + height)
    left = rng.integers(0, 255, (height, width), dtype=np.uint8)
    right = left if same_size else rng.integers(0, 255, (height + 1, width), dtype=np.uint8)
    calibration = StereoCalibration(camera(width, height, distortion, 0.0),
                                    camera(width, height, distortion, -5.0))
    pipeline = StereoMatchingPipeline(MatcherConfig(window_size=window,
                                                    disparity_range=disparities))
    try:
        calibration.require_valid()
        if left.shape != right.shape:
            raise RectificationError('sizes differ')  # what correlation_node checks first
        result = pipeline.process(left, right, calibration)
    except NAMED_ERRORS:
        return
    assert np.all(np.isfinite(result.points.xyz))
