#!/usr/bin/env python3
"""DEVELOPMENT ONLY: the top face fitted as a shape to both images, against the chain's point.

The model and the fit are the chain's own (stereo_fuzzy_perception.core.best_point.
top_shape_fit; its docstring gives the model). This probe fits every decided scene of a tuning
split and prints what several rules for taking the fitted centre would give (weight of the
fit, furthest move, least drop of the cost per pixel, furthest as-good end of the fits from
shifted starts) beside the chain's point before the fit, and how long the fit took (costs and
Nelder-Mead) per scene. It is how the rule in top_shape_fit (WEIGHT, MAX_MOVE_M, MIN_DROP,
MAX_SPREAD_M, FAR_MOVE_M) and its cost settings were chosen: on the train and validation
splits and pools of rigs no split used, never on the evaluation split. The matched scenes come from
rig_tuning.py's cache (--cache; made by its first run on a split).

    source scripts/env.sh
    nice python benchmarks/outline_fit_probe.py --split train --save /tmp/fit_train.json
    nice python benchmarks/outline_fit_probe.py --split validation --point-stride 3
    nice python benchmarks/outline_fit_probe.py --oversampling 3   # the antialiased renders
    nice python benchmarks/outline_fit_probe.py --restarts 3 --simplex-mm 0.01   # slower
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402
from stereo_fuzzy_perception.core.best_point import top_shape_fit  # noqa: E402
from stereo_fuzzy_perception.core.best_point.correlation_area import AreaConfig  # noqa: E402
from stereo_fuzzy_perception.core.best_point.point_selectors import (  # noqa: E402
    BestPointChooser,
    decision_area,
)
from stereo_fuzzy_perception.core.rig_geometry import StereoRig  # noqa: E402

from benchmarks.rig_tuning import add_cached_split_arguments, scenes  # noqa: E402

INF = float('inf')

RULES = [(0.0, 0.0, 0.0, INF, 0.0), (1.0, 100.0, 0.0, INF, 100.0), (1.0, 5.0, 0.02, INF, 5.0),
         (0.5, 5.0, 0.01, INF, 5.0), (0.7, 5.0, 0.02, INF, 5.0), (0.7, 5.0, 0.01, INF, 5.0),
         (0.7, 3.0, 0.01, INF, 3.0), (0.7, 8.0, 0.01, INF, 8.0), (0.7, 5.0, 0.005, INF, 5.0),
         (0.7, 7.0, 0.005, INF, 7.0), (0.7, 5.0, 0.01, 1.5, 5.0), (0.7, 5.0, 0.005, 1.5, 5.0),
         (0.7, 7.0, 0.01, 1.5, 7.0), (0.7, 7.0, 0.005, 1.0, 7.0), (0.7, 7.0, 0.005, 1.5, 7.0),
         (0.7, 7.0, 0.005, 2.0, 7.0), (1.0, 7.0, 0.005, 1.5, 7.0), (0.5, 7.0, 0.005, 1.5, 7.0),
         (0.7, 7.0, 0.005, 1.5, 10.0), (0.7, 7.0, 0.005, 1.5, 12.0), (0.7, 7.0, 0.005, 1.5, 15.0),
         (0.7, 7.0, 0.005, INF, 12.0)]
"""(weight, furthest move [mm], least drop per pixel, furthest as-good minimum from the shifted
starts [mm], furthest move taking the fit whole [mm]) of the rules printed."""


def main() -> None:
    """Fit the top of every decided scene of the split and print the rules' outcomes."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    add_cached_split_arguments(parser)
    parser.add_argument('--point-stride', type=int, default=1, choices=(1, 3))
    parser.add_argument('--restarts', type=int, default=top_shape_fit.RESTARTS,
                        help='start Nelder-Mead again from where it stopped, up to this often')
    parser.add_argument('--samples', type=int, default=top_shape_fit.SAMPLES,
                        help='heights sampled down the side wall and to the right camera')
    parser.add_argument('--band-mm', type=float, default=1000.0 * top_shape_fit.BAND_M,
                        help='how far beyond the guessed shapes pixels are scored')
    parser.add_argument('--simplex-mm', type=float,
                        default=1000.0 * top_shape_fit.SIMPLEX_SIZE_M,
                        help="Nelder-Mead's simplex size at which it stops")
    parser.add_argument('--min-parallax-px', type=float, default=top_shape_fit.MIN_PARALLAX_PX,
                        help="tops standing less than this out of the surface's disparity are "
                        'not fitted')
    parser.add_argument('--full-resolution-px', type=int,
                        default=top_shape_fit.FULL_RESOLUTION_PX,
                        help='faces wider than this are scored on every second, third... pixel')
    parser.add_argument('--save', metavar='FILE', help="write each scene's points (JSON)")
    args = parser.parse_args()
    top_shape_fit.BAND_M = args.band_mm / 1000.0
    top_shape_fit.SIMPLEX_SIZE_M = args.simplex_mm / 1000.0
    top_shape_fit.FULL_RESOLUTION_PX = args.full_resolution_px
    top_shape_fit.MIN_PARALLAX_PX = args.min_parallax_px
    # the chain's point before the fit: the probe applies the rules itself
    chooser = BestPointChooser.create('fuzzy_fitted', replace(AreaConfig(), fit_top_shape=False),
                                      StereoRig())
    rows = []
    seconds = []
    for label, scene in scenes(args.split, args.per_type, args.point_stride, Path(args.cache),
                               2, args.oversampling):
        pose = scene.rig.world_from_left_camera()
        decision = replace(chooser, world_from_camera=pose).decide(scene.points, scene.left,
                                                                   scene.right)
        if decision.best_point_world is None:
            continue
        chain = np.asarray(decision.best_point_world, dtype=float)
        area = decision_area(scene.points, scene.left, scene.right, pose, chooser.area_config)
        started = time.perf_counter()
        fit = top_shape_fit.fitted(area, scene.points, scene.left, scene.right, pose,
                                   chain[:2], max(2, args.samples), args.restarts)
        took = time.perf_counter() - started
        if fit is not None:
            seconds.append(took)
        target = np.asarray(scene.target_world, dtype=float)
        rows.append((label, chain, fit, target))
        fitted = (f', fitted {fit.shape} {1000.0 * np.linalg.norm(fit.centre - target[:2]):5.1f}'
                  f' mm on the surface, drop {fit.drop_per_px:.3f}, spread'
                  f' {1000.0 * fit.spread_m:.1f} mm' if fit else ', not fitted')
        print(f'{label}: chain {1000.0 * np.linalg.norm(chain - target):5.1f} mm{fitted} '
              f'({1000.0 * took:.0f} ms)', flush=True)
    print(f'{len(rows)} decided {args.split} scenes at stride {args.point_stride}, '
          f'{len(seconds)} fitted: within 3 mm / over '
          f'10 mm (the fit took {1000.0 * np.median(seconds):.0f} ms median, '
          f'{1000.0 * np.max(seconds):.0f} ms at most, on this machine)')
    for weight, max_move_mm, min_drop, max_spread_mm, far_move_mm in RULES:
        errors = np.array([1000.0 * np.linalg.norm(top_shape_fit.moved_toward_fit(
            chain, fit, weight, max_move_mm / 1000.0, min_drop, max_spread_mm / 1000.0,
            far_move_mm / 1000.0) - target) for _, chain, fit, target in rows])
        print(f'  weight {weight:.1f}, move <= {max_move_mm:g} mm, drop >= {min_drop:g}, '
              f'spread <= {max_spread_mm:g} mm, whole up to {far_move_mm:g} mm: '
              f'{int(np.sum(errors <= 3.0))} / {int(np.sum(errors > 10.0))}, '
              f'mean {np.mean(errors):.2f} mm')
    if args.save:
        Path(args.save).write_text(json.dumps({
            label: {'chain': chain.tolist(), 'target': target.tolist(),
                    'fit': None if fit is None else {'shape': fit.shape,
                                                     'centre': fit.centre.tolist(),
                                                     'drop': fit.drop_per_px,
                                                     'spread': fit.spread_m}}
            for label, chain, fit, target in rows}, indent=0))


if __name__ == '__main__':
    main()
