"""Match where the object is: the previous decision's correlation area as the search region.

The chapter correlates only inside the correlation area (Fig. 2). Once the fuzzy stage has found
the object's top face, the next pairs need not be matched everywhere: the area's world points
(its border points, on the top face, and the work surface under it) are grown by a margin for
the object's size and motion into a box, and the box is projected into the left rectified image
(the region of interest) and into disparities (the search range):

* box: the border points' x-y extent grown on each side by `margin_object_sizes` times the
  object's extent (at least `margin_m`), from the measured surface under it (less
  SURFACE_BELOW_M) up to the top face plus the same margin;
* region: the bounding rectangle of the box's eight corners in the left rectified image;
* disparities: those of the box's corners and of the surface plane at the region's corners
  (for a plane, the disparity is affine in the rectified pixel, so its extremes over a
  rectangle lie at the corners), widened by MARGIN_PX.

A region is only trusted after the pair was matched in it (`region_problem`): the surface
disparity predicted from the decision's plane tells which matches stand out of the surface. If
some stand out in the region's outer ring (the object reaches past the region: it moved, or it
is another object), if matches pile up at the largest disparity searched (something taller
than the tracked object), if too few stand out inside (the object left) or if those that do
lie away from where the top face was (it moved), the pair is matched again on the whole image:
a wrong region costs time, not a wrong point.

Before the decision on a pair matched on the whole image arrives, `region_from_matches` finds
a region in that pair's own matches: those standing out of the surface plane the last region
knew (the work surface does not move when the object changes), when they form one object,
grown by the same margins. It is checked like any other region.

ROS-free: numpy and OpenCV only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from stereo_fuzzy_perception.core.camera_model import StereoCalibration
from stereo_fuzzy_perception.core.matching.disparity_range import MARGIN_PX, SURFACE_BELOW_M
from stereo_fuzzy_perception.core.matching.window_matcher import DisparityMap, MatchStatus

OBJECT_AT_EDGE = 'object_at_edge'
AT_DISPARITY_LIMIT = 'at_disparity_limit'
OBJECT_LOST = 'object_lost'
OBJECT_MOVED = 'object_moved'
REGION_PROBLEMS = (OBJECT_AT_EDGE, AT_DISPARITY_LIMIT, OBJECT_LOST, OBJECT_MOVED)

RING_PX = 6
"""Width of the region's outer ring in which no match may stand out of the surface [px]."""

EDGE_SHARE = 0.02
"""Largest share of the ring's matches that may stand out (mismatches, noise) [-]."""

EDGE_COUNT = 4
"""Standing matches in the ring tolerated whatever their share."""

FOUND_SHARE = 0.5
"""Smallest share of the top face's projected pixels (at the point stride) that must stand out
inside the region for the object to count as still there [-]."""

MOVED_SHARE = 1.0
"""Largest distance between the median of the standing matches and the top face's projected
centre, in the top face's projected extent [-]."""

STANDING_SHARE = 0.5
"""A match stands out of the surface when its disparity exceeds the surface's by this share of
the top face's excess (and by NOISE_SIGMAS of the surface noise) [-]."""

NOISE_SIGMAS = 3.0


class AreaProjectionError(ValueError):
    """A correlation area that gives no usable search region (behind or outside the cameras)."""


@dataclass(frozen=True)
class TrackedArea:
    """The correlation area of one decision, as the fuzzy stage measured it.

    Attributes:
        stamp_s: Stamp of the pair it was decided on [s].
        border_points: (4, 3) border points of the top face in world [m] (section 4.1).
        top_height_m: Top face above the measured surface [m].
        surface_point: A point of the work surface plane in world [m].
        surface_normal: Unit normal of the surface plane in world, pointing up.
        disparity_sigma_px: Disparity noise of the matches on the surface [px].
    """

    stamp_s: float
    border_points: np.ndarray
    top_height_m: float
    surface_point: tuple[float, float, float]
    surface_normal: tuple[float, float, float]
    disparity_sigma_px: float

    def problem(self) -> str | None:
        """Return why this area cannot be tracked, or None."""
        points = np.asarray(self.border_points, dtype=float)
        if points.shape != (4, 3) or not np.all(np.isfinite(points)):
            return 'border points are not four finite world points'
        normal = np.asarray(self.surface_normal, dtype=float)
        if not np.all(np.isfinite(normal)) or not 0.5 < float(np.linalg.norm(normal)) < 2.0:
            return f'surface normal {tuple(normal)} is not a unit vector'
        values = (self.top_height_m, self.disparity_sigma_px, *self.surface_point)
        if not all(math.isfinite(value) for value in values) or self.top_height_m <= 0.0:
            return 'top height, surface or noise not finite and positive'
        return None


