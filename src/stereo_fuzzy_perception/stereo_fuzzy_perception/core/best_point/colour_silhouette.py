"""The top face from the object's colour: its silhouette in the left colour image, its
matches' height, and its rim in both colour images (a look at the pair for colour cameras;
BestPointChooser tries it first).

ROS-free: numpy, OpenCV and scipy.ndimage. Grey correlation finds a top only where its
matches stand out of the table's noise, and places its rim only to within a window; an
object whose colour differs from the table's shows its whole silhouette in one image, pixel
by pixel. Four steps:

1. *The silhouette.* Chromaticity (r, g) = (R, G) / (R + G + B) does not change with how
   brightly a surface is lit, so the top and the side walls of one object share it while a
   textured table keeps its own. The table's chromaticity is measured at the matches lying on
   the measured work surface (within SURFACE_SIGMAS of their height noise); a pixel belongs
   to an object when its chromaticity lies more than COLOUR_SIGMAS of the table's spread away.
   The silhouette is the largest such region inside the workspace box whose matches stand
   above the table in a ring around it (their median at least MIN_MEDIAN_HEIGHT_M and
   MEDIAN_SIGMAS standard errors of that median) and that is no longer than twice
   max_object_across_m.
2. *The top's height.* A prism standing on the surface, seen from one camera, has a footprint
   that both its top plane and the surface project inside its silhouette: every other point
   of either plane lies outside it (the top's plane beyond the far rim, the surface in front
   of the near wall). So given the top's height h, the footprint is the set of surface points
   p for which p + h n and p both project inside the silhouette (n the surface normal). The
   top's pixels are then the footprint seen at h, and h the median height of the matches
   INNER_PX or more inside them; starting from the silhouette's upper heights, TOP_PASSES
   passes settle it. A top whose matches scatter by more than MAX_TOP_SPREAD_SIGMAS of their
   own height noise (median absolute deviation) is not measured: a low-texture top's few
   matches, or wall and table ones.
3. *The rim in both images.* Where the silhouette's outline is the top's, the height at which
   it falls on the right image's silhouette (its own table colour: the right camera has its
   own gain and offset) is searched as plain_top_height searches a plain top's. A far rig's
   table is matched in bands a centimetre above or below its plane (the renderer's moire), and
   a patch of colour printed on such a band would stand on matches alone; both images put its
   rim on the table. A top whose rim is clearly found below the surface and RIM_SLACK_M below
   its matches is refused. (The rim's height is not used otherwise: on boxes it comes out low,
   the band taking in the silhouette's side edges.)
4. *The point.* The footprint's centre at the top's height. When the look gives nothing, the
   grey looks decide.

Why it is measured this way, and what it gains: the package README, "A top from the colour
silhouette".
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from scipy import ndimage

from stereo_fuzzy_perception.core.best_point.face_outline import left_image_pixels, world_rays
from stereo_fuzzy_perception.core.best_point.plain_top_height import (
    inside_part,
    plane_disparity,
    sample_rows,
    score_peak,
)
from stereo_fuzzy_perception.core.best_point.work_surface import (
    MAD_SCALE,
    SurfacePlane,
    height_per_disparity,
)
from stereo_fuzzy_perception.core.camera_model import CameraCalibration
from stereo_fuzzy_perception.core.matched_points import MatchedPoints, RectifiedImage
from stereo_fuzzy_perception.core.rig_geometry import transform_points

COLOUR_SIGMAS = 6.0
"""A pixel is an object's when its chromaticity lies this many of the table's spreads (robust,
per component) from the table's."""

MIN_BRIGHTNESS = 15.0
"""Pixels darker than this (mean of R, G, B on 0-255) carry no chromaticity: sensor noise
decides their ratios."""

SURFACE_SIGMAS = 2.0
"""Matches within this many sigmas of their height noise of the surface are the table's."""

MIN_TABLE_MATCHES = 100
"""Fewer table matches than this measure no table colour."""

MIN_REGION_PX = 100
"""A silhouette smaller than this in the left image is no object's [px]."""

MIN_REGION_MATCHES = 15
"""A silhouette with fewer matches this far inside it has no height to stand on."""

MIN_MEDIAN_HEIGHT_M = 0.002
"""A silhouette whose matches' median height is lower than this is the table's own colour."""

