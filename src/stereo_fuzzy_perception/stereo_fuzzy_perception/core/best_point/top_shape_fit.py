"""The top face fitted as a disc or a rectangle to both images, pixel by pixel. ROS-free.

The correlation area's outline comes from the left image's edges around the matches, and on
coarse rigs it errs by about a pixel either way: a correlation window straddling the rim takes
the disparity of whichever side is textured more. Here the outline is found from both images
at once, pixel by pixel, with no window:

- Each pixel of a crop around the area is compared with the right image where three surfaces
  would put it: the top face's plane (at the area's top height), the work surface, and the
  side wall (the planes between them, taken where the pixel's ray enters the object). The
  cost of a pixel on a surface is |right - (gain * left + offset)| in units of the table's
  contrast, capped at CAP (gain and offset fitted on the crop's pixels far from the area).
- A top face is a disc (centre, radius) or a rectangle (centre, angle, sides) on the top's
  plane. It labels each pixel: on the top when its ray meets the plane inside the shape, on
  the wall when its ray enters the object's side before reaching the surface, on the surface
  otherwise; a surface pixel that the object hides from the right camera costs what a
  mismatch costs (the crop's median cost at the top's disparity far from the area). Labels
  are soft across one pixel, so the summed cost moves smoothly with the shape.
- Both shapes are fitted by Nelder-Mead from the area's point and principal axes, started
  again where the simplex stalled; the lower cost wins.
- To be cheap enough for a node: where a pixel's ray enters the object and whether the object
  hides its surface point from the right camera are computed exactly for the two shapes (no
  stepping down the ray), only the pixels whose label a shape near the starting ones can
  change are scored shape by shape (BAND_M), and the cost runs in numba.

BestPointChooser moves its point toward the fitted centre only where the fit agrees with it
(within MAX_MOVE_M, or FAR_MOVE_M taken whole), lowered the cost clearly (MIN_DROP per pixel)
and is found again from starts shifted around its own (MAX_SPREAD_M): a fit that lowered the
cost by little found nothing, a periodic table can match the top's disparity a centimetre
away, and a fit whose shifted starts end elsewhere at nearly its cost sits in a flat valley of
the cost, not at the top. benchmarks/outline_fit_probe.py measures the rule's variants on the
tuning splits.
"""

from __future__ import annotations

import math
import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import cv2
import numba
import numpy as np
from scipy import optimize

from stereo_fuzzy_perception.core.best_point.correlation_area import CorrelationArea
from stereo_fuzzy_perception.core.best_point.face_outline import world_rays
from stereo_fuzzy_perception.core.best_point.plain_top_height import plane_disparity
from stereo_fuzzy_perception.core.camera_model import CameraCalibration
from stereo_fuzzy_perception.core.matched_points import MatchedPoints, RectifiedImage

DISC, RECTANGLE = 0, 1
SHAPE_NAMES = ('disc', 'rectangle')

CAP = 1.5
"""A pixel's cost is capped at this many times the table's grey-level spread."""

MARGIN_PX = 25
"""The crop reaches this far beyond the area."""

FAR_PX = 15
"""Pixels this far from the area are the table's: they fit gain and offset."""

MIN_FAR_PIXELS = 200
"""Fewer table pixels than this in the crop fit no gain and offset: no fit."""

MIN_PARALLAX_PX = 0.5
"""A top whose plane and the surface's differ by less in the right image is not fitted: below
half a pixel the labels top and surface hardly differ in cost. Above it the lowest objects'
tops on near rigs are fitted too (why, measured: the package README, "The top fitted to both
images")."""

SAMPLES = 30
"""Heights at which the side wall's cost is taken, from a tenth of the top's height below it
down to the surface; a wall pixel costs what it does at the first of them below where its ray
enters the object (10 quantise a tall wall's disparity too coarsely: the fit then prefers
wrong shapes)."""

RESTARTS = 1
"""Nelder-Mead is started again where its simplex stalled, up to this often (more restarts
and a smaller simplex at the end gave the same points on the tuning splits, at a higher
cost: benchmarks/EXPERIMENTS.md, nineteenth session)."""

SIMPLEX_SIZE_M = 1e-4
"""Nelder-Mead stops when its simplex is this small (and its costs within half a unit)."""

BAND_M = 0.005
"""Shapes are scored on the pixels whose label a shape reaching this much further out or in
than the guessed ones (and two pixels) can change; a shape reaching further is scored as if
the pixels beyond kept their labels."""

MAX_MOVE_M = 0.007
"""A fitted centre within this of the chain's point is taken WEIGHT of the way..."""

FAR_MOVE_M = 0.012
"""...but whole, up to this far: a fit found again from every start (each shifted fit ending
as low, within MAX_SPREAD_M) that lies so far from the point says that the point is off, and
the fit is the better of the two (on the tuning splits such points were mostly far off and
their fits close to the true centre; a few points it moves get worse). Fits that some starts
left for another shape took more good points away than they mended
(benchmarks/EXPERIMENTS.md, twenty-ninth and thirty-second sessions)."""

MIN_DROP = 0.005
"""A fit that lowered the cost by less than this per pixel of the crop is not taken."""

