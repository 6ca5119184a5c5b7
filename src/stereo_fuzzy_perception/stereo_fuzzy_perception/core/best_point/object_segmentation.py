"""The object among the points above the work surface, and its top face. ROS-free.

Heights come in units of each point's own noise (z = height / sigma_h, work_surface.py), so the
same thresholds hold near and far:

1. Candidates: points more than `margin_sigmas` above the surface.
2. Regions: candidates connected in the left image's grid of matches (8-neighbours, bridging a
   gap of one missing match). Table noise above the margin comes in blobs the size of a
   correlation window, an object as one region that covers its whole image.
3. An object is a region whose median z is at least `object_sigmas`: the tail of the surface
   noise that crossed the margin stays just above it, an object's top stands above it as a
   whole (a disc of 5 mm at 0.8 m in the rendered scenes: ~10 sigma). A region that covers
   several averaging squares holds as many independent averages of the noise, so its median
   is significant sooner: it is an object when its median times the square root of that
   number reaches `object_sigmas` and its top stands `area_top_sigmas` of one point's noise
   above the surface (the area test: a low disc on a far rig, a box whose region is half the
   table around it). Of several objects the one with the most points is kept; none means no
   object, whatever the noise did.
   On a plain work surface, or one of sparse marks, the confident matches off the object
   include scattered mismatches, which set the noise unit of step 3 and hide a low object.
   When no region is an object, the object is also looked for where the left image has
   texture (textured_regions, choose_textured_object): a textured region is an object when
   its matches' median height stands `object_sigmas` standard errors above the surface.
4. The top face: the highest dense level of the region's heights (bins of one sigma, a bin is
   dense when it holds TOP_DENSE_SHARE of the fullest), refined to the median of the heights
   within TOP_WINDOW_SIGMAS of it. The correlation area is the region's points within
   `band_sigmas` of that top: the face, not its highest noisy points, and only the rim of the
   side walls that noise cannot tell from the face.
"""

from __future__ import annotations

import contextlib
import math
from dataclasses import dataclass

import cv2
import numpy as np
from scipy import ndimage
from scipy.spatial import ConvexHull, QhullError

from stereo_fuzzy_perception.core.best_point.work_surface import MAD_SCALE
from stereo_fuzzy_perception.core.matched_points import RectifiedImage

TOP_DENSE_SHARE = 0.25
"""A height bin belongs to the object's top when it holds this share of the fullest bin."""

TOP_WINDOW_SIGMAS = 2.0
"""The top height is the median of the heights within this many sigmas of the dense top bin."""

TOP_MODE_ITERATIONS = 100
"""Most steps top_mode takes (each moves the level by at most TOP_WINDOW_SIGMAS)."""

TOP_MODE_TOLERANCE = 1e-3
"""top_mode stops when a step moves the level by less than this share of its window."""

TALL_REGION_SHARE = 4.0
"""A region whose median stands this many times object_sigmas out, yet whose densest heights
are the surface's, has its top taken from its points standing OFF_SURFACE_SIGMAS up: a tall
object whose top is poorly matched (plain, its heights scattered over many bins) and the
surface at its foot, which the averaging squares took into its region, fills the bins."""

OFF_SURFACE_SIGMAS = 3.0
"""...those points: this many sigmas of their own (and min_object_height_m) above the surface."""

TEXTURE_CONTRAST = 3.0
"""A pixel is textured when the grey levels' standard deviation over a correlation window
around it is this many times the TEXTURE_REFERENCE_PERCENTILE of the image's: on a plain work
surface that is the surface's own (sensor noise and faint marks); on a textured one the
surface is textured nearly everywhere, and its regions' matches lie on it."""

TEXTURE_REFERENCE_PERCENTILE = 25.0
"""The image's contrast level the surface's is taken as [%]: a low percentile, so that an
object filling much of a tracked region's crop does not raise it."""

TEXTURE_OPENING = 2
"""Openings (3 x 3 px) of the textured pixels: specks and thin lines of the surface's own marks
go, and a textured region does not join another through them."""

MAX_GRID_CELLS = 4_000_000
"""Largest image grid the regions are found on (a 2000 x 2000 image at point_stride 1)."""

