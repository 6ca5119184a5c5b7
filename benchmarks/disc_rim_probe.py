#!/usr/bin/env python3
"""DEVELOPMENT ONLY: can both images tell a refused disc's height from its rim, at best?

Most pairs the chain refuses on far rigs are 5 mm discs whose matches stand no further out of
the table than the table's own noise (benchmarks/EXPERIMENTS.md). Their rim is a long,
often high-contrast edge, though, and an edge's position is measured over its whole length.
This probe asks what that edge can give at best: for each disc of a tuning split the chain
refuses, the disc's *true* top outline (the scene's ground truth, projected into the left
rectified image) is aligned with the right image at heights from the surface to
--max-height-mm, and the height of the best alignment is compared with the true one.

The alignment is a two-layer one: the smoothed grey levels of a band of BAND_PX either side
of the outline, the pixels inside it taken to the right image on the top's plane at the height
tried and those outside on the surface, correlated (zero-mean normalised) with the right image
there. Only the band's far side counts, the half of the outline away from the cameras, where
no side wall joins the top in the image (the near side's wall lies between the two planes).
The chain does not do this: a real look would have to find the outline from the image first,
and this probe gives it the true one, so what it measures is a ceiling for such a look.

It prints, per render, how many of the refused discs come out within 1.5 mm of their true
height, how many nearer the surface than the top, and the correlation gained between the
surface's height and the best one (how clearly the curve peaks). The matched scenes come from
rig_tuning.py's cache (--cache; made by its first run on a split).

    source scripts/env.sh
    nice python benchmarks/disc_rim_probe.py --split train
    nice python benchmarks/disc_rim_probe.py --split validation --oversampling 3
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import cv2  # noqa: E402
import numpy as np  # noqa: E402
from stereo_fuzzy_perception.core.best_point.correlation_area import (  # noqa: E402
    NO_OBJECT,
    AreaConfig,
)
from stereo_fuzzy_perception.core.best_point.plain_top_height import (  # noqa: E402
    plane_disparity,
    sample_rows,
)
from stereo_fuzzy_perception.core.best_point.point_selectors import decision_area  # noqa: E402
from stereo_fuzzy_perception.core.best_point.work_surface import SurfacePlane  # noqa: E402
from stereo_fuzzy_perception.simulation.synthetic_scenes import SyntheticScene  # noqa: E402

from benchmarks.rig_tuning import add_cached_split_arguments, scenes  # noqa: E402

BAND_PX = 2.5
"""The band reaches this far either side of the outline [px]."""

SMOOTHING_SIGMA_PX = 1.0
"""Both images are smoothed with this Gaussian before they are compared [px]."""

STEP_M = 0.0005
"""Heights are tried this far apart, the best refined by a parabola [m]."""

WITHIN_M = 0.0015
"""A height this close to the true one counts as found [m]."""


def left_pixel(scene: SyntheticScene, world: np.ndarray) -> np.ndarray:
    """Return the left rectified pixel (column, row) of a point in `world`."""
    camera = np.linalg.inv(scene.rig.world_from_left_camera()) @ np.append(world, 1.0)
    rectified = np.asarray(scene.left.R, float) @ camera[:3]
    pixel = np.asarray(scene.left.P, float) @ np.append(rectified, 1.0)
    return pixel[:2] / pixel[2]


def true_outline(scene: SyntheticScene) -> np.ndarray:
    """Return the true top face's outline (K, 2) in the left rectified image [px]."""
    return np.array([left_pixel(scene, np.array([x, y, scene.prism.height]))
                     for x, y in scene.prism.polygon])


