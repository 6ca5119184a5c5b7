"""A plain object on a textured surface, from the left image alone, when the matches show none.

A top without texture is matched only along its rim, where the correlation windows take in the
surface's texture and with it the surface's disparity; a low one (a disc a few millimetres
high, a fraction of a pixel of parallax on a far rig) does not stand out of the surface's noise
at all. correlation_area.py then finds no object. The left image still shows such a top: a
compact region of nearly constant grey inside the surface's texture. So, for a pair refused
after every other look:

1. Seeds: the left image's pixels whose contrast over FLAT_SIDE_PX squares is under
   PLAIN_CONTRAST_SHARE of the image's median contrast (or the sensor's noise), opened, in
   regions of at least MIN_SEED_PX that stay clear of the image's edges.
2. Each seed's face: the pixels of its grey around it, one convex region closed within its
   box (face_outline.plain_region), covering at least MIN_OBJECT_AREA_PX, and of an object's
   size on the surface at some height. Where more than MAX_FACES such faces lie (a plain
   surface, or one printed with plain blocks), nothing tells an object from the surface and
   the look ends there.
3. Its height: where its rim lies in both rectified images (plain_top_height.py), with a peak
   of at least MIN_PEAK, and at least min_object_height_m above the surface (a printed patch
   lies on the surface: its rim aligns at height zero).
4. Exactly one such face, of an object's size on its top plane, is the object; two or more are
   not told apart, and none is given. Where the matches did find a face, refused in pieces or
   for its scatter, the plain face must hold SCATTERED_SEED_SHARE of its matches: a plain
   patch printed on a textured top, at the top's height, is not the object they found.

plain_top_at_matched_height looks at a face refused for its scatter, or too narrow for any
object, the same way: the plain region holding its matches, at the face's matched height when
both images confirm it.

plain_face_without_side_wall cuts a plain face taken whole from the image to its part above its
own foot, where a side wall of the top's grey joined it, as plain_top_at_matched_height does; a
region that is mostly such a wall gives no face.

ROS-free: numpy, scipy and OpenCV.
"""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np

from stereo_fuzzy_perception.core.best_point.correlation_area import (
    MIN_OBJECT_AREA_PX,
    NO_POINTS,
    STATUS_OK,
    AreaConfig,
    CorrelationArea,
)
from stereo_fuzzy_perception.core.best_point.face_outline import (
    FLAT_SIDE_PX,
    MAD_TO_SIGMA,
    PLAIN_OPENING_PX,
    PLAIN_SEED_SHARE,
    PLAIN_TOLERANCE_GREY,
    PLAIN_TOLERANCE_SIGMAS,
    SCATTERED_SEED_SHARE,
    SMOOTHING_SIGMA_PX,
    face_within,
    left_image_pixels,
    plain_region,
)
from stereo_fuzzy_perception.core.best_point.object_segmentation import (
    across_m,
    grid_step,
    local_contrast,
)
from stereo_fuzzy_perception.core.best_point.plain_top_height import (
    MIN_MARGIN,
    RimAlignment,
    plain_top_height,
)
from stereo_fuzzy_perception.core.camera_model import CameraCalibration
from stereo_fuzzy_perception.core.matched_points import MatchedPoints

PLAIN_CONTRAST_SHARE = 0.25
"""A seed pixel's contrast is at most this share of the image's median contrast."""

NOISE_CONTRAST_GREY = 1.5
"""... or at most this many grey levels (of 255): sensor noise on a plain top."""

MIN_SEED_PX = 150
"""Fewest pixels of a seed region: a plain top's inside, its rim's shading left out."""

MAX_FACES = 5
"""More plain regions of an object's shape and size than this: the surface itself is plain in
places, or printed with plain blocks (and the height of each is a search of its own)."""

MIN_PEAK = 0.9
"""Lowest correlation of the rim's memberships at the face's height (plain_top_height's peak):
with no match to confirm the face, only a rim both images show clearly is taken."""