_EIGHT_NEIGHBOURS = np.ones((3, 3), dtype=bool)


def on_pixel_grid(columns: np.ndarray) -> bool:
    """Return True when the matches lie on whole pixel columns (correlation_node's output)."""
    columns = np.asarray(columns, dtype=float)
    return bool(np.all(columns == np.round(columns)))


def grid_step(columns: np.ndarray, rows: np.ndarray) -> float:
    """Return the spacing [px] of the matches' image grid (correlation_node's point_stride).

    Matches on whole pixels: the greatest common divisor of the gaps between the distinct
    columns. Matches anywhere (geometric scenes): twice the mean spacing of the points over
    their bounding box, so that neighbours share or touch cells. Either way coarse enough
    that the grid has at most MAX_GRID_CELLS cells, whatever coordinates come in.
    """
    columns = np.asarray(columns, dtype=float)
    rows = np.asarray(rows, dtype=float)
    distinct = np.unique(columns)
    if len(distinct) < 2:
        step = 1.0
    elif np.all(distinct == np.round(distinct)):
        step = float(max(1, int(np.gcd.reduce(np.diff(distinct).astype(np.int64)))))
    else:
        extent = float(np.ptp(columns) * max(float(np.ptp(rows)), 1.0))
        step = max(1.0, 2.0 * math.sqrt(extent / len(columns)))
    span = (float(np.ptp(columns)) + 1.0) * (float(np.ptp(rows)) + 1.0) if len(rows) else 1.0
    return max(step, math.sqrt(span / MAX_GRID_CELLS))


def _grid_cells(u: np.ndarray, v: np.ndarray, step: float) -> tuple[np.ndarray, tuple[int, int]]:
    """Return each point's cell (linear index) in the image grid of spacing step, and its shape."""
    column = np.round(np.asarray(u, dtype=float) / step).astype(np.int64)
    row = np.round(np.asarray(v, dtype=float) / step).astype(np.int64)
    column -= column.min()
    row -= row.min()
    shape = (int(row.max()) + 1, int(column.max()) + 1)
    return row * shape[1] + column, shape


def square_cells(step: float, size_px: float) -> int:
    """Return the side [cells] of the averaging square of size_px on a grid of spacing step.

    Odd and at least one cell, so that the square is centred on its point.
    """
    return max(1, int(round(size_px / step)) | 1)


def smoothed_on_grid(u: np.ndarray, v: np.ndarray, values: np.ndarray, step: float,
                     size_px: float) -> np.ndarray:
    """Return each point's mean of `values` over the matches within a square of size_px.

    Args:
        u: (N,) left image column of every match [px], N > 0.
        v: (N,) row [px].
        values: (N,) what is averaged.
        step: Grid spacing [px] (grid_step).
        size_px: Side of the averaging square [px] (at least one cell).
    """
    cells, shape = _grid_cells(u, v, step)
    size = square_cells(step, size_px)
    total = ndimage.uniform_filter(np.bincount(cells, weights=values, minlength=shape[0]
                                               * shape[1]).reshape(shape), size, mode='constant')
    count = ndimage.uniform_filter(np.bincount(cells, minlength=shape[0] * shape[1]).astype(
        float).reshape(shape), size, mode='constant')
    mean: np.ndarray = total.reshape(-1)[cells] / count.reshape(-1)[cells]
    return mean


def plausible_average(u: np.ndarray, v: np.ndarray, values: np.ndarray, plausible: np.ndarray,
                      step: float, size_px: float) -> np.ndarray:
    """Return each point's mean of `values` over the plausible matches within a square of size_px.

    Args:
        u: (N,) left image column of every match [px], N > 0.
        v: (N,) row [px].
        values: (N,) what is averaged.
        plausible: (N,) bool, the matches that take part in the averages.
        step: Grid spacing [px] (grid_step).
        size_px: Side of the averaging square [px] (at least one cell).

    Returns:
        (N,) the means; -inf where the square holds no plausible match.
    """
    weight = np.asarray(plausible, dtype=float)
    # The ratio of two means over the same square: the sum over the plausible matches by
    # their number.
    total = smoothed_on_grid(u, v, np.where(plausible, values, 0.0), step, size_px)
    share = smoothed_on_grid(u, v, weight, step, size_px)
    mean: np.ndarray = np.full(len(weight), -np.inf)
    np.divide(total, share, out=mean, where=share > 0.0)
    return mean


