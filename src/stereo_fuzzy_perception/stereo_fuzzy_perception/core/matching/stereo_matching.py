"""The correlation stage in one call: rectify, match (Eqs. 7-8), triangulate (Eq. 1).

correlation_node calls `StereoMatchingPipeline.process` once per pair and the benchmark times
the same call. ROS-free: numpy, OpenCV and the matcher's C kernel only.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field

import numpy as np

from stereo_fuzzy_perception.core.camera_model import StereoCalibration
from stereo_fuzzy_perception.core.matched_points import MatchedPoints, RectifiedImage
from stereo_fuzzy_perception.core.matching.area_search import SearchRegion, region_problem
from stereo_fuzzy_perception.core.matching.rectification import (
    RectificationError,
    StereoRectifier,
)
from stereo_fuzzy_perception.core.matching.triangulation import triangulate
from stereo_fuzzy_perception.core.matching.window_matcher import (
    DisparityMap,
    MatcherConfig,
    match,
    pixels_read,
)


@dataclass(frozen=True)
class StereoMatchResult:
    """Everything the correlation stage produces for one pair.

    Attributes:
        rectified: Calibration of the rectified images (K = P[:3, :3], D = 0, R, P).
        disparity_map: Dense disparity [px], scores and status.
        points: Valid matches triangulated in the left camera's optical frame [m].
        timings_ms: Time of each step [ms]: rectify, match, triangulate (and, when a search
            region failed its check, `region` for the matching in it).
        region: The search region the result comes from; None for the whole image.
        region_problem: Why the search region asked for was not kept (area_search's
            region_problem), '' when it was kept or none was asked for.
        point_stride: Every point_stride-th row and column of the matches was triangulated.
    """

    rectified: StereoCalibration
    disparity_map: DisparityMap
    points: MatchedPoints
    timings_ms: dict[str, float] = field(default_factory=dict)
    region: SearchRegion | None = None
    region_problem: str = ''
    point_stride: int = 1


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
                full_disparity: bool = False,
                region: SearchRegion | None = None) -> StereoMatchResult:
        """Match one raw grey pair.

        Args:
            left: Raw left grey image (H, W), uint8 or uint16.
            right: Raw right grey image (H, W).
            calibration: The pair's calibration (raw K, D, R, P).
            full_disparity: Decide every row of the disparity map. Otherwise only the rows the
                point stride keeps are decided (the others are SKIPPED_ROW), which saves most
                of the matching of the rows in between; the points are the same either way.
            region: Match only in this region (area_search.search_region): only the pixels its
                windows read are rectified, only its disparities searched. When the result
                fails the region's check (area_search.region_problem), the pair is matched
                again on the whole image (rectifying only what the region did not) and
                `region_problem` says why.

        Returns:
            The rectified calibration, the disparity map and the triangulated points.

        Raises:
            CalibrationError: Unusable calibration.
            RectificationError: An image size that differs from the calibration.
            MatcherInputError: Images the matcher cannot use (or an ROI outside them).
        """
        config, stride = self.config, self.point_stride
        row_step = 1 if full_disparity else stride
        start = time.perf_counter()
        timings: dict[str, float] = {}
        problem = ''
        if region is not None:
            narrowed = dataclasses.replace(config, roi=region.roi,
                                           min_disparity=region.min_disparity,
                                           disparity_range=region.disparity_range)
            left_rect, right_rect, rectified = self._rectify(left, right, calibration,
                                                             narrowed)
            rectified_at = time.perf_counter()
            disparity_map = match(left_rect, right_rect, narrowed, row_step=row_step,
                                  threads=self.threads)
            matched_at = time.perf_counter()
            problem = region_problem(disparity_map, region, stride) or ''
            if not problem:
                return self._finish(rectified, disparity_map, start, rectified_at, matched_at,
                                    timings, _parts_read(left_rect, right_rect, narrowed,
                                                         calibration), stride, region)
            timings['region'] = 1e3 * (time.perf_counter() - start)
            start = time.perf_counter()
        # after a region, only what its rectification did not cover
        left_rect, right_rect, rectified = self._rectify(left, right, calibration, config,
                                                         continued=region is not None)
        rectified_at = time.perf_counter()
        disparity_map = match(left_rect, right_rect, config, row_step=row_step,
                              threads=self.threads)
        matched_at = time.perf_counter()
        return self._finish(rectified, disparity_map, start, rectified_at, matched_at, timings,
                            _parts_read(left_rect, right_rect, config, calibration), stride,
                            None, problem)

    def colour_parts(self, left: np.ndarray, right: np.ndarray | None,
                     calibration: StereoCalibration, points: MatchedPoints) -> None:
        """Give `points` (a result's) the raw colour images rectified as the grey ones were,
        each cut to the part of it the matcher read (points.left_image, points.right_image):
        the fuzzy stage takes the object's silhouette from the left one and the height of its
        rim from both (colour_silhouette.py).

        Raises:
            RectificationError: A colour image of another size than its calibration's.
        """
        maps = self.rectifier.maps(calibration)
        for side, colour, part, rectify in (('left', left, points.left_image, maps[0]),
                                            ('right', right, points.right_image, maps[1])):
            if colour is None or part is None:
                continue
            camera = calibration.left if side == 'left' else calibration.right
            height, width = colour.shape[:2]
            if (width, height) != (camera.width, camera.height):
                raise RectificationError(
                    f'{side} colour image is {width}x{height} but its calibration is '
                    f'{camera.width}x{camera.height}')
            rectified = rectify.apply(colour)
            rows, columns = part.pixels.shape[:2]
            setattr(points, f'{side}_colour', RectifiedImage(np.ascontiguousarray(
                rectified[part.y:part.y + rows, part.x:part.x + columns]), part.x, part.y,
                part.window_size))

    def _rectify(self, left: np.ndarray, right: np.ndarray, calibration: StereoCalibration,
                 config: MatcherConfig, continued: bool = False
                 ) -> tuple[np.ndarray, np.ndarray, StereoCalibration]:
        """Rectify the pixels a match with `config` reads (window_matcher.pixels_read).

        Only rows are left out unless both images are 8-bit, for which the matcher's sums are
        exact whatever the columns it does not read hold.
        """
        self.rectifier.check_sizes(left, right, calibration)  # before the region's bounds
        read = pixels_read(config, calibration.left.width, calibration.left.height)
        if left.dtype == np.uint8 and right.dtype == np.uint8:
            columns = (read.left_columns, read.right_columns)
        else:
            whole = (0, calibration.left.width)
            columns = (whole, whole)
        return self.rectifier.rectify_part(left, right, calibration, read.rows, columns,
                                           continued)

    def _finish(self, rectified: StereoCalibration, disparity_map: DisparityMap, start: float,
                rectified_at: float, matched_at: float, timings: dict[str, float],
                images: tuple[RectifiedImage, RectifiedImage], stride: int,
                region: SearchRegion | None, problem: str = ''
                ) -> StereoMatchResult:
        """Triangulate every stride-th row and column and return the result with the steps'
        times."""
        points = triangulate(disparity_map.disparity, disparity_map.score, rectified, stride)
        points.left_image, points.right_image = images
        done = time.perf_counter()
        timings.update(rectify=1e3 * (rectified_at - start),
                       match=1e3 * (matched_at - rectified_at),
                       triangulate=1e3 * (done - matched_at))
        return StereoMatchResult(rectified, disparity_map, points, timings, region, problem,
                                 stride)


def _parts_read(left_rect: np.ndarray, right_rect: np.ndarray, config: MatcherConfig,
                calibration: StereoCalibration) -> tuple[RectifiedImage, RectifiedImage]:
    """Return copies of the parts of the left and right rectified images that a match with
    config read (the rectifier's buffers hold other pairs' pixels elsewhere and are reused)."""
    read = pixels_read(config, calibration.left.width, calibration.left.height)
    (top, bottom) = read.rows

    def part(image: np.ndarray, columns: tuple[int, int]) -> RectifiedImage:
        return RectifiedImage(image[top:bottom, columns[0]:columns[1]].copy(), columns[0], top,
                              config.window_size)

    return part(left_rect, read.left_columns), part(right_rect, read.right_columns)