MEDIAN_SIGMAS = 5.0
"""...or lower than this many standard errors of that median (1.25 MAD / sqrt(n)), each
measured from the table's matches in a ring around the region: a far rig's table is matched
in bands a centimetre above or below its plane (the renderer's moire), and a patch of
another colour printed on such a band is no object."""

RING_PX = (3, 15)
"""The ring around a region: from this many pixels outside it to this many, or half the
region's side if more [px]."""

MIN_RING_MATCHES = 30
"""A ring with fewer table matches than this measures no local table level: the plane's is
used."""

INNER_PX = 2
"""Heights are taken from the matches this far inside a region: a window straddling its rim
takes the disparity of whichever side is textured more."""

TOP_PASSES = 2
"""Passes of footprint -> top's pixels -> their matches' median height."""

MAX_TOP_SPREAD_SIGMAS = 8.0
"""A top whose matches scatter by more than this many of their median height noise (median
absolute deviation, scaled to a sigma) is not measured well enough."""

MIN_TOP_MATCHES = 5
"""A top with fewer matches inside it is not measured."""

FOOTPRINT_STEP_M = 0.0005
"""Grid step of the footprint on the surface [m]."""

RIM_BAND_PX = 2
"""The rim's band lies within this of the silhouette's outline, inside and outside [px]."""

MIN_RIM_PX = 20
"""A rim band of fewer pixels measures no height."""

RIM_STEP_PX = 0.05
"""Spacing of the rim heights tried, in disparity at the rim's centre [px]."""

RIM_BELOW_M = 0.01
"""Rim heights are tried from this far below the surface (a patch of colour printed on the
table has its rim there, and must be seen to) to this far above the matches' top [m]."""

RIM_FAR_PX = 1.0
"""Rim heights whose disparity differs from the peak's by more than this are other heights."""

RIM_MARGIN_PX = 8
"""The right image is read this far beyond where the rim's band can fall [px]."""

MIN_RIM_PEAK = 0.3
"""A rim whose memberships correlate less than this at their best height says nothing."""

RIM_SLACK_M = 0.005
"""A top is refused when its rim, clearly found, lies below the surface and more than this
below the matches' top: both images put the silhouette's outline on the table, where a patch
of colour printed on it lies, while the matches float it on the table's moire [m]."""


@dataclass(frozen=True)
class ColourTop:
    """A top face found from the colour silhouette.

    Attributes:
        point: (3,) the footprint's centre at the top's height, in `world` [m].
        top_height: The top's height above the work surface [m].
        footprint: (M, 3) the footprint's grid points at the top's height, in `world` [m].
        silhouette_px: The silhouette's area in the left image [px].
        top_matches: Matches inside the top's pixels that measured its height.
        spread_sigmas: Their heights' scatter in sigmas of their noise.
        rim: The height where the silhouette's rim falls on itself in the right image (None:
            no right colour image, or no clear peak).
    """

    point: np.ndarray
    top_height: float
    footprint: np.ndarray
    silhouette_px: int
    top_matches: int
    spread_sigmas: float
    rim: RimHeight | None = None


@dataclass(frozen=True)
class RimHeight:
    """The height at which the silhouette's rim in the left image falls on its rim in the
    right one.

    Attributes:
        height: Height above the work surface [m].
        peak: Correlation of the rim's memberships at that height [-1, 1].
        margin: How far the peak stands above the best height that moves the rim by more than
            RIM_FAR_PX in the right image.
    """

    height: float
    peak: float
    margin: float


@dataclass(frozen=True)
class _Matches:
    columns: np.ndarray
    rows: np.ndarray
    heights: np.ndarray
    sigmas: np.ndarray
    u_right: np.ndarray