def far_side_band(scene: SyntheticScene, outline: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return the far side's band pixels (columns, rows) and whether each lies inside."""
    hull = cv2.convexHull(outline.astype(np.float32))
    low = np.floor(outline.min(axis=0)).astype(int) - 4
    high = np.ceil(outline.max(axis=0)).astype(int) + 4
    columns, rows = (grid.ravel() for grid in np.meshgrid(np.arange(low[0], high[0]),
                                                          np.arange(low[1], high[1])))
    distance = np.array([cv2.pointPolygonTest(hull, (float(u), float(v)), True)
                         for u, v in zip(columns, rows, strict=True)])
    # toward the cameras is where a point sinking to the table moves in the image
    top = scene.target_world
    down = left_pixel(scene, top - np.array([0.0, 0.0, top[2]])) - left_pixel(scene, top)
    centre = outline.mean(axis=0)
    far = (columns - centre[0]) * down[0] + (rows - centre[1]) * down[1] < 0.0
    band = (np.abs(distance) <= BAND_PX) & far
    return columns[band], rows[band], distance[band] > 0.0


def rim_heights(scene: SyntheticScene, surface: SurfacePlane, max_height_m: float
                ) -> tuple[float, float] | None:
    """Return (best height [m], correlation gained over the surface's height), or None when
    the band leaves either image."""
    assert scene.points.left_image is not None and scene.points.right_image is not None
    left_image, right_image = scene.points.left_image, scene.points.right_image
    columns, rows, inside = far_side_band(scene, true_outline(scene))
    height, width = left_image.pixels.shape
    if not len(columns) or (columns.min() - left_image.x < 0 or rows.min() - left_image.y < 0
                            or columns.max() - left_image.x >= width
                            or rows.max() - left_image.y >= height):
        return None
    left_smooth, right_smooth = (
        cv2.GaussianBlur(part.pixels.astype(np.float32), (0, 0), SMOOTHING_SIGMA_PX)
        for part in (left_image, right_image))
    to_right = plane_disparity(scene.left, scene.right, scene.rig.world_from_left_camera(),
                               surface)
    u, v = columns.astype(float), rows.astype(float)
    grey = left_smooth[rows - left_image.y, columns - left_image.x]
    grey = grey - grey.mean()
    on_surface = to_right(u, v, 0.0)
    heights = np.arange(0.0, max_height_m + 1e-9, STEP_M)
    scores = np.full(len(heights), -1.0)
    for index, level in enumerate(heights):
        right_u = np.where(inside, to_right(u, v, level), on_surface)
        if right_u.min() - right_image.x < 1 or (
                right_u.max() - right_image.x > right_image.pixels.shape[1] - 2):
            continue
        right_grey = sample_rows(right_smooth, right_u, v, right_image)
        right_grey = right_grey - right_grey.mean()
        norm = float(np.linalg.norm(grey) * np.linalg.norm(right_grey))
        if norm > 0.0:
            scores[index] = float(grey @ right_grey) / norm
    best = int(np.argmax(scores))
    found = float(heights[best])
    if 0 < best < len(heights) - 1:
        curvature = scores[best - 1] - 2.0 * scores[best] + scores[best + 1]
        if curvature < 0.0:
            found += 0.5 * (scores[best - 1] - scores[best + 1]) / curvature * STEP_M
    return found, float(scores[best] - scores[0])


def main() -> None:
    """Align the true rim of every disc of the split the chain refuses; print the heights."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    add_cached_split_arguments(parser)
    parser.add_argument('--max-height-mm', type=float, default=20.0)
    args = parser.parse_args()
    config = AreaConfig()
    rows = []
    for label, scene in scenes(args.split, args.per_type, 1, Path(args.cache), 2,
                               args.oversampling):
        if scene.object_type != 'circle':
            continue
        pose = scene.rig.world_from_left_camera()
        area = decision_area(scene.points, scene.left, scene.right, pose, config)
        if area.status != NO_OBJECT:
            continue
        measured = rim_heights(scene, area.surface, args.max_height_mm / 1000.0)
        if measured is None:
            continue
        height, gain = measured
        rows.append((label, scene.prism.height, height, gain))
        print(f'  {label}: true {1000 * scene.prism.height:.1f} mm, rim {1000 * height:.1f} mm, '
              f'correlation gained {gain:.4f}')
    errors = np.array([found - true for _, true, found, _ in rows])
    lower = sum(found < 0.5 * true for _, true, found, _ in rows)
    print(f'{len(rows)} discs refused as no_object (split {args.split}, oversampling '
          f'{args.oversampling}): rim height within {1000 * WITHIN_M:g} mm of the true one '
          f'{int(np.sum(np.abs(errors) <= WITHIN_M))}, nearer the surface than the top '
          f'{lower}; median |error| {1000 * float(np.median(np.abs(errors))):.1f} mm'
          if len(rows) else 'no disc refused as no_object')


if __name__ == '__main__':
    main()
