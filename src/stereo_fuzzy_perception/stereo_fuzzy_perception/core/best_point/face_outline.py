"""The top face's outline from the left rectified image (step 1, after correlation_area.py).

The matches alone place the top face's rim only to within a correlation window: a window that
straddles the rim takes the disparity of the side with more texture, so the face grows by up to
half a window where the table is plainer ("fattening") and shrinks where the top is plainer, and
a plain top is matched only along its rim. A face 20-50 px across then has its centre a few
pixels off, several millimetres. The image itself shows the rim to a pixel: the edge between the
top and what lies beyond it. So, when the matches come with the rectified image:

1. The face's outline from its matches: the convex hull of the largest connected piece of them
   (the objects' tops are convex, and so are their images).
2. Each point of that outline moves along its normal to the strongest intensity edge across it,
   within the reach of fattening inward (the window's radius and a pixel) and OUTWARD_PX
   outward, the edges weighted by a Gaussian of the move (sigma: that inward reach) so that
   where the matches already found the rim a texture edge nearby does not pull it away; the
   moves are median-filtered along the outline, so that the texture's own edges cannot pull
   single points away either.
3. The face is the convex hull of the moved outline. Its pixels, on the matches' grid, are cut
   with the top face's plane (the measured surface raised by the top height) along their rays:
   points spread evenly over the whole face, each weighted by the patch of the face it sees.

Where the outline cannot be taken (no image, a face at the image's or the crop's edge, a
degenerate outline), the area stays the matches' own.

A plain (low-texture) top is matched only along its rim, where the window takes in the rim's
edge: its matches are arcs that fill little of their outline, and correlation_area.py refuses
it as a face in pieces. The image shows such a face whole, as one region of nearly constant
intensity around those matches, bounded by the table's texture or the rim's shading.
plain_face_from_image takes that region as the face, when it is one convex region, closed
within the image, holding most of the matches (within the window's radius of it: a match
whose window straddles the rim sits outside the plain pixels), and of an object's size on the
top plane;
otherwise the refusal stands. A plain top refused for its scatter is taken the same way, but only
with its height measured from both rectified images (plain_top_height.py): its matched heights
are not its top's. ROS-free: numpy, scipy and OpenCV.
"""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np
from scipy import ndimage

from stereo_fuzzy_perception.core.best_point.correlation_area import OUTLINE_IMAGE, CorrelationArea
from stereo_fuzzy_perception.core.best_point.object_segmentation import (
    across_m,
    grid_step,
    image_regions,
    local_contrast,
)
from stereo_fuzzy_perception.core.best_point.plain_top_height import plain_top_height
from stereo_fuzzy_perception.core.camera_model import CameraCalibration
from stereo_fuzzy_perception.core.matched_points import RectifiedImage

OUTWARD_PX = 3.0
"""How far outward an outline point may move [px]: a face that the matches cut short at a plain
rim (the window took the table's disparity there)."""

OFFSET_STEP_PX = 0.5
"""Spacing of the positions tried along each normal [px]."""

SMOOTHING_SIGMA_PX = 1.0
"""Gaussian smoothing of the image before its gradient [px]: sensor noise, not the rim."""

NORMAL_SIGMA_PX = 2.0
"""Smoothing of the outline's mask from which its normals are taken [px]."""

MEDIAN_POINTS = 9
"""Outline points over which the moves are median-filtered."""

SUBPIXEL = 4
"""Bits of sub-pixel precision when the moved outline is filled (OpenCV's `shift`)."""

PLAIN_TOLERANCE_SIGMAS = 3.0
"""A plain face's pixels lie within this many sigmas of its matches' grey levels (sigma from
their median absolute deviation)."""

PLAIN_TOLERANCE_GREY = 4.0
"""... and at least within this many grey levels (of 255): sensor noise on a plain face."""

PLAIN_OPENING_PX = 2
"""Radius of the opening that cuts a plain region's thin bridges into the table [px]."""

