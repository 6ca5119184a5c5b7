#!/usr/bin/env python3
"""DEVELOPMENT ONLY: the top face fitted as a shape to both images, against the chain's point.

A lead, not part of the chain (benchmarks/EXPERIMENTS.md, "Eighteenth session"). The chain's
outline comes from the left image's edges around the matches, and on the rigs of the train and
validation splits it errs by about a pixel either way: a correlation window straddling the rim
takes the disparity of whichever side is textured more. Here the outline is found from both
images at once, pixel by pixel, with no window:

- Each pixel of a crop around the chain's area is compared with the right image where three
  surfaces would put it: the top face's plane (at the chain's top height), the work surface,
  and the side wall (the planes between them, taken where the pixel's ray enters the object).
  The cost of a pixel on a surface is |right - (gain * left + offset)| in units of the table's
  contrast, capped at CAP (gain and offset fitted on the crop's pixels far from the area).
- A top face is a disc (centre, radius) or a rectangle (centre, angle, sides) on the top's
  plane. It labels each pixel: on the top when its ray meets the plane inside the shape, on
  the wall when its ray enters the object's side before reaching the surface, on the surface
  otherwise; a surface pixel that the object hides from the right camera costs what a
  mismatch costs (the crop's median cost at the top's disparity far from the area). Labels
  are soft across one pixel, so the summed cost moves smoothly with the shape.
- Both shapes are fitted by Nelder-Mead from the chain's point and its area's principal axes
  (with --starts 5 also from four starts 2 px around it; with --restarts K started again where
  its simplex stalled, up to K times); the lower cost wins.

The fitted centre is taken only where it lies within a few millimetres of the chain's point
and lowered the cost clearly (a small drop per pixel is a fit that found nothing), alone or
blended with the chain's point: the probe prints the outcomes of several such rules (weight
of the fit, furthest move, least drop) on the split's decided scenes, beside the chain's. Its
cost per pair is far beyond fuzzy_best_point_node's budget at 30 Hz (benchmarks/EXPERIMENTS.md
gives it): the reason it is a probe.

    source scripts/env.sh
    nice python benchmarks/outline_fit_probe.py --split train --save /tmp/fit_train.json
    nice python benchmarks/outline_fit_probe.py --split validation
    nice python benchmarks/outline_fit_probe.py --samples 10 --restarts 0   # coarser, faster
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import cv2  # noqa: E402
import numpy as np  # noqa: E402
from scipy import optimize  # noqa: E402
from stereo_fuzzy_perception.core.best_point.correlation_area import (  # noqa: E402
    AreaConfig,
    CorrelationArea,
)
from stereo_fuzzy_perception.core.best_point.plain_top_height import (  # noqa: E402
    _plane_disparity,
    _sample,
)
from stereo_fuzzy_perception.core.best_point.point_selectors import (  # noqa: E402
    BestPointChooser,
    decision_area,
)
from stereo_fuzzy_perception.core.rig_geometry import StereoRig  # noqa: E402
from stereo_fuzzy_perception.simulation.synthetic_scenes import SyntheticScene  # noqa: E402

from benchmarks.rig_tuning import SPLITS, scenes  # noqa: E402

CAP = 1.5
"""A pixel's cost is capped at this many times the table's grey-level spread."""

MARGIN_PX = 25
"""The crop reaches this far beyond the chain's area."""

FAR_PX = 15
"""Pixels this far from the chain's area are the table's: they fit gain and offset."""

MIN_PARALLAX_PX = 1.5
"""A top whose plane and the surface's differ by less in the right image is not fitted."""

SAMPLES = 30
"""Heights sampled down the side wall and along the right camera's view to the surface (10
quantise a tall wall's disparity too coarsely: the fit then prefers wrong shapes)."""

RESTARTS = 3
"""Nelder-Mead is started again where its simplex stalled, up to this often."""


def disc_distance(xy: np.ndarray, shape: np.ndarray) -> np.ndarray:
    """Return the signed distance [m] of points (..., 2) from a disc (cx, cy, r): < 0 inside."""
    cx, cy, radius = shape
    distance: np.ndarray = np.hypot(xy[..., 0] - cx, xy[..., 1] - cy) - radius
    return distance


def rectangle_distance(xy: np.ndarray, shape: np.ndarray) -> np.ndarray:
    """Return the signed distance [m] of points (..., 2) from a rectangle (cx, cy, angle, a, b):
    sides a along the angle and b across it; < 0 inside."""
    cx, cy, angle, along, across = shape
    cos, sin = math.cos(angle), math.sin(angle)
    dx, dy = xy[..., 0] - cx, xy[..., 1] - cy
    beyond_a = np.abs(cos * dx + sin * dy) - along / 2.0
    beyond_b = np.abs(-sin * dx + cos * dy) - across / 2.0
    outside = np.hypot(np.maximum(beyond_a, 0.0), np.maximum(beyond_b, 0.0))
    distance: np.ndarray = outside + np.minimum(np.maximum(beyond_a, beyond_b), 0.0)
    return distance


