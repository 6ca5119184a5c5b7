"""The correlation area of the chapter's section 4: object points, border points, four areas.

ROS-free (numpy, numba for the one pass over every point, scipy.ndimage for connected
components). Steps 1-3 of the package README:

1. Matched points go to `world` with the rig's pose; those inside the workspace box and at least
   `surface_margin_m` above the work surface are the object's points. Separated clusters (cells of
   side `cluster_gap_m`, 26-connected) are counted and, if asked, only the largest is kept. The
   gantry approaches from above, so the correlation area is the object's top: the points within
   `top_band_m` below the robust top (the 99th percentile of the cluster's heights up to its
   highest dense 1 mm height level, so sparse wrong matches above the object do not lift it).
   The top height is the median height of the correlation area's points.
2. Border points (4.1): the points of minimum and maximum u and v in the left rectified image.
3. Four areas (Fig. 4): the area's bounding box in the left rectified image split through its
   middle: 1 top-left, 2 bottom-left, 3 top-right, 4 bottom-right. For each area its centre (mean
   of its points in 3D and in both images), d1 and d2 (pixel distance of that centre from the
   principal point of the left and right rectified image) and r = d1 / d2.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from scipy import ndimage

from .matched_points import MatchedPoints

# Status codes: why no best point could be chosen (also the diagnostics keys).
STATUS_OK = 'ok'
NO_POINTS = 'no_points'
TOO_FEW_POINTS = 'too_few_points'
DEGENERATE_AREA = 'degenerate_area'
NO_RULE_FIRED = 'no_rule_fired'

TOP_QUANTILE = 0.99
"""The robust top of a cluster: this quantile of its heights below the densest top level (the
value of rank floor(0.99 (n - 1)), no interpolation); see _robust_top."""

TOP_BIN_M = 0.001
"""Height bins [m] in which the object's top face is looked for (_robust_top)."""

TOP_DENSE_SHARE = 0.1
"""A height bin is part of the object when it holds at least this share of the fullest bin."""

MAX_GRID_CELLS = 4_000_000
"""Upper bound on the clustering grid; beyond it the cells grow (recorded in cluster_cell_m)."""

BORDER_PAIRS = ((0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3))
"""Pairs of border points (min u, max u, min v, max v) whose Eq. 9 distances are reported."""


class CorrelationAreaError(ValueError):
    """A configuration that cannot select a correlation area, with the bad value named."""


@dataclass(frozen=True)
class AreaConfig:
    """How the correlation area is found (step 1).

    Attributes:
        workspace_min: Lower corner (x, y, z) of the workspace box in `world` [m].
        workspace_max: Upper corner (x, y, z) of the workspace box in `world` [m].
        surface_margin_m: Points must be this far above the work surface (z = 0) [m].
        cluster_gap_m: Cell size of the clustering grid [m]: points closer than this are always
            joined, clusters further apart than 2*sqrt(3) times it are always separate.
        keep_largest_cluster: Keep only the largest cluster (else all valid points).
        top_band_m: Height of the band below the object's top that forms the area [m].
        min_points: Fewer points in the correlation area means no best point.
    """

    workspace_min: tuple[float, float, float] = (0.0, 0.0, 0.0)
    workspace_max: tuple[float, float, float] = (0.40, 0.30, 0.20)
    surface_margin_m: float = 0.003
    cluster_gap_m: float = 0.01
    keep_largest_cluster: bool = True
    top_band_m: float = 0.004
    min_points: int = 20

    def problem(self) -> str | None:
        """Return why this configuration is unusable, or None."""
        for axis, (low, high) in enumerate(zip(self.workspace_min, self.workspace_max,
                                               strict=True)):
            if not low < high:
                return (f'workspace box axis {"xyz"[axis]}: min {low} must be below max {high}')
        if self.cluster_gap_m <= 0.0:
            return f'cluster_gap_m={self.cluster_gap_m} must be positive'
        if self.top_band_m <= 0.0:
            return f'top_band_m={self.top_band_m} must be positive'
        if self.surface_margin_m < 0.0:
            return f'surface_margin_m={self.surface_margin_m} must not be negative'
        if self.min_points < 1:
            return f'min_points={self.min_points} must be at least 1'
        return None


