"""The correlation area of the chapter's section 4: object points, border points, four areas.

ROS-free: numba kernels for the passes over the points (a decision at 100k points must stay
under 5 ms on one core; numpy made a pass per operation), scipy.ndimage for the connected
components of the (small) clustering grid. Steps 1-3 of the package README:

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

from stereo_fuzzy_perception.core.matched_points import MatchedPoints

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


def warm_up() -> None:
    """Compile (or load from numba's cache) the kernels for float64 points (what
    conversions.cloud_to_matched_points gives), so the first decision is fast."""
    grid = np.stack(np.meshgrid(np.arange(0.1, 0.15, 0.01), np.arange(0.1, 0.15, 0.01),
                                [0.02]), axis=-1).reshape(-1, 3)
    pixels = np.arange(len(grid), dtype=float)
    area = find_correlation_area(MatchedPoints(grid, pixels, pixels, pixels, pixels), np.eye(4),
                                 AreaConfig(min_points=1))
    split_into_areas(area, (0.0, 0.0), (0.0, 0.0))


@numba.njit(cache=True, nogil=True)
def _count_cells(world: np.ndarray, low: np.ndarray, cell: float, cells: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Return each point's cell (linear index, C order) and the points per cell (a grid)."""
    count = world.shape[1]
    linear = np.empty(count, np.int64)
    per_cell = np.zeros((cells[0], cells[1], cells[2]), np.int64)
    flat = per_cell.reshape(-1)
    scale = 1.0 / cell
    for index in range(count):
        code = 0
        for axis in range(3):
            step = min(int((world[axis, index] - low[axis]) * scale), cells[axis] - 1)
            code = code * cells[axis] + step
        linear[index] = code
        flat[code] += 1
    return linear, per_cell


