"""A plain top's height from where its plain region lies in the right image. ROS-free.

A top without texture is matched only near its rim, where a correlation window takes in the
table's texture beyond the rim and with it the table's disparity, and inside it on sensor noise:
its matched heights scatter by millimetres and their median is not the top's. The plain region
itself (face_outline.plain_face_from_image) is seen by both cameras, and its outline is the
top's rim in both: each height of a plane parallel to the work surface maps the left image's
pixels to the right image's (the plane's disparity), and at the top's height the region's rim
in the left image falls on its rim in the right one.

So the height is searched: along a band across the region's outline in the left image, each
pixel's membership in the region's grey (a Gaussian of its distance from the face's grey, in
units of the tolerance that found the region) is compared with the membership of the right
image's pixel the plane maps it to (the right grey: the median the region's inside maps to,
the tolerance scaled by the two images' contrast: the right camera has its own gain). The
height whose memberships correlate best is the top's, refined by a parabola; a peak that is
weak or not clearly above every other height far from it gives no height.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np
from scipy import ndimage

from stereo_fuzzy_perception.core.best_point.work_surface import SurfacePlane
from stereo_fuzzy_perception.core.camera_model import CameraCalibration
from stereo_fuzzy_perception.core.matched_points import RectifiedImage

BAND_PX = 3
"""The band compared lies within this of the region's outline, inside and outside [px]."""

SMOOTHING_SIGMA_PX = 1.0
"""Gaussian smoothing of both images before the memberships (as face_outline's)."""

DISPARITY_STEP_PX = 0.1
"""Spacing of the heights tried, in the disparity they give at the region's centre [px]."""

MIN_PEAK = 0.6
"""Lowest correlation of the memberships at the top's height."""

MIN_MARGIN = 0.15
"""The peak stands at least this far above the best height that moves the region by more than
FAR_PX in the right image: a region whose rim the right image shows nowhere or everywhere
(a plain table, a side wall of the top's grey) has no such peak."""

FAR_PX = 1.5
"""Heights whose disparity at the region's centre differs from the peak's by more than this
are other heights [px]."""

LEVEL_SAMPLES = 500
"""At most this many of the region's inside pixels, evenly spread, give its grey in the right
image at each height: a median, it needs no more, and the search tries hundreds of heights."""


@dataclass(frozen=True)
class PlainTopHeight:
    """The height found and how clearly.

    Attributes:
        height_m: Height of the top above the work surface [m].
        peak: Correlation of the memberships at that height.
        margin: How far the peak stands above the best height far from it.
    """

    height_m: float
    peak: float
    margin: float


def plain_top_height(outline: np.ndarray, grey: float, tolerance: float,
                     left_image: RectifiedImage, right_image: RectifiedImage,
                     left: CameraCalibration, right: CameraCalibration,
                     world_from_camera: np.ndarray, surface: SurfacePlane,
                     max_height_m: float) -> PlainTopHeight | None:
    """Return the height of the plain top whose outline is given, or None.

    Args:
        outline: (K, 2) convex outline of the plain region in the left rectified image [px].
        grey: The region's grey level in the left image (smoothed as here).
        tolerance: The grey levels from `grey` that found the region.
        left_image: The part of the left rectified image the matcher read.
        right_image: The part of the right rectified image the matcher read.
        left: Rectified calibration of the left image.
        right: Rectified calibration of the right image.
        world_from_camera: 4x4 pose of the left optical frame in `world`.
        surface: The work surface the height is measured from.
        max_height_m: Highest top tried [m].

    Returns:
        The height, or None when the band leaves either image or no clear peak shows it.
    """
    alignment = RimAlignment.of(outline, grey, tolerance, left_image, right_image, left, right,
                                world_from_camera, surface)
    if alignment is None:
        return None
    centre = alignment.centre
    to_right = alignment.to_right
    span = to_right(centre[0], centre[1], 0.0) - to_right(centre[0], centre[1], max_height_m)
    count = int(min(2000, max(3, math.ceil(abs(float(span[0])) / DISPARITY_STEP_PX) + 1)))
    heights = np.linspace(0.0, max_height_m, count)
    scores = alignment.scores(heights)
    centre_columns = to_right(np.full(count, centre[0, 0]), np.full(count, centre[1, 0]),
                              heights)
    height, peak, margin = score_peak(scores, heights, centre_columns, FAR_PX)
    if peak < MIN_PEAK or margin < MIN_MARGIN:
        return None
    return PlainTopHeight(height, peak, margin)