SHIFTED_START_M = 0.002
"""The winning shape is fitted again from its start moved this far along x and along y, each
way: four more fits as thorough as the first (cheaper ones, unrestarted and stopped at a
coarser simplex, took fewer points within 3 mm: benchmarks/EXPERIMENTS.md, twenty-ninth
session)."""

SHIFT_DIRECTIONS = ((1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0))
"""The directions (x, y) the winning shape's start is moved in, SHIFTED_START_M each."""

NEAR_COST_PER_PX = 0.003
"""A shifted start's minimum within this of the fit's cost per pixel of the crop is as good
as the fit (so is a lower one)."""

MAX_SPREAD_M = 0.0015
"""A fitted centre is not taken when an as-good minimum lies further than this from it: the
cost's valley is flat there, and where the fit ends is chance (chosen with MAX_MOVE_M,
FAR_MOVE_M and MIN_DROP: benchmarks/EXPERIMENTS.md, twenty-ninth session)."""

WEIGHT = 0.7
"""The point is moved this share of the way to a fitted centre within MAX_MOVE_M that passed
the tests above..."""

SHARP_SPREAD_M = 0.00025
"""...and all the way when every shifted start ended within this of it: the cost's valley is
sharp there, and on the tuning and check runs such fits lay closer to the true centre than
the chain's point far more often than not (benchmarks/EXPERIMENTS.md, thirty-second
session)."""

REFUSED_FACE_MIN_DROP = 0.01
"""A face refused after every look as in pieces (AreaConfig.min_top_fill) or as smaller in the
left image than any object's top (correlation_area.MIN_OBJECT_AREA_PX) is given the centre of
the top fitted around it, whole, when the fit is found again (a shifted start ends as low, and
every one that does within MAX_SPREAD_M) and lowered the cost by at least this per pixel:
twice MIN_DROP, for the fit is then the only evidence of where the top is (the few bare
tables' blotches whose fits were found again had drops just below it: benchmarks/
EXPERIMENTS.md, thirtieth session). A fit that no shifted start ended at as low a cost is not
found again, though its spread is 0: the probes over refused faces found such fits mostly far
off."""

SAME_OBJECT_M = 0.004
"""A TopShapeMemory gives its fit again for a point this close to the one it was made for
(the fitted centre is still taken only within FAR_MOVE_M of the new point)."""

FULL_RESOLUTION_PX = 50
"""A face up to this wide or tall in the left image is scored on every pixel of its crop; a
wider one on every second (up to twice this), third...: the fit's cost grows with the crop,
and a wide face has pixels to spare."""

MAX_TOP_WIDTH_PX = 150
"""A face wider or taller than this in the left image is not fitted. Faces over twice
FULL_RESOLUTION_PX are scored on every third pixel, so a face up to this wide costs about
what one of 100 px does (why this bound, measured: the package README, "The top fitted to
both images")."""


def _disc_fitter() -> ThreadPoolExecutor:
    return ThreadPoolExecutor(max_workers=1, thread_name_prefix='top_shape_fit')


_DISC_FITTER = _disc_fitter()
"""Fits the disc while the calling thread fits the rectangle, then half of the winner's
shifted fits while the calling thread fits the other half (fit_top_shape)."""


def _new_disc_fitter_after_fork() -> None:
    # A forked child inherits the executor without its thread, but with the count of an idle
    # one: its first disc would wait forever. It gets an executor of its own.
    global _DISC_FITTER
    _DISC_FITTER = _disc_fitter()


os.register_at_fork(after_in_child=_new_disc_fitter_after_fork)


@dataclass(frozen=True)
class TopShapeCosts:
    """What every hypothesis of the top is scored on: a crop's pixels and their costs.

    Arrays hold the band's pixels, laid out pixel first for the kernel (N pixels, S
    heights)."""

    on_top: np.ndarray  # (N, 2) where each pixel's ray meets the top's plane [m]
    wall: np.ndarray  # (N, 4) x0, y0, x1, y1 [m]: the ray's path from below the top's plane
    # to the surface, where it may enter the side wall
    view: np.ndarray  # (N, 4) the surface point's view line to the right camera, up to the
    # top's level: the object hides the point where it crosses the shape
    metres_per_px: np.ndarray  # (N,) between the scored pixels, on the top's plane
    top_cost: np.ndarray  # (N,)
    wall_cost: np.ndarray  # (N, S) at each sampled wall height
    surface_cost: np.ndarray  # (N,)
    mismatch: float
    constant: float  # the summed cost of the crop's pixels outside the band
    pixels: int  # in the crop, band or not

    def cost(self, shape: int, parameters: np.ndarray) -> float:
        """Return the summed cost of the pixels labelled by the shape (DISC: cx, cy, radius;
        RECTANGLE: cx, cy, angle, side along the angle, side across it)."""
        return self.constant + float(_total_cost(
            shape, np.asarray(parameters, dtype=np.float64), self.on_top, self.wall,
            self.view, self.metres_per_px, self.top_cost, self.wall_cost, self.surface_cost,
            self.mismatch))