SEED_MARGIN_PX = 10
"""Added to the seed's size around it for the box its face is looked for in [px]."""

HOLDS_WITHIN_PX = 3.0
"""A scattered face's match lies in a plain region when it lies inside its outline or within
this of it (the rim's matches straddle the rim) [px]."""

MIN_RISE = MIN_MARGIN
"""At a scattered face's matched height the rim's memberships correlate at least this much
better than at the surface's: the plain region stands there, not on the surface."""

HEIGHT_CHECK_M = 0.02
"""The rim's alignment at a scattered face's matched height is compared with its alignment at
the heights up to this far either side of it [m]..."""

HEIGHT_CHECK_STEP_M = 0.001
"""...taken this far apart [m]..."""

MAX_HEIGHT_SHORTFALL = 0.03
"""...and the region is not taken when some other height aligns better by more than this:
both images put the rim elsewhere, the matched height is not confirmed."""

MIN_KEPT_SHARE = 0.6
"""A plain face taken whole from the image is cut to its part above its own foot only when
the part keeps at least this share of its pixels: a side wall's image is a strip along the
face. A region whose part above its foot keeps less is mostly wall, or of a printed, wood or
fabric top whose plain region is no plain top: it gives no face (the shares and outcomes
measured: src/stereo_fuzzy_perception/README.md, step 1)."""

PlainOutline = tuple[np.ndarray, float, float]
"""A plain region's outline (K, 2) in the left rectified image [px], its grey and the
tolerance that found it (_plain_outline)."""


def plain_object_from_image(refused: CorrelationArea, points: MatchedPoints,
                            left: CameraCalibration, right: CameraCalibration,
                            world_from_camera: np.ndarray, config: AreaConfig
                            ) -> CorrelationArea | None:
    """Return the one plain object the left image shows on a textured surface, or None.

    Args:
        refused: The correlation area refused after every other look (its work surface is
            the one the height is measured from).
        points: The pair's matches, with both rectified images (left_image, right_image).
        left: Rectified calibration of the left image.
        right: Rectified calibration of the right image.
        world_from_camera: 4x4 pose of the left optical frame in `world`.
        config: The correlation area's settings (min_points, min/max_object_across_m,
            min/max_object_height_m).

    Returns:
        The area whose points are the face's pixels on the matches' grid, cut with its top
        plane (status ok); None when the images show no such object, or more than one.
    """
    if refused.status == NO_POINTS:
        return None
    looked = _plain_outlines(refused, points, left, right, world_from_camera, config)
    if looked is None:
        return None
    outlines, base, step = looked
    if len(outlines) > MAX_FACES:
        return None  # plain patches of an object's shape all over: nothing tells them apart
    found = [(outline, face) for outline, face in (
        (outline, _face_at_its_height(outline, level, tolerance, base, step, points, left,
                                      right, world_from_camera, config))
        for outline, level, tolerance in outlines) if face is not None]
    if len(found) != 1:
        return None
    outline, face = found[0]
    matched = refused.face_in_pieces or refused.scattered_face
    if matched is not None and _share_held(outline, matched) < SCATTERED_SEED_SHARE:
        return None  # the matches found a face the plain region is not: print on a top
    return face


