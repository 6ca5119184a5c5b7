"""A plain OpenCV pipeline for the top-face centre: the reference every selector must beat.

    rectify (the project's StereoRectifier, same maps as the matcher)
      -> cv2.StereoSGBM (block 5, P1 = 8 b^2, P2 = 32 b^2, uniqueness 10, speckle filter,
         left-right check 1 px; the same disparity search as the matcher)
      -> triangulate every pixel (triangulation.triangulate) and move it to `world`
      -> height mask: inside the workspace box and more than `surface_margin_m` above the table
      -> largest 8-connected component of the mask in the image
      -> top band: the component's pixels within `top_band_m` of its 99th height percentile
      -> best point: mean x, y and median z of the band.

No fuzzy system, no learned parameters: what anyone would write with OpenCV in an afternoon.
ROS-free: numpy and OpenCV only.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from stereo_fuzzy_perception.core.camera_model import StereoCalibration
from stereo_fuzzy_perception.core.matching.rectification import StereoRectifier
from stereo_fuzzy_perception.core.matching.triangulation import triangulate
from stereo_fuzzy_perception.core.rig_geometry import transform_points


@dataclass
class OpenCvReference:
    """StereoSGBM + height mask + largest component + top band + centroid.

    Attributes:
        min_disparity: Smallest disparity searched [px].
        disparity_range: Disparities searched [px] (rounded up to a multiple of 16 for SGBM).
        block_size: SGBM block side [px], odd.
        workspace_min: Lower corner of the workspace box in `world` [m].
        workspace_max: Upper corner [m].
        surface_margin_m: Points must be this far above the table [m].
        top_band_m: Band below the component's top that forms the top face [m].
        min_pixels: A component smaller than this gives no point.
    """

    min_disparity: int
    disparity_range: int
    block_size: int = 5
    workspace_min: tuple[float, float, float] = (0.0, 0.0, 0.0)
    workspace_max: tuple[float, float, float] = (0.40, 0.30, 0.20)
    surface_margin_m: float = 0.003
    top_band_m: float = 0.004
    min_pixels: int = 20

    def __post_init__(self) -> None:
        self._rectifier = StereoRectifier()
        block = self.block_size
        self._sgbm = cv2.StereoSGBM.create(
            minDisparity=self.min_disparity,
            numDisparities=16 * ((self.disparity_range + 15) // 16),
            blockSize=block, P1=8 * block * block, P2=32 * block * block,
            disp12MaxDiff=1, uniquenessRatio=10, speckleWindowSize=100, speckleRange=2)

    def disparity(self, left_rectified: np.ndarray, right_rectified: np.ndarray) -> np.ndarray:
        """Return SGBM's disparity [px] of a rectified grey pair, NaN where it has none."""
        raw = self._sgbm.compute(left_rectified, right_rectified).astype(np.float32) / 16.0
        raw[raw < self.min_disparity] = np.nan
        return raw

    def best_point(self, left: np.ndarray, right: np.ndarray, calibration: StereoCalibration,
                   world_from_camera: np.ndarray) -> np.ndarray | None:
        """Return the top-face centre in `world` [m] of a raw grey pair, or None.

        Args:
            left: Raw left grey image.
            right: Raw right grey image.
            calibration: The pair's calibration (raw K, D, R, P).
            world_from_camera: 4x4 pose of the left optical frame in `world`.
        """
        left_rect, right_rect, rectified = self._rectifier.rectify(left, right, calibration)
        disparity = self.disparity(left_rect, right_rect)
        points = triangulate(disparity, np.ones_like(disparity), rectified)
        if not len(points):
            return None
        world = transform_points(world_from_camera, points.xyz.astype(float))
        low, high = np.array(self.workspace_min), np.array(self.workspace_max)
        inside = np.all((world >= low) & (world <= high), axis=1)
        inside &= world[:, 2] > self.surface_margin_m
        mask = np.zeros(disparity.shape, dtype=np.uint8)
        rows, columns = points.v_left.astype(int), points.u_left.astype(int)
        mask[rows[inside], columns[inside]] = 1
        count, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
        if count < 2:
            return None
        largest = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
        if stats[largest, cv2.CC_STAT_AREA] < self.min_pixels:
            return None
        in_component = inside & (labels[rows, columns] == largest)
        heights = world[in_component, 2]
        top = float(np.percentile(heights, 99))
        band = world[in_component][heights >= top - self.top_band_m]
        return np.array([band[:, 0].mean(), band[:, 1].mean(), float(np.median(band[:, 2]))])


__all__ = ['OpenCvReference']
