"""A face in pieces matched again on its own plane (step 1, after every other look). ROS-free.

A top printed with stripes, a wood grain or a woven fabric repeats itself every few pixels.
The matcher searches the whole disparity range of the workspace and, on such a top, often
finds its best score a period or two away from the true disparity: those matches stand far
above or below the top, fail the left-right check, or are left out as higher than any object,
and what stays on the top is a face in pieces (correlation_area.py refuses it: its matches
fill less than min_top_fill of its outline). The pieces that stay say where the top is,
though: a plane parallel to the surface at the pieces' height. So, for a pair refused after
every other look whose matches made a face in pieces:

1. Each pixel of the matches' grid inside the pieces' convex hull is matched again with the
   matcher's correlation (Eq. 8, zero-mean normalised, the matcher's window), only at the
   right image's columns near where the pieces' plane puts it: nearer than the repeat of
   such a texture, so the period the pieces chose is the only one in reach.
2. A pixel takes the new match where the correlation peaks within SEARCH_PX of the plane's
   column, higher than a pixel further out on either side (a best at the search's end says
   the true disparity lies beyond it), with at least MIN_SCORE, refined by a parabola like
   the matcher's, and triangulated like the matcher's points.
   Pieces whose hull covers less of the image than any object's top (MIN_OBJECT_AREA_PX)
   are not matched again: no top is made whole from them (on a bare wood table a blob of
   matches a repeat off, its hull 120 px², was confirmed at 59 mm).
3. The pair's matches with those pixels replaced are looked at again from the start
   (point_selectors.decision_area). The new matches are not taken on trust: a face that
   passes every test with them is the top, and one that does not stays refused. Where the
   pieces' height was not the top's, the search around it peaks at its ends or scores low,
   and the face stays in pieces.

What it changes, measured on the tuning splits: benchmarks/EXPERIMENTS.md (twenty-seventh
session). ROS-free: numpy and OpenCV.
"""

from __future__ import annotations

import cv2
import numpy as np

from stereo_fuzzy_perception.core.best_point.correlation_area import (
    MIN_OBJECT_AREA_PX,
    CorrelationArea,
)
from stereo_fuzzy_perception.core.best_point.object_segmentation import grid_step
from stereo_fuzzy_perception.core.best_point.plain_top_height import _plane_disparity
from stereo_fuzzy_perception.core.camera_model import CameraCalibration
from stereo_fuzzy_perception.core.matched_points import MatchedPoints, RectifiedImage

SEARCH_PX = 1
"""A pixel takes a new match only where its correlation peaks at a whole column within this
of where the pieces' plane puts it, higher than at the columns a pixel further on either side
[px]: the plane's disparity is known to about a pixel, and a peak further away belongs to
another repeat of the texture or to another surface."""

MIN_SCORE = 0.5
"""Lowest correlation a pixel's new match may have."""

DEFAULT_WINDOW = 9
"""The correlation window's side when the images do not say the matcher's [px]."""


def face_matched_again(pieces: CorrelationArea, points: MatchedPoints,
                       left: CameraCalibration, right: CameraCalibration,
                       world_from_camera: np.ndarray) -> MatchedPoints | None:
    """Return the pair's matches with the pixels inside the pieces' hull matched again around
    the pieces' plane, or None when nothing could be matched again.

    Args:
        pieces: The face in pieces (CorrelationArea.face_in_pieces): its pixels, top height
            and the surface it stands on.
        points: The pair's matches, with both rectified images (left_image, right_image).
        left: Rectified calibration of the left image.
        right: Rectified calibration of the right image.
        world_from_camera: 4x4 pose of the left optical frame in `world`.
    """
    left_image, right_image = points.left_image, points.right_image
    if (left_image is None or right_image is None or len(pieces.u_left) < 3
            or left_image.pixels.ndim != 2 or right_image.pixels.ndim != 2):
        return None
    step = grid_step(points.u_left, points.v_left)
    inside = _grid_inside(pieces, points, step)
    if len(inside[0]) * step ** 2 < MIN_OBJECT_AREA_PX:
        return None  # pieces spread over less than any object's top: no top to make whole
    on_plane = _PlaneMatcher(pieces, left_image, right_image, left, right, world_from_camera)
    columns, rows, right_columns, scores = on_plane.matched(*inside)
    if not len(columns):
        return None
    xyz = _triangulated(columns, rows, right_columns, left, right)
    replaced = set(zip(np.rint(columns).astype(int).tolist(), np.rint(rows).astype(int).tolist(),
                       strict=True))
    kept = np.array([(int(round(u)), int(round(v))) not in replaced for u, v in
                     zip(points.u_left.tolist(), points.v_left.tolist(), strict=True)],
                    dtype=bool)

    def joined(old: np.ndarray, new: np.ndarray) -> np.ndarray:
        return np.concatenate([old[kept], new.astype(old.dtype)])

    return MatchedPoints(joined(points.xyz, xyz), joined(points.u_left, columns),
                         joined(points.v_left, rows), joined(points.u_right, right_columns),
                         joined(points.score, scores), left_image, right_image)