def plain_top_at_matched_height(face: CorrelationArea, points: MatchedPoints,
                                left: CameraCalibration, right: CameraCalibration,
                                world_from_camera: np.ndarray, config: AreaConfig
                                ) -> CorrelationArea | None:
    """Return a face refused for its scatter (or a sliver: a face narrower than any object) as
    the plain region that holds it, at its matched height, or None.

    A plain top is matched along its rim, where the windows see the rim's edge, and inside on
    sensor noise: its heights scatter, yet their densest upper level is often the top's.
    plain_top_height's search over every height finds no clear peak on most such tops: a
    side wall of the top's grey joins the region, and its foot aligns on the surface. Here
    the height is the face's own (CorrelationArea.top_height), and both images only confirm
    it. Of the left image's plain regions (the seeds and faces of plain_object_from_image)
    that hold SCATTERED_SEED_SHARE of the face's matches, each without its side wall where
    one shows (_without_side_wall), the one whose rim, carried to the right image by the
    face's height, lies on the right image's rim better than carried by the surface's by the
    most is taken at that height, when by at least MIN_RISE: the region stands there, it is
    not a patch of the surface. Nor is it taken when, uncut, its rim aligns better than at the
    face's height by MAX_HEIGHT_SHORTFALL at another height within HEIGHT_CHECK_M: the matches
    agree on a height the images do not.

    Args:
        face: CorrelationArea.scattered_face of the refused area, or a face too narrow for
            any object (one arc of a plain top's rim, matched at the top's height).
        points: The pair's matches, with both rectified images (left_image, right_image).
        left: Rectified calibration of the left image.
        right: Rectified calibration of the right image.
        world_from_camera: 4x4 pose of the left optical frame in `world`.
        config: The correlation area's settings (min_points, min/max_object_across_m).

    Returns:
        The area whose points are the region's pixels on the matches' grid, cut with the
        face's top plane (status ok); None when no plain region holds the face or it does not
        stand at the face's height.
    """
    looked = _plain_outlines(face, points, left, right, world_from_camera, config)
    if looked is None or len(face.u_left) == 0:
        return None
    outlines, base, step = looked
    assert points.left_image is not None and points.right_image is not None
    rises = []
    for outline, level, tolerance in outlines:
        if _share_held(outline, face) < SCATTERED_SEED_SHARE:
            continue
        top = _without_side_wall(outline, level, tolerance, face, base, step, points, left,
                                 right, world_from_camera)
        alignment = RimAlignment.of(top, level, tolerance, points.left_image,
                                    points.right_image, left, right, world_from_camera,
                                    face.surface)
        if alignment is not None:
            at_face, at_surface = alignment.scores(np.array([face.top_height, 0.0]))
            rises.append((at_face - at_surface, top, alignment, at_face, top is outline))
    if not rises:
        return None
    rise, outline, alignment, at_face, whole = max(rises, key=lambda item: item[0])
    if rise < MIN_RISE:
        return None
    if whole:
        # A region cut above its foot has one edge that is no rim in the image: its alignment
        # peaks off the top's height, and only an uncut region's says where the top is.
        around = face.top_height + np.arange(-HEIGHT_CHECK_M, HEIGHT_CHECK_M + 1e-9,
                                             HEIGHT_CHECK_STEP_M)
        elsewhere = float(np.max(alignment.scores(around[around > 0.0])))
        if elsewhere - at_face > MAX_HEIGHT_SHORTFALL:
            return None
    return _object_sized_face(base, face.top_height, outline, step, left, right,
                              world_from_camera, config)