@dataclass(frozen=True)
class SearchRegion:
    """Where and over which disparities a pair is matched, and how its result is checked.

    Attributes:
        roi: (x, y, width, height) [px] in the left rectified image.
        min_disparity: Smallest disparity searched [px].
        disparity_range: Number of disparities searched [px].
        surface_plane: (a, b, c): the surface's disparity at rectified (u, v) is a u + b v + c.
        standing_px: Disparity above the surface's from which a match stands out [px].
        top_face_px: Pixels of the top face projected into the left image [px^2].
        top_centre: (u, v) of the top face's projected centre [px].
        noise_px: Disparity above the surface's that only noise reaches (NOISE_SIGMAS of the
            surface noise) [px]; 0 when unknown.
    """

    roi: tuple[int, int, int, int]
    min_disparity: int
    disparity_range: int
    surface_plane: tuple[float, float, float]
    standing_px: float
    top_face_px: float
    top_centre: tuple[float, float] = (math.nan, math.nan)
    noise_px: float = 0.0


def _rectified_from_world(calibration: StereoCalibration,
                          world_from_camera: np.ndarray) -> np.ndarray:
    """Return the 4x4 left rectified frame <- world transform."""
    camera_from_world = np.linalg.inv(np.asarray(world_from_camera, dtype=float))
    rectify = np.eye(4)
    rectify[:3, :3] = np.asarray(calibration.left.R, dtype=float)
    transform: np.ndarray = rectify @ camera_from_world
    return transform


