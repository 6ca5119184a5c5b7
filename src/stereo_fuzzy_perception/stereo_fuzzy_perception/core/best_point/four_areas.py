"""Border points and the four areas of the chapter's section 4 (steps 2 and 3). ROS-free.

2. Border points (4.1): the points of minimum and maximum u and v in the left rectified image.
3. Four areas (Fig. 4): the area's bounding box in the left rectified image split through its
   middle: 1 top-left, 2 bottom-left, 3 top-right, 4 bottom-right. For each area its centre
   (weighted mean of its points in 3D and in both images), d1 and d2 (pixel distance of that
   centre from the principal point of the left and right rectified image) and r = d1 / d2.

The correlation area they split is correlation_area.py (step 1).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from stereo_fuzzy_perception.core.best_point.correlation_area import (
    DEGENERATE_AREA,
    STATUS_OK,
    AreaConfig,
    CorrelationArea,
    find_correlation_area,
)
from stereo_fuzzy_perception.core.matched_points import MatchedPoints

BORDER_PAIRS = ((0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3))
"""Pairs of border points (min u, max u, min v, max v) whose Eq. 9 distances are reported."""


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
        weights: (4,) sum of the points' weights per area (CorrelationArea.weight).
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
    weights: np.ndarray
    d1: np.ndarray
    d2: np.ndarray
    ratio: np.ndarray

    @property
    def ok(self) -> bool:
        """Return True when the area could be split into four areas."""
        return self.status == STATUS_OK

    def union_centre(self, areas: tuple[int, ...]) -> np.ndarray:
        """Return the centre [m] of the union of `areas` (numbered 1..4): weighted like its
        points."""
        index = np.asarray(areas, dtype=int) - 1
        weights = self.weights[index]
        return np.asarray((weights @ np.nan_to_num(self.centres[index])) / weights.sum())


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
def _area_sums(u: np.ndarray, v: np.ndarray, u_right: np.ndarray, world: np.ndarray,
               weight: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, float]:
    """Border points and per-area sums of a correlation area in two passes.

    Returns:
        border (4,): indices of min u, max u, min v, max v, ties broken by the smallest
            (u, v, x, y, z) so that input order cannot matter; counts (4,) per area; sums
            (4, 7) of weighted x, y, z, u, v, u_right and the weights per area; u_mid; v_mid.
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
    sums = np.zeros((4, 7))
    for index in range(len(u)):
        for slot in range(4):
            key = u[index] if slot < 2 else v[index]
            if key == extremes[slot] and (border[slot] < 0
                                          or _precedes(index, border[slot], u, v, world)):
                border[slot] = index
        area = 2 * int(u[index] >= u_mid) + int(v[index] >= v_mid)  # 0..3: areas 1..4
        counts[area] += 1
        w = weight[index]
        for axis in range(3):
            sums[area, axis] += w * world[index, axis]
        sums[area, 3] += w * u[index]
        sums[area, 4] += w * v[index]
        sums[area, 5] += w * u_right[index]
        sums[area, 6] += w
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
    border, counts, sums, u_mid, v_mid = _area_sums(u, v, area.u_right, world,
                                                    area.point_weights())
    border_points = world[border]
    border_distances = np.array([math.dist(border_points[i], border_points[j])
                                 for i, j in BORDER_PAIRS])
    with np.errstate(invalid='ignore', divide='ignore'):
        means = sums[:, :6] / sums[:, 6:]  # NaN for an empty area
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
    centre = sums[:, :3].sum(axis=0) / sums[:, 6].sum()
    return FourAreas(status, reason, border_points, border_distances, centre, centres, cu, cv,
                     cur, counts, sums[:, 6].copy(), d1, d2, ratio)


def warm_up() -> None:
    """Compile (or load from numba's cache) the kernels for float64 points (what
    conversions.cloud_to_matched_points gives), so the first decision is fast."""
    grid = np.stack(np.meshgrid(np.arange(0.1, 0.15, 0.01), np.arange(0.1, 0.15, 0.01),
                                [0.02]), axis=-1).reshape(-1, 3)
    pixels = np.arange(len(grid), dtype=float)
    area = find_correlation_area(MatchedPoints(grid, pixels, pixels, pixels - 10.0, pixels),
                                 np.eye(4), AreaConfig(min_points=1))
    if not area.ok:
        area = CorrelationArea(STATUS_OK, '', len(grid), len(grid), 1, len(grid), 0.02, grid,
                               pixels, pixels, pixels, pixels, np.ones(len(grid)))
    split_into_areas(area, (0.0, 0.0), (0.0, 0.0))
