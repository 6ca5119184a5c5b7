"""The correlation area of the chapter's section 4 (step 1): the object's top face.

ROS-free: numpy, scipy.ndimage and a numba kernel for the pass over every point. Step 1 of the
package README:

1. Matched points go to `world` with the rig's pose and are kept inside the workspace box
   (extended `surface_search_m` below its floor). The work surface is measured from them
   (work_surface.py: a robust plane fit), with the pair's disparity noise sigma_d; heights are
   distances from that plane, each with its own sigma_h = sigma_d * height_per_disparity. The
   object is the region of the left image's match grid that stands out of the surface in
   sigmas (or, when none does, a textured region of the left image whose own matches stand
   above it), and the correlation area is its top face (object_segmentation.py). The top height
   is that face's height above the measured surface (z = 0 of `world` by definition), so a
   rig pose a few millimetres off does not move it.

Steps 2 and 3 (border points, four areas) are four_areas.py.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numba
import numpy as np

from stereo_fuzzy_perception.core.best_point.object_segmentation import (
    ObjectRegion,
    across_m,
    choose_object,
    choose_textured_object,
    grid_step,
    grown_region,
    hull_fill,
    image_regions,
    on_pixel_grid,
    plausible_average,
    smoothed_on_grid,
    square_cells,
    textured_regions,
    top_mode,
)
from stereo_fuzzy_perception.core.best_point.work_surface import (
    INLIER_SIGMAS,
    MAD_SCALE,
    SURFACE_ASSUMED,
    SURFACE_PLAIN,
    SurfacePlane,
    fit_work_surface,
    height_per_disparity,
)
from stereo_fuzzy_perception.core.matched_points import MatchedPoints, RectifiedImage

# Status codes: why no best point could be chosen (also the diagnostics keys).
STATUS_OK = 'ok'
NO_POINTS = 'no_points'
NO_OBJECT = 'no_object'
TOO_FEW_POINTS = 'too_few_points'
DEGENERATE_AREA = 'degenerate_area'
UNCERTAIN_TOP = 'uncertain_top'
NO_RULE_FIRED = 'no_rule_fired'

# Where the top face's outline comes from (CorrelationArea.outline).
OUTLINE_MATCHES = 'matches'
OUTLINE_IMAGE = 'image'

LOOK_MATCHES = 'matches'
LOOK_PLAIN_FACE = 'plain face from the image'
LOOK_FACE_AT_MODE = 'face at its mode'
LOOK_PIECES_OUTLINED = 'pieces outlined from the image'
LOOK_TEXTURED_REGION = 'textured region of the image'
LOOK_PLAIN_OBJECT = 'plain object in the image'
LOOK_PLAIN_TOP_AT_MATCHED_HEIGHT = 'plain top at its matched height'
LOOK_FITTED_PIECES = 'top fitted around a face in pieces'
LOOK_FITTED_SMALL_FACE = 'top fitted around a face smaller than any top'
LOOK_COLOUR_SILHOUETTE = 'top from the colour silhouette'
"""Which look at the pair gave the face (CorrelationArea.look, point_selectors.decision_area):
the matches' own face, or a look after the matches' face was refused."""

WIDER_SQUARE = 2.0
"""A pair where nothing stands out as an object over squares of smoothing_px is looked at
again over squares this many times as wide (plus a pixel, so that the side stays odd)."""

OBJECT_TOP_SIGMAS = 2.0
"""An object's top face stands at least this many sigmas of its points above the surface
(object_segmentation.choose_object)."""

MIN_OBJECT_AREA_PX = 200.0
"""An object covers at least this much of the left image [px^2] (a square of 14 px): a
pattern of the surface's errors the size of a correlation window is not one."""

FACE_LEVEL = 0.5
"""A point of the face has an averaged height of at least this share of the top's."""

HALF_NORMAL_MEDIAN = 0.6745
"""Median of |N(0, 1)|."""

IMPOSSIBLE_HEIGHT_SIGMAS = 3.0
"""A match higher than max_object_height_m by more than this many sigmas of its height noise
is no object's: a mismatch, left out of everything after the surface fit."""

SURFACE_AROUND_M = 0.1
"""The work surface is measured this far around the workspace box too [m]."""

class CorrelationAreaError(ValueError):
    """A configuration that cannot select a correlation area, with the bad value named."""