def colour_top(points: MatchedPoints, left: CameraCalibration, right: CameraCalibration,
               world_from_camera: np.ndarray, surface: SurfacePlane,
               workspace: tuple[tuple[float, float, float], tuple[float, float, float]],
               max_object_across_m: float, max_object_height_m: float = 0.10
               ) -> tuple[ColourTop | None, str]:
    """Return the top face the left colour image shows, or None and why not.

    Args:
        points: The matches, with their left rectified colour image (points.left_colour).
        left: Rectified calibration of the left image.
        right: Rectified calibration of the right image.
        world_from_camera: 4x4 pose of the left optical frame in `world`.
        surface: The work surface measured from the matches, with their disparity noise.
        workspace: (lower, upper) corners of the workspace box in `world` [m].
        max_object_across_m: The longest top of any object [m].
        max_object_height_m: The highest top of any object [m].
    """
    image = points.left_colour
    if image is None or len(points) == 0:
        return None, 'no colour image'
    pose = np.asarray(world_from_camera, dtype=float)
    matches = _matches_in(points, image, left, right, pose, surface)
    chroma, lit = _chromaticity(image.pixels)
    table = (np.abs(matches.heights) <= SURFACE_SIGMAS * matches.sigmas)
    table &= lit[matches.rows, matches.columns]
    if int(table.sum()) < MIN_TABLE_MATCHES:
        return None, f'{int(table.sum())} matches on the table, too few for its colour'
    table_chroma = chroma[matches.rows[table], matches.columns[table]]
    centre = np.median(table_chroma, axis=0)
    spread = MAD_SCALE * np.median(np.abs(table_chroma - centre), axis=0) + 1e-4
    distance = _distance(chroma, centre, spread)
    inside = _in_workspace(image, left, pose, surface, workspace)
    candidate = (lit & inside & (distance > COLOUR_SIGMAS)).astype(np.uint8)
    candidate = cv2.morphologyEx(candidate, cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))
    candidate = cv2.morphologyEx(candidate, cv2.MORPH_CLOSE, np.ones((5, 5), np.uint8))
    labels, count = ndimage.label(candidate)
    if count == 0:
        return None, 'no region of another colour than the table'
    inner = _eroded(candidate, INNER_PX)
    label_at = labels[matches.rows, matches.columns]
    inner_at = inner[matches.rows, matches.columns]
    areas = np.bincount(labels.ravel(), minlength=count + 1)
    boxes = ndimage.find_objects(labels)
    best, why = 0, 'no region of another colour large enough'
    # the largest region that passes: tried from the largest down
    for label in np.argsort(-areas[1:], kind='stable') + 1:
        if areas[label] < MIN_REGION_PX:
            break
        mine = (label_at == label) & inner_at
        if int(mine.sum()) < MIN_REGION_MATCHES:
            why = 'no region of another colour with enough matches inside'
            continue
        heights = matches.heights[mine]
        local = _ring_level(labels, int(label), boxes[label - 1], label_at, matches)
        median = float(np.median(heights)) - local
        error = 1.2533 * MAD_SCALE * float(np.median(np.abs(heights - median - local))
                                            ) / math.sqrt(len(heights))
        if median < max(MIN_MEDIAN_HEIGHT_M, MEDIAN_SIGMAS * error):
            why = (f'the regions of another colour stand {1000.0 * median:.1f} mm or less '
                   "above the table around them: the table's own colours")
            continue
        box = boxes[label - 1]
        rows, columns = np.nonzero(labels[box] == label)
        upper = max(float(np.percentile(heights, 90)), 0.0)
        across = _extent(columns + box[1].start + image.x, rows + box[0].start + image.y,
                         upper, left, pose, surface)
        if across > 2.0 * max_object_across_m:
            why = f'the region of another colour is {1000.0 * across:.0f} mm long, no object'
            continue
        best = int(label)
        break
    if best == 0:
        return None, why
    silhouette = cv2.dilate((labels == best).astype(np.uint8), np.ones((3, 3), np.uint8)) > 0
    mine = (label_at == best) & inner_at
    top_height = max(float(np.percentile(matches.heights[mine], 90)), 0.0)
    on_top = np.zeros(0, dtype=bool)
    for _ in range(TOP_PASSES):
        footprint = _footprint(silhouette, image, top_height, left, pose, surface)
        if len(footprint) == 0:
            return None, "the silhouette holds no footprint at the top's height"
        on_top = _top_matches(footprint, silhouette.shape, image, left, pose, matches)
        if int(on_top.sum()) < MIN_TOP_MATCHES:
            return None, f'{int(on_top.sum())} matches on the top, too few to measure it'
        top_height = float(np.median(matches.heights[on_top]))
    heights = matches.heights[on_top]
    spread = MAD_SCALE * float(np.median(np.abs(heights - top_height)))
    spread_sigmas = spread / max(float(np.median(matches.sigmas[on_top])), 1e-6)
    if spread_sigmas > MAX_TOP_SPREAD_SIGMAS:
        return None, (f"the top's {len(heights)} matches scatter by {spread_sigmas:.1f} sigmas "
                      f'of their noise (more than {MAX_TOP_SPREAD_SIGMAS:g}): not measured')
    footprint = _footprint(silhouette, image, top_height, left, pose, surface)
    if len(footprint) == 0:
        return None, "the silhouette holds no footprint at the top's height"
    centre_on_top = footprint.mean(axis=0)
    rim = None
    if points.right_colour is not None:
        top_pixels = _top_pixels(footprint, silhouette.shape, image, left, pose)
        right_rows = matches.rows[table]
        right_columns = (np.rint(matches.u_right[table]).astype(np.int64)
                         - points.right_colour.x)
        right_colours = _chromaticity(points.right_colour.pixels)
        right_chroma = right_colours[0]
        seen = (right_columns >= 0) & (right_columns < right_chroma.shape[1]) & (
            right_rows + image.y - points.right_colour.y >= 0) & (
            right_rows + image.y - points.right_colour.y < right_chroma.shape[0])
        table_right = right_chroma[right_rows[seen] + image.y - points.right_colour.y,
                                   right_columns[seen]]
        if len(table_right) >= MIN_TABLE_MATCHES:
            rim = rim_height(silhouette, top_pixels, image, points.right_colour,
                             right_colours, table_right, left, right, pose, surface,
                             -RIM_BELOW_M,
                             min(top_height + RIM_BELOW_M, max_object_height_m))
    if rim is not None and rim.peak >= MIN_RIM_PEAK and rim.height < min(
            top_height - RIM_SLACK_M, 0.0):
        return None, (f"the silhouette's rim lies {1000.0 * rim.height:.1f} mm from the surface "
                      f'in both images, its matches {1000.0 * top_height:.1f} mm above it: a '
                      'patch of colour on the table, not an object')
    return ColourTop(centre_on_top, top_height, footprint, int(silhouette.sum()),
                     int(on_top.sum()), spread_sigmas, rim), ''