Distance = Callable[[np.ndarray, np.ndarray], np.ndarray]

SHAPES: dict[str, Distance] = {'disc': disc_distance, 'rectangle': rectangle_distance}


@dataclass(frozen=True)
class PixelCosts:
    """What every hypothesis of the top is scored on: a crop's pixels and their costs."""

    on_top: np.ndarray  # (N, 2) where each pixel's ray meets the top's plane [m]
    down_wall: np.ndarray  # (S, N, 2) the ray's points from the top's plane to the surface
    to_right: np.ndarray  # (S, N, 2) the surface point's view line to the right camera
    metres_per_px: np.ndarray  # (N,) on the top's plane
    top_cost: np.ndarray  # (N,)
    wall_cost: np.ndarray  # (S, N) at each sampled wall height
    surface_cost: np.ndarray  # (N,)
    mismatch: float

    def cost(self, shape: np.ndarray, distance: Distance) -> float:
        """Return the summed cost of the pixels labelled by the shape."""
        top = np.clip(0.5 - distance(self.on_top, shape) / self.metres_per_px, 0.0, 1.0)
        along_wall = distance(self.down_wall, shape)
        inside = along_wall < 0.0
        entered = np.where(inside.any(axis=0), np.argmax(inside, axis=0),
                           np.argmin(along_wall, axis=0))
        wall = (1.0 - top) * np.clip(0.5 - along_wall.min(axis=0) / self.metres_per_px, 0, 1)
        surface = 1.0 - top - wall
        hidden = np.clip(0.5 - distance(self.to_right, shape).min(axis=0)
                         / self.metres_per_px, 0.0, 1.0)
        wall_cost = self.wall_cost[entered, np.arange(len(top))]
        return float(np.sum(top * self.top_cost + wall * wall_cost + surface * (
            (1.0 - hidden) * self.surface_cost + hidden * self.mismatch)))


def pixel_costs(scene: SyntheticScene, area: CorrelationArea, pose: np.ndarray,
                samples: int = SAMPLES) -> PixelCosts | None:
    """Return the costs of the crop around the area, or None when the top barely stands out
    in disparity or the crop leaves either image."""
    left_image, right_image = scene.points.left_image, scene.points.right_image
    surface = area.surface
    normal = surface.normal
    surface_level = surface.offset_m * float(normal[2])
    top_level = area.top_height + surface_level
    height, width = left_image.pixels.shape
    u_low = max(int(area.u_left.min()) - MARGIN_PX, left_image.x + 2)
    v_low = max(int(area.v_left.min()) - MARGIN_PX, left_image.y + 1)
    u_high = min(int(area.u_left.max()) + MARGIN_PX + 1, left_image.x + width - 2)
    v_high = min(int(area.v_left.max()) + MARGIN_PX + 1, left_image.y + height - 1)
    columns, rows = (grid.ravel() for grid in np.meshgrid(
        np.arange(u_low, u_high, dtype=float), np.arange(v_low, v_high, dtype=float)))
    column_at = _plane_disparity(scene.left, scene.right, pose, surface)
    on_top_right, on_surface_right = column_at(columns, rows, area.top_height), column_at(
        columns, rows, 0.0)
    if abs(float(np.median(on_top_right - on_surface_right))) < MIN_PARALLAX_PX:
        return None
    right_width = right_image.pixels.shape[1]
    for right_columns in (on_top_right, on_surface_right):
        if right_columns.min() < right_image.x + 1 or (
                right_columns.max() > right_image.x + right_width - 2):
            return None
    right = right_image.pixels.astype(np.float32)
    left_grey = left_image.pixels.astype(np.float32)[
        (rows - left_image.y).astype(int), (columns - left_image.x).astype(int)]
    chain = np.zeros((v_high - v_low, u_high - u_low), np.uint8)
    chain[(np.rint(area.v_left) - v_low).astype(int).clip(0, chain.shape[0] - 1),
          (np.rint(area.u_left) - u_low).astype(int).clip(0, chain.shape[1] - 1)] = 1
    far = cv2.dilate(chain, np.ones((2 * FAR_PX + 1,) * 2, np.uint8)).ravel() == 0
    if np.count_nonzero(far) < 200:
        return None
    surface_grey = _sample(right, on_surface_right, rows, right_image)
    gain, offset = np.linalg.lstsq(np.column_stack([left_grey[far], np.ones(np.count_nonzero(
        far))]), surface_grey[far], rcond=None)[0]
    unit = max(float(np.std(left_grey[far])) * abs(float(gain)), 1e-3)
    expected = gain * left_grey + offset

    def cost_at(height_m: float) -> np.ndarray:
        grey = _sample(right, column_at(columns, rows, height_m), rows, right_image)
        cost: np.ndarray = np.minimum(np.abs(grey - expected) / unit, CAP)
        return cost

    top_cost, surface_cost = cost_at(area.top_height), np.minimum(
        np.abs(surface_grey - expected) / unit, CAP)
    fractions = np.linspace(0.1, 1.0, samples)
    wall_cost = np.array([cost_at(area.top_height * (1.0 - t)) for t in fractions])
    rectification = np.asarray(scene.left.R, dtype=float).reshape(3, 3)
    intrinsic = np.asarray(scene.left.P, dtype=float)[:3, :3]
    rays = pose[:3, :3] @ rectification.T @ (np.linalg.inv(intrinsic) @ np.vstack(
        [columns, rows, np.ones_like(columns)]))
    centre = pose[:3, 3]
    facing = normal @ rays
    top_depth = (top_level - normal @ centre) / facing
    surface_depth = (surface_level - normal @ centre) / facing
    on_top = (centre[:, None] + rays * top_depth)[:2].T
    on_surface = centre[:, None] + rays * surface_depth
    focal = float(intrinsic[0, 0])
    baseline = -float(np.asarray(scene.right.P, dtype=float)[0, 3]) / focal
    right_centre = centre + pose[:3, :3] @ rectification.T @ np.array([baseline, 0.0, 0.0])
    down_wall = np.array([on_top + (on_surface[:2].T - on_top) * t for t in fractions])
    view = []
    for t in np.linspace(0.05, 1.0, samples):
        level = surface_level + t * (top_level - surface_level)
        reach = (level - on_surface[2]) / (right_centre[2] - on_surface[2])
        view.append((on_surface[:2] + (right_centre[:2, None] - on_surface[:2]) * reach).T)
    metres_per_px = top_depth * np.linalg.norm(rays, axis=0) / focal
    return PixelCosts(on_top, down_wall, np.array(view), metres_per_px, top_cost, wall_cost,
                      surface_cost, float(np.median(top_cost[far])))