def score_peak(scores: np.ndarray, heights: np.ndarray, centre_columns: np.ndarray,
               far_px: float) -> tuple[float, float, float]:
    """Return the best-scoring height (refined by a parabola through its neighbours), its
    score, and how far that stands above the best score of the heights whose column at the
    region's centre (centre_columns, one per height) lies more than far_px from the peak's."""
    best = int(np.argmax(scores))
    peak = float(scores[best])
    far = np.abs(centre_columns - centre_columns[best]) > far_px
    margin = peak - float(np.max(scores[far])) if np.any(far) else peak
    height = float(heights[best])
    if 0 < best < len(heights) - 1:
        before, after = scores[best - 1], scores[best + 1]
        curvature = before - 2.0 * peak + after
        if curvature < 0.0:
            height += 0.5 * (before - after) / curvature * float(heights[1] - heights[0])
    return height, peak, margin


@dataclass(frozen=True)
class RimAlignment:
    """How well a plain region's rim in the left image falls on its rim in the right one, for
    the region on a plane parallel to the surface at a given height: the correlation of the
    band's memberships in the region's grey (the module's docstring)."""

    band_u: np.ndarray
    band_v: np.ndarray
    inside_u: np.ndarray  # at most LEVEL_SAMPLES of them
    inside_v: np.ndarray
    left_member: np.ndarray  # the band's memberships in the left image, less their mean
    right_smooth: np.ndarray
    right_tolerance: float
    right_image: RectifiedImage
    to_right: Callable[[np.ndarray, np.ndarray, float | np.ndarray], np.ndarray]
    centre: np.ndarray  # (2, 1) the inside's mean pixel (column, row)

    @staticmethod
    def of(outline: np.ndarray, grey: float, tolerance: float, left_image: RectifiedImage,
           right_image: RectifiedImage, left: CameraCalibration, right: CameraCalibration,
           world_from_camera: np.ndarray, surface: SurfacePlane,
           away_from: np.ndarray | None = None) -> RimAlignment | None:
        """Return the alignment of the region inside `outline` (as plain_top_height's
        arguments), or None when its band leaves the image or holds one grey only. With
        `away_from` (an outline inside it), only the part of the band further than BAND_PX
        from that outline's own band counts: the part of the rim the smaller region does
        not share."""
        band_u, band_v, inside_u, inside_v = _band(outline, left_image)
        if away_from is not None and len(band_u):
            contour = np.asarray(away_from, dtype=np.float32).reshape(-1, 1, 2)
            apart = np.array([abs(cv2.pointPolygonTest(contour, (float(u), float(v)), True))
                              for u, v in zip(band_u, band_v, strict=True)]) > 2 * BAND_PX
            band_u, band_v = band_u[apart], band_v[apart]
        if len(band_u) < 20 or len(inside_u) < 10:
            return None
        left_smooth = cv2.GaussianBlur(left_image.pixels.astype(np.float32), (0, 0),
                                       SMOOTHING_SIGMA_PX)
        right_smooth = cv2.GaussianBlur(right_image.pixels.astype(np.float32), (0, 0),
                                        SMOOTHING_SIGMA_PX)
        tolerance = max(float(tolerance), 1e-6)
        left_member = np.exp(-0.5 * ((left_smooth[band_v - left_image.y, band_u - left_image.x]
                                      - grey) / tolerance) ** 2)
        left_member -= left_member.mean()
        if not np.any(left_member):
            return None
        right_tolerance = tolerance * _contrast(right_smooth) / max(_contrast(left_smooth), 1e-6)
        centre = np.array([[float(np.mean(inside_u))], [float(np.mean(inside_v))]])
        every = max(1, len(inside_u) // LEVEL_SAMPLES)
        return RimAlignment(band_u, band_v, inside_u[::every], inside_v[::every], left_member,
                            right_smooth, right_tolerance, right_image,
                            plane_disparity(left, right, world_from_camera, surface), centre)

    def scores(self, heights: np.ndarray) -> np.ndarray:
        """Return the correlation at each height [m] above the surface, -1 where the band or
        the inside leaves the right image."""
        scores = np.full(len(heights), -1.0)
        for index, height in enumerate(heights):
            band_right = self.to_right(self.band_u, self.band_v, height)
            inside_right = self.to_right(self.inside_u, self.inside_v, height)
            if not (inside_part(band_right, self.band_v, self.right_image)
                    and inside_part(inside_right, self.inside_v, self.right_image)):
                continue
            level = float(np.median(sample_rows(self.right_smooth, inside_right,
                                                self.inside_v, self.right_image)))
            member = np.exp(-0.5 * ((sample_rows(self.right_smooth, band_right, self.band_v,
                                                 self.right_image) - level)
                                    / self.right_tolerance) ** 2)
            member -= member.mean()
            norm = float(np.linalg.norm(member) * np.linalg.norm(self.left_member))
            if norm > 0.0:
                scores[index] = float(member @ self.left_member) / norm
        return scores


def _band(outline: np.ndarray, image: RectifiedImage
          ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Return the band's pixels across the outline and the pixels inside it (columns, rows,
    columns, rows) in rectified image coordinates; none when the band reaches the image part's
    edge, where the dilation was cut."""
    mask = np.zeros(image.pixels.shape[:2], np.uint8)
    local = np.round((np.asarray(outline, dtype=float) - (image.x, image.y))
                     * 16.0).astype(np.int32)
    cv2.fillConvexPoly(mask, local, 1, shift=4)
    disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * BAND_PX + 1, 2 * BAND_PX + 1))
    inner = cv2.erode(mask, disc) > 0
    band = (cv2.dilate(mask, disc) > 0) & ~inner
    if band[0].any() or band[-1].any() or band[:, 0].any() or band[:, -1].any():
        nothing = np.zeros(0, dtype=int)
        return nothing, nothing, nothing, nothing
    band_v, band_u = np.nonzero(band)
    inside_v, inside_u = np.nonzero(inner)
    return band_u + image.x, band_v + image.y, inside_u + image.x, inside_v + image.y


def _contrast(pixels: np.ndarray) -> float:
    """Return the interquartile range of an image's grey levels."""
    low, high = np.percentile(pixels, [25.0, 75.0])
    return float(high - low)


def plane_disparity(left: CameraCalibration, right: CameraCalibration,
                    world_from_camera: np.ndarray, surface: SurfacePlane
                    ) -> Callable[[np.ndarray, np.ndarray, float | np.ndarray], np.ndarray]:
    """Return f(u, v, height) -> the right image's column of each left pixel (u, v) on the plane
    parallel to the surface at that height, one height or one per pixel (the rays cut as in
    face_outline.on_top_plane)."""
    pose = np.asarray(world_from_camera, dtype=float)
    to_world = pose[:3, :3] @ np.asarray(left.R, dtype=float).reshape(3, 3).T @ np.linalg.inv(
        np.asarray(left.P, dtype=float)[:3, :3])
    normal = surface.normal
    facing_of = normal @ to_world  # n . ray = facing_of @ (u, v, 1)
    centre_level = float(normal @ pose[:3, 3])
    baseline_term = -float(np.asarray(right.P, dtype=float)[0, 3])
    shift = float(left.P[0, 2] - right.P[0, 2])

    def column(u: np.ndarray, v: np.ndarray, height: float | np.ndarray) -> np.ndarray:
        facing = facing_of[0] * u + facing_of[1] * v + facing_of[2]
        depth = (height + surface.offset_m * float(normal[2]) - centre_level) / facing
        result: np.ndarray = u - shift - baseline_term / depth
        return result

    return column


def inside_part(columns: np.ndarray, rows: np.ndarray, image: RectifiedImage) -> bool:
    """Return True when every (column, row) lies inside the image part, a pixel from its
    edges."""
    height, width = image.pixels.shape[:2]
    return bool(np.all(columns >= image.x + 1) and np.all(columns <= image.x + width - 2)
                and np.all(rows >= image.y) and np.all(rows <= image.y + height - 1))


def sample_rows(pixels: np.ndarray, columns: np.ndarray, rows: np.ndarray,
                image: RectifiedImage) -> np.ndarray:
    """Return the pixels at (column, row) of the image part, bilinear along the rows."""
    sampled: np.ndarray = ndimage.map_coordinates(
        pixels, [np.asarray(rows, dtype=float) - image.y,
                 np.asarray(columns, dtype=float) - image.x], order=1, mode='nearest')
    return sampled