def _project(calibration: StereoCalibration, rectified: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return left u, v and the disparity [px] of (N, 3) points in the left rectified frame."""
    homogeneous = np.column_stack([rectified, np.ones(len(rectified))])
    left = homogeneous @ np.asarray(calibration.left.P, dtype=float).T
    right = homogeneous @ np.asarray(calibration.right.P, dtype=float).T
    u_left = left[:, 0] / left[:, 2]
    return u_left, left[:, 1] / left[:, 2], u_left - right[:, 0] / right[:, 2]


def surface_disparity_plane(calibration: StereoCalibration, rectified_from_world: np.ndarray,
                            point: np.ndarray, normal: np.ndarray
                            ) -> tuple[float, float, float]:
    """Return (a, b, c) with the plane's disparity at rectified pixel (u, v) = a u + b v + c.

    A plane n . X = e of the left rectified frame meets the ray (u - cx) / f, (v - cy) / fy, 1
    at depth Z = e / (n . ray), and d = shift + f B / Z is affine in (u, v).

    Raises:
        AreaProjectionError: When the plane passes through the camera.
    """
    rotation, translation = rectified_from_world[:3, :3], rectified_from_world[:3, 3]
    n = rotation @ normal
    e = float(n @ (rotation @ point + translation))
    if abs(e) < 1e-9:
        raise AreaProjectionError('the surface plane passes through the camera')
    left_p = np.asarray(calibration.left.P, dtype=float)
    right_p = np.asarray(calibration.right.P, dtype=float)
    f_baseline = left_p[0, 3] - right_p[0, 3]
    shift = left_p[0, 2] - right_p[0, 2]
    fx, fy, cx, cy = left_p[0, 0], left_p[1, 1], left_p[0, 2], left_p[1, 2]
    a = f_baseline * n[0] / (fx * e)
    b = f_baseline * n[1] / (fy * e)
    c = shift + f_baseline * (n[2] - n[0] * cx / fx - n[1] * cy / fy) / e
    return float(a), float(b), float(c)


def search_region(area: TrackedArea, calibration: StereoCalibration,
                  world_from_camera: np.ndarray, full_range: tuple[int, int],
                  margin_object_sizes: float, margin_m: float) -> SearchRegion:
    """Return the region and disparities in which the area's object is matched next.

    Args:
        area: The previous decision's correlation area.
        calibration: Rectified stereo calibration (R and P of both cameras).
        world_from_camera: 4x4 pose of the left camera's optical frame in world.
        full_range: (min_disparity, disparity_range) of a whole-image search [px]; the
            narrowed range stays inside it.
        margin_object_sizes: Margin on each side, in object extents [-].
        margin_m: Smallest margin on each side [m].

    Returns:
        The region, clipped to the image.

    Raises:
        AreaProjectionError: When the box is behind a camera, outside the image, or its
            disparities are outside the whole-image range.
    """
    points = np.asarray(area.border_points, dtype=float)
    low_xy, high_xy = points[:, :2].min(axis=0), points[:, :2].max(axis=0)
    extent = float(max(high_xy - low_xy))
    margin = max(margin_m, margin_object_sizes * extent)
    normal = np.asarray(area.surface_normal, dtype=float)
    normal = normal / np.linalg.norm(normal)
    surface_point = np.asarray(area.surface_point, dtype=float)
    xy = np.array([[x, y] for x in (low_xy[0] - margin, high_xy[0] + margin)
                   for y in (low_xy[1] - margin, high_xy[1] + margin)])
    # surface height under each corner: n . (p - p0) = 0
    surface_z = surface_point[2] - ((xy - surface_point[:2]) @ normal[:2]) / normal[2]
    top_z = float(points[:, 2].max()) + margin
    corners = np.vstack([np.column_stack([xy, surface_z - SURFACE_BELOW_M]),
                         np.column_stack([xy, np.full(4, top_z)])])
    transform = _rectified_from_world(calibration, world_from_camera)
    rectified = corners @ transform[:3, :3].T + transform[:3, 3]
    if np.any(rectified[:, 2] <= 1e-6):
        raise AreaProjectionError('the area is not in front of the left camera')
    u, v, disparity = _project(calibration, rectified)
    width, height = calibration.left.width, calibration.left.height
    x0, x1 = max(0, math.floor(u.min())), min(width, math.ceil(u.max()) + 1)
    y0, y1 = max(0, math.floor(v.min())), min(height, math.ceil(v.max()) + 1)
    if x1 - x0 < 2 or y1 - y0 < 2:
        raise AreaProjectionError('the area lies outside the left image')
    plane = surface_disparity_plane(calibration, transform, surface_point, normal)
    lowered = surface_disparity_plane(calibration, transform,
                                      surface_point - SURFACE_BELOW_M * normal, normal)
    region_corners = np.array([[x0, y0], [x1 - 1, y0], [x0, y1 - 1], [x1 - 1, y1 - 1]], float)
    surface = [a * region_corners[:, 0] + b * region_corners[:, 1] + c
               for a, b, c in (plane, lowered)]
    every = np.concatenate([disparity, *surface])
    full_low, full_count = full_range
    low = max(full_low, math.floor(float(every.min())) - MARGIN_PX)
    high = min(full_low + full_count - 1, math.ceil(float(every.max())) + MARGIN_PX)
    if high < low:
        raise AreaProjectionError(
            f"the area's disparities {every.min():.1f}..{every.max():.1f} px lie outside the "
            f'whole-image range {full_low}..{full_low + full_count - 1} px')
    top = points @ transform[:3, :3].T + transform[:3, 3]
    top_u, top_v, top_disparity = _project(calibration, top)
    excess = float(np.median(top_disparity - (plane[0] * top_u + plane[1] * top_v + plane[2])))
    noise = NOISE_SIGMAS * area.disparity_sigma_px
    standing = max(STANDING_SHARE * excess, noise)
    return SearchRegion((x0, y0, x1 - x0, y1 - y0), low, high - low + 1, plane, standing,
                        _quadrilateral_area(top_u, top_v),
                        (float(top_u.mean()), float(top_v.mean())), noise)


def _quadrilateral_area(u: np.ndarray, v: np.ndarray) -> float:
    """Return the area of the convex hull of four image points [px^2]."""
    centre_u, centre_v = float(u.mean()), float(v.mean())
    order = np.argsort(np.arctan2(v - centre_v, u - centre_u))
    u, v = u[order], v[order]
    return 0.5 * abs(float(np.dot(u, np.roll(v, -1)) - np.dot(v, np.roll(u, -1))))


def region_problem(disparity_map: DisparityMap, region: SearchRegion,
                   point_stride: int) -> str | None:
    """Return why the region did not hold the object in this pair's matches, or None.

    Args:
        disparity_map: The pair matched inside `region`.
        region: The region it was matched in.
        point_stride: Rows and columns the points keep (the decided ones at least).

    Returns:
        OBJECT_AT_EDGE when matches in the region's outer ring stand out of the surface,
        AT_DISPARITY_LIMIT when matches pile up at the largest disparity searched,
        OBJECT_LOST when too few stand out inside it, OBJECT_MOVED when those that do lie away
        from the top face's projected centre; None when the region holds the object.
    """
    x, y, width, height = region.roi
    # the rows and columns the points keep: multiples of the stride
    first_row, first_column = -(-y // point_stride) * point_stride, \
        -(-x // point_stride) * point_stride
    rows = np.arange(first_row, y + height, point_stride)
    columns = np.arange(first_column, x + width, point_stride)
    status = disparity_map.status[np.ix_(rows, columns)]
    disparity = disparity_map.disparity[np.ix_(rows, columns)]
    a, b, c = region.surface_plane
    surface = a * columns[None, :] + b * rows[:, None] + c
    valid = status == MatchStatus.VALID
    standing = valid & (np.nan_to_num(disparity - surface, nan=-np.inf) > region.standing_px)
    ring = ((rows[:, None] < y + RING_PX) | (rows[:, None] >= y + height - RING_PX)
            | (columns[None, :] < x + RING_PX) | (columns[None, :] >= x + width - RING_PX))
    at_edge = int(np.count_nonzero(standing & ring))
    if at_edge > max(EDGE_COUNT, EDGE_SHARE * int(np.count_nonzero(valid & ring))):
        return OBJECT_AT_EDGE
    largest = region.min_disparity + region.disparity_range - 1
    at_limit = int(np.count_nonzero(valid & (np.nan_to_num(disparity) >= largest - 1)))
    if at_limit > max(EDGE_COUNT, EDGE_SHARE * int(np.count_nonzero(valid))):
        return AT_DISPARITY_LIMIT
    found_v, found_u = np.nonzero(standing)
    if len(found_u) < FOUND_SHARE * region.top_face_px / point_stride ** 2:
        return OBJECT_LOST
    centre_u, centre_v = region.top_centre
    if math.isfinite(centre_u) and math.hypot(
            float(np.median(columns[found_u])) - centre_u,
            float(np.median(rows[found_v])) - centre_v) > MOVED_SHARE * math.sqrt(
                region.top_face_px):
        return OBJECT_MOVED
    return None


MIN_FOUND_POINTS = 12
"""Fewest standing matches (at the point stride) that make an object in region_from_matches."""

OTHER_OBJECT_SHARE = 0.25
"""A second group of standing matches this share of the largest one's size is another object:
region_from_matches then gives no region (the fuzzy stage chooses between them) [-]."""


def region_from_matches(disparity_map: DisparityMap, reference: SearchRegion,
                        calibration: StereoCalibration, point_stride: int,
                        full_range: tuple[int, int],
                        margin_object_sizes: float) -> SearchRegion | None:
    """Return a region around the one object standing out of the surface in whole-image matches.

    Args:
        disparity_map: A pair matched on the whole image (at least the point stride's rows).
        reference: An earlier region of the same rig: its surface plane and its `noise_px`
            (its `standing_px` when that is unknown) tell which matches stand out of the work
            surface, whatever the height of the object it was made for.
        calibration: The rectified calibration (P of both cameras).
        point_stride: Rows and columns the points keep.
        full_range: (min_disparity, disparity_range) of the whole-image search [px].
        margin_object_sizes: Margin on each side, in the object's extents in the image [-].

    Returns:
        The region (its check's figures from the standing matches), or None when fewer than
        MIN_FOUND_POINTS stand out, when they form more than one object, or when the region's
        disparities leave the whole-image range.
    """
    height, width = disparity_map.disparity.shape
    rows = np.arange(0, height, point_stride)
    columns = np.arange(0, width, point_stride)
    status = disparity_map.status[np.ix_(rows, columns)]
    disparity = disparity_map.disparity[np.ix_(rows, columns)]
    a, b, c = reference.surface_plane
    surface = a * columns[None, :] + b * rows[:, None] + c
    threshold = reference.noise_px if reference.noise_px > 0.0 else reference.standing_px
    standing = (status == MatchStatus.VALID) & (
        np.nan_to_num(disparity - surface, nan=-np.inf) > threshold)
    if np.count_nonzero(standing) < MIN_FOUND_POINTS:
        return None
    # groups of standing matches, across one missing match
    grown = cv2.dilate(standing.astype(np.uint8), np.ones((3, 3), np.uint8))
    _, labels = cv2.connectedComponents(grown, connectivity=8)
    sizes = np.bincount(labels[standing])
    sizes[0] = 0
    order = np.argsort(sizes)[::-1]
    largest = int(order[0])
    if sizes[largest] < MIN_FOUND_POINTS or (
            len(order) > 1 and sizes[order[1]] >= OTHER_OBJECT_SHARE * sizes[largest]):
        return None
    found_v, found_u = np.nonzero(standing & (labels == largest))
    u, v = columns[found_u].astype(float), rows[found_v].astype(float)
    found_disparity = disparity[found_v, found_u].astype(float)
    extent = max(float(u.max() - u.min()), float(v.max() - v.min()), float(point_stride))
    margin = margin_object_sizes * extent + point_stride
    x0, x1 = max(0, math.floor(u.min() - margin)), min(width, math.ceil(u.max() + margin) + 1)
    y0, y1 = max(0, math.floor(v.min() - margin)), min(height, math.ceil(v.max() + margin) + 1)
    left_p = np.asarray(calibration.left.P, dtype=float)
    right_p = np.asarray(calibration.right.P, dtype=float)
    f_baseline = left_p[0, 3] - right_p[0, 3]
    shift = left_p[0, 2] - right_p[0, 2]
    corners_u = np.array([x0, x1 - 1, x0, x1 - 1], float)
    corners_v = np.array([y0, y0, y1 - 1, y1 - 1], float)
    corner_surface = a * corners_u + b * corners_v + c
    # the surface SURFACE_BELOW_M lower, as search_region's box reaches (depth f B / (d - shift))
    lowered = corner_surface - (corner_surface - shift) ** 2 * SURFACE_BELOW_M / abs(f_baseline)
    top = float(found_disparity.max())
    excess = top - float(np.median(a * u + b * v + c))
    full_low, full_count = full_range
    low = max(full_low, math.floor(float(lowered.min())) - MARGIN_PX)
    high = min(full_low + full_count - 1,
               math.ceil(top + max(0.0, margin_object_sizes * excess)) + MARGIN_PX)
    if high < low or x1 - x0 < 2 or y1 - y0 < 2:
        return None
    return SearchRegion((x0, y0, x1 - x0, y1 - y0), low, high - low + 1,
                        reference.surface_plane, threshold,
                        float(len(u)) * point_stride ** 2,
                        (float(np.median(u)), float(np.median(v))), reference.noise_px)