@dataclass(frozen=True)
class ShapeFit:
    """The best shape found, its centre and how much it lowered the cost per pixel."""

    shape: str
    centre: np.ndarray  # (2,) [m]
    drop_per_px: float


def fit_top(costs: PixelCosts, guess: np.ndarray, axes: tuple[float, float, float],
            starts: int, restarts: int = 0) -> ShapeFit:
    """Fit a disc and a rectangle from the guessed centre (x, y) and the area's principal axes
    (angle, long side, short side); return the one of lower cost."""
    angle, long_side, short_side = axes
    step = 2.0 * float(np.median(costs.metres_per_px))
    # the disc starts at the radius whose spread is the area's total (below the top's own)
    initial = {'disc': (np.array([*guess, math.sqrt((long_side ** 2 + short_side ** 2) / 12.0)]),
                        np.array([step, step, step])),
               'rectangle': (np.array([*guess, angle, long_side, short_side]),
                             np.array([step, step, 0.15, step, step]))}
    offsets = [(0.0, 0.0), (1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0)][:max(1, starts)]
    best: tuple[float, str, np.ndarray] | None = None
    for name, (start, scales) in initial.items():
        for du, dv in offsets:
            shifted = start.copy()
            shifted[:2] += (du * step, dv * step)
            simplex = np.vstack([shifted] + [shifted + np.eye(len(shifted))[i] * scales[i]
                                             for i in range(len(shifted))])
            result = optimize.minimize(costs.cost, shifted, args=(SHAPES[name],),
                                       method='Nelder-Mead', options={
                                           'initial_simplex': simplex, 'xatol': 1e-5,
                                           'fatol': 0.5, 'maxiter': 400})
            for _ in range(restarts):
                # Nelder-Mead's simplex collapses short of the minimum; started again from
                # where it stopped, with a simplex of the first one's size, it goes on
                simplex = np.vstack([result.x] + [result.x + np.eye(len(start))[i] * scales[i]
                                                  for i in range(len(start))])
                again = optimize.minimize(costs.cost, result.x, args=(SHAPES[name],),
                                          method='Nelder-Mead', options={
                                              'initial_simplex': simplex, 'xatol': 1e-5,
                                              'fatol': 0.5, 'maxiter': 400})
                if again.fun >= result.fun - 0.5:
                    break
                result = again
            if best is None or result.fun < best[0]:
                best = (float(result.fun), name, result.x)
    assert best is not None
    chain_cost = costs.cost(initial['disc'][0], disc_distance)
    return ShapeFit(best[1], best[2][:2], (chain_cost - best[0]) / len(costs.top_cost))