@dataclass(frozen=True)
class AreaConfig:
    """How the correlation area is found (step 1). Thresholds are in sigmas of each point's
    own height noise, so one set of values holds at 0.3 m and at 0.9 m.

    Attributes:
        workspace_min: Lower corner (x, y, z) of the workspace box in `world` [m].
        workspace_max: Upper corner (x, y, z) of the workspace box in `world` [m].
        surface_search_m: The work surface is looked for within this of z = 0 [m] (how far
            the rig pose may be off at the edge of the view).
        surface_margin_sigmas: Object candidates stand this many sigmas above the surface.
        object_sigmas: A region is an object when its median height, averaged over
            smoothing_px, is this many sigmas of that average (and its top
            OBJECT_TOP_SIGMAS of one point's).
        area_top_sigmas: The area test (object_segmentation.choose_object): a region whose
            median falls short of object_sigmas is still an object when it covers n squares
            of smoothing_px, its median times sqrt(n) (the n averages are independent samples
            of the noise) is object_sigmas, and its top stands this many sigmas of its points
            above the surface, more than the OBJECT_TOP_SIGMAS of a region high on its own;
            0 turns the area test off.
        plausible_average: Average for the object test only the matches no higher than
            max_object_height_m above the surface (mismatches on a plain table float at any
            height and drown a real object's average); the top face is still found on the
            average of all. Off by default: it lets in faces the face's tests do not yet
            refuse (the package README, "Averages over plausible heights").
        top_band_sigmas: The correlation area is the object's points within this many sigmas
            of its top face.
        smoothing_px: Side of the image square over which heights are averaged before the
            object test [px] (a few correlation windows).
        min_disparity_sigma_px: Lower bound of the measured disparity noise [px].
        assumed_disparity_sigma_px: Disparity noise when the surface cannot be measured [px].
        min_points: Fewer points in the correlation area means no best point.
        max_object_across_m: A top face longer than this on the surface (along its principal
            axis, object_segmentation.across_m) is no object's [m]: the objects are at most
            80 mm across, plus the rim that window matching adds; a longer one is a patch of
            the surface or of the view's edge, and a wrong point is worse than none.
        min_object_across_m: A top face narrower than this on the surface (across its
            principal axis, object_segmentation.width_m) is no object's [m]: the objects are at
            least 15 mm across; a narrower one is a sliver of a face (a plain top's rim, a strip
            of side wall), whose centre is not the face's; 0 turns the test off.
        max_object_height_m: A top face higher than this above the work surface is no
            object's [m]: the objects stand at most 80 mm high; a higher face is a blob of
            mismatches (repeated texture matched a period off) floating over the scene. Matches
            higher than this by more than IMPOSSIBLE_HEIGHT_SIGMAS of their noise are left out
            after the surface fit.
        min_object_height_m: A region whose top stands lower than this above the work surface
            is no object [m]: the objects stand at least 5 mm high; a lower top that still
            stands out in sigmas is the surface's own pattern (a bare table on a rig that
            resolves depth finely). 0 turns the test off.
        max_top_spread_m: A top face whose heights scatter more than this beyond what its
            points' noise explains (sqrt(std^2 - sigma_h^2), sigma_h their median height
            noise) is not measured well enough for a point within millimetres [m]: a level
            face scatters by its points' noise only, and side-wall, table or badly matched
            points in the band add to it. Measured on the randomized training scenes, larger
            errors come almost only from faces beyond it; 0 turns the test off.
        min_top_fill: Share of the top face's outline in the image (the convex hull of its
            matches) that holds matches [-]: a face in pieces (arcs of a rim, bits of a side
            wall, a low-texture top seen only at its edges) gives a centre that is not the
            face's; 0 turns the test off.
        outline_from_image: When the matches come with the left rectified image, take the
            top face's outline from the image's edges (face_outline.py) rather than from the
            matches alone; and a face refused as in pieces (min_top_fill) is taken after all
            when the image shows it as one plain region around its matches
            (face_outline.plain_face_from_image) or, one piece with holes only just in
            pieces, within its rim in the image (point_selectors.PIECES_OUTLINED_*).
        min_surface_score: When the matches near the work surface score below this (their
            median correlation score), the surface is plain: its windows hold sensor noise,
            matched anywhere along the search range. Then only the matches scoring at least
            this are used, and the surface is where the rig pose puts it (z = 0, source
            'plain', noise assumed_disparity_sigma_px); 0 turns this off.
        fit_top_shape: When the matches come with both rectified images, fit the top face as
            a disc or a rectangle to both, pixel by pixel (top_shape_fit.py), and move the
            best point most of the way to the fitted centre where the two agree and the fit
            is clear; a face refused as in pieces, or as smaller in the image than any top,
            is given the fitted centre when the fit is clearer still (BestPointChooser).
        colour_silhouette: When the matches come with the left image in colour, look first
            for the object's silhouette in it, a region of another chromaticity than the
            table's whose matches stand above the surface, and give the centre of the
            footprint it shows at its top's matched height (colour_silhouette.py); the grey
            looks decide when it finds none, or a top its matches do not measure.
    """

    workspace_min: tuple[float, float, float] = (0.0, 0.0, 0.0)
    workspace_max: tuple[float, float, float] = (0.40, 0.30, 0.20)
    surface_search_m: float = 0.02
    surface_margin_sigmas: float = 3.0
    object_sigmas: float = 5.0
    area_top_sigmas: float = 3.0
    plausible_average: bool = False
    top_band_sigmas: float = 2.0
    smoothing_px: float = 15.0
    min_disparity_sigma_px: float = 0.03
    assumed_disparity_sigma_px: float = 0.2
    min_points: int = 20
    max_object_across_m: float = 0.10
    min_object_across_m: float = 0.01
    max_object_height_m: float = 0.10
    min_object_height_m: float = 0.002
    max_top_spread_m: float = 0.002
    min_top_fill: float = 0.5
    outline_from_image: bool = True
    min_surface_score: float = 0.5
    fit_top_shape: bool = True
    colour_silhouette: bool = True

    def problem(self) -> str | None:
        """Return why this configuration is unusable, or None."""
        for axis, (low, high) in enumerate(zip(self.workspace_min, self.workspace_max,
                                               strict=True)):
            if not low < high:
                return (f'workspace box axis {"xyz"[axis]}: min {low} must be below max {high}')
        for name in ('surface_search_m', 'surface_margin_sigmas', 'object_sigmas',
                     'top_band_sigmas', 'smoothing_px', 'min_disparity_sigma_px',
                     'assumed_disparity_sigma_px', 'max_object_across_m',
                     'max_object_height_m'):
            if not getattr(self, name) > 0.0:
                return f'{name}={getattr(self, name)} must be positive'
        for name in ('max_top_spread_m', 'min_top_fill', 'area_top_sigmas',
                     'min_object_across_m', 'min_object_height_m'):
            if not getattr(self, name) >= 0.0:
                return f'{name}={getattr(self, name)} must not be negative'
        if not 0.0 <= self.min_surface_score < 1.0:
            return f'min_surface_score={self.min_surface_score} must be in [0, 1)'
        if not self.min_object_across_m < self.max_object_across_m:
            return (f'min_object_across_m={self.min_object_across_m} must be below '
                    f'max_object_across_m={self.max_object_across_m}')
        if not self.min_object_height_m < self.max_object_height_m:
            return (f'min_object_height_m={self.min_object_height_m} must be below '
                    f'max_object_height_m={self.max_object_height_m}')
        if self.object_sigmas < self.surface_margin_sigmas:
            return (f'object_sigmas={self.object_sigmas} must not be below '
                    f'surface_margin_sigmas={self.surface_margin_sigmas}')
        if self.min_points < 1:
            return f'min_points={self.min_points} must be at least 1'
        return None