def plain_face_without_side_wall(face: CorrelationArea, points: MatchedPoints,
                                 left: CameraCalibration, right: CameraCalibration,
                                 world_from_camera: np.ndarray, config: AreaConfig
                                 ) -> CorrelationArea | None:
    """Return a plain face taken whole from the image (face_outline.plain_face_from_image) cut
    to its part above its own foot where a side wall of its grey joined it, the face as it is
    where none did, or None where the region is mostly wall.

    The plain region holding a top whose walls are of its grey reaches down the nearer walls
    to the surface, and the face's pixels cut with the top's plane lie beyond its rim toward
    the cameras there. The face is cut as a scattered plain top is (_without_side_wall: only
    where the rest of its rim aligns better at the surface's height than at the face's),
    with the face's grey and tolerance taken from its pixels, and only when the part keeps
    MIN_KEPT_SHARE of them. When it keeps less (or is no object's face), the region is mostly
    wall, or a textured top's plain patch: the image cannot tell the top there, and the
    face, whole, would lie beyond its rim.

    Args:
        face: The plain face, its points the region's pixels on the matches' grid.
        points: The pair's matches, with both rectified images (left_image, right_image).
        left: Rectified calibration of the left image.
        right: Rectified calibration of the right image.
        world_from_camera: 4x4 pose of the left optical frame in `world`.
        config: The correlation area's settings (min_points, min/max_object_across_m).
    """
    image = points.left_image
    finite = np.isfinite(points.u_left) & np.isfinite(points.v_left)
    if image is None or points.right_image is None or len(face.u_left) < 3 or not np.any(
            finite):
        return face
    grey_level = 257.0 if image.pixels.dtype == np.uint16 else 1.0
    smooth = cv2.GaussianBlur(image.pixels.astype(np.float32), (0, 0), SMOOTHING_SIGMA_PX)
    columns = np.clip(np.round(face.u_left).astype(int) - image.x, 0, smooth.shape[1] - 1)
    rows = np.clip(np.round(face.v_left).astype(int) - image.y, 0, smooth.shape[0] - 1)
    greys = smooth[rows, columns]
    level, tolerance = _grey_and_tolerance(greys, grey_level)
    outline = cv2.convexHull(np.column_stack([face.u_left, face.v_left]).astype(
        np.float32)).reshape(-1, 2).astype(float)
    step = grid_step(points.u_left[finite], points.v_left[finite])
    top = _without_side_wall(outline, level, tolerance, face, face, step, points, left, right,
                             world_from_camera)
    if top is outline:
        return face
    cut = _object_sized_face(face, face.top_height, top, step, left, right, world_from_camera,
                             config)
    if cut is None or len(cut.u_left) < MIN_KEPT_SHARE * len(face.u_left):
        return None
    return cut


def _without_side_wall(outline: np.ndarray, level: float, tolerance: float,
                       face: CorrelationArea, base: CorrelationArea, step: float,
                       points: MatchedPoints, left: CameraCalibration,
                       right: CameraCalibration, world_from_camera: np.ndarray) -> np.ndarray:
    """Return the region's outline, or that of its part above its own foot when the rest of
    its rim lies on the surface: a side wall of the top's grey joins the region down to the
    surface, and where it does, the region's rim is the wall's foot."""
    top = _above_own_foot(outline, face.top_height, base, step, left, right, world_from_camera)
    if top is None:
        return outline
    assert points.left_image is not None and points.right_image is not None
    beyond = RimAlignment.of(outline, level, tolerance, points.left_image, points.right_image,
                             left, right, world_from_camera, face.surface, away_from=top)
    if beyond is None:
        return outline  # the part is the whole region, or its rim's rest too short to tell
    at_face, at_surface = beyond.scores(np.array([face.top_height, 0.0]))
    return top if at_surface > at_face else outline


def _above_own_foot(outline: np.ndarray, height: float, base: CorrelationArea, step: float,
                    left: CameraCalibration, right: CameraCalibration,
                    world_from_camera: np.ndarray) -> np.ndarray | None:
    """Return the outline of the region's pixels whose point on the top's plane, moved down
    to the surface, the left image shows inside the region too, or None when none does."""
    face = face_within(dataclasses.replace(base, top_height=height), outline, step, left, right,
                       world_from_camera, 3)
    if face is None:
        return None
    feet = left_image_pixels(face.xyz_world - height * face.surface.normal, left,
                             world_from_camera)
    contour = outline.astype(np.float32).reshape(-1, 1, 2)
    kept = np.array([cv2.pointPolygonTest(contour, (float(u), float(v)), True) >= -1.0
                     for u, v in feet])
    if np.count_nonzero(kept) < 3:
        return None
    hull = cv2.convexHull(np.column_stack([face.u_left[kept], face.v_left[kept]]).astype(
        np.float32)).reshape(-1, 2)
    return hull.astype(float) if len(hull) >= 3 and cv2.contourArea(hull) >= 4.0 else None