class _PlaneMatcher:
    """Left pixels matched on the plane parallel to the surface at the pieces' height."""

    def __init__(self, pieces: CorrelationArea, left_image: RectifiedImage,
                 right_image: RectifiedImage, left: CameraCalibration,
                 right: CameraCalibration, world_from_camera: np.ndarray) -> None:
        self.left_image, self.right_image = left_image, right_image
        self.half = (left_image.window_size or DEFAULT_WINDOW) // 2
        self.to_right = _plane_disparity(left, right, world_from_camera, pieces.surface)
        self.height = pieces.top_height
        self.left_pixels = left_image.pixels.astype(np.float32)
        self.right_pixels = right_image.pixels.astype(np.float32)

    def matched(self, columns: np.ndarray, rows: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Return (columns, rows, right columns, scores) of the pixels that take a new match."""
        left_image, right_image, half = self.left_image, self.right_image, self.half
        expected = np.rint(self.to_right(columns, rows, self.height)).astype(np.int64)
        left_u = columns.astype(np.int64) - left_image.x
        left_v = rows.astype(np.int64) - left_image.y
        right_v = rows.astype(np.int64) - right_image.y
        right_u = expected - right_image.x
        reach = SEARCH_PX + 1
        height, width = left_image.pixels.shape
        right_height, right_width = right_image.pixels.shape
        usable = ((left_u >= half) & (left_u < width - half) & (left_v >= half)
                  & (left_v < height - half) & (right_v >= half)
                  & (right_v < right_height - half) & (right_u - reach >= half)
                  & (right_u + reach < right_width - half))
        columns, rows = columns[usable], rows[usable]
        left_u, left_v, right_u, right_v = (part[usable] for part in
                                            (left_u, left_v, right_u, right_v))
        offsets = np.arange(-reach, reach + 1)
        scores = np.stack([_correlation(self.left_pixels, self.right_pixels, left_u, left_v,
                                        right_u + offset, right_v, half)
                           for offset in offsets], axis=1).reshape(len(columns), len(offsets))
        # the best of all the columns scored, one beyond the search on either side: a best at
        # the search's end or beyond it says the true disparity lies further away
        best = np.argmax(scores, axis=1)
        index = np.arange(len(best))
        taken = (np.abs(offsets[best]) <= SEARCH_PX) & (scores[index, best] >= MIN_SCORE)
        best = np.clip(best, 1, len(offsets) - 2)
        peak, before, after = scores[index, best], scores[index, best - 1], scores[index, best + 1]
        curvature = before - 2.0 * peak + after
        shift = np.where(curvature < 0.0,
                         0.5 * (before - after) / np.where(curvature < 0.0, curvature, -1.0), 0.0)
        right_columns = (right_u + offsets[best] + right_image.x + shift).astype(float)
        return columns[taken], rows[taken], right_columns[taken], peak[taken]


def _grid_inside(pieces: CorrelationArea, points: MatchedPoints, step: float
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Return the matches' grid pixels (columns, rows) inside the pieces' convex hull."""
    origin_u, origin_v = float(points.u_left[0]), float(points.v_left[0])
    hull = cv2.convexHull(np.column_stack([pieces.u_left, pieces.v_left]).astype(np.float32))
    first_u = origin_u + np.ceil((float(pieces.u_left.min()) - origin_u) / step) * step
    first_v = origin_v + np.ceil((float(pieces.v_left.min()) - origin_v) / step) * step
    grid_u, grid_v = (grid.ravel() for grid in np.meshgrid(
        np.arange(first_u, float(pieces.u_left.max()) + 0.5, step),
        np.arange(first_v, float(pieces.v_left.max()) + 0.5, step)))
    inside = np.array([cv2.pointPolygonTest(hull, (float(u), float(v)), False) >= 0
                       for u, v in zip(grid_u, grid_v, strict=True)], dtype=bool)
    return grid_u[inside], grid_v[inside]


def _correlation(left: np.ndarray, right: np.ndarray, left_u: np.ndarray, left_v: np.ndarray,
                 right_u: np.ndarray, right_v: np.ndarray, half: int) -> np.ndarray:
    """Return the zero-mean normalised correlation of each left window with its right one
    (-1 where either is flat)."""
    offsets = np.arange(-half, half + 1)
    down, across = (grid.ravel() for grid in np.meshgrid(offsets, offsets, indexing='ij'))
    left_windows = left[left_v[:, None] + down, left_u[:, None] + across]
    right_windows = right[right_v[:, None] + down, right_u[:, None] + across]
    left_windows = left_windows - left_windows.mean(axis=1, keepdims=True)
    right_windows = right_windows - right_windows.mean(axis=1, keepdims=True)
    norm = np.sqrt((left_windows ** 2).sum(axis=1) * (right_windows ** 2).sum(axis=1))
    products = (left_windows * right_windows).sum(axis=1)
    correlation: np.ndarray = np.where(norm > 0.0, products / np.where(norm > 0.0, norm, 1.0),
                                       -1.0)
    return correlation


def _triangulated(columns: np.ndarray, rows: np.ndarray, right_columns: np.ndarray,
                  left: CameraCalibration, right: CameraCalibration) -> np.ndarray:
    """Return the (N, 3) points [m] in the left optical frame of rectified matches, as the
    matcher's triangulation makes them (matching/triangulation.py)."""
    left_p = np.asarray(left.P, dtype=float)
    right_p = np.asarray(right.P, dtype=float)
    depth = (left_p[0, 3] - right_p[0, 3]) / (columns - right_columns
                                              - (left_p[0, 2] - right_p[0, 2]))
    x = ((columns - left_p[0, 2]) * depth - left_p[0, 3]) / left_p[0, 0]
    y = (rows - left_p[1, 2]) * depth / left_p[1, 1]
    rectified = np.column_stack([x, y, depth])
    optical: np.ndarray = rectified @ np.asarray(left.R, dtype=float).reshape(3, 3)
    return optical