ASSUMED_SURFACE = SurfacePlane(SURFACE_ASSUMED, 0.0, 0.0, 0.0, math.nan, 0)


@dataclass(frozen=True)
class CorrelationArea:
    """The object's top surface as seen by the stereo pair (step 1), or why there is none.

    Attributes:
        status: STATUS_OK or a status code.
        reason: Human-readable reason when status is not ok ('' when ok).
        points_in: Matches received.
        points_valid: Finite, in front of the cameras, inside the workspace box or on the
            surface around it (SURFACE_AROUND_M).
        clusters_found: Regions of the image grid standing out of the surface noise.
        points_used: Points of the correlation area.
        top_height: Height of the object's top face above the measured work surface [m]
            (NaN when unknown): its world z, the surface being z = 0 of `world`, whatever
            small error the rig pose has.
        xyz_world: (M, 3) area points in `world` [m].
        u_left: (M,) [px].
        v_left: (M,) [px].
        u_right: (M,) [px].
        score: (M,) correlation scores.
        weight: (M,) share of the top face each point stands for (mean 1): matches are
            denser where the face is nearer, so an unweighted mean leans toward the cameras.
        surface: The work surface and the pair's disparity noise.
        object_height_sigmas: Median height of the object's region in sigmas (NaN: none).
        outline: OUTLINE_MATCHES when the points are the face's matches, OUTLINE_IMAGE when
            they are its pixels inside the outline taken from the image (face_outline.py).
        face_in_pieces: When the area is refused because its matches fill too little of
            their outline (min_top_fill), the face as its matches give it (status ok): a plain
            top is matched only along its rim, and the image may still show the whole face
            (face_outline.plain_face_from_image). None otherwise.
        scattered_face: When the area is refused because its heights scatter
            (max_top_spread_m), the face as its matches give it (status ok): a plain top's
            matched heights scatter, and both images may still show its height
            (plain_top_height.py). None otherwise.
        face_too_small: When the area is refused because its face covers less of the left
            image than any object's top (point_selectors.decision_area), the face as it was
            (status ok): a narrow box's top can be that small, and the top fitted to both
            images may still show it whole (BestPointChooser). None otherwise.
        face_at_mode: When the area is refused as a face in pieces, the same face taken at
            the mode of its region's heights (object_segmentation.top_mode), if that face
            passes every test: a top matched worse than the surface has its densest upper
            level on the upper side of its heights, and the band below that level holds only
            their upper part. Taken only when the image shows no plain face. None otherwise.
        texture_tried: Refused with no region of the grid standing out, after the left
            image's textured regions were looked at too: find_textured_area would find
            nothing more.
        look: Which look at the pair gave the face (LOOK_*): the matches' own, or one that
            point_selectors.decision_area took after the matches' face was refused.
    """

    status: str
    reason: str
    points_in: int
    points_valid: int
    clusters_found: int
    points_used: int
    top_height: float
    xyz_world: np.ndarray
    u_left: np.ndarray
    v_left: np.ndarray
    u_right: np.ndarray
    score: np.ndarray
    weight: np.ndarray | None = None
    surface: SurfacePlane = ASSUMED_SURFACE
    object_height_sigmas: float = math.nan
    outline: str = OUTLINE_MATCHES
    face_in_pieces: CorrelationArea | None = None
    scattered_face: CorrelationArea | None = None
    face_too_small: CorrelationArea | None = None
    face_at_mode: CorrelationArea | None = None
    texture_tried: bool = False
    look: str = LOOK_MATCHES

    def point_weights(self) -> np.ndarray:
        """Return the points' weights (ones when none were given)."""
        return np.ones(len(self.u_left)) if self.weight is None else self.weight

    @property
    def ok(self) -> bool:
        """Return True when the area has enough points."""
        return self.status == STATUS_OK