def grown_region(u: np.ndarray, v: np.ndarray, member: np.ndarray, step: float,
                 size_px: float) -> np.ndarray:
    """Return the points within a square of size_px around any member, in the image grid.

    Args:
        u: (N,) left image column of every match [px], N > 0.
        v: (N,) row [px].
        member: (N,) bool, the region.
        step: Grid spacing [px] (grid_step).
        size_px: Side of the square [px].
    """
    cells, shape = _grid_cells(u, v, step)
    grid = np.zeros(shape[0] * shape[1], dtype=bool)
    grid[cells[member]] = True
    size = square_cells(step, size_px)
    grown = ndimage.maximum_filter(grid.reshape(shape), size, mode='constant')
    inside: np.ndarray = grown.reshape(-1)[cells]
    return inside


def hull_fill(u: np.ndarray, v: np.ndarray, step: float) -> float:
    """Return the share of the convex hull of points in the image that their cells cover.

    Each point stands for a step x step cell of the matches' grid; the hull is taken around
    the cells (grown by half a cell), so a solid patch of any size fills about 1. Fewer than
    three points or points on a line: 1 (no outline to fill).

    Args:
        u: (N,) left image column of every match [px].
        v: (N,) row [px].
        step: Grid spacing [px] (grid_step).
    """
    if len(u) < 3:
        return 1.0
    centres = np.column_stack([np.asarray(u, dtype=float), np.asarray(v, dtype=float)])
    # The hull of the cells is the hull of the corners of the cells at the centres' hull
    # vertices: two small hulls instead of one over four corners of every point. Centres on a
    # line have no hull: then every centre's corners.
    with contextlib.suppress(QhullError):
        centres = centres[ConvexHull(centres).vertices]
    half = 0.5 * step
    corners = np.concatenate([centres + (du, dv) for du in (-half, half)
                              for dv in (-half, half)])
    try:
        outline = float(ConvexHull(corners).volume)  # the area, for points in a plane
    except QhullError:
        return 1.0
    return min(1.0, len(u) * step ** 2 / outline) if outline > 0.0 else 1.0


def image_regions(u: np.ndarray, v: np.ndarray, candidate: np.ndarray, step: float
                  ) -> tuple[np.ndarray, int]:
    """Label candidates connected in the image grid of the matches.

    Args:
        u: (N,) left image column of every match [px].
        v: (N,) row [px].
        candidate: (N,) bool, the points to group.
        step: Grid spacing [px] (grid_step).

    Returns:
        (labels (N,): 1..n for candidates, 0 for the others; n).
    """
    labels = np.zeros(len(u), dtype=np.int64)
    if not np.any(candidate):
        return labels, 0
    column = np.round(np.asarray(u, dtype=float)[candidate] / step).astype(np.int64)
    row = np.round(np.asarray(v, dtype=float)[candidate] / step).astype(np.int64)
    column -= column.min() - 1
    row -= row.min() - 1
    grid = np.zeros((int(row.max()) + 2, int(column.max()) + 2), dtype=bool)
    grid[row, column] = True
    # One cell of dilation joins candidates across one missing match; the labels are read
    # back at the candidates only.
    grown = ndimage.binary_dilation(grid, structure=_EIGHT_NEIGHBOURS)
    cell_labels, count = ndimage.label(grown, structure=_EIGHT_NEIGHBOURS)
    labels[candidate] = cell_labels[row, column]
    return labels, int(count)


@dataclass(frozen=True)
class ObjectRegion:
    """The object's region among the candidates, or why there is none.

    Attributes:
        label: Label of the object's region (0: none).
        regions: Regions among the candidates.
        objects: Regions that pass both height tests.
        median_sigmas: Median z of the chosen region (or of the largest when none passed).
        points: Points of that region.
        top_m: Height of its top face [m] (NaN when none passed).
    """

    label: int
    regions: int
    objects: int
    median_sigmas: float
    points: int
    top_m: float = math.nan


