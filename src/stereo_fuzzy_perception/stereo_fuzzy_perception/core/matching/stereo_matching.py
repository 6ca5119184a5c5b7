"""The correlation stage in one call: rectify, match (Eqs. 7-8), triangulate (Eq. 1).

correlation_node calls `StereoMatchingPipeline.process` once per pair and the benchmark times
the same call. ROS-free: numpy, OpenCV and the matcher's C kernel only.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from stereo_fuzzy_perception.core.camera_model import StereoCalibration
from stereo_fuzzy_perception.core.matched_points import MatchedPoints
from stereo_fuzzy_perception.core.matching.rectification import StereoRectifier
from stereo_fuzzy_perception.core.matching.triangulation import triangulate
from stereo_fuzzy_perception.core.matching.window_matcher import DisparityMap, MatcherConfig, match


@dataclass(frozen=True)
class StereoMatchResult:
    """Everything the correlation stage produces for one pair.

    Attributes:
        rectified: Calibration of the rectified images (K = P[:3, :3], D = 0, R, P).
        disparity_map: Dense disparity [px], scores and status.
        points: Valid matches triangulated in the left camera's optical frame [m].
        timings_ms: Time of each step [ms]: rectify, match, triangulate.
    """

    rectified: StereoCalibration
    disparity_map: DisparityMap
    points: MatchedPoints
    timings_ms: dict[str, float] = field(default_factory=dict)


class StereoMatchingPipeline:
    """Rectify -> match -> triangulate, with rectification maps cached per calibration.

    The configuration can be replaced at any time (`config` is swapped atomically); a call in
    progress finishes with the configuration it started with.
    """

    def __init__(self, config: MatcherConfig | None = None, point_stride: int = 1,
                 threads: int | None = None) -> None:
        self.config = config or MatcherConfig()
        self.point_stride = point_stride
        self.threads = threads  # the matcher's threads; None = window_matcher.default_threads()
        self.rectifier = StereoRectifier()

    def process(self, left: np.ndarray, right: np.ndarray, calibration: StereoCalibration,
                full_disparity: bool = False) -> StereoMatchResult:
        """Match one raw grey pair.

        Args:
            left: Raw left grey image (H, W), uint8 or uint16.
            right: Raw right grey image (H, W).
            calibration: The pair's calibration (raw K, D, R, P).
            full_disparity: Decide every row of the disparity map. Otherwise only the rows the
                point stride keeps are decided (the others are SKIPPED_ROW), which saves most
                of the matching of the rows in between; the points are the same either way.

        Returns:
            The rectified calibration, the disparity map and the triangulated points.

        Raises:
            CalibrationError: Unusable calibration.
            RectificationError: An image size that differs from the calibration.
            MatcherInputError: Images the matcher cannot use (or an ROI outside them).
        """
        config, stride = self.config, self.point_stride
        start = time.perf_counter()
        left_rect, right_rect, rectified = self.rectifier.rectify(left, right, calibration)
        rectified_at = time.perf_counter()
        disparity_map = match(left_rect, right_rect, config,
                              row_step=1 if full_disparity else stride, threads=self.threads)
        matched_at = time.perf_counter()
        points = triangulate(disparity_map.disparity, disparity_map.score, rectified, stride)
        done = time.perf_counter()
        timings = {'rectify': 1e3 * (rectified_at - start),
                   'match': 1e3 * (matched_at - rectified_at),
                   'triangulate': 1e3 * (done - matched_at)}
        return StereoMatchResult(rectified, disparity_map, points, timings)