@dataclass(frozen=True)
class CorrelationArea:
    """The object's top surface as seen by the stereo pair (step 1), or why there is none.

    Attributes:
        status: STATUS_OK or a status code.
        reason: Human-readable reason when status is not ok ('' when ok).
        points_in: Matches received.
        points_valid: Finite, inside the workspace box, above the work surface.
        clusters_found: Separated clusters among the valid points.
        points_used: Points of the correlation area.
        top_height: World z of the object's top [m] (NaN when unknown).
        xyz_world: (M, 3) area points in `world` [m].
        u_left: (M,) [px].
        v_left: (M,) [px].
        u_right: (M,) [px].
        score: (M,) correlation scores.
        cluster_cell_m: Cell size the clustering used [m].
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
    cluster_cell_m: float

    @property
    def ok(self) -> bool:
        """Return True when the area has enough points."""
        return self.status == STATUS_OK


@numba.njit(cache=True, nogil=True)
def _object_points(xyz: np.ndarray, pose: np.ndarray, low: np.ndarray, high: np.ndarray,
                   u_left: np.ndarray, v_left: np.ndarray, u_right: np.ndarray,
                   score: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return (world (3, M) [m], indices (M,)) of the points inside the box [low, high].

    Two passes in float64 over points of any float type, the first without branches (a
    point is in or out about half the time: mispredicted branches cost more than computing
    the transform twice). With numpy the transform, six comparisons, four finiteness tests
    and the compaction each made a pass of their own (1.5 of a decision's 5 ms at 100k
    points). NaN / inf rows fail the comparisons or the finiteness test.
    """
    count = xyz.shape[0]
    inside = np.empty(count, np.bool_)
    used = 0
    for index in range(count):
        px, py, pz = float(xyz[index, 0]), float(xyz[index, 1]), float(xyz[index, 2])
        x = pose[0, 0] * px + pose[0, 1] * py + pose[0, 2] * pz + pose[0, 3]
        y = pose[1, 0] * px + pose[1, 1] * py + pose[1, 2] * pz + pose[1, 3]
        z = pose[2, 0] * px + pose[2, 1] * py + pose[2, 2] * pz + pose[2, 3]
        finite = np.isfinite(float(u_left[index]) + float(v_left[index])
                             + float(u_right[index]) + float(score[index]))
        keep = ((low[0] <= x) & (x <= high[0]) & (low[1] <= y) & (y <= high[1])
                & (low[2] <= z) & (z <= high[2]) & finite)
        inside[index] = keep
        used += keep
    world = np.empty((3, used), np.float64)
    kept = np.empty(used, np.int64)
    slot = 0
    for index in range(count):
        if inside[index]:
            px, py, pz = float(xyz[index, 0]), float(xyz[index, 1]), float(xyz[index, 2])
            for axis in range(3):
                world[axis, slot] = (pose[axis, 0] * px + pose[axis, 1] * py
                                     + pose[axis, 2] * pz + pose[axis, 3])
            kept[slot] = index
            slot += 1
    return world, kept


def warm_up() -> None:
    """Compile (or load from numba's cache) the kernels for float64 points (what
    conversions.cloud_to_matched_points gives), so the first decision is fast."""
    empty = np.zeros(0)
    _object_points(np.zeros((0, 3)), np.eye(4), np.zeros(3), np.ones(3), empty, empty, empty,
                   empty)
    _dense_top_limit(np.zeros(1), TOP_BIN_M, TOP_DENSE_SHARE)


def _label_clusters(world: np.ndarray, gap: float) -> tuple[np.ndarray, int, float]:
    """Return a cluster label per point (0..n-1), the number of clusters and the cell size.

    Args:
        world: (3, N) point coordinates [m], one row per axis.
        gap: Cell size [m].
    """
    low = np.array([row.min() for row in world])
    extent = np.array([row.max() for row in world]) - low
    cell = gap
    cells = np.floor(extent / cell).astype(np.int64) + 1
    if float(np.prod(cells.astype(float))) > MAX_GRID_CELLS:
        cell = max(gap, float(np.cbrt(np.prod(extent + gap) / MAX_GRID_CELLS)) * 1.01)
        cells = np.floor(extent / cell).astype(np.int64) + 1
    index = [np.minimum(((row - start) * (1.0 / cell)).astype(np.int64), count - 1)
             for row, start, count in zip(world, low, cells, strict=True)]
    linear = (index[0] * cells[1] + index[1]) * cells[2] + index[2]
    occupied = np.zeros(tuple(int(n) for n in cells), dtype=bool)
    occupied.ravel()[linear] = True
    labels, count = ndimage.label(occupied, structure=np.ones((3, 3, 3), dtype=bool))
    return labels.ravel()[linear] - 1, int(count), cell


def _order_statistic(values: np.ndarray, fraction: float) -> float:
    """Return the value of rank floor(fraction * (n - 1)) in ascending order (no interpolation)."""
    rank = int(fraction * (len(values) - 1))
    return float(np.partition(values, rank)[rank])