PLAIN_SEED_SHARE = 0.5
"""A plain face holds at least this share of its matches, within the window's radius (the rest
sit on the rim's edge)."""

SCATTERED_SEED_SHARE = 0.75
"""A plain face for a face refused for its scatter holds at least this share of its matches,
within the window's radius: those matches are the face's band around its top height, its rim
when the top is plain; a region that leaves a quarter of them out is not that face."""

PLAIN_CONVEXITY = 0.85
"""A plain face covers at least this share of its convex hull (the objects' tops are
convex)."""

MATCHES_BELOW_SHARE = 0.02
"""A scattered face's height found from both images lies at most MAX_BELOW_MATCHES_M below
all but this share of its matches' heights..."""

MAX_BELOW_MATCHES_M = 0.005
"""...[m]: its matches scatter above the top (mismatches, the rim's windows taking in the
wall) more than below it, yet a height below nearly all of them is a rim found on another
level (a wall's foot, a plain patch of the table), not this face's top."""

FLAT_SIDE_PX = 5
"""Side of the square over which a match's local grey-level deviation is measured [px]."""

FLAT_SHARE = 0.25
"""The flattest share of the matches gives a plain face's grey and noise."""

PLAIN_MARGIN_PX = 10
"""Added to the box in which a plain face is looked for [px]."""

MAD_TO_SIGMA = 1.4826
"""Standard deviation of a normal distribution per median absolute deviation."""