def _share_held(outline: np.ndarray, face: CorrelationArea) -> float:
    """Return the share of the face's matches inside the outline or within HOLDS_WITHIN_PX."""
    contour = outline.astype(np.float32).reshape(-1, 1, 2)
    return float(np.mean([cv2.pointPolygonTest(contour, (float(u), float(v)), True)
                          >= -HOLDS_WITHIN_PX
                          for u, v in zip(face.u_left, face.v_left, strict=True)]))


def _plain_outlines(area: CorrelationArea, points: MatchedPoints, left: CameraCalibration,
                    right: CameraCalibration, world_from_camera: np.ndarray, config: AreaConfig
                    ) -> tuple[list[PlainOutline], CorrelationArea, float] | None:
    """Return the faces of the left image's plain seeds, the area their faces are made from
    (the area's surface, the matches' grid) and the grid's step, or None when the pair has
    no images to look at."""
    image, right_image = points.left_image, points.right_image
    finite = np.isfinite(points.u_left) & np.isfinite(points.v_left)
    if (image is None or right_image is None or not np.any(finite)
            or any(part.pixels.ndim != 2 or min(part.pixels.shape) < 2
                   for part in (image, right_image))):
        return None  # nothing to look at (a peer's empty or malformed image is no object)
    grey_level = 257.0 if image.pixels.dtype == np.uint16 else 1.0
    smooth = cv2.GaussianBlur(image.pixels.astype(np.float32), (0, 0), SMOOTHING_SIGMA_PX)
    seeds = _seed_regions(smooth, grey_level)
    u, v = points.u_left[finite], points.v_left[finite]
    step = grid_step(u, v)
    # The face's points come from the area's surface and the matches' grid; a refused area
    # has no points to give them.
    base = dataclasses.replace(area, status=STATUS_OK, reason='', u_left=u[:1],
                               v_left=v[:1], u_right=u[:1], xyz_world=np.zeros((1, 3)),
                               score=np.array([float(np.median(points.score[finite]))]),
                               weight=None, face_in_pieces=None, scattered_face=None,
                               face_at_mode=None)
    outlines = [outline for outline in (
        _plain_outline(smooth, rows, columns, grey_level, base, step, points, left, right,
                       world_from_camera, config) for rows, columns in seeds)
        if outline is not None]
    return outlines, base, step


def _seed_regions(smooth: np.ndarray, grey_level: float) -> list[tuple[np.ndarray, np.ndarray]]:
    """Return the (rows, columns) of each plain seed region of the image."""
    contrast = local_contrast(smooth, FLAT_SIDE_PX)
    plain = contrast <= max(PLAIN_CONTRAST_SHARE * float(np.median(contrast)),
                            NOISE_CONTRAST_GREY * grey_level)
    opened = cv2.morphologyEx(plain.astype(np.uint8), cv2.MORPH_OPEN, cv2.getStructuringElement(
        cv2.MORPH_ELLIPSE, (2 * PLAIN_OPENING_PX + 1, 2 * PLAIN_OPENING_PX + 1)))
    count, labels, stats, _ = cv2.connectedComponentsWithStats(opened, connectivity=4)
    height, width = smooth.shape
    seeds = []
    for label in range(1, count):
        x, y, w, h, size = stats[label]
        if (size < MIN_SEED_PX or x == 0 or y == 0 or x + w >= width or y + h >= height
                or max(w, h) > 0.5 * min(width, height)):
            continue  # too small, open to the image's edge, or the surface itself
        rows, columns = np.nonzero(labels[y:y + h, x:x + w] == label)
        seeds.append((rows + y, columns + x))
    return seeds