@dataclass(frozen=True)
class TopShapeFit:
    """The best shape found, its centre on the surface, how much it lowered the cost per
    pixel of the crop against the area's own disc, how far from the centre the fits from
    shifted starts ended at as low a cost (0: all of them at the centre, or none as low), and
    how many of those fits ended as low."""

    shape: str
    centre: np.ndarray  # (2,) [m]
    drop_per_px: float
    spread_m: float = 0.0
    found_again: int = len(SHIFT_DIRECTIONS)


@numba.njit(cache=True, nogil=True)
def _signed_distance(shape: int, p: np.ndarray, cos: float, sin: float, x: float,
                     y: float) -> float:
    """Return the signed distance [m] of (x, y) from the shape: < 0 inside."""
    dx: float = x - p[0]
    dy: float = y - p[1]
    if shape == DISC:
        radius: float = p[2]
        return math.sqrt(dx * dx + dy * dy) - radius
    half_a: float = p[3] / 2.0
    half_b: float = p[4] / 2.0
    beyond_a = abs(cos * dx + sin * dy) - half_a
    beyond_b = abs(-sin * dx + cos * dy) - half_b
    outside_a, outside_b = max(beyond_a, 0.0), max(beyond_b, 0.0)
    return math.sqrt(outside_a * outside_a + outside_b * outside_b) + min(
        max(beyond_a, beyond_b), 0.0)


@numba.njit(cache=True, nogil=True)
def _segment_distance(x0: float, y0: float, x1: float, y1: float, cx: float,
                      cy: float) -> float:
    """Return the distance of (cx, cy) from the segment (x0, y0)-(x1, y1)."""
    dx, dy = x1 - x0, y1 - y0
    length2 = dx * dx + dy * dy
    t = 0.0
    if length2 > 0.0:
        t = min(max(((cx - x0) * dx + (cy - y0) * dy) / length2, 0.0), 1.0)
    ex, ey = x0 + t * dx - cx, y0 + t * dy - cy
    return math.sqrt(ex * ex + ey * ey)


@numba.njit(cache=True, nogil=True)
def _slab(start: float, step: float, half: float) -> tuple[float, float]:
    """Return the parameters (low, high) between which start + t * step lies within +-half."""
    if abs(step) < 1e-15:
        return (-1e30, 1e30) if abs(start) < half else (1e30, -1e30)
    low, high = (-half - start) / step, (half - start) / step
    return (low, high) if low <= high else (high, low)


@numba.njit(cache=True, nogil=True)
def _box_nearest(t: float, sx: float, sy: float, ex: float, ey: float, hx: float, hy: float,
                 nearest: float, nearest_at: float) -> tuple[float, float]:
    """Return the lesser of (nearest, nearest_at) and the signed distance of the point at t
    (clipped to [0, 1]) of the segment (sx, sy) + t (ex, ey) from the box +-hx, +-hy, with t."""
    t = min(max(t, 0.0), 1.0)
    beyond_a, beyond_b = abs(sx + t * ex) - hx, abs(sy + t * ey) - hy
    outside_a, outside_b = max(beyond_a, 0.0), max(beyond_b, 0.0)
    distance = math.sqrt(outside_a * outside_a + outside_b * outside_b) + min(
        max(beyond_a, beyond_b), 0.0)
    return (distance, t) if distance < nearest else (nearest, nearest_at)


@numba.njit(cache=True, nogil=True)
def _segment_in_shape(shape: int, p: np.ndarray, cos: float, sin: float, x0: float, y0: float,
                      x1: float, y1: float) -> tuple[float, float, float, float]:
    """Return where the segment (x0, y0)-(x1, y1), as t in [0, 1], runs inside the shape
    (t_in, t_out; t_in >= t_out when it never does), and the least signed distance of its
    points from the shape with the t where it lies.

    The shapes are convex and their signed distances convex along a line, so the least lies
    at an end or where the line crosses a boundary between the distance's pieces: a side's
    line, an axis or a diagonal of the inside, or the foot of a corner."""
    ax, ay, dx, dy = x0 - p[0], y0 - p[1], x1 - x0, y1 - y0
    if shape == DISC:
        a, b, c = dx * dx + dy * dy, ax * dx + ay * dy, ax * ax + ay * ay - p[2] * p[2]
        if a <= 0.0:
            nearest = math.sqrt(ax * ax + ay * ay) - p[2]
            return (-1e30, 1e30, nearest, 0.0) if c < 0.0 else (1e30, -1e30, nearest, 0.0)
        foot = min(max(-b / a, 0.0), 1.0)
        nx, ny = ax + foot * dx, ay + foot * dy
        nearest = math.sqrt(nx * nx + ny * ny) - p[2]
        discriminant = b * b - a * c
        if discriminant <= 0.0:
            return 1e30, -1e30, nearest, foot
        root = math.sqrt(discriminant)
        return (-b - root) / a, (-b + root) / a, nearest, foot
    # in the rectangle's own axes
    sx, sy = cos * ax + sin * ay, -sin * ax + cos * ay
    ex, ey = cos * dx + sin * dy, -sin * dx + cos * dy
    hx, hy = p[3] / 2.0, p[4] / 2.0
    low_x, high_x = _slab(sx, ex, hx)
    low_y, high_y = _slab(sy, ey, hy)
    t_in, t_out = max(low_x, low_y), min(high_x, high_y)
    best = _box_nearest(0.0, sx, sy, ex, ey, hx, hy, 1e30, 0.0)
    best = _box_nearest(1.0, sx, sy, ex, ey, hx, hy, *best)
    for t in (low_x, high_x, low_y, high_y):
        best = _box_nearest(t, sx, sy, ex, ey, hx, hy, *best)
    if max(t_in, 0.0) < min(t_out, 1.0):
        # inside, the distance is max(|x| - hx, |y| - hy): its pieces meet on the axes and
        # the diagonals; the corners' feet, outside, cannot be nearer
        for along, start in ((ex, sx), (ey, sy)):  # the axes, where |x| or |y| turns
            if abs(along) > 1e-15:
                best = _box_nearest(-start / along, sx, sy, ex, ey, hx, hy, *best)
        gap = hx - hy
        for along, start in ((ex - ey, sx - sy), (ex + ey, sx + sy)):
            if abs(along) > 1e-15:
                best = _box_nearest((gap - start) / along, sx, sy, ex, ey, hx, hy, *best)
                best = _box_nearest((-gap - start) / along, sx, sy, ex, ey, hx, hy, *best)
    else:
        # outside, the distance to a side is linear and to a corner least at the corner's foot
        length2 = ex * ex + ey * ey
        if length2 > 0.0:
            for corner_x, corner_y in ((hx, hy), (hx, -hy), (-hx, hy), (-hx, -hy)):
                best = _box_nearest(((corner_x - sx) * ex + (corner_y - sy) * ey) / length2,
                                    sx, sy, ex, ey, hx, hy, *best)
    nearest, nearest_at = best
    return t_in, t_out, nearest, nearest_at