def blended(chain: np.ndarray, fit: ShapeFit | None, weight: float, max_move_m: float,
            min_drop: float) -> np.ndarray:
    """Return the chain's point moved `weight` of the way to the fitted centre on the surface,
    when the fit lies within max_move_m of it and lowered the cost by min_drop per pixel."""
    if fit is None or fit.drop_per_px < min_drop or np.hypot(
            *(fit.centre - chain[:2])) > max_move_m:
        return chain
    point = np.array(chain, dtype=float)
    point[:2] = (1.0 - weight) * point[:2] + weight * fit.centre
    return point


def principal_axes(xy: np.ndarray) -> tuple[float, float, float]:
    """Return the angle [rad] and the long and short sides [m] of the uniform rectangle with
    the spread of the points xy (as object_segmentation.across_m)."""
    variances, vectors = np.linalg.eigh(np.cov(np.asarray(xy, dtype=float).T))
    return (math.atan2(vectors[1, 1], vectors[0, 1]), math.sqrt(12.0 * max(variances[1], 1e-10)),
            math.sqrt(12.0 * max(variances[0], 1e-10)))


def main() -> None:
    """Fit the top of every decided scene of the split and print the blends' outcomes."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--split', default='train', choices=SPLITS)
    parser.add_argument('--per-type', type=int, default=50)
    parser.add_argument('--cache', default='/tmp/rig_tuning_cache',
                        help="rig_tuning.py's cache of matched scenes (stride 1)")
    parser.add_argument('--oversampling', type=int, default=1, choices=(1, 3),
                        help="the split rendered antialiased (rig_tuning.py's cache of it)")
    parser.add_argument('--starts', type=int, default=1, choices=(1, 5))
    parser.add_argument('--restarts', type=int, default=RESTARTS,
                        help='start Nelder-Mead again from where it stopped, up to this often')
    parser.add_argument('--samples', type=int, default=SAMPLES,
                        help='heights sampled down the side wall and to the right camera')
    parser.add_argument('--save', metavar='FILE', help="write each scene's points (JSON)")
    args = parser.parse_args()
    chooser = BestPointChooser.create('fuzzy_fitted', AreaConfig(), StereoRig())
    rows = []
    for label, scene in scenes(args.split, args.per_type, 1, Path(args.cache), 2,
                               args.oversampling):
        pose = scene.rig.world_from_left_camera()
        decision = replace(chooser, world_from_camera=pose).decide(scene.points, scene.left,
                                                                   scene.right)
        if decision.best_point_world is None:
            continue
        chain = np.asarray(decision.best_point_world, dtype=float)
        area = decision_area(scene.points, scene.left, scene.right, pose, AreaConfig())
        costs = pixel_costs(scene, area, pose, max(2, args.samples)) if area.ok else None
        fit = (fit_top(costs, chain[:2], principal_axes(area.xyz_world[:, :2]), args.starts,
                       args.restarts) if costs is not None else None)
        target = np.asarray(scene.target_world, dtype=float)
        rows.append((label, chain, fit, target))
        fitted = (f', fitted {fit.shape} {1000.0 * np.linalg.norm(fit.centre - target[:2]):5.1f}'
                  f' mm on the surface, drop {fit.drop_per_px:.3f}' if fit else ', not fitted')
        print(f'{label}: chain {1000.0 * np.linalg.norm(chain - target):5.1f} mm{fitted}',
              flush=True)
    print(f'{len(rows)} decided {args.split} scenes: within 3 mm / over 10 mm')
    for weight, max_move_mm, min_drop in [(0.0, 0.0, 0.0), (1.0, 100.0, 0.0), (1.0, 5.0, 0.02),
                                          (0.5, 5.0, 0.0), (0.5, 5.0, 0.02), (0.5, 100.0, 0.02),
                                          (0.3, 5.0, 0.02), (0.7, 5.0, 0.02)]:
        errors = np.array([1000.0 * np.linalg.norm(blended(chain, fit, weight,
                                                           max_move_mm / 1000.0, min_drop)
                                                   - target)
                           for _, chain, fit, target in rows])
        print(f'  weight {weight:.1f}, move <= {max_move_mm:g} mm, drop >= {min_drop:g}: '
              f'{int(np.sum(errors <= 3.0))} / {int(np.sum(errors > 10.0))}')
    if args.save:
        Path(args.save).write_text(json.dumps({
            label: {'chain': chain.tolist(), 'target': target.tolist(),
                    'fit': None if fit is None else {'shape': fit.shape,
                                                     'centre': fit.centre.tolist(),
                                                     'drop': fit.drop_per_px}}
            for label, chain, fit, target in rows}, indent=0))


if __name__ == '__main__':
    main()
