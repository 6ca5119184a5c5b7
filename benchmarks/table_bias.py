"""How far the bare table's own matches are off around the object, at the scale of its top.

A diagnosis of the rendered scenes, for the benchmarks (it knows the ground truth): the matched
disparities of the table's pixels against the disparities the table's plane (z = 0) gives
them, averaged over squares of SQUARE_PX (an object's top in the image), within AROUND_PX of
the object's image. The spread of those averages is what no averaging over an object's top
takes out, in millimetres of depth at the object. TinyRenderer samples each texture at pixel
centres (no filtering, no antialiasing), so a texture finer than the pixels folds into a
moire whose phase differs between the two cameras: bands of table tens of pixels wide whose
disparities are off by the same few tenths of a pixel. Where that spread reaches the height of
a low object, or the millimetres of an outline, the table looks like an object and an object
like the table; which scenes those are is what this column shows beside the outcomes.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from stereo_fuzzy_perception.core.best_point.object_segmentation import grid_step
from stereo_fuzzy_perception.simulation.synthetic_scenes import SyntheticScene, project_rectified

from benchmarks.true_top import left_pixel_rays

SQUARE_PX = 31
"""Side of the squares the table's errors are averaged over [px]: an object's top in the image
(the evaluation's tops are 24-100 px across)."""

AROUND_PX = 150.0
"""Only the table within this distance of the object's image [px]: where the object is
looked for and outlined."""

CLEAR_PX = 15.0
"""The table closer than this to the object's image is left out [px]: windows there straddle
the object."""

MAX_ERROR_PX = 1.0
"""Matches off by more are mismatches, not the table's bias, and left out [px]."""

MIN_SQUARE_SHARE = 0.5
"""A square counts when at least this share of its matches is on the table."""


def table_disparity_bias(scene: SyntheticScene) -> tuple[float, float]:
    """Return the spread of the table's square-averaged disparity errors around the object
    [px] and the depth [mm] one pixel of disparity moves at the object's top; the spread is
    NaN when fewer than two squares of table are matched there (a plain table).

    The spread is the root mean square of the squares' mean errors about their median (a
    constant offset the measured work surface takes out).
    """
    points = scene.points
    u = np.asarray(points.u_left, float).reshape(-1)
    v = np.asarray(points.v_left, float).reshape(-1)
    u_right = np.asarray(points.u_right, float).reshape(-1)
    finite = np.isfinite(u) & np.isfinite(v) & np.isfinite(u_right)
    u, v, u_right = u[finite], v[finite], u_right[finite]
    pose = scene.rig.world_from_left_camera()
    # where each pixel's ray meets the table (z = 0), and that point in the right image
    centre, rays = left_pixel_rays(scene, u, v)
    with np.errstate(divide='ignore', invalid='ignore'):
        scale = -centre[2] / rays[:, 2]
    on_table = centre + rays * scale[:, None]
    error = u_right - project_rectified(on_table, pose, scene.left, scene.right)[2]
    # depth [mm] per pixel of disparity at the top's centre: Z^2 / (f B), Z = f B / disparity
    focal_baseline = -float(np.asarray(scene.right.P, float)[0, 3])
    shift = float(np.asarray(scene.left.P, float)[0, 2] - np.asarray(scene.right.P, float)[0, 2])
    target_left, _, target_right, _ = project_rectified(scene.target_world[None, :], pose,
                                                        scene.left, scene.right)
    depth_per_px_mm = 1000.0 * focal_baseline / float(target_left[0] - target_right[0]
                                                      - shift) ** 2
    if not len(u):
        return math.nan, depth_per_px_mm
    prism = scene.prism
    corners = np.vstack([np.column_stack([prism.polygon, np.full(len(prism.polygon), z)])
                         for z in (0.0, prism.height)])
    corner_u, corner_v, _, _ = project_rectified(corners, pose, scene.left, scene.right)
    # distance of each match from the object's image: the hull of its projected corners
    origin = np.floor([u.min(), v.min()]).astype(int)
    outside = np.ones((int(v.max()) - origin[1] + 1, int(u.max()) - origin[0] + 1), np.uint8)
    hull = cv2.convexHull((np.column_stack([corner_u, corner_v]) - origin).astype(np.float32))
    cv2.fillConvexPoly(outside, np.rint(hull).astype(np.int32), 0)
    distance = cv2.distanceTransform(outside, cv2.DIST_L2, 5)[
        np.rint(v).astype(int) - origin[1], np.rint(u).astype(int) - origin[0]]
    table = ((scale > 0.0) & (distance > CLEAR_PX) & (distance <= AROUND_PX)
             & (np.abs(error) <= MAX_ERROR_PX))
    if not np.any(table):
        return math.nan, depth_per_px_mm
    step = max(1, int(round(grid_step(u, v))))
    columns = np.rint((u[table] - u.min()) / step).astype(int)
    rows = np.rint((v[table] - v.min()) / step).astype(int)
    shape = (rows.max() + 1, columns.max() + 1)
    sums = np.zeros(shape, np.float64)
    counts = np.zeros(shape, np.float64)
    np.add.at(sums, (rows, columns), error[table])
    np.add.at(counts, (rows, columns), 1.0)
    side = max(1, int(round(SQUARE_PX / step)))
    square_sums = cv2.boxFilter(sums, -1, (side, side), normalize=False,
                                borderType=cv2.BORDER_CONSTANT)
    square_counts = cv2.boxFilter(counts, -1, (side, side), normalize=False,
                                  borderType=cv2.BORDER_CONSTANT)
    full = square_counts >= MIN_SQUARE_SHARE * side * side
    if np.count_nonzero(full) < 2:
        return math.nan, depth_per_px_mm
    means = square_sums[full] / square_counts[full]
    return float(np.sqrt(np.mean((means - np.median(means)) ** 2))), depth_per_px_mm


def table_bias_mm(scene: SyntheticScene) -> float:
    """Return the table's square-averaged disparity spread around the object in millimetres
    of depth at the object (NaN when the table there is not matched)."""
    spread_px, depth_per_px_mm = table_disparity_bias(scene)
    return spread_px * depth_per_px_mm