def face_from_image(area: CorrelationArea, image: RectifiedImage, left: CameraCalibration,
                    right: CameraCalibration, world_from_camera: np.ndarray,
                    min_points: int) -> CorrelationArea | None:
    """Return the correlation area with its outline taken from the image, or None.

    Args:
        area: The matches' correlation area, status ok.
        image: The part of the left rectified image the matches were found in.
        left: Rectified calibration of the left image.
        right: Rectified calibration of the right image.
        world_from_camera: 4x4 pose of the left optical frame in `world`.
        min_points: Fewest points of a face (AreaConfig.min_points).

    Returns:
        The area whose points are the outlined face's pixels on the matches' grid, cut with
        the top face's plane; None when the outline cannot be taken from this image (the area
        of the matches stands then).
    """
    step = grid_step(area.u_left, area.v_left)
    radius = max(1, image.window_size // 2)
    inward = radius + 1.0
    outline = hull_outline(area.u_left, area.v_left, step)
    if outline is None:
        return None
    margin = int(np.ceil(max(inward, OUTWARD_PX) + 3.0 * SMOOTHING_SIGMA_PX + 2.0))
    around = crop_around(outline, margin, image)
    if around is None:
        return None  # the face reaches past the image sent: the matches' outline stands
    crop, low = around
    moved = _snapped(crop, outline - low, inward)
    if moved is None:
        return None
    return face_within(area, moved + low, step, left, right, world_from_camera, min_points)


def crop_around(outline: np.ndarray, margin: int, image: RectifiedImage
                ) -> tuple[np.ndarray, np.ndarray] | None:
    """Return the image's pixels (float32) within margin of an outline's box and the box's
    corner (column, row) in the rectified image, or None when the box reaches past the image
    sent."""
    low = np.floor(outline.min(axis=0)).astype(int) - margin
    high = np.ceil(outline.max(axis=0)).astype(int) + margin
    origin = np.array([image.x, image.y])
    if np.any(low < origin) or np.any(high >= origin + image.pixels.shape[::-1]):
        return None
    crop = image.pixels[low[1] - image.y:high[1] - image.y + 1,
                        low[0] - image.x:high[0] - image.x + 1].astype(np.float32)
    return crop, low


def face_within(area: CorrelationArea, outline: np.ndarray, step: float,
                left: CameraCalibration, right: CameraCalibration,
                world_from_camera: np.ndarray, min_points: int) -> CorrelationArea | None:
    """Return the area whose points are the grid pixels inside outline [px] cut with the top
    face's plane, or None when fewer than min_points pixels are."""
    columns, rows = filled_on_grid(outline, step, area.u_left[0], area.v_left[0])
    if len(columns) < min_points:
        return None
    return on_top_plane(area, columns, rows, left, right, world_from_camera)


def plain_face_from_image(face: CorrelationArea, image: RectifiedImage,
                          left: CameraCalibration, right: CameraCalibration,
                          world_from_camera: np.ndarray, min_points: int,
                          max_across_m: float, right_image: RectifiedImage | None = None,
                          max_height_m: float = 0.1) -> CorrelationArea | None:
    """Return a refused face taken whole from the image's plain region, or None.

    Args:
        face: The face as its matches give it (CorrelationArea.face_in_pieces or
            scattered_face).
        image: The part of the left rectified image the matches were found in.
        left: Rectified calibration of the left image.
        right: Rectified calibration of the right image.
        world_from_camera: 4x4 pose of the left optical frame in `world`.
        min_points: Fewest points of a face (AreaConfig.min_points).
        max_across_m: Longest top face on the surface (AreaConfig.max_object_across_m).
        right_image: For a face refused for its scatter (CorrelationArea.scattered_face),
            whose matched heights are not its top's: the part of the right rectified image the
            matcher read. The face is then taken only with the height where the region's rim
            lies in both images (plain_top_height.py), found at its flattest matches' grey and
            holding SCATTERED_SEED_SHARE of its matches, and when that height is not more than
            MAX_BELOW_MATCHES_M below nearly all of the face's matches.
        max_height_m: Highest top searched for in both images [m].

    Returns:
        The area whose points are the region's pixels on the matches' grid, cut with the top
        face's plane; None when the image shows no such region (the refusal stands).
    """
    pixels = image.pixels
    columns = np.round(face.u_left).astype(int) - image.x
    rows = np.round(face.v_left).astype(int) - image.y
    # The region is looked for in a box twice the matches' extent around them: a plain face
    # reaches beyond its rim's arcs, a leak into the table reaches the box's edge.
    reach = int(2 * max(np.ptp(columns), np.ptp(rows))) + PLAIN_MARGIN_PX
    low = np.maximum([columns.min() - reach, rows.min() - reach], 0)
    high = np.minimum([columns.max() + reach + 1, rows.max() + reach + 1],
                      pixels.shape[::-1])
    if np.any(columns < 0) or np.any(rows < 0) or np.any(columns >= pixels.shape[1]) \
            or np.any(rows >= pixels.shape[0]):
        return None  # matches outside the image sent: nothing to compare them with
    crop = cv2.GaussianBlur(pixels[low[1]:high[1], low[0]:high[0]].astype(np.float32),
                            (0, 0), SMOOTHING_SIGMA_PX)
    grey_level = 257.0 if pixels.dtype == np.uint16 else 1.0
    hull = None
    levels = _plain_levels(crop, rows - low[1], columns - low[0])
    # A scattered face is looked for at the grey of its flattest matches only: its rim matches
    # take in the table, and the median of all their greys finds table regions.
    for level, spread in levels[:1] if right_image is not None else levels:
        tolerance = max(PLAIN_TOLERANCE_SIGMAS * spread, PLAIN_TOLERANCE_GREY * grey_level)
        hull = plain_region(np.abs(crop - level) <= tolerance, rows - low[1],
                             columns - low[0], image.window_size // 2,
                             SCATTERED_SEED_SHARE if right_image is not None
                             else PLAIN_SEED_SHARE)
        if hull is not None:
            break
    if hull is None:
        return None
    if right_image is not None:
        measured = plain_top_height(hull.astype(float) + low + (image.x, image.y), level,
                                    tolerance, image, right_image, left, right,
                                    world_from_camera, face.surface, max_height_m)
        if measured is None:
            return None
        lowest = float(np.quantile(face.surface.heights(face.xyz_world.T), MATCHES_BELOW_SHARE))
        if measured.height_m < lowest - MAX_BELOW_MATCHES_M:
            return None
        face = dataclasses.replace(face, top_height=measured.height_m)
    whole = face_within(face, hull.astype(float) + low + (image.x, image.y),
                        grid_step(face.u_left, face.v_left), left, right, world_from_camera,
                        min_points)
    if whole is None or across_m(whole.xyz_world[:, :2]) > max_across_m:
        return None
    return whole


def _plain_levels(crop: np.ndarray, rows: np.ndarray, columns: np.ndarray
                  ) -> list[tuple[float, float]]:
    """Return the grey levels (level, sigma) a plain face is looked for at, narrower first.

    The matches sit at the rim, where windows take in the rim's edge: first the grey of the
    flattest of them (their quarter with the least local deviation, which lie on the face
    itself) with the image's noise there, then the median and spread of all of them (a top
    with faint texture of its own).
    """
    local = local_contrast(crop, FLAT_SIDE_PX)[rows, columns]
    seeds = crop[rows, columns]
    flat = local <= np.quantile(local, FLAT_SHARE)
    everything = float(np.median(seeds))
    return [(float(np.median(seeds[flat])), float(np.median(local[flat]))),
            (everything, MAD_TO_SIGMA * float(np.median(np.abs(seeds - everything))))]


def plain_region(plain: np.ndarray, rows: np.ndarray, columns: np.ndarray, reach: int,
                  min_share: float = PLAIN_SEED_SHARE) -> np.ndarray | None:
    """Return the hull (K, 2) of the plain pixels' region around the matches, or None.

    Args:
        plain: Which pixels of the crop are of the face's grey.
        rows: The matches' rows in the crop.
        columns: Their columns.
        reach: The correlation window's radius [px]: a match whose window straddles the rim
            sits up to this far outside the face's plain pixels and still belongs to it.
        min_share: Share of the matches the region holds at least.
    """
    # Opening cuts the thin bridges through which the region would leak into table texture
    # of the same grey.
    opened = cv2.morphologyEx(plain.astype(np.uint8), cv2.MORPH_OPEN, cv2.getStructuringElement(
        cv2.MORPH_ELLIPSE, (2 * PLAIN_OPENING_PX + 1, 2 * PLAIN_OPENING_PX + 1)))
    count, labels, stats, _ = cv2.connectedComponentsWithStats(opened, connectivity=4)
    # Each match goes to the region within `reach` of it (the nearest region's pixel).
    distance, (near_rows, near_columns) = ndimage.distance_transform_edt(
        labels == 0, return_indices=True)
    seeded = np.where(distance <= reach, labels[near_rows, near_columns], 0)
    held = np.bincount(seeded[rows, columns], minlength=count)
    held[0] = 0
    region = int(np.argmax(held))
    if region == 0 or held[region] < min_share * len(columns):
        return None
    x, y, width, height, size = stats[region]
    if x == 0 or y == 0 or x + width >= plain.shape[1] or y + height >= plain.shape[0]:
        return None  # open to the box's edge: table or background, not a face
    contours, _ = cv2.findContours((labels == region).astype(np.uint8), cv2.RETR_EXTERNAL,
                                   cv2.CHAIN_APPROX_NONE)
    hull: np.ndarray = cv2.convexHull(max(contours, key=cv2.contourArea)).reshape(-1, 2)
    if size < PLAIN_CONVEXITY * cv2.contourArea(hull):
        return None  # not one convex face: a face with a wall or the table's texture
    return hull


def hull_outline(u: np.ndarray, v: np.ndarray, step: float) -> np.ndarray | None:
    """Return the convex hull (K, 2) of the face's matches [px], or None when flat.

    Only the largest connected piece of the matches counts: a stray match of the band's
    height away from the face would otherwise widen the hull all the way to it. Each match
    stands for its grid cell less the pixel it sits on: at a point stride of one the hull of
    the matches, at a coarser one the rim lies on average that far beyond the outer matches.
    """
    labels, count = image_regions(u, v, np.ones(len(u), dtype=bool), step)
    if count > 1:
        largest = np.argmax(np.bincount(labels)[1:]) + 1
        u, v = u[labels == largest], v[labels == largest]
    half = 0.5 * (step - 1.0)
    # the corners of the cells at the centres' hull vertices only: the same hull
    centres = cv2.convexHull(np.column_stack([u, v]).astype(np.float32)).reshape(-1, 2)
    corners = np.concatenate([centres + np.array([du, dv], dtype=np.float32)
                              for du in (-half, half) for dv in (-half, half)])
    hull = cv2.convexHull(corners).reshape(-1, 2)
    if len(hull) < 3 or cv2.contourArea(hull) < 4.0:
        return None
    return hull.astype(float)


def _snapped(crop: np.ndarray, hull: np.ndarray, inward: float) -> np.ndarray | None:
    """Return the outline (K, 2) moved to the image's edges, in crop pixels, or None."""
    mask = np.zeros(crop.shape, np.uint8)
    cv2.fillConvexPoly(mask, np.round(hull * (1 << SUBPIXEL)).astype(np.int32), 1,
                       shift=SUBPIXEL)
    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    if not contours:
        return None
    contour = max(contours, key=len).reshape(-1, 2).astype(float)
    if len(contour) < MEDIAN_POINTS:
        return None
    blurred = cv2.GaussianBlur(mask.astype(np.float32), (0, 0), NORMAL_SIGMA_PX)
    columns, rows = contour[:, 0].astype(int), contour[:, 1].astype(int)
    normals = -np.column_stack([cv2.Sobel(blurred, cv2.CV_32F, 1, 0, ksize=3)[rows, columns],
                                cv2.Sobel(blurred, cv2.CV_32F, 0, 1, ksize=3)[rows, columns]])
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    if np.any(length == 0.0):
        return None
    normals /= length
    smooth = cv2.GaussianBlur(crop, (0, 0), SMOOTHING_SIGMA_PX)
    gradient_u = cv2.Sobel(smooth, cv2.CV_32F, 1, 0, ksize=3)
    gradient_v = cv2.Sobel(smooth, cv2.CV_32F, 0, 1, ksize=3)
    offsets = np.arange(-inward, OUTWARD_PX + 1e-9, OFFSET_STEP_PX)
    tried = contour[None, :, :] + offsets[:, None, None] * normals[None, :, :]
    where = [tried[..., 1], tried[..., 0]]
    across = np.abs(ndimage.map_coordinates(gradient_u, where, order=1) * normals[:, 0]
                    + ndimage.map_coordinates(gradient_v, where, order=1) * normals[:, 1])
    # A weak preference for small moves: where the matches already found the rim, a texture
    # edge a few pixels inside the face must be much stronger to pull the outline to it.
    across *= np.exp(-0.5 * (offsets / inward) ** 2)[:, None]
    moves = ndimage.median_filter(offsets[np.argmax(across, axis=0)], size=MEDIAN_POINTS,
                                  mode='wrap')
    moved: np.ndarray = contour + moves[:, None] * normals
    return moved


def filled_on_grid(outline: np.ndarray, step: float, u_grid: float, v_grid: float
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Return the grid pixels (columns, rows) inside the convex hull of outline [px].

    The grid is the matches' (spacing step through (u_grid, v_grid)).
    """
    hull = cv2.convexHull(outline.astype(np.float32)).reshape(-1, 2).astype(float)
    low = np.floor(hull.min(axis=0)).astype(int) - 1
    high = np.ceil(hull.max(axis=0)).astype(int) + 1
    mask = np.zeros((high[1] - low[1] + 1, high[0] - low[0] + 1), np.uint8)
    cv2.fillConvexPoly(mask, np.round((hull - low) * (1 << SUBPIXEL)).astype(np.int32), 1,
                       shift=SUBPIXEL)
    rows, columns = np.nonzero(mask)
    columns, rows = columns + low[0], rows + low[1]
    spacing = max(1, int(round(step)))
    on_grid = (((columns - int(round(u_grid))) % spacing == 0)
               & ((rows - int(round(v_grid))) % spacing == 0))
    return columns[on_grid].astype(float), rows[on_grid].astype(float)


def world_rays(columns: np.ndarray, rows: np.ndarray, left: CameraCalibration,
               world_from_camera: np.ndarray) -> np.ndarray:
    """Return the rays (3, M) in `world` of the left rectified image's pixels, K^-1 (u, v, 1)
    turned out of the rectified frame: depth 1 along the rectified optical axis."""
    pose = np.asarray(world_from_camera, dtype=float)
    rectification = np.asarray(left.R, dtype=float).reshape(3, 3)
    intrinsic = np.asarray(left.P, dtype=float)[:3, :3]
    rays: np.ndarray = pose[:3, :3] @ rectification.T @ (np.linalg.inv(intrinsic) @ np.vstack(
        [columns, rows, np.ones_like(rows)]))
    return rays


def left_image_pixels(world: np.ndarray, left: CameraCalibration,
                      world_from_camera: np.ndarray) -> np.ndarray:
    """Return where the left rectified image shows the points world (N, 3): (N, 2) [px], the
    inverse of world_rays."""
    camera_from_world = np.linalg.inv(np.asarray(world_from_camera, dtype=float))
    rectification = np.asarray(left.R, dtype=float).reshape(3, 3)
    intrinsic = np.asarray(left.P, dtype=float)[:3, :3]
    projected = intrinsic @ (rectification @ (camera_from_world[:3, :3]
                                              @ np.asarray(world, dtype=float).T
                                              + camera_from_world[:3, 3:4]))
    pixels: np.ndarray = (projected[:2] / projected[2]).T
    return pixels


def on_top_plane(area: CorrelationArea, columns: np.ndarray, rows: np.ndarray,
                  left: CameraCalibration, right: CameraCalibration,
                  world_from_camera: np.ndarray) -> CorrelationArea | None:
    """Return the area whose points are the pixels' rays cut with the top face's plane.

    A pixel's ray in the rectified frame is K^-1 (u, v, 1), depth 1; cut with the plane
    n . p = level at depth s = (level - n . C) / (n . D). The patch of the plane one pixel
    sees is proportional to 1 / |n . D|^3 (central projection onto a plane), its weight.
    """
    pose = np.asarray(world_from_camera, dtype=float)
    rays = world_rays(columns, rows, left, pose)
    surface = area.surface
    normal = surface.normal
    level = area.top_height + surface.offset_m * float(normal[2])
    centre = pose[:3, 3]
    facing = normal @ rays
    with np.errstate(divide='ignore', invalid='ignore'):
        depth = (level - float(normal @ centre)) / facing
    if not np.all(np.isfinite(depth)) or np.any(depth <= 0.0):
        return None  # a ray that never meets the face's plane in front of the camera
    world = centre[:, None] + rays * depth
    baseline_term = -float(np.asarray(right.P, dtype=float)[0, 3])  # fx * B
    shift = float(left.P[0, 2] - right.P[0, 2])
    u_right = columns - shift - baseline_term / depth
    weight = np.abs(facing) ** -3.0
    weight /= weight.mean()
    score = np.full(len(columns), float(np.median(area.score)))
    return dataclasses.replace(area, xyz_world=np.ascontiguousarray(world.T), u_left=columns,
                               v_left=rows, u_right=u_right, score=score, weight=weight,
                               points_used=len(columns), outline=OUTLINE_IMAGE)