@numba.njit(cache=True, nogil=True)
def _object_points(xyz: np.ndarray, pose: np.ndarray, low: np.ndarray, high: np.ndarray,
                   u_left: np.ndarray, v_left: np.ndarray, u_right: np.ndarray,
                   score: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Return the points inside the box [low, high]: world (3, M) [m], indices (M,), and the
    smallest and largest world coordinate (3,) of those points (+inf, -inf when M = 0).

    Float64 over points of any float type. The first pass (transform, box and finiteness
    tests) has no branches, so it vectorises; the second compacts. Measured at 100k points:
    twice as fast as one pass that compacts as it goes (its stores wait on the running
    count), four times numpy's pass per operation. NaN / inf rows fail the comparisons or the
    finiteness test.
    """
    count = xyz.shape[0]
    world = np.empty((3, count))
    inside = np.empty(count, np.bool_)
    # Locals, not pose[i, j] in the loop: the stores could alias the pose, so numba would
    # reload it for every point.
    r00, r01, r02, t0 = pose[0, 0], pose[0, 1], pose[0, 2], pose[0, 3]
    r10, r11, r12, t1 = pose[1, 0], pose[1, 1], pose[1, 2], pose[1, 3]
    r20, r21, r22, t2 = pose[2, 0], pose[2, 1], pose[2, 2], pose[2, 3]
    x_low, y_low, z_low, x_high, y_high, z_high = low[0], low[1], low[2], high[0], high[1], \
        high[2]
    used = 0
    for index in range(count):
        px, py, pz = float(xyz[index, 0]), float(xyz[index, 1]), float(xyz[index, 2])
        x = r00 * px + r01 * py + r02 * pz + t0
        y = r10 * px + r11 * py + r12 * pz + t1
        z = r20 * px + r21 * py + r22 * pz + t2
        world[0, index], world[1, index], world[2, index] = x, y, z
        finite = np.isfinite(float(u_left[index]) + float(v_left[index])
                             + float(u_right[index]) + float(score[index]))
        keep = ((x_low <= x) & (x <= x_high) & (y_low <= y) & (y <= y_high)
                & (z_low <= z) & (z <= z_high) & finite)
        inside[index] = keep
        used += keep
    compact = np.empty((3, used))
    kept = np.empty(used, np.int64)
    smallest = np.full(3, np.inf)
    largest = np.full(3, -np.inf)
    slot = 0
    for index in range(count):
        if inside[index]:
            for axis in range(3):
                value = world[axis, index]
                compact[axis, slot] = value
                smallest[axis] = min(smallest[axis], value)
                largest[axis] = max(largest[axis], value)
            kept[slot] = index
            slot += 1
    return compact, kept, smallest, largest


def find_correlation_area(points: MatchedPoints, world_from_camera: np.ndarray,
                          config: AreaConfig, disparity_shift_px: float = 0.0
                          ) -> CorrelationArea:
    """Select the object's top surface among matched points (step 1).

    When no region stands out of the surface over squares of smoothing_px, the pair is looked
    at again over squares WIDER_SQUARE times as wide: a low object on a far rig, wider than
    the square, whose squares are each too noisy to stand out, stands out over wider ones,
    with the surface's noise measured over the same squares.

    Args:
        points: Matched points, xyz in the camera frame [m].
        world_from_camera: 4x4 pose of that camera frame in `world`.
        config: Workspace box and thresholds.
        disparity_shift_px: cx_left - cx_right of the rectified projections [px]
            (0 for a calibration rectified with zero disparity at infinity).

    Returns:
        The correlation area; status explains when there is none: no points, no object
        standing out of the surface, too few points on its top. Never raises for bad points:
        NaN and infinite rows are ignored.

    Raises:
        CorrelationAreaError: When the configuration is unusable.
    """
    reason = config.problem()
    if reason:
        raise CorrelationAreaError(reason)
    measured = _measured_points(points, world_from_camera, config, disparity_shift_px)
    if isinstance(measured, CorrelationArea):
        return measured
    # The image's texture does not depend on the square: the first look alone sees it.
    area, none_stood_out = _object_area(measured, config, config.smoothing_px,
                                        points.left_image)
    if not none_stood_out:
        return area
    wider_px = WIDER_SQUARE * config.smoothing_px + 1.0
    wider, none_stood_out_either = _object_area(measured, config, wider_px)
    if none_stood_out_either:
        nor_texture = (', nor is a textured region of the image, its matches a median '
                       'object_sigmas standard errors high' if points.left_image is not None
                       else '')
        return dataclasses.replace(area, reason=f'{area.reason} (nor over squares of '
                                                 f'{wider_px:g} px{nor_texture})',
                                   texture_tried=points.left_image is not None)
    return wider


def find_textured_area(points: MatchedPoints, world_from_camera: np.ndarray,
                       config: AreaConfig, disparity_shift_px: float = 0.0
                       ) -> CorrelationArea | None:
    """Return the object's top face found as a textured region of the left image only
    (object_segmentation.choose_textured_object), or None when there is none or its face is
    refused. For a pair whose correlation area was refused however its face was looked at
    (point_selectors.decision_area): a textured object on a plain or sparsely marked table
    whose region of the match grid took the table's mismatches with it.

    Args and configuration errors: as find_correlation_area; None without a left image.
    """
    reason = config.problem()
    if reason:
        raise CorrelationAreaError(reason)
    if points.left_image is None:
        return None
    measured = _measured_points(points, world_from_camera, config, disparity_shift_px)
    if isinstance(measured, CorrelationArea):
        return None
    area, _ = _object_area(measured, config, config.smoothing_px, points.left_image,
                           textured_only=True)
    return area if area.ok else None


def _refused(status: str, why: str, points_in: int, valid: int,
             surface: SurfacePlane = ASSUMED_SURFACE, regions: int = 0,
             sigmas: float = math.nan) -> CorrelationArea:
    """Return an area without points: status and why say why there is none."""
    empty = np.zeros(0)
    return CorrelationArea(status, why, points_in, valid, regions, 0, math.nan, np.zeros((0, 3)),
                           empty, empty, empty, empty, empty, surface, sigmas)


@dataclass(frozen=True)
class _MeasuredPoints:
    """A pair's matches in `world` with their heights above the measured work surface: what
    the object is looked for in, once or twice (find_correlation_area). Arrays are per match."""

    points_in: int
    valid: int
    world: np.ndarray  # (3, N) [m]
    u_left: np.ndarray
    v_left: np.ndarray
    u_right: np.ndarray
    score: np.ndarray
    disparity: np.ndarray  # [px], the rectification's shift taken out
    per_px: np.ndarray  # height per pixel of disparity [m]
    sigma: np.ndarray  # height noise [m]
    heights: np.ndarray  # above the surface [m]
    surface: SurfacePlane


def _measured_points(points: MatchedPoints, world_from_camera: np.ndarray, config: AreaConfig,
                     disparity_shift_px: float) -> _MeasuredPoints | CorrelationArea:
    """Return the matches in the workspace with their heights above the measured surface, or
    the refusal when none can be used."""
    points_in = len(points)
    pose = np.asarray(world_from_camera, dtype=float)
    xyz = np.ascontiguousarray(points.xyz).reshape(-1, 3)
    if xyz.dtype not in (np.float32, np.float64):
        xyz = xyz.astype(float)
    columns = [np.asarray(column).reshape(-1) for column in
               (points.u_left, points.v_left, points.u_right, points.score)]
    low = np.array(config.workspace_min, dtype=float)
    high = np.array(config.workspace_max, dtype=float)
    low[2] -= config.surface_search_m
    # The surface around the box measures the plane too (its tilt above all).
    low[:2] -= SURFACE_AROUND_M
    high[:2] += SURFACE_AROUND_M
    # world: (3, N), one contiguous row per axis
    world, selected, _, _ = _object_points(xyz, pose, low, high, *columns)
    u_left, v_left, u_right, score = (column[selected].astype(float) for column in columns)
    disparity = u_left - u_right - disparity_shift_px
    in_front = disparity > 0.0
    if not np.all(in_front):
        world, selected = world[:, in_front], selected[in_front]
        u_left, v_left, u_right, score, disparity = (
            column[in_front] for column in (u_left, v_left, u_right, score, disparity))
    valid = len(selected)
    if valid == 0:
        return _refused(NO_POINTS, f'none of {points_in} matched points is finite, in front of '
                                   'the cameras and inside the workspace box', points_in, valid)
    camera_centre = pose[:3, 3]
    near_surface = np.abs(world[2]) <= config.surface_search_m
    if config.min_surface_score and np.any(near_surface) and (
            float(np.median(score[near_surface])) < config.min_surface_score):
        # A plain surface: its windows hold sensor noise, matched anywhere along the search
        # range, and the plane fitted to them is wherever that noise put it. Only the
        # confident matches say where anything is, and the surface is where the rig pose
        # puts it.
        confident = score >= config.min_surface_score
        world, selected = world[:, confident], selected[confident]
        u_left, v_left, u_right, score, disparity = (
            column[confident] for column in (u_left, v_left, u_right, score, disparity))
        surface = SurfacePlane(SURFACE_PLAIN, 0.0, 0.0, 0.0, max(
            config.assumed_disparity_sigma_px, config.min_disparity_sigma_px), 0)
        if not len(selected):
            return _refused(NO_POINTS, f'the work surface is plain (its matches score below '
                                       f'min_surface_score={config.min_surface_score:g}) and '
                                       'no match in the workspace box scores that',
                            points_in, valid, surface)
    else:
        surface = fit_work_surface(
            world, height_per_disparity(world, camera_centre, disparity,
                                        np.array([0.0, 0.0, 1.0])),
            config.surface_search_m, config.min_disparity_sigma_px,
            config.assumed_disparity_sigma_px)
    per_px = height_per_disparity(world, camera_centre, disparity, surface.normal)
    sigma = surface.disparity_sigma_px * per_px
    heights = surface.heights(world)
    # No object stands higher than max_object_height_m: a match above it by more than its noise
    # is a mismatch (a periodic table matched a period off, a plain one matched on sensor
    # noise), and takes no part in the averages, the surface's noise or the regions.
    possible = heights <= config.max_object_height_m + IMPOSSIBLE_HEIGHT_SIGMAS * sigma
    if not np.all(possible):
        world, selected = world[:, possible], selected[possible]
        u_left, v_left, u_right, score, disparity, per_px, sigma, heights = (
            column[possible] for column in (u_left, v_left, u_right, score, disparity, per_px,
                                            sigma, heights))
        if not len(selected):
            # a plain surface's few confident matches can all be mismatches floating above it
            return _refused(NO_POINTS, f'every match left ({len(possible)}) stands higher above '
                                       'the work surface than any object (max_object_height_m='
                                       f'{config.max_object_height_m:g}): mismatches',
                            points_in, valid, surface)
    return _MeasuredPoints(points_in, valid, world, u_left, v_left, u_right, score, disparity,
                           per_px, sigma, heights, surface)


def _object_area(measured: _MeasuredPoints, config: AreaConfig, smoothing_px: float,
                 left_image: RectifiedImage | None = None, textured_only: bool = False
                 ) -> tuple[CorrelationArea, bool]:
    """Return the object's top face with heights averaged over squares of smoothing_px (or
    why there is none), and whether it was refused because no region of the grid stood out as
    an object. With the left image, when no region does (or, textured_only, whatever they
    do), a textured region of the image whose matches stand out is an object too."""
    m = measured
    points_in, valid, world, surface = m.points_in, m.valid, m.world, m.surface
    u_left, v_left, per_px, sigma, heights = m.u_left, m.v_left, m.per_px, m.sigma, m.heights

    def refused(status: str, why: str, surface: SurfacePlane = ASSUMED_SURFACE,
                regions: int = 0, sigmas: float = math.nan) -> CorrelationArea:
        return _refused(status, why, points_in, valid, surface, regions, sigmas)

    # Heights in disparity pixels have the same noise everywhere; averaged over a square of
    # the image they show an object that one point's noise would hide, and the surface's
    # noise after the same averaging (MAD of the surface points) is the unit of the test.
    residual_px = heights / per_px
    step = grid_step(u_left, v_left)
    smoothed = smoothed_on_grid(u_left, v_left, residual_px, step, smoothing_px)
    detected = (plausible_average(u_left, v_left, residual_px,
                                  heights <= config.max_object_height_m, step,
                                  smoothing_px)
                if config.plausible_average else smoothed)
    on_surface = (np.abs(residual_px) <= INLIER_SIGMAS * surface.disparity_sigma_px) & (
        np.isfinite(detected))
    smoothed_sigma = max(MAD_SCALE * float(np.median(np.abs(detected[on_surface])))
                         if np.any(on_surface) else surface.disparity_sigma_px,
                         config.min_disparity_sigma_px)
    z_scores = detected / smoothed_sigma
    (x_low, y_low, _), (x_high, y_high, _) = config.workspace_min, config.workspace_max
    in_box = (world[0] >= x_low) & (world[0] <= x_high) & (world[1] >= y_low) & (
        world[1] <= y_high)
    candidate = ((z_scores > config.surface_margin_sigmas) & in_box
                 & (world[2] >= config.workspace_min[2]))
    labels, regions = image_regions(u_left, v_left, candidate, step)
    fewest = max(config.min_points, math.ceil(MIN_OBJECT_AREA_PX / step ** 2))
    # Matches in one averaging square of smoothing_px: its share of the area test's count.
    square_points = float(square_cells(step, smoothing_px) ** 2)
    found = (ObjectRegion(0, regions, 0, math.nan, 0) if textured_only else
             choose_object(labels, regions, z_scores, heights, sigma, config.object_sigmas,
                           OBJECT_TOP_SIGMAS, fewest, square_points, config.area_top_sigmas,
                           config.min_object_height_m))
    textured = False
    if found.label == 0 and left_image is not None:
        # On a plain surface, or one of sparse marks, the confident matches off the object
        # include scattered mismatches: they set the unit of the averages above and hide a
        # low object. A textured object on it shows in the image itself, and its own matches'
        # scatter is the unit of its height.
        texture_labels, areas = textured_regions(left_image, u_left, v_left)
        texture_labels[~(in_box & (world[2] >= config.workspace_min[2]))] = 0
        textured_found = choose_textured_object(
            texture_labels, areas, heights, sigma, step, left_image.window_size,
            config.object_sigmas, fewest, MIN_OBJECT_AREA_PX, config.min_object_height_m)
        if textured_found.label:
            labels, found, textured = texture_labels, textured_found, True
    if found.label == 0:
        area_test = (f', or over its n squares of smoothing_px a median of object_sigmas / '
                     f'sqrt(n) and a top area_top_sigmas={config.area_top_sigmas:g} sigmas high'
                     if config.area_top_sigmas else '')
        detail = ('no point stands out of it' if regions == 0 else
                  f'{regions} regions stand out of it, the largest ({found.points} points, '
                  f'{found.points / square_points:.1f} squares) by a median '
                  f'{found.median_sigmas:.1f} sigmas; an object needs '
                  f'object_sigmas={config.object_sigmas:g}, a top {OBJECT_TOP_SIGMAS:g} sigmas '
                  f'of its points high and {fewest} points' + area_test
                  + (f', and a top at least min_object_height_m={config.min_object_height_m:g}'
                     if config.min_object_height_m else ''))
        return refused(NO_OBJECT, f'no object on the work surface ({surface.source}, '
                                  f'disparity noise {surface.disparity_sigma_px:.2f} px): '
                                  + detail, surface, regions, found.median_sigmas), True
    member = labels == found.label
    # The face: points near the region, within the band of the top, whose neighbourhood
    # stands at least half as high. Half height is where the averaging square sits half on
    # the face, so the face's rim is found where it is, not where noise cut the region; the
    # surface around a low object and the foot of a side wall stay out even when their noise
    # reaches the band.
    # A textured region is the object's image already; beyond it lie the plain surface's
    # mismatches, some at the top's height by chance.
    near = member if textured else grown_region(u_left, v_left, member, step, smoothing_px)
    face = _top_face(measured, config, found, member, near, found.top_m, in_box, smoothed,
                     step, textured)
    if face.face_in_pieces is not None:
        # The densest upper level of a top whose own heights spread wider than the surface's
        # noise lies on the upper side of their spread, and the band below it then holds
        # only their upper part: a face in pieces. At the mode of its heights the face may
        # pass every test; a plain top's whole face in the image comes first all the same
        # (point_selectors.decision_area), its matches being only the rim's.
        mode = top_mode(heights[member], sigma[member], found.top_m)
        at_mode = _top_face(measured, config, found, member, near, mode, in_box, smoothed,
                            step, textured)
        if at_mode.ok:
            face = dataclasses.replace(face, face_at_mode=at_mode)
    return face, False


def _top_face(measured: _MeasuredPoints, config: AreaConfig, found: ObjectRegion,
              member: np.ndarray, near: np.ndarray, top: float, in_box: np.ndarray,
              smoothed: np.ndarray, step: float, textured: bool) -> CorrelationArea:
    """Return the object's top face at height `top` (the points of `near` within its band),
    or why it is refused: too few points, too high, too long, scattered or in pieces."""
    m = measured
    points_in, valid, world, surface = m.points_in, m.valid, m.world, m.surface
    u_left, v_left, u_right, score, disparity, per_px, sigma, heights = (
        m.u_left, m.v_left, m.u_right, m.score, m.disparity, m.per_px, m.sigma, m.heights)
    regions = found.regions

    def refused(status: str, why: str) -> CorrelationArea:
        return _refused(status, why, points_in, valid, surface, regions, found.median_sigmas)

    # The face's own noise: a textured top can be matched worse than the surface (and has
    # systematic errors of its own); its spread above the top, where no side wall lies, is
    # half of a normal distribution.
    over = member & (heights > top)
    above = heights[over] / per_px[over] - top / per_px[over]
    face_px = float(np.median(above)) / HALF_NORMAL_MEDIAN if len(above) >= 10 else 0.0
    band_sigma = max(surface.disparity_sigma_px, face_px) * per_px
    band = np.flatnonzero(near & in_box & (heights - top <= config.top_band_sigmas * band_sigma)
                          & (top - heights <= 0.5 * config.top_band_sigmas * band_sigma)
                          & (smoothed * per_px >= FACE_LEVEL * top))
    used = len(band)
    if used < config.min_points:
        return refused(TOO_FEW_POINTS, f"{used} points on the object's top face, need "
                                       f'min_points={config.min_points}')
    xyz_world = np.ascontiguousarray(world[:, band].T)
    if top > config.max_object_height_m:
        return refused(NO_OBJECT, f'the top face found stands {1000.0 * top:.0f} mm above the '
                                  'work surface, higher than any object '
                                  f'(max_object_height_m={config.max_object_height_m:g})')
    length = across_m(xyz_world[:, :2])
    if length > config.max_object_across_m:
        return refused(NO_OBJECT, f'the top face found is {1000.0 * length:.0f} mm long on the '
                                  'work surface, longer than any object '
                                  f'(max_object_across_m={config.max_object_across_m:g})')
    face_heights = heights[band]
    # The scatter the points' own noise does not explain: a far rig's face scatters by its
    # noise and is still one level face; side-wall, table or badly matched points add to it.
    spread = float(np.std(face_heights))
    noise = float(np.median(sigma[band]))
    excess = math.sqrt(max(0.0, spread ** 2 - noise ** 2))
    # A match on the pixel grid stands for the patch of the face its pixel sees,
    # Z_rect^3 / (f^2 |n . v|): |n . v| is the same for every point of a level face and Z_rect
    # is f B / d. Matches anywhere else (geometric scenes) are taken as spread evenly.
    weight = disparity[band] ** -3.0 if on_pixel_grid(u_left) else np.ones(used)
    weight /= weight.mean()
    face = CorrelationArea(STATUS_OK, '', points_in, valid, regions, used,
                           float(np.median(face_heights)), xyz_world, u_left[band],
                           v_left[band], u_right[band], score[band], weight, surface,
                           found.median_sigmas)
    if config.max_top_spread_m and excess > config.max_top_spread_m:
        why = (f"the top face's heights scatter by {1000.0 * spread:.1f} mm (standard "
               f"deviation), {1000.0 * excess:.1f} mm beyond what its points' noise "
               f'({1000.0 * noise:.1f} mm) explains, more than max_top_spread_m='
               f'{config.max_top_spread_m:g}: not measured well enough for a point')
        # The plain-top fallbacks (face_outline.py) would take the plain pixels around a
        # textured object, the surface, for its face.
        return dataclasses.replace(refused(UNCERTAIN_TOP, why),
                                   scattered_face=None if textured else face)
    fill = hull_fill(u_left[band], v_left[band], step)
    if fill < config.min_top_fill:
        in_pieces = refused(UNCERTAIN_TOP, f"the top face's matches fill {100.0 * fill:.0f} % of "
                                           f'its outline in the image, less than min_top_fill='
                                           f'{config.min_top_fill:g}: a face in pieces')
        return dataclasses.replace(in_pieces, face_in_pieces=None if textured else face)
    return face