@numba.njit(cache=True, nogil=True)
def signed_distances(shape: int, p: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """Return the signed distances [m] of the points xy (N, 2) from the shape: < 0 inside."""
    cos, sin = (math.cos(p[2]), math.sin(p[2])) if shape == RECTANGLE else (1.0, 0.0)
    result = np.empty(xy.shape[0])
    for i in range(xy.shape[0]):
        result[i] = _signed_distance(shape, p, cos, sin, xy[i, 0], xy[i, 1])
    return result


@numba.njit(cache=True, nogil=True)
def _apart_at_least(shape: int, p: np.ndarray, cos: float, sin: float, reach: float,
                    x0: float, y0: float, x1: float, y1: float) -> float:
    """Return a lower bound [m] of the distance between the segment (x0, y0)-(x1, y1) and the
    shape: how far it passes beyond the shape's bounding circle (radius `reach`) and, for a
    rectangle, how far the segment's box in the rectangle's own axes lies from it."""
    apart = _segment_distance(x0, y0, x1, y1, p[0], p[1]) - reach
    if shape == DISC:
        return apart
    ax, ay, bx, by = x0 - p[0], y0 - p[1], x1 - p[0], y1 - p[1]
    sx0, sy0 = cos * ax + sin * ay, -sin * ax + cos * ay
    sx1, sy1 = cos * bx + sin * by, -sin * bx + cos * by
    hx, hy = p[3] / 2.0, p[4] / 2.0
    gap_x = max(min(sx0, sx1) - hx, -hx - max(sx0, sx1), 0.0)
    gap_y = max(min(sy0, sy1) - hy, -hy - max(sy0, sy1), 0.0)
    return max(apart, math.sqrt(gap_x * gap_x + gap_y * gap_y))


@numba.njit(cache=True, nogil=True)
def _total_cost(shape: int, p: np.ndarray, on_top: np.ndarray, wall: np.ndarray,
                view: np.ndarray, metres_per_px: np.ndarray, top_cost: np.ndarray,
                wall_cost: np.ndarray, surface_cost: np.ndarray, mismatch: float) -> float:
    """Return the summed cost of the pixels labelled by the shape (TopShapeCosts.cost).

    A pixel's wall cost is the one of the first sampled height inside the object, as if the
    ray were walked down in steps. A segment that passes further than half a pixel from the
    shape (_apart_at_least) labels nothing and is not looked at."""
    count, samples = wall.shape[0], wall_cost.shape[1]
    if shape == DISC:
        cos, sin, reach = 1.0, 0.0, p[2]
    else:
        cos, sin, reach = math.cos(p[2]), math.sin(p[2]), 0.5 * math.hypot(p[3], p[4])
    last = samples - 1
    total = 0.0
    for i in range(count):
        pixel = metres_per_px[i]
        top = min(max(0.5 - _signed_distance(shape, p, cos, sin, on_top[i, 0], on_top[i, 1])
                      / pixel, 0.0), 1.0)
        if top >= 1.0:
            total += top_cost[i]
            continue
        side, entered = 0.0, 0
        x0, y0, x1, y1 = wall[i, 0], wall[i, 1], wall[i, 2], wall[i, 3]
        if _apart_at_least(shape, p, cos, sin, reach, x0, y0, x1, y1) < 0.5 * pixel:
            t_in, t_out, nearest, nearest_at = _segment_in_shape(shape, p, cos, sin, x0, y0,
                                                                 x1, y1)
            entered = int(math.ceil(max(t_in, 0.0) * last)) if t_in < t_out else samples
            if entered > last or entered >= t_out * last:
                entered = int(round(nearest_at * last))  # never inside at a sampled height
            side = (1.0 - top) * min(max(0.5 - nearest / pixel, 0.0), 1.0)
        surface = 1.0 - top - side
        hidden = 0.0
        x0, y0, x1, y1 = view[i, 0], view[i, 1], view[i, 2], view[i, 3]
        if surface > 0.0 and _apart_at_least(shape, p, cos, sin, reach, x0, y0, x1,
                                             y1) < 0.5 * pixel:
            nearest = _segment_in_shape(shape, p, cos, sin, x0, y0, x1, y1)[2]
            hidden = min(max(0.5 - nearest / pixel, 0.0), 1.0)
        total += (top * top_cost[i] + side * wall_cost[i, entered]
                  + surface * ((1.0 - hidden) * surface_cost[i] + hidden * mismatch))
    return total


def top_shape_costs(area: CorrelationArea, left_image: RectifiedImage,
                    right_image: RectifiedImage, left: CameraCalibration,
                    right: CameraCalibration, world_from_camera: np.ndarray,
                    guess: np.ndarray, axes: tuple[float, float, float],
                    samples: int = SAMPLES) -> TopShapeCosts | None:
    """Return the costs of the crop around the area for shapes near the guessed centre (x, y)
    with the area's principal axes (angle, long side, short side), or None when the top barely
    stands out in disparity, the crop leaves either image part or has too little table in it.

    Only the pixels whose label a shape within BAND_M of the guessed ones can change are
    scored shape by shape (the band); the others add a constant."""
    pose = np.asarray(world_from_camera, dtype=float)
    surface = area.surface
    normal = surface.normal
    surface_level = surface.offset_m * float(normal[2])
    top_level = area.top_height + surface_level
    height, width = left_image.pixels.shape[:2]
    u_low = max(int(area.u_left.min()) - MARGIN_PX, left_image.x + 2)
    v_low = max(int(area.v_left.min()) - MARGIN_PX, left_image.y + 1)
    u_high = min(int(area.u_left.max()) + MARGIN_PX + 1, left_image.x + width - 2)
    v_high = min(int(area.v_left.max()) + MARGIN_PX + 1, left_image.y + height - 1)
    if u_high <= u_low or v_high <= v_low:
        return None
    # a face wider than FULL_RESOLUTION_PX is scored on every step-th pixel of the crop
    step = max(1, math.ceil(max(np.ptp(area.u_left), np.ptp(area.v_left))
                            / FULL_RESOLUTION_PX))
    columns, rows = (grid.ravel() for grid in np.meshgrid(
        np.arange(u_low, u_high, step, dtype=float), np.arange(v_low, v_high, step, dtype=float)))
    column_at = plane_disparity(left, right, pose, surface)
    on_top_right, on_surface_right = (column_at(columns, rows, area.top_height),
                                      column_at(columns, rows, 0.0))
    if not (np.all(np.isfinite(on_top_right)) and np.all(np.isfinite(on_surface_right))):
        return None  # a ray parallel to the planes: the pose does not see them
    if not (abs(float(np.median(on_top_right - on_surface_right))) >= MIN_PARALLAX_PX):
        return None
    right_height, right_width = right_image.pixels.shape[:2]
    if rows.min() < right_image.y or rows.max() > right_image.y + right_height - 1:
        return None
    for right_columns in (on_top_right, on_surface_right):
        if right_columns.min() < right_image.x + 1 or (
                right_columns.max() > right_image.x + right_width - 2):
            return None
    right_pixels = right_image.pixels.astype(np.float32)
    left_grey = left_image.pixels.astype(np.float32)[
        (rows - left_image.y).astype(int), (columns - left_image.x).astype(int)]
    chain = np.zeros((len(np.unique(rows)), len(np.unique(columns))), np.uint8)
    chain[((np.rint(area.v_left) - v_low) // step).astype(int).clip(0, chain.shape[0] - 1),
          ((np.rint(area.u_left) - u_low) // step).astype(int).clip(0, chain.shape[1] - 1)] = 1
    reach = math.ceil(FAR_PX / step)
    far = cv2.dilate(chain, np.ones((2 * reach + 1,) * 2, np.uint8)).ravel() == 0
    if np.count_nonzero(far) * step ** 2 < MIN_FAR_PIXELS:
        return None
    row_in_right = (rows - right_image.y).astype(np.int64)
    surface_grey = _along_rows(right_pixels, on_surface_right - right_image.x, row_in_right)
    gain, offset = np.linalg.lstsq(np.column_stack([left_grey[far], np.ones(np.count_nonzero(
        far))]), surface_grey[far], rcond=None)[0]
    unit = max(float(np.std(left_grey[far])) * abs(float(gain)), 1e-3)
    expected = gain * left_grey + offset

    def cost_at(heights_m: np.ndarray, pixels: np.ndarray) -> np.ndarray:
        """Return the costs (heights, pixels) of the pixels on planes at those heights."""
        right_columns = column_at(columns[pixels][None, :], rows[pixels][None, :],
                                  np.asarray(heights_m, dtype=float)[:, None])
        grey = _along_rows(right_pixels, (right_columns - right_image.x).ravel(),
                           np.broadcast_to(row_in_right[pixels], right_columns.shape).ravel())
        cost: np.ndarray = np.minimum(np.abs(grey.reshape(right_columns.shape)
                                             - expected[pixels]) / unit, CAP)
        return cost

    top_cost = cost_at(np.array([area.top_height]), np.arange(len(columns)))[0]
    surface_cost = np.minimum(np.abs(surface_grey - expected) / unit, CAP)
    mismatch = float(np.median(top_cost[far]))
    rays = world_rays(columns, rows, left, pose)
    centre = pose[:3, 3]
    facing = normal @ rays
    top_depth = (top_level - normal @ centre) / facing
    surface_depth = (surface_level - normal @ centre) / facing
    if not (np.all(top_depth > 0.0) and np.all(surface_depth > 0.0)):
        return None  # a plane behind the camera for some pixel: no view of the object
    on_top = (centre[:, None] + rays * top_depth)[:2].T
    on_surface = centre[:, None] + rays * surface_depth
    focal = float(np.asarray(left.P, dtype=float)[0, 0])
    baseline = -float(np.asarray(right.P, dtype=float)[0, 3]) / focal
    rectification = np.asarray(left.R, dtype=float).reshape(3, 3)
    right_centre = centre + pose[:3, :3] @ rectification.T @ np.array([baseline, 0.0, 0.0])
    # between the samples: the labels are soft across one of them
    metres_per_px = step * top_depth * np.linalg.norm(rays, axis=0) / focal
    # where the surface point's view line to the right camera reaches the top's level
    view_reach = (top_level - on_surface[2]) / (right_centre[2] - on_surface[2])
    view_end = (on_surface[:2] + (right_centre[:2, None] - on_surface[:2]) * view_reach).T

    angle, long_side, short_side = axes
    band_m = BAND_M + 2.0 * float(np.median(metres_per_px))
    radius = math.sqrt((long_side ** 2 + short_side ** 2) / 12.0)
    outer = max(radius, 0.5 * math.hypot(long_side, short_side)) + band_m
    inner = min(radius, 0.5 * short_side) - band_m - metres_per_px
    guess = np.asarray(guess, dtype=float)
    from_guess = np.hypot(*(on_top - guess).T)
    inside = from_guess < inner
    outside = (from_guess > outer) & (_segments_from(on_top, on_surface[:2].T, guess) > outer) & (
        _segments_from(on_surface[:2].T, view_end, guess) > outer)
    band = np.flatnonzero(~inside & ~outside)
    # the wall's heights are sampled from a tenth of the top's height below it down to the
    # surface; the view line from a twentieth of it above the surface up to the top's level
    fractions = np.linspace(0.1, 1.0, samples)
    wall_cost = cost_at(area.top_height * (1.0 - fractions), band)
    top_xy, surface_xy = on_top[band], on_surface[:2, band].T
    wall = np.hstack([top_xy + 0.1 * (surface_xy - top_xy), surface_xy])
    view_start = surface_xy + 0.05 * (view_end[band] - surface_xy)
    view = np.hstack([view_start, view_end[band]])
    constant = float(np.sum(top_cost[inside]) + np.sum(surface_cost[outside]))
    return TopShapeCosts(
        np.ascontiguousarray(top_xy), np.ascontiguousarray(wall), np.ascontiguousarray(view),
        np.ascontiguousarray(metres_per_px[band]),
        np.ascontiguousarray(top_cost[band], dtype=np.float64),
        np.ascontiguousarray(wall_cost.T, dtype=np.float64),
        np.ascontiguousarray(surface_cost[band], dtype=np.float64), mismatch, constant,
        len(columns))


@numba.njit(cache=True, nogil=True)
def _along_rows(pixels: np.ndarray, columns: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """Return the grey levels at (column, row) of the image, linear along its rows (rectified
    images share their rows), the nearest edge pixel beyond its sides."""
    last = pixels.shape[1] - 1
    result = np.empty(len(columns), dtype=np.float64)
    for i in range(len(columns)):
        column = min(max(columns[i], 0.0), float(last)) if columns[i] == columns[i] else 0.0
        left = min(int(column), last - 1)
        share = column - left
        row = pixels[rows[i]]
        result[i] = (1.0 - share) * row[left] + share * row[left + 1]
    return result


def _segments_from(starts: np.ndarray, ends: np.ndarray, point: np.ndarray) -> np.ndarray:
    """Return the distance of the point (2,) from each segment starts[i]-ends[i] (N, 2)."""
    direction = ends - starts
    length2 = np.maximum(np.sum(direction ** 2, axis=1), 1e-30)
    t = np.clip(np.sum((point - starts) * direction, axis=1) / length2, 0.0, 1.0)
    distance: np.ndarray = np.hypot(*(starts + t[:, None] * direction - point).T)
    return distance


def principal_axes(xy: np.ndarray) -> tuple[float, float, float]:
    """Return the angle [rad] and the long and short sides [m] of the uniform rectangle with
    the spread of the points xy (as object_segmentation.across_m)."""
    variances, vectors = np.linalg.eigh(np.cov(np.asarray(xy, dtype=float).T))
    return (math.atan2(vectors[1, 1], vectors[0, 1]), math.sqrt(12.0 * max(variances[1], 1e-10)),
            math.sqrt(12.0 * max(variances[0], 1e-10)))


def _minimise(costs: TopShapeCosts, shape: int, start: np.ndarray, scales: np.ndarray,
              restarts: int) -> optimize.OptimizeResult:
    """Return Nelder-Mead's minimum from `start`, started again where it stalled."""
    result = None
    for _ in range(restarts + 1):
        origin = start if result is None else result.x
        simplex = np.vstack([origin] + [origin + np.eye(len(origin))[i] * scales[i]
                                        for i in range(len(origin))])
        again = optimize.minimize(lambda p: costs.cost(shape, p), origin, method='Nelder-Mead',
                                  options={'initial_simplex': simplex, 'xatol': SIMPLEX_SIZE_M,
                                           'fatol': 0.5, 'maxiter': 400})
        if result is not None and again.fun >= result.fun - 0.5:
            break  # Nelder-Mead's simplex collapses short of the minimum: restarted, it goes on
        result = again
    return result


def fit_top_shape(costs: TopShapeCosts, guess: np.ndarray, axes: tuple[float, float, float],
                  restarts: int = RESTARTS) -> TopShapeFit:
    """Fit a disc and a rectangle from the guessed centre (x, y) and the area's principal axes
    (angle, long side, short side); return the one of lower cost."""
    angle, long_side, short_side = axes
    step = 2.0 * float(np.median(costs.metres_per_px))
    # the disc starts at the radius whose spread is the area's total
    disc = np.array([*guess, math.sqrt((long_side ** 2 + short_side ** 2) / 12.0)])
    starts = {DISC: (disc, np.array([step, step, step])),
              RECTANGLE: (np.array([*guess, angle, long_side, short_side]),
                          np.array([step, step, 0.15, step, step]))}
    # the disc's fit runs beside the rectangle's: the kernel releases the GIL
    disc_fit = _DISC_FITTER.submit(_minimise, costs, DISC, *starts[DISC], restarts)
    fits = {RECTANGLE: _minimise(costs, RECTANGLE, *starts[RECTANGLE], restarts),
            DISC: disc_fit.result()}
    shape = min((DISC, RECTANGLE), key=lambda name: fits[name].fun)
    best = fits[shape]
    drop = (costs.cost(DISC, disc) - best.fun) / costs.pixels
    start, scales = starts[shape]
    shifted = []
    for direction in SHIFT_DIRECTIONS:
        moved = start.copy()
        moved[:2] += SHIFTED_START_M * np.asarray(direction)
        shifted.append(moved)
    # two of the shifted fits run in the second thread while this one runs the other two
    elsewhere = [_DISC_FITTER.submit(_minimise, costs, shape, moved, scales, restarts)
                 for moved in shifted[:2]]
    others = [_minimise(costs, shape, moved, scales, restarts) for moved in shifted[2:]]
    others += [future.result() for future in elsewhere]
    as_good = [np.hypot(*(other.x[:2] - best.x[:2])) for other in others
               if other.fun <= best.fun + NEAR_COST_PER_PX * costs.pixels]
    return TopShapeFit(SHAPE_NAMES[shape], np.asarray(best.x[:2], dtype=float), drop,
                       float(max(as_good, default=0.0)), len(as_good))


def fitted(area: CorrelationArea, points: MatchedPoints, left: CameraCalibration,
           right: CameraCalibration, world_from_camera: np.ndarray, guess: np.ndarray,
           samples: int = SAMPLES, restarts: int = RESTARTS) -> TopShapeFit | None:
    """Return the top fitted around the guessed centre (x, y) [m] of the area's face, or None
    when there is no face, the matches came without both images, the face is wider than
    MAX_TOP_WIDTH_PX, or the crop cannot be scored (top_shape_costs)."""
    if not area.ok or points.left_image is None or points.right_image is None or len(
            area.xyz_world) < 3:
        return None
    if max(np.ptp(area.u_left), np.ptp(area.v_left)) > MAX_TOP_WIDTH_PX:
        return None
    axes = principal_axes(area.xyz_world[:, :2])
    costs = top_shape_costs(area, points.left_image, points.right_image, left, right,
                            world_from_camera, guess, axes, samples)
    return None if costs is None else fit_top_shape(costs, guess, axes, restarts)


def moved_toward_fit(point: np.ndarray, fit: TopShapeFit | None, weight: float = WEIGHT,
                     max_move_m: float = MAX_MOVE_M, min_drop: float = MIN_DROP,
                     max_spread_m: float = MAX_SPREAD_M,
                     far_move_m: float = FAR_MOVE_M,
                     sharp_spread_m: float = SHARP_SPREAD_M) -> np.ndarray:
    """Return the point moved toward the fitted centre on the surface when the fit lowered the
    cost by min_drop per pixel and its shifted starts ended within max_spread_m of it:
    `weight` of the way when the centre lies within max_move_m of the point (all the way when
    every shifted start found it again within sharp_spread_m), all the way when it lies within
    far_move_m and every shifted start found it again; otherwise the point as it was."""
    point = np.array(point, dtype=float)
    if fit is None or not (fit.drop_per_px >= min_drop) or not (fit.spread_m <= max_spread_m):
        return point
    move = float(np.hypot(*(fit.centre - point[:2])))
    found_by_every_start = fit.found_again >= len(SHIFT_DIRECTIONS)
    if move <= max_move_m:
        sharp = found_by_every_start and fit.spread_m <= sharp_spread_m
        share = 1.0 if sharp else weight
        point[:2] = (1.0 - share) * point[:2] + share * fit.centre
    elif move <= far_move_m and found_by_every_start:
        # the spread is only over the starts that ended as low: a fit that most starts left
        # for another shape is no reason to move a point this far (FAR_MOVE_M)
        point[:2] = fit.centre
    return point


def centre_for_refused_face(point: np.ndarray, fit: TopShapeFit | None,
                            min_drop: float = REFUSED_FACE_MIN_DROP,
                            max_spread_m: float = MAX_SPREAD_M) -> np.ndarray | None:
    """Return the point of a face refused as in pieces or as too small in the image
    (REFUSED_FACE_MIN_DROP) moved to its fitted centre, when the fit lowered the cost by
    min_drop per pixel, at least one shifted start found it again, and every one that ended as
    low ended within max_spread_m of it; None when the fit says too little for a point."""
    if fit is None or not (fit.drop_per_px >= min_drop) or not (
            fit.spread_m <= max_spread_m) or fit.found_again < 1:
        return None
    return np.array([*fit.centre, point[2]], dtype=float)


@dataclass
class TopShapeMemory:
    """The last top fitted, given again for the pairs of the same object that follow.

    A camera at 30 Hz sees a standing object for many pairs, and the fit costs far more than
    a decision: fuzzy_best_point_node fits an object's top once, on its first pair, and moves
    the points of the pairs after it toward the same fitted centre while their point stays
    within SAME_OBJECT_M of the first one's and the camera pose stays. Benchmarks decide each
    scene on its own and keep no memory.

    Attributes:
        point: The point (world) the remembered fit was made for, or None.
        pose: The camera pose it was made with.
        fit: The fit (None: the pair could not be fitted).
        counts: Fits made, fits given again, points moved toward a fit, faces in pieces and
            faces too small in the image given their fitted centre (BestPointChooser).
    """

    point: np.ndarray | None = None
    pose: np.ndarray | None = None
    fit: TopShapeFit | None = None
    counts: dict[str, int] = field(default_factory=lambda: dict(fitted=0, recalled=0, moved=0,
                                                                  pieces=0, small=0))

    def recall(self, point: np.ndarray, pose: np.ndarray) -> tuple[bool, TopShapeFit | None]:
        """Return (True, the fit) when one was made for the same object, else (False, None)."""
        if self.point is None or self.pose is None or not np.array_equal(self.pose, pose) or not (
                np.linalg.norm(np.asarray(point, dtype=float) - self.point) <= SAME_OBJECT_M):
            return False, None
        self.counts['recalled'] += 1
        return True, self.fit

    def remember(self, point: np.ndarray, pose: np.ndarray, fit: TopShapeFit | None) -> None:
        """Keep the fit made for the point."""
        self.point, self.pose, self.fit = (np.array(point, dtype=float),
                                           np.array(pose, dtype=float), fit)
        self.counts['fitted'] += 1


def fitted_around(area: CorrelationArea, points: MatchedPoints, left: CameraCalibration,
                  right: CameraCalibration, world_from_camera: np.ndarray, point: np.ndarray,
                  memory: TopShapeMemory | None = None) -> TopShapeFit | None:
    """Return the top fitted around the decision's point (fitted), given again by the memory
    where it has one for the same object."""
    known, fit = (memory.recall(point, world_from_camera) if memory is not None
                  else (False, None))
    if not known:
        fit = fitted(area, points, left, right, world_from_camera, point[:2])
        if memory is not None:
            memory.remember(point, world_from_camera, fit)
    return fit


def point_with_fitted_top(area: CorrelationArea, points: MatchedPoints,
                          left: CameraCalibration, right: CameraCalibration,
                          world_from_camera: np.ndarray, point: np.ndarray,
                          memory: TopShapeMemory | None = None) -> np.ndarray:
    """Return the decision's point moved toward the top fitted around it (moved_toward_fit)."""
    fit = fitted_around(area, points, left, right, world_from_camera, point, memory)
    moved = moved_toward_fit(point, fit)
    if memory is not None and not np.array_equal(moved, point):
        memory.counts['moved'] += 1
    return moved


def warm_up() -> None:
    """Compile (or load from numba's cache) the kernels, so the first fit is not slowed."""
    pixels = np.zeros((1, 2))
    segments = np.array([[0.0, 0.0, 0.01, 0.0]])
    ones = np.ones(1)
    costs = TopShapeCosts(pixels, segments, segments, np.full(1, 0.001), ones, np.ones((1, 2)),
                          ones, 1.0, 0.0, 1)
    costs.cost(DISC, np.array([0.0, 0.0, 0.01]))
    costs.cost(RECTANGLE, np.array([0.0, 0.0, 0.1, 0.02, 0.01]))
    signed_distances(DISC, np.array([0.0, 0.0, 0.01]), pixels)
    _along_rows(np.zeros((1, 2), dtype=np.float32), np.zeros(1), np.zeros(1, dtype=np.int64))