def _plain_outline(smooth: np.ndarray, rows: np.ndarray, columns: np.ndarray,
                   grey_level: float, base: CorrelationArea, step: float,
                   points: MatchedPoints, left: CameraCalibration, right: CameraCalibration,
                   world_from_camera: np.ndarray, config: AreaConfig
                   ) -> PlainOutline | None:
    """Return (outline (K, 2) in the left rectified image [px], grey level, tolerance) of the
    face grown from one seed region, or None when it is no object's face at any height."""
    image = points.left_image
    assert image is not None  # plain_object_from_image checked
    greys = smooth[rows, columns]
    level, tolerance = _grey_and_tolerance(greys, grey_level)
    reach = int(max(np.ptp(rows), np.ptp(columns))) + SEED_MARGIN_PX
    low = np.maximum([columns.min() - reach, rows.min() - reach], 0)
    high = np.minimum([columns.max() + reach + 1, rows.max() + reach + 1], smooth.shape[::-1])
    crop = smooth[low[1]:high[1], low[0]:high[0]]
    hull = plain_region(np.abs(crop - level) <= tolerance, rows - low[1], columns - low[0], 0,
                        PLAIN_SEED_SHARE)
    if hull is None or cv2.contourArea(hull.astype(np.float32)) < MIN_OBJECT_AREA_PX:
        return None
    outline = hull.astype(float) + low + (image.x, image.y)
    # On the surface the face is as large as it can be, at the highest top as small.
    largest = face_within(dataclasses.replace(base, top_height=0.0), outline, step, left, right,
                          world_from_camera, config.min_points)
    smallest = face_within(dataclasses.replace(base, top_height=config.max_object_height_m),
                           outline, step, left, right, world_from_camera, config.min_points)
    if (largest is None or smallest is None
            or across_m(largest.xyz_world[:, :2]) < config.min_object_across_m
            or across_m(smallest.xyz_world[:, :2]) > config.max_object_across_m):
        return None
    return outline, level, tolerance


def _grey_and_tolerance(greys: np.ndarray, grey_level: float) -> tuple[float, float]:
    """Return a plain region's grey (the median of its pixels' greys) and the tolerance around
    it that holds its pixels (PLAIN_TOLERANCE_SIGMAS of their spread, at least
    PLAIN_TOLERANCE_GREY grey levels of 255 in units of grey_level)."""
    level = float(np.median(greys))
    spread = MAD_TO_SIGMA * float(np.median(np.abs(greys - level)))
    return level, max(PLAIN_TOLERANCE_SIGMAS * spread, PLAIN_TOLERANCE_GREY * grey_level)


def _face_at_its_height(outline: np.ndarray, level: float, tolerance: float,
                        base: CorrelationArea, step: float, points: MatchedPoints,
                        left: CameraCalibration, right: CameraCalibration,
                        world_from_camera: np.ndarray, config: AreaConfig
                        ) -> CorrelationArea | None:
    """Return the face inside outline at the height both images give it, or None."""
    assert points.left_image is not None and points.right_image is not None
    measured = plain_top_height(outline, level, tolerance, points.left_image,
                                points.right_image, left, right, world_from_camera,
                                base.surface, config.max_object_height_m)
    if (measured is None or measured.peak < MIN_PEAK
            or measured.height_m < config.min_object_height_m):
        return None
    return _object_sized_face(base, measured.height_m, outline, step, left, right,
                              world_from_camera, config)


def _object_sized_face(base: CorrelationArea, height: float, outline: np.ndarray, step: float,
                       left: CameraCalibration, right: CameraCalibration,
                       world_from_camera: np.ndarray, config: AreaConfig
                       ) -> CorrelationArea | None:
    """Return the face inside outline on the top plane at `height`, or None when it has fewer
    than min_points grid pixels or is no object's size on that plane."""
    face = face_within(dataclasses.replace(base, top_height=height), outline, step, left, right,
                       world_from_camera, config.min_points)
    if face is None:
        return None
    length = across_m(face.xyz_world[:, :2])
    if not config.min_object_across_m <= length <= config.max_object_across_m:
        return None
    return face