def across_m(xy: np.ndarray) -> float:
    """Return the length [m] of a set of points on the surface along their principal axis.

    The side of the uniform strip with the same spread, sqrt(12 * largest variance): the long
    side of a rectangle, 0.87 times the diameter of a disc, whatever its orientation, and
    hardly moved by a few stray points.

    Args:
        xy: (M, 2) positions on the surface [m].
    """
    return _principal_sides_m(xy)[1]


def width_m(xy: np.ndarray) -> float:
    """Return the width [m] of a set of points on the surface across their principal axis.

    As across_m, along the other axis: the short side of a rectangle, 0.87 times the diameter
    of a disc.

    Args:
        xy: (M, 2) positions on the surface [m].
    """
    return _principal_sides_m(xy)[0]


def _principal_sides_m(xy: np.ndarray) -> tuple[float, float]:
    """Return the sides [m] of the uniform rectangle with the spread of xy (short, long)."""
    if len(xy) < 2:
        return 0.0, 0.0
    variances = np.linalg.eigvalsh(np.cov(np.asarray(xy, dtype=float).T))
    short, long = (math.sqrt(12.0 * max(float(value), 0.0)) for value in variances)
    return short, long


def choose_object(labels: np.ndarray, count: int, z_scores: np.ndarray, heights: np.ndarray,
                  sigmas: np.ndarray, object_sigmas: float, top_sigmas: float,
                  min_points: int, square_points: float = 0.0,
                  area_top_sigmas: float = 0.0, min_top_m: float = 0.0) -> ObjectRegion:
    """Return the region that is an object, or label 0 when none is.

    A region is an object when it has min_points points, their median z (heights averaged
    over the image, in sigmas of that average) is object_sigmas, and its top face
    (top_height) stands top_sigmas above the surface in sigmas of one point. The second test
    keeps out low, wide patterns that averaging makes significant: the surface's own
    systematic errors (sub-pixel bias, a plane that fits a slightly curved surface), a
    millimetre high. The area test (square_points and area_top_sigmas positive): a region of
    n = points / square_points averaging squares (at least 1) whose median z is below
    object_sigmas is an object when median z * sqrt(n) is object_sigmas and its top stands
    area_top_sigmas above the surface: the averages over n squares are n independent
    samples of the noise, their median scatters sqrt(n) times less. Whichever test, its top
    stands at least min_top_m above the surface. A region standing TALL_REGION_SHARE times
    object_sigmas out whose top is too low has it measured again from its points standing
    OFF_SURFACE_SIGMAS up. Of several objects the one with the most points.

    Args:
        labels: (N,) region of every point (0: none).
        count: Number of regions.
        z_scores: (N,) averaged heights in sigmas.
        heights: (N,) heights above the surface [m].
        sigmas: (N,) their standard deviations [m].
        object_sigmas: Lowest median z of an object.
        top_sigmas: Lowest top height of an object, in sigmas of its points.
        min_points: Fewest points of an object.
        square_points: Points of the grid in one averaging square (0: no area test).
        area_top_sigmas: Lowest top height of an object found by the area test, in sigmas
            of its points (0: no area test).
        min_top_m: Lowest top height of any object [m] (AreaConfig.min_object_height_m).
    """
    if count == 0:
        return ObjectRegion(0, 0, 0, math.nan, 0)
    members = labels > 0
    sizes = np.bincount(labels[members], minlength=count + 1)
    order = np.argsort(labels[members], kind='stable')
    sorted_scores = z_scores[members][order]
    bounds = np.concatenate([[0], np.cumsum(sizes[1:])])
    medians = np.full(count + 1, math.nan)
    # Only the regions that can pass, and the largest (the refusal names it): table noise
    # comes in many small blobs.
    largest = int(np.argmax(sizes))
    for label in {largest, *np.flatnonzero(sizes >= max(min_points, 1)).tolist()} - {0}:
        medians[label] = float(np.median(sorted_scores[bounds[label - 1]:bounds[label]]))
    high = medians >= object_sigmas
    passed = high.copy()
    if square_points > 0.0 and area_top_sigmas > 0.0:
        squares = np.maximum(1.0, sizes / square_points)
        passed |= medians * np.sqrt(squares) >= object_sigmas
    passed &= sizes >= min_points
    objects = []
    for passing in np.flatnonzero(passed):
        label = int(passing)
        region = labels == label
        top = top_height(heights[region], sigmas[region])
        top_in_sigmas = top_sigmas if high[label] else max(top_sigmas, area_top_sigmas)
        least = max(top_in_sigmas * float(np.median(sigmas[region])), min_top_m)
        if top < least and medians[label] >= TALL_REGION_SHARE * object_sigmas:
            standing = region & (heights > np.maximum(OFF_SURFACE_SIGMAS * sigmas, min_top_m))
            if np.count_nonzero(standing) >= max(min_points, 1):  # top_height needs one
                top = top_height(heights[standing], sigmas[standing])
        if top >= least:
            objects.append((int(sizes[label]), label, top))
    if not objects:
        return ObjectRegion(0, count, 0, float(medians[largest]), int(sizes[largest]))
    size, chosen, top = max(objects)
    return ObjectRegion(chosen, count, len(objects), float(medians[chosen]), size, top)


