"""Where a rendered scene's true top face lies in its left image, for the benchmarks and the
tuning tools: they know the answer, which no selector may.

- `left_pixel_rays`: the world rays of left rectified pixels;
- `top_face_pixels`: which of those pixels see the true top face;
- `true_outline_point`: the best point that the true top's outline gives at the median height
  of its own matches. rig_generalisation_benchmark.py reports it as its diagnosis row and
  rig_tuning.py with `--true-outline`: what the matches' heights allow when the top is found
  perfectly, so that the gap between it and a selector is the loss of finding the top, and the
  gap between it and the perfect-depth ceiling the matcher's.
"""

from __future__ import annotations

import cv2
import numpy as np
from stereo_fuzzy_perception.core.rig_geometry import transform_points
from stereo_fuzzy_perception.simulation.synthetic_scenes import SyntheticScene

DIAGNOSIS_ROW = ("diagnosis: the true top's outline at its matches' median height "
                 '(knows the outline)')
"""The row true_outline_point fills in rig_generalisation_benchmark.py's tables and CSV, and
that rig_breakdown.py reads back."""

INNER_PX = 2
"""true_outline_point takes the matches this far inside the top's outline in the left image: a
window straddling the rim takes the disparity of whichever side is textured more."""


def left_pixel_rays(scene: SyntheticScene, columns: np.ndarray, rows: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Return the left camera's centre (3,) and the rays (N, 3) in `world` of left rectified
    pixels (columns, rows), each ray scaled to unit rectified depth."""
    pose = scene.rig.world_from_left_camera()
    projection, rotation = np.asarray(scene.left.P, float), np.asarray(scene.left.R, float)
    rectified_rays = np.column_stack([(columns - projection[0, 2]) / projection[0, 0],
                                      (rows - projection[1, 2]) / projection[1, 1],
                                      np.ones(len(columns))])
    world_rays: np.ndarray = rectified_rays @ rotation @ pose[:3, :3].T
    return pose[:3, 3], world_rays


def top_face_pixels(scene: SyntheticScene, columns: np.ndarray, rows: np.ndarray
                    ) -> np.ndarray:
    """Return which left rectified pixels (columns, rows) see the scene's true top face.

    Each pixel's ray (rectified, taken back into the camera's optical frame and into `world`)
    is cut with the top's plane; the top being the scene's highest surface, a pixel whose ray
    meets it inside the prism sees it.
    """
    centre, world_rays = left_pixel_rays(scene, columns, rows)
    with np.errstate(divide='ignore', invalid='ignore'):
        scale = (scene.prism.height - centre[2]) / world_rays[:, 2]
    on_top = centre + world_rays * scale[:, None]
    seen: np.ndarray = (scale > 0) & scene.prism.contains_xy(on_top[:, :2])
    return seen


def true_outline_point(scene: SyntheticScene) -> np.ndarray:
    """Return the point the true top's outline gives at its matches' median height, in `world`
    (NaN: no match inside it).

    The median world height of the matches INNER_PX or more inside the left pixels that see
    the top; then the centroid of those pixels' rays cut at that height, each weighted by the
    area of the top it sees, as a selector's point is its face's. Its error is the matcher's
    noise and bias on the top alone.
    """
    width, height = scene.left.width, scene.left.height
    columns, rows = np.meshgrid(np.arange(width, dtype=float), np.arange(height, dtype=float))
    seen = top_face_pixels(scene, columns.ravel(), rows.ravel()).reshape(height, width)
    size = 2 * INNER_PX + 1
    inner = cv2.erode(seen.astype(np.uint8), np.ones((size, size), np.uint8)) > 0
    u = np.rint(scene.points.u_left).astype(int)
    v = np.rint(scene.points.v_left).astype(int)
    inside = (u >= 0) & (u < width) & (v >= 0) & (v < height)
    inside[inside] = inner[v[inside], u[inside]]
    world = transform_points(scene.rig.world_from_left_camera(),
                             scene.points.xyz[inside].astype(float))
    if not len(world) or not seen.any():
        return np.full(3, np.nan)
    level = float(np.median(world[:, 2]))
    centre, rays = left_pixel_rays(scene, columns[seen], rows[seen])
    depth = (level - centre[2]) / rays[:, 2]  # rectified depth: the rays have unit depth
    cut = centre + rays * depth[:, None]
    # each pixel stands for the patch of the level top it sees, whose area grows as depth^3
    return np.asarray(np.average(cut, axis=0, weights=depth ** 3), float)