def rim_height(silhouette: np.ndarray, top_pixels: np.ndarray, image: RectifiedImage,
               right_image: RectifiedImage, right_chroma: tuple[np.ndarray, np.ndarray],
               table_right: np.ndarray, left: CameraCalibration,
               right: CameraCalibration, pose: np.ndarray, surface: SurfacePlane,
               low_m: float, high_m: float) -> RimHeight | None:
    """Return the height of the silhouette's rim where it is the top's, from where it lies in
    both colour images, or None (no rim, or no clear peak).

    The rim's band: pixels within RIM_BAND_PX of the silhouette's outline that lie within
    RIM_BAND_PX of the top's pixels' outline too (a box's near edges and walls are inside the
    silhouette, its far edges on it). Each band pixel's membership is the silhouette's,
    smoothed; in the right image, how far its chromaticity is from the right image's own table
    colour (the right camera has its own gain and offset), in COLOUR_SIGMAS, capped at 1.
    """
    disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * RIM_BAND_PX + 1,) * 2)
    mask = silhouette.astype(np.uint8)
    band = (cv2.dilate(mask, disc) > 0) & ~(cv2.erode(mask, disc) > 0)
    top = top_pixels.astype(np.uint8)
    band &= (cv2.dilate(top, disc) > 0) & ~(cv2.erode(top, disc) > 0)
    rows, columns = np.nonzero(band)
    if len(rows) < MIN_RIM_PX:
        return None
    left_member = cv2.GaussianBlur(mask.astype(np.float32), (0, 0), 1.0)[rows, columns]
    left_member = left_member - left_member.mean()
    if not np.any(left_member):
        return None
    columns_px, rows_px = columns + image.x, rows + image.y
    to_right = plane_disparity(left, right, pose, surface)
    # Only the part of the right image the band can fall on at any height tried, with a
    # margin the smoothing and the sampling cannot see past: the same values, a fraction of
    # the work.
    reach = np.concatenate([to_right(columns_px.astype(float), rows_px.astype(float), at)
                            for at in (low_m, high_m)])
    if not np.all(np.isfinite(reach)):
        return None
    height, width = right_image.pixels.shape[:2]
    first_column = max(int(math.floor(reach.min())) - RIM_MARGIN_PX - right_image.x, 0)
    stop_column = min(int(math.ceil(reach.max())) + RIM_MARGIN_PX + 1 - right_image.x, width)
    first_row = max(int(rows_px.min()) - RIM_MARGIN_PX - right_image.y, 0)
    stop_row = min(int(rows_px.max()) + RIM_MARGIN_PX + 1 - right_image.y, height)
    if stop_column - first_column < 3 or stop_row <= first_row:
        return None
    window = (slice(first_row, stop_row), slice(first_column, stop_column))
    chroma, lit = right_chroma[0][window], right_chroma[1][window]
    centre = np.median(table_right, axis=0)
    spread = MAD_SCALE * np.median(np.abs(table_right - centre), axis=0) + 1e-4
    objectness = np.minimum(_distance(chroma, centre, spread) / COLOUR_SIGMAS,
                            1.0).astype(np.float32)
    objectness = cv2.GaussianBlur(objectness * lit, (0, 0), 1.0)
    right_part = RectifiedImage(objectness, right_image.x + first_column,
                                right_image.y + first_row)
    centre_u, centre_v = float(columns_px.mean()), float(rows_px.mean())
    span = abs(float(to_right(np.array([centre_u]), np.array([centre_v]), low_m)[0]
                     - to_right(np.array([centre_u]), np.array([centre_v]), high_m)[0]))
    count = int(min(2000, max(3, math.ceil(span / RIM_STEP_PX) + 1)))
    heights = np.linspace(low_m, high_m, count)
    scores = np.full(count, -1.0)
    for index, height in enumerate(heights):
        at = to_right(columns_px.astype(float), rows_px.astype(float), float(height))
        if not inside_part(at, rows_px, right_image):
            continue
        member = sample_rows(objectness, at, rows_px, right_part)
        member = member - member.mean()
        norm = float(np.linalg.norm(member) * np.linalg.norm(left_member))
        if norm > 0.0:
            scores[index] = float(member @ left_member) / norm
    at_centre = to_right(np.full(count, centre_u), np.full(count, centre_v), heights)
    return RimHeight(*score_peak(scores, heights, at_centre, RIM_FAR_PX))