def top_height(heights: np.ndarray, sigmas: np.ndarray) -> float:
    """Return the height [m] of an object's top face from its points' heights and sigmas.

    Args:
        heights: (M,) heights above the surface [m], M > 0.
        sigmas: (M,) their standard deviations [m].
    """
    bin_m = max(float(np.median(sigmas)), 1e-6)
    lowest = float(heights.min())
    bins = ((heights - lowest) / bin_m).astype(np.int64)
    per_bin = np.bincount(bins)
    dense = np.flatnonzero(per_bin >= TOP_DENSE_SHARE * per_bin.max())
    level = lowest + (float(dense[-1]) + 0.5) * bin_m
    for _ in range(3):
        near = heights[np.abs(heights - level) <= TOP_WINDOW_SIGMAS * bin_m]
        if not len(near):
            break
        level = float(np.median(near))
    return level


def top_mode(heights: np.ndarray, sigmas: np.ndarray, start: float) -> float:
    """Return the mode [m] of an object's top heights nearest `start` (a top_height).

    The median of the heights within TOP_WINDOW_SIGMAS of the level, taken again until it no
    longer moves (at most TOP_MODE_ITERATIONS times): where the top's own heights spread wider
    than the surface's noise, top_height's few steps leave the level on their upper side.

    Args:
        heights: (M,) heights above the surface [m], M > 0.
        sigmas: (M,) their standard deviations [m].
        start: The level to start from [m].
    """
    window = TOP_WINDOW_SIGMAS * max(float(np.median(sigmas)), 1e-6)
    level = start
    for _ in range(TOP_MODE_ITERATIONS):
        near = heights[np.abs(heights - level) <= window]
        if not len(near):
            break
        moved = float(np.median(near))
        if abs(moved - level) <= TOP_MODE_TOLERANCE * window:
            return moved
        level = moved
    return level


def local_contrast(pixels: np.ndarray, side: int) -> np.ndarray:
    """Return each pixel's grey-level standard deviation over the side x side square around
    it (float32 pixels; OpenCV's box filter, borders reflected)."""
    mean = cv2.blur(pixels, (side, side))
    contrast: np.ndarray = np.sqrt(np.maximum(cv2.blur(pixels * pixels, (side, side))
                                              - mean * mean, 0.0))
    return contrast