@numba.njit(cache=True, nogil=True)
def _dense_top_limit(heights: np.ndarray, bin_m: float, share: float) -> float:
    """Return the upper edge [m] of the highest height bin with `share` of the fullest's count."""
    low, high = heights.min(), heights.max()
    counts = np.zeros(int((high - low) / bin_m) + 1, np.int64)
    for height in heights:
        counts[int((height - low) / bin_m)] += 1
    threshold = share * counts.max()
    highest = len(counts) - 1
    while counts[highest] < threshold:
        highest -= 1
    return float(low + (highest + 1) * bin_m)


def _robust_top(heights: np.ndarray) -> float:
    """Return the height of the object's top among a cluster's heights [m].

    The top face is the densest height level; wrong matches above it are sparse. A plain 99 %
    quantile was lifted by them whenever they were more than 1 % of the points (measured: a
    top 4-8 mm too high, and a top band that missed the face). So the points are binned by
    height (TOP_BIN_M), the highest bin holding at least TOP_DENSE_SHARE of the fullest bin
    ends the object, and the top is the TOP_QUANTILE of the heights up to that bin.
    """
    limit = _dense_top_limit(heights, TOP_BIN_M, TOP_DENSE_SHARE)
    return _order_statistic(heights[heights < limit], TOP_QUANTILE)


def _median(values: np.ndarray) -> float:
    """Return the median (mean of the two middle values for an even count)."""
    count = len(values)
    middle = count // 2
    if count % 2:
        return float(np.partition(values, middle)[middle])
    pair = np.partition(values, (middle - 1, middle))[middle - 1:middle + 1]
    return float(0.5 * (pair[0] + pair[1]))


def find_correlation_area(points: MatchedPoints, world_from_camera: np.ndarray,
                          config: AreaConfig) -> CorrelationArea:
    """Select the object's top surface among matched points (step 1).

    Args:
        points: Matched points, xyz in the camera frame [m].
        world_from_camera: 4x4 pose of that camera frame in `world`.
        config: Workspace box, margins, clustering and band.

    Returns:
        The correlation area; status explains when it has too few points. Never raises for
        bad points: NaN and infinite rows are ignored.

    Raises:
        CorrelationAreaError: When the configuration is unusable.
    """
    reason = config.problem()
    if reason:
        raise CorrelationAreaError(reason)
    points_in = len(points)
    pose = np.asarray(world_from_camera, dtype=float)
    xyz = np.ascontiguousarray(points.xyz).reshape(-1, 3)
    if xyz.dtype not in (np.float32, np.float64):
        xyz = xyz.astype(float)
    columns = [np.asarray(column).reshape(-1) for column in
               (points.u_left, points.v_left, points.u_right, points.score)]
    low = np.array(config.workspace_min, dtype=float)
    high = np.array(config.workspace_max, dtype=float)
    low[2] = max(low[2], config.surface_margin_m)
    # world: (3, N), one contiguous row per axis
    world, selected = _object_points(xyz, pose, low, high, *columns)
    valid = len(selected)

    def refused(status: str, why: str, clusters: int = 0, cell: float = math.nan
                ) -> CorrelationArea:
        empty = np.zeros(0)
        return CorrelationArea(status, why, points_in, valid, clusters, 0, math.nan,
                               np.zeros((0, 3)), empty, empty, empty, empty, cell)

    if valid == 0:
        return refused(NO_POINTS, f'none of {points_in} matched points is finite, inside the '
                                  'workspace box and above the work surface')
    labels, clusters, cell = _label_clusters(world, config.cluster_gap_m)
    if config.keep_largest_cluster and clusters > 1:
        keep = labels == int(np.argmax(np.bincount(labels, minlength=clusters)))
        world, selected = np.compress(keep, world, axis=1), selected[keep]
    top = _robust_top(world[2])
    band = world[2] >= top - config.top_band_m
    world, selected = np.compress(band, world, axis=1), selected[band]
    used = len(selected)
    if used < config.min_points:
        return refused(TOO_FEW_POINTS, f'{used} points in the correlation area, need '
                                       f'min_points={config.min_points}', clusters, cell)
    u_left, v_left, u_right, score = (column[selected].astype(float) for column in columns)
    return CorrelationArea(STATUS_OK, '', points_in, valid, clusters, used,
                           _median(world[2]), np.ascontiguousarray(world.T), u_left,
                           v_left, u_right, score, cell)