def _ring_level(labels: np.ndarray, label: int, box: tuple[slice, slice],
                label_at: np.ndarray, matches: _Matches) -> float:
    """Return the median height of the table's matches in a ring around the region `label`
    of `labels` (box: its bounding slices), or 0, the plane's, when the ring holds too few of
    them."""
    side = max(box[0].stop - box[0].start, box[1].stop - box[1].start)
    outer = max(RING_PX[1], side // 2)
    height, width = labels.shape
    top, left = max(box[0].start - outer, 0), max(box[1].start - outer, 0)
    bottom, right = min(box[0].stop + outer, height), min(box[1].stop + outer, width)
    region = (labels[top:bottom, left:right] == label).astype(np.uint8)
    near = cv2.dilate(region, np.ones((2 * RING_PX[0] + 1,) * 2, np.uint8))
    far = cv2.dilate(region, np.ones((2 * outer + 1,) * 2, np.uint8))
    inside = ((matches.rows >= top) & (matches.rows < bottom) & (matches.columns >= left)
              & (matches.columns < right) & (label_at == 0))
    rows, columns = matches.rows[inside] - top, matches.columns[inside] - left
    in_ring = (far[rows, columns] > 0) & (near[rows, columns] == 0)
    if int(in_ring.sum()) < MIN_RING_MATCHES:
        return 0.0
    return float(np.median(matches.heights[inside][in_ring]))


def _chromaticity(pixels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return (H, W, 2) chromaticity (r, g) of RGB pixels, blurred over 3x3 first, and which
    pixels are bright enough to carry it. (OpenCV's per-pixel operations: numpy's reductions
    over three channels cost several times the rest.)"""
    scale = 255.0 / 65535.0 if pixels.dtype == np.uint16 else 1.0
    blurred = cv2.blur(pixels.astype(np.float32) * np.float32(scale), (3, 3))
    total = cv2.transform(blurred, np.ones((1, 3), np.float32))
    darkest = cv2.min(cv2.min(pixels[..., 0], pixels[..., 1]), pixels[..., 2])
    lit: np.ndarray = (total > 3.0 * MIN_BRIGHTNESS) & (darkest > 0)  # 0: outside the rectified
    denominator = np.maximum(total, np.float32(1e-3))
    chroma = np.empty(pixels.shape[:2] + (2,), np.float32)
    np.divide(blurred[..., 0], denominator, out=chroma[..., 0])
    np.divide(blurred[..., 1], denominator, out=chroma[..., 1])
    return chroma, lit


def _distance(chroma: np.ndarray, centre: np.ndarray, spread: np.ndarray) -> np.ndarray:
    """Return each pixel's chromaticity distance from `centre`, in units of `spread` per
    component."""
    red = (chroma[..., 0] - np.float32(centre[0])) / np.float32(spread[0])
    green = (chroma[..., 1] - np.float32(centre[1])) / np.float32(spread[1])
    distance: np.ndarray = np.sqrt(red * red + green * green)
    return distance


def _matches_in(points: MatchedPoints, image: RectifiedImage, left: CameraCalibration,
                right: CameraCalibration, pose: np.ndarray, surface: SurfacePlane) -> _Matches:
    """Return the matches inside the colour image: pixel, height above the surface and its
    noise."""
    height, width = image.pixels.shape[:2]
    columns = np.rint(points.u_left).astype(np.int64) - image.x
    rows = np.rint(points.v_left).astype(np.int64) - image.y
    xyz = points.xyz.astype(float)
    usable = ((columns >= 0) & (columns < width) & (rows >= 0) & (rows < height)
              & np.all(np.isfinite(xyz), axis=1))
    world = transform_points(pose, xyz[usable]).T
    shift = float(left.P[0, 2] - right.P[0, 2])
    disparity = np.maximum(points.u_left[usable] - points.u_right[usable] - shift, 1e-3)
    sigmas = surface.disparity_sigma_px * height_per_disparity(
        world, pose[:3, 3], disparity.astype(float), surface.normal)
    return _Matches(columns[usable], rows[usable], surface.heights(world), sigmas,
                    points.u_right[usable].astype(float))


def _on_plane(columns: np.ndarray, rows: np.ndarray, level: float, left: CameraCalibration,
              pose: np.ndarray, surface: SurfacePlane) -> np.ndarray:
    """Return (N, 3) where the rays of left rectified pixels cut the plane `level` above the
    surface (NaN where they never do in front of the camera)."""
    rays = world_rays(columns.astype(float), rows.astype(float), left, pose)
    normal = surface.normal
    plane = surface.offset_m * float(normal[2]) + level
    facing = normal @ rays
    with np.errstate(divide='ignore', invalid='ignore'):
        depth = (plane - float(normal @ pose[:3, 3])) / facing
    cut = (pose[:3, 3, None] + rays * depth).T
    cut[~(depth > 0.0)] = np.nan
    return np.asarray(cut)


def _in_workspace(image: RectifiedImage, left: CameraCalibration, pose: np.ndarray,
                  surface: SurfacePlane,
                  workspace: tuple[tuple[float, float, float], tuple[float, float, float]]
                  ) -> np.ndarray:
    """Return which pixels of the image see the workspace box on the surface or above it (at
    one of three heights up to half the box's): the box's rectangle at each height, on the
    plane parallel to the surface, projected and filled."""
    height, width = image.pixels.shape[:2]
    low, high = np.asarray(workspace[0], float), np.asarray(workspace[1], float)
    corners = np.array([[low[0], low[1]], [high[0], low[1]], [high[0], high[1]],
                        [low[0], high[1]]])
    on_surface = (surface.slope_x * corners[:, 0] + surface.slope_y * corners[:, 1]
                  + surface.offset_m)
    camera_from_world = np.linalg.inv(pose)
    mask = np.zeros((height, width), np.uint8)
    for level in (0.0, 0.25 * (high[2] - low[2]), 0.5 * (high[2] - low[2])):
        world = (np.column_stack([corners, on_surface]) + level * surface.normal)
        in_camera = world @ camera_from_world[:3, :3].T + camera_from_world[:3, 3]
        if np.any(in_camera[:, 2] <= 0.0):
            return np.ones((height, width), dtype=bool)  # a corner behind the camera: all
        pixels = left_image_pixels(world, left, pose) - (image.x, image.y)
        cv2.fillConvexPoly(mask, np.round(pixels * 16.0).astype(np.int32), 1, shift=4)
    inside: np.ndarray = mask > 0
    return inside


def _extent(columns: np.ndarray, rows: np.ndarray, level: float, left: CameraCalibration,
            pose: np.ndarray, surface: SurfacePlane) -> float:
    """Return the larger side [m] of the box holding the pixels' rays cut at `level`."""
    cut = _on_plane(columns, rows, level, left, pose, surface)
    cut = cut[np.all(np.isfinite(cut), axis=1)]
    if not len(cut):
        return math.inf
    return float(max(np.ptp(cut[:, 0]), np.ptp(cut[:, 1])))


def _footprint(silhouette: np.ndarray, image: RectifiedImage, level: float,
               left: CameraCalibration, pose: np.ndarray, surface: SurfacePlane) -> np.ndarray:
    """Return (M, 3) the surface points whose top at `level` and whose foot both project
    inside the silhouette, raised to `level` (the module docstring, step 2)."""
    rows, columns = np.nonzero(silhouette)
    columns, rows = columns + image.x, rows + image.y
    bounds = [_on_plane(columns, rows, at, left, pose, surface) for at in (level, 0.0)]
    cut = np.vstack(bounds)
    cut = cut[np.all(np.isfinite(cut), axis=1)]
    if not len(cut):
        return np.zeros((0, 3))
    low, high = cut[:, :2].min(axis=0), cut[:, :2].max(axis=0)
    x, y = np.meshgrid(np.arange(low[0], high[0], FOOTPRINT_STEP_M),
                       np.arange(low[1], high[1], FOOTPRINT_STEP_M))
    grid = np.column_stack([x.ravel(), y.ravel()])
    normal = surface.normal
    foot = np.column_stack([grid, surface.slope_x * grid[:, 0] + surface.slope_y * grid[:, 1]
                            + surface.offset_m])
    kept = np.ones(len(grid), dtype=bool)
    for at in (level, 0.0):
        pixels = left_image_pixels(foot + at * normal, left, pose)
        column = np.rint(pixels[:, 0]).astype(np.int64) - image.x
        row = np.rint(pixels[:, 1]).astype(np.int64) - image.y
        seen = ((column >= 0) & (column < silhouette.shape[1]) & (row >= 0)
                & (row < silhouette.shape[0]))
        kept &= seen
        kept[seen] &= silhouette[row[seen], column[seen]]
    top: np.ndarray = foot[kept] + level * normal
    return top


def _top_pixels(footprint: np.ndarray, shape: tuple[int, ...], image: RectifiedImage,
                left: CameraCalibration, pose: np.ndarray) -> np.ndarray:
    """Return the pixels of the image part that see the footprint (at its height)."""
    pixels = left_image_pixels(footprint, left, pose)
    column = np.clip(np.rint(pixels[:, 0]).astype(np.int64) - image.x, 0, shape[1] - 1)
    row = np.clip(np.rint(pixels[:, 1]).astype(np.int64) - image.y, 0, shape[0] - 1)
    seen = np.zeros(shape[:2], dtype=np.uint8)
    seen[row, column] = 1
    closed: np.ndarray = cv2.morphologyEx(seen, cv2.MORPH_CLOSE, np.ones((3, 3), np.uint8)) > 0
    return closed


def _top_matches(footprint: np.ndarray, shape: tuple[int, ...], image: RectifiedImage,
                 left: CameraCalibration, pose: np.ndarray, matches: _Matches) -> np.ndarray:
    """Return which matches lie INNER_PX or more inside the footprint's pixels."""
    inner = _eroded(_top_pixels(footprint, shape, image, left, pose), INNER_PX)
    on_top: np.ndarray = inner[matches.rows, matches.columns] > 0
    return on_top


def _eroded(mask: np.ndarray, by: int) -> np.ndarray:
    size = 2 * by + 1
    eroded: np.ndarray = cv2.erode(mask.astype(np.uint8), np.ones((size, size), np.uint8)) > 0
    return eroded


__all__ = ['COLOUR_SIGMAS', 'ColourTop', 'MAX_TOP_SPREAD_SIGMAS', 'colour_top']