def _label_clusters(world: np.ndarray, low: np.ndarray, high: np.ndarray, gap: float
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Cluster points on a grid: occupied cells that touch (26-connected) form one cluster.

    Args:
        world: (3, N) point coordinates [m], one row per axis (N > 0).
        low: (3,) smallest coordinates of the points [m].
        high: (3,) largest coordinates of the points [m].
        gap: Cell size [m].

    Returns:
        (each point's cell (linear index), the label of each cell: 1..n (0: empty), (n,) points
        per cluster, cell size [m]).
    """
    extent = high - low
    cell = gap
    cells = np.floor(extent / cell).astype(np.int64) + 1
    if float(np.prod(cells.astype(float))) > MAX_GRID_CELLS:
        cell = max(gap, float(np.cbrt(np.prod(extent + gap) / MAX_GRID_CELLS)) * 1.01)
        cells = np.floor(extent / cell).astype(np.int64) + 1
    linear, per_cell = _count_cells(world, low, cell, cells)
    cell_labels, count = ndimage.label(per_cell > 0, structure=np.ones((3, 3, 3), dtype=bool))
    sizes = np.bincount(cell_labels.reshape(-1), weights=per_cell.reshape(-1),
                        minlength=count + 1)[1:].astype(np.int64)
    return linear, cell_labels.reshape(-1), sizes, cell


@numba.njit(cache=True, nogil=True)
def _top_band(world: np.ndarray, point_cells: np.ndarray, cell_labels: np.ndarray, keep: int,
              band_m: float) -> tuple[np.ndarray, float]:
    """Return (columns of `world` in the top band, median height of the band [m]).

    Only points in cells labelled `keep` count (all points when keep is 0). The top face is
    the densest height level; wrong matches above it are sparse. A plain 99 % quantile was
    lifted by them whenever they were more than 1 % of the points (measured: a top 4-8 mm too
    high, and a top band that missed the face). So the points are binned by height
    (TOP_BIN_M), the highest bin holding at least TOP_DENSE_SHARE of the fullest bin ends the
    object, and the top is the TOP_QUANTILE of the heights in the bins up to that one (the
    value of rank floor(q (n - 1)), no interpolation). The band is the points within band_m
    below the top. Compactions are written without branches (write always, advance when kept):
    whether a point is kept is hard to predict.
    """
    members = np.empty(world.shape[1], np.int64)
    heights = np.empty(world.shape[1])
    lowest, highest = np.inf, -np.inf
    count = 0
    for index in range(world.shape[1]):
        height = world[2, index]
        member = keep == 0 or cell_labels[point_cells[index]] == keep
        members[count] = index
        heights[count] = height
        lowest = min(lowest, height) if member else lowest
        highest = max(highest, height) if member else highest
        count += member
    bins = np.empty(count, np.int64)
    per_bin = np.zeros(int((highest - lowest) / TOP_BIN_M) + 1, np.int64)
    for slot in range(count):
        bins[slot] = int((heights[slot] - lowest) / TOP_BIN_M)
        per_bin[bins[slot]] += 1
    top_bin = len(per_bin) - 1
    dense = TOP_DENSE_SHARE * per_bin.max()
    while per_bin[top_bin] < dense:
        top_bin -= 1
    # The quantile's rank falls in one bin (bins are ordered by height): sort only that bin.
    rank = int(TOP_QUANTILE * (per_bin[:top_bin + 1].sum() - 1))
    rank_bin = 0
    while rank >= per_bin[rank_bin]:
        rank -= per_bin[rank_bin]
        rank_bin += 1
    in_rank_bin = np.empty(per_bin[rank_bin])
    filled = 0
    for slot in range(count):
        if bins[slot] == rank_bin:
            in_rank_bin[filled] = heights[slot]
            filled += 1
    floor = np.partition(in_rank_bin, rank)[rank] - band_m
    used = 0
    for slot in range(count):
        height = heights[slot]
        members[used] = members[slot]
        heights[used] = height
        used += height >= floor
    return members[:used], float(np.median(heights[:used]))


@numba.njit(cache=True, nogil=True)
def _gather_area(world: np.ndarray, selected: np.ndarray, band: np.ndarray, u_left: np.ndarray,
                 v_left: np.ndarray, u_right: np.ndarray, score: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Return the band's points: world (M, 3) and the input columns as float64 (M,)."""
    used = len(band)
    xyz = np.empty((used, 3))
    columns = np.empty((4, used))
    for slot in range(used):
        column = band[slot]
        for axis in range(3):
            xyz[slot, axis] = world[axis, column]
        point = selected[column]
        columns[0, slot] = u_left[point]
        columns[1, slot] = v_left[point]
        columns[2, slot] = u_right[point]
        columns[3, slot] = score[point]
    return xyz, columns[0], columns[1], columns[2], columns[3]


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
    world, selected, smallest, largest = _object_points(xyz, pose, low, high, *columns)
    valid = len(selected)

    def refused(status: str, why: str, clusters: int = 0, cell: float = math.nan
                ) -> CorrelationArea:
        empty = np.zeros(0)
        return CorrelationArea(status, why, points_in, valid, clusters, 0, math.nan,
                               np.zeros((0, 3)), empty, empty, empty, empty, cell)

    if valid == 0:
        return refused(NO_POINTS, f'none of {points_in} matched points is finite, inside the '
                                  'workspace box and above the work surface')
    point_cells, cell_labels, sizes, cell = _label_clusters(world, smallest, largest,
                                                            config.cluster_gap_m)
    clusters = len(sizes)
    keep = int(np.argmax(sizes)) + 1 if config.keep_largest_cluster and clusters > 1 else 0
    band, top_height = _top_band(world, point_cells, cell_labels, keep, config.top_band_m)
    used = len(band)
    if used < config.min_points:
        return refused(TOO_FEW_POINTS, f'{used} points in the correlation area, need '
                                       f'min_points={config.min_points}', clusters, cell)
    xyz_world, u_left, v_left, u_right, score = _gather_area(world, selected, band, *columns)
    return CorrelationArea(STATUS_OK, '', points_in, valid, clusters, used, top_height,
                           xyz_world, u_left, v_left, u_right, score, cell)


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


@numba.njit(cache=True, nogil=True)
def _precedes(first: int, second: int, u: np.ndarray, v: np.ndarray, world: np.ndarray) -> bool:
    """Return True when point `first` sorts before `second` by (u, v, x, y, z)."""
    if u[first] != u[second]:
        return bool(u[first] < u[second])
    if v[first] != v[second]:
        return bool(v[first] < v[second])
    for axis in range(3):
        if world[first, axis] != world[second, axis]:
            return bool(world[first, axis] < world[second, axis])
    return False


@numba.njit(cache=True, nogil=True)
def _area_sums(u: np.ndarray, v: np.ndarray, u_right: np.ndarray, world: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, float]:
    """Border points and per-area sums of a correlation area in two passes.

    Returns:
        border (4,): indices of min u, max u, min v, max v, ties broken by the smallest
            (u, v, x, y, z) so that input order cannot matter; counts (4,) per area; sums
            (4, 6) of x, y, z, u, v, u_right per area; u_mid; v_mid.
    """
    u_min = u_max = u[0]
    v_min = v_max = v[0]
    for index in range(len(u)):
        u_min, u_max = min(u_min, u[index]), max(u_max, u[index])
        v_min, v_max = min(v_min, v[index]), max(v_max, v[index])
    u_mid = 0.5 * (u_min + u_max)
    v_mid = 0.5 * (v_min + v_max)
    extremes = (u_min, u_max, v_min, v_max)
    border = np.full(4, -1, np.int64)
    counts = np.zeros(4, np.int64)
    sums = np.zeros((4, 6))
    for index in range(len(u)):
        for slot in range(4):
            key = u[index] if slot < 2 else v[index]
            if key == extremes[slot] and (border[slot] < 0
                                          or _precedes(index, border[slot], u, v, world)):
                border[slot] = index
        area = 2 * int(u[index] >= u_mid) + int(v[index] >= v_mid)  # 0..3: areas 1..4
        counts[area] += 1
        for axis in range(3):
            sums[area, axis] += world[index, axis]
        sums[area, 3] += u[index]
        sums[area, 4] += v[index]
        sums[area, 5] += u_right[index]
    return border, counts, sums, u_mid, v_mid


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
    u, v, world = area.u_left, area.v_left, area.xyz_world
    border, counts, sums, u_mid, v_mid = _area_sums(u, v, area.u_right, world)
    border_points = world[border]
    border_distances = np.array([math.dist(border_points[i], border_points[j])
                                 for i, j in BORDER_PAIRS])
    with np.errstate(invalid='ignore', divide='ignore'):
        means = sums / counts[:, np.newaxis]  # NaN for an empty area
        centres = np.ascontiguousarray(means[:, :3])
        cu, cv, cur = means[:, 3].copy(), means[:, 4].copy(), means[:, 5].copy()
        d1 = np.hypot(cu - left_principal[0], cv - left_principal[1])
        d2 = np.hypot(cur - right_principal[0], cv - right_principal[1])
        ratio = d1 / d2
    status, reason = STATUS_OK, ''
    u_min, u_max, v_min, v_max = (float(u[border[0]]), float(u[border[1]]),
                                  float(v[border[2]]), float(v[border[3]]))
    if u_mid == u_min or v_mid == v_min:
        status, reason = DEGENERATE_AREA, (
            f'the correlation area spans {u_max - u_min:.3g} x '
            f'{v_max - v_min:.3g} px in the left image: a line or a point cannot be '
            'split into four areas')
    elif not np.any(np.isfinite(ratio)):
        status, reason = DEGENERATE_AREA, 'every area centre sits on the right principal point'
    centre = sums[:, :3].sum(axis=0) / len(u)
    return FourAreas(status, reason, border_points, border_distances, centre, centres, cu, cv,
                     cur, counts, d1, d2, ratio)