@dataclass(frozen=True)
class FourAreas:
    """Border points (4.1) and the four areas of Fig. 4 with their fuzzy inputs.

    Arrays indexed by area hold areas 1..4 at 0..3.

    Attributes:
        status: STATUS_OK or DEGENERATE_AREA (no extent in u or v, or no finite ratio). An
            empty area alone is not degenerate: its ratio is NaN, so its rules do not fire.
        reason: Why the areas are degenerate ('' when ok).
        border_points: (4, 3) world points of min u, max u, min v, max v [m].
        border_distances: (6,) Eq. 9 distances for BORDER_PAIRS [m].
        centre: (3,) mean of all area points in `world` [m].
        centres: (4, 3) area centres in `world` [m] (NaN for an empty area).
        centres_u_left: (4,) [px].
        centres_v_left: (4,) [px].
        centres_u_right: (4,) [px].
        counts: (4,) points per area.
        d1: (4,) distance of each centre from the left principal point [px].
        d2: (4,) distance of each centre from the right principal point [px].
        ratio: (4,) r = d1 / d2.
    """

    status: str
    reason: str
    border_points: np.ndarray
    border_distances: np.ndarray
    centre: np.ndarray
    centres: np.ndarray
    centres_u_left: np.ndarray
    centres_v_left: np.ndarray
    centres_u_right: np.ndarray
    counts: np.ndarray
    d1: np.ndarray
    d2: np.ndarray
    ratio: np.ndarray

    @property
    def ok(self) -> bool:
        """Return True when the area could be split into four areas."""
        return self.status == STATUS_OK

    def union_centre(self, areas: tuple[int, ...]) -> np.ndarray:
        """Return the centre [m] of the union of `areas` (numbered 1..4): count-weighted."""
        index = np.asarray(areas, dtype=int) - 1
        counts = self.counts[index].astype(float)
        return np.asarray((counts @ self.centres[index]) / counts.sum())


def _extreme_index(key: np.ndarray, ties: list[np.ndarray], largest: bool) -> int:
    """Index of the min (max) of `key`; ties broken by the smallest (ties[0], ties[1], ...)."""
    target = key.max() if largest else key.min()
    candidates = np.flatnonzero(key == target)
    if len(candidates) == 1:
        return int(candidates[0])
    order = np.lexsort([column[candidates] for column in ties][::-1])
    return int(candidates[order[0]])


def split_into_areas(area: CorrelationArea, left_principal: tuple[float, float],
                     right_principal: tuple[float, float]) -> FourAreas:
    """Find the border points and the four areas of a correlation area (steps 2-3).

    Args:
        area: A correlation area with status ok.
        left_principal: (cx, cy) of the left rectified projection [px].
        right_principal: (cx, cy) of the right rectified projection [px].

    Returns:
        The border points and areas; status DEGENERATE_AREA (with the reason) when the area has
        no extent along an image axis or no centre has a finite ratio (d2 = 0). Empty areas
        have NaN centres and ratios.
    """
    u, v, ur, world = area.u_left, area.v_left, area.u_right, area.xyz_world
    ties = [u, v, world[:, 0], world[:, 1], world[:, 2]]
    border_index = [_extreme_index(u, ties, False), _extreme_index(u, ties, True),
                    _extreme_index(v, ties, False), _extreme_index(v, ties, True)]
    border_points = world[border_index]
    border_distances = np.array([np.linalg.norm(border_points[i] - border_points[j])
                                 for i, j in BORDER_PAIRS])
    u_mid = 0.5 * (float(u.min()) + float(u.max()))
    v_mid = 0.5 * (float(v.min()) + float(v.max()))
    right_half = u >= u_mid
    bottom_half = v >= v_mid
    labels = 2 * right_half.astype(np.int64) + bottom_half.astype(np.int64)  # 0..3: areas 1..4
    counts = np.bincount(labels, minlength=4)
    with np.errstate(invalid='ignore', divide='ignore'):
        def area_mean(values: np.ndarray) -> np.ndarray:
            return np.bincount(labels, weights=values, minlength=4) / counts

        centres = np.column_stack([area_mean(np.ascontiguousarray(world[:, axis]))
                                   for axis in range(3)])
        cu, cv, cur = area_mean(u), area_mean(v), area_mean(ur)
        d1 = np.hypot(cu - left_principal[0], cv - left_principal[1])
        d2 = np.hypot(cur - right_principal[0], cv - right_principal[1])
        ratio = d1 / d2
    status, reason = STATUS_OK, ''
    if u_mid == float(u.min()) or v_mid == float(v.min()):
        status, reason = DEGENERATE_AREA, (
            f'the correlation area spans {float(u.max() - u.min()):.3g} x '
            f'{float(v.max() - v.min()):.3g} px in the left image: a line or a point cannot be '
            'split into four areas')
    elif not np.any(np.isfinite(ratio)):
        status, reason = DEGENERATE_AREA, 'every area centre sits on the right principal point'
    return FourAreas(status, reason, border_points, border_distances, world.mean(axis=0),
                     centres, cu, cv, cur, counts, d1, d2, ratio)