def textured_regions(image: RectifiedImage, u: np.ndarray, v: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Label the matches by the textured region of the left image they lie in.

    A pixel is textured when the standard deviation of the grey levels over a correlation
    window (image.window_size) around it is TEXTURE_CONTRAST times the image's
    TEXTURE_REFERENCE_PERCENTILE; textured pixels connected in the image (8 neighbours, after
    TEXTURE_OPENING openings) are a region.

    Args:
        image: The left rectified image the matches were found in (or the part read).
        u: (N,) left image column of every match [px].
        v: (N,) row [px].

    Returns:
        (labels (N,): 1..n for matches in a region, 0 for the others; areas (n + 1,): each
        region's pixels, areas[0] the untextured ones).
    """
    pixels = np.asarray(image.pixels, dtype=np.float32)
    if pixels.ndim != 2 or not pixels.size:
        return np.zeros(len(u), dtype=np.int64), np.zeros(1, dtype=np.int64)
    contrast = local_contrast(pixels, max(1, int(image.window_size)))
    reference = float(np.percentile(contrast, TEXTURE_REFERENCE_PERCENTILE))
    # OpenCV's opening and labelling, far faster than scipy.ndimage's (the package README has
    # the figures): this runs on every pair refused for want of an object. Outside the image
    # counts as untextured.
    textured = cv2.morphologyEx((contrast > TEXTURE_CONTRAST * reference).astype(np.uint8),
                                cv2.MORPH_OPEN, np.ones((3, 3), np.uint8),
                                iterations=TEXTURE_OPENING, borderType=cv2.BORDER_CONSTANT,
                                borderValue=0)
    count, region_of_pixel = cv2.connectedComponents(textured, connectivity=8)
    count -= 1  # the background is label 0
    column = np.rint(np.asarray(u, dtype=float)).astype(np.int64) - int(image.x)
    row = np.rint(np.asarray(v, dtype=float)).astype(np.int64) - int(image.y)
    inside = (column >= 0) & (row >= 0) & (column < pixels.shape[1]) & (row < pixels.shape[0])
    labels = np.zeros(len(column), dtype=np.int64)
    labels[inside] = region_of_pixel[row[inside], column[inside]]
    return labels, np.bincount(region_of_pixel.reshape(-1), minlength=count + 1)


def choose_textured_object(labels: np.ndarray, areas: np.ndarray, heights: np.ndarray,
                           sigmas: np.ndarray, step: float, window_px: float,
                           object_sigmas: float, min_points: int, min_area_px: float,
                           min_top_m: float) -> ObjectRegion:
    """Return the textured region that is an object, or label 0 when none is.

    A region (textured_regions) of at least min_area_px pixels holding min_points matches is
    an object when its matches' median height is object_sigmas standard errors above the
    surface and at least min_top_m. Matches within a correlation window of each other share
    its errors, so the standard error is the heights' spread (MAD) over the square root of
    the windows the matches cover (each match standing for step x step pixels), not of the
    matches. Of several objects the one standing out by the most standard errors; its top is
    top_height. Not the one with the most matches: a plain surface's sparse marks can join
    into one wide textured region whose mismatches stand a few millimetres up by chance, its
    face then longer than any object, beside the object's own region.

    Args:
        labels: (N,) textured region of every match (0: none).
        areas: (n + 1,) pixels of each region.
        heights: (N,) heights above the surface [m].
        sigmas: (N,) their standard deviations [m].
        step: Grid spacing of the matches [px] (grid_step).
        window_px: Side of the correlation window [px].
        object_sigmas: Lowest median height of an object, in standard errors.
        min_points: Fewest matches of an object.
        min_area_px: Fewest pixels of an object's region.
        min_top_m: Lowest median height of an object [m].
    """
    counts = np.bincount(labels, minlength=len(areas))
    objects = []
    for label in np.flatnonzero((counts >= max(min_points, 1)) & (areas >= min_area_px)):
        if label == 0:
            continue
        region = labels == label
        region_heights = heights[region]
        median = float(np.median(region_heights))
        spread = MAD_SCALE * float(np.median(np.abs(region_heights - median)))
        windows = max(1.0, counts[label] * step ** 2 / window_px ** 2)
        standard_error = max(spread, 1e-9) / math.sqrt(windows)
        if median >= max(object_sigmas * standard_error, min_top_m):
            objects.append((median / standard_error, int(label), int(counts[label]),
                            top_height(region_heights, sigmas[region])))
    if not objects:
        return ObjectRegion(0, len(areas) - 1, 0, math.nan, 0)
    median_sigmas, chosen, size, top = max(objects)
    return ObjectRegion(chosen, len(areas) - 1, len(objects), median_sigmas, size, top)
