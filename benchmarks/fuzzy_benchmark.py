#!/usr/bin/env python3
"""Benchmark the best-point stage: time per decision and best-point error of every selector.

1. Time per decision (BestPointChooser.decide, one core) at 1k, 10k and 100k matched points,
   next to a reference measured in the same run (one numpy pass over the points: transform to
   world and mean), so the figures can be compared across machines. Goal: under 5 ms at 100k.
2. Best-point error on seeded evaluation scenes (default: 60 per object type, seed 3; training
   used seeds 1 and 2): horizontal and vertical error, mean and p95 [mm], and the share of
   scenes with a best point within 3 mm (3D) of the top-face centre, per selector; then that
   share per object type, laid out like the chapter's Table 1.

    source scripts/env.sh
    python benchmarks/fuzzy_benchmark.py                    # noisy scenes (0.1-0.3 px)
    python benchmarks/fuzzy_benchmark.py --noise 0 0        # perfect 3D points
    python benchmarks/fuzzy_benchmark.py --source geometric --per-type 100

Prints markdown tables.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / 'src' / 'stereo_fuzzy_perception'))
for variable in ('OMP_NUM_THREADS', 'OPENBLAS_NUM_THREADS', 'MKL_NUM_THREADS'):
    os.environ.setdefault(variable, '1')  # one core

import numpy as np  # noqa: E402
from stereo_fuzzy_perception.core.best_point.correlation_area import AreaConfig  # noqa: E402
from stereo_fuzzy_perception.core.best_point.point_selectors import SELECTORS, BestPointChooser  # noqa: E402
from stereo_fuzzy_perception.core.matched_points import MatchedPoints  # noqa: E402
from stereo_fuzzy_perception.simulation.selector_training import (  # noqa: E402
    best_point_errors,
    make_scenes,
    score_errors,
)
from stereo_fuzzy_perception.simulation.synthetic_scenes import (  # noqa: E402
    OBJECT_TYPES,
    SCENE_SOURCES,
    ConvexPrism,
    GeometricSceneSource,
)

SELECTOR_ORDER = ('fuzzy_chapter', 'fuzzy_fitted', 'centroid', 'max_score', 'neural_network')
assert set(SELECTOR_ORDER) == set(SELECTORS)


def points_of_size(points: MatchedPoints, count: int, rng: np.random.Generator
                   ) -> MatchedPoints:
    """Return `count` points drawn from a scene's points (with replacement if needed)."""
    index = rng.choice(len(points), count, replace=count > len(points))
    return points.subset(np.sort(index))


def time_call(function, repeats: int) -> np.ndarray:
    """Return the run times of `function` [ms] (after one warm-up call)."""
    function()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        times.append(1000.0 * (time.perf_counter() - start))
    return np.array(times)


def timing_table(repeats: int) -> None:
    source = GeometricSceneSource(point_spacing_m=0.0004, surface_ring_m=0.03)
    side = 0.07
    square = 0.5 * side * np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])
    cube = ConvexPrism(square + np.array([0.2, 0.15]), side)
    scene = source.scene_of(cube, 'cubic_square', np.random.default_rng(0), 0.2)
    assert scene is not None
    rng = np.random.default_rng(1)
    pose = scene.rig.world_from_left_camera()
    config = AreaConfig()
    choosers = {name: BestPointChooser.create(name, config, scene.rig) for name in SELECTOR_ORDER}
    print(f'### Time per decision [ms], median (p95) of {repeats} runs, one core\n')
    print(f'(a dense 7 cm cube scene with {len(scene.points)} points, {scene.object_points} '
          'on the object, resampled to each size)\n')
    print('| points | reference pass | ' + ' | '.join(SELECTOR_ORDER) + ' |')
    print('|---' * (len(SELECTOR_ORDER) + 2) + '|')
    for count in (1_000, 10_000, 100_000):
        points = points_of_size(scene.points, count, rng)
        reference = time_call(
            lambda p=points: (np.dot(pose[:3, :3], p.xyz.T) + pose[:3, 3:4]).mean(axis=1),
            repeats)
        cells = [f'{np.median(reference):.3f}']
        for chooser in choosers.values():
            decision = chooser.decide(points, scene.left, scene.right)
            assert decision.has_best_point, decision.status_text()
            times = time_call(lambda c=chooser, p=points: c.decide(p, scene.left, scene.right),
                              repeats)
            cells.append(f'{np.median(times):.2f} ({np.percentile(times, 95):.2f})')
        print(f'| {count:,} | ' + ' | '.join(cells) + ' |')
    print()


def accuracy_tables(source_name: str, per_type: int, seed: int,
                    noise: tuple[float, float]) -> None:
    source = SCENE_SOURCES[source_name]()
    if isinstance(source, GeometricSceneSource):
        source.disparity_noise_px = noise
    scenes = make_scenes(source, per_type, seed)
    rig = scenes[0].rig
    config = AreaConfig()
    print(f'### Best-point error on {len(scenes)} {source_name} scenes ({per_type} per object '
          f'type, seed {seed}, disparity noise {noise[0]}-{noise[1]} px)\n')
    print('| selector | horizontal mean [mm] | horizontal p95 [mm] | vertical mean [mm] | '
          'vertical p95 [mm] | within 3 mm | decided |')
    print('|---|---|---|---|---|---|---|')
    per_kind: dict[str, dict[str, float]] = {}
    for name in SELECTOR_ORDER:
        chooser = BestPointChooser.create(name, config, rig)
        errors = best_point_errors(chooser, scenes)
        score = score_errors(errors)
        print(f'| {name} | {score.horizontal_mean:.2f} | {score.horizontal_p95:.2f} | '
              f'{score.vertical_mean:.2f} | {score.vertical_p95:.2f} | '
              f'{100 * score.success_rate:.1f} % | {score.decided}/{score.scenes} |')
        kinds = np.array([scene.object_type for scene in scenes])
        per_kind[name] = {kind: score_errors(errors[kinds == kind]).success_rate
                          for kind in OBJECT_TYPES}
    print("\n### Within 3 mm per object type (the layout of the chapter's Table 1)\n")
    print('| selector | circle | cylinder | cubic rectangle | cubic square |')
    print('|---|---|---|---|---|')
    for name in SELECTOR_ORDER:
        print(f'| {name} | ' + ' | '.join(f'{100 * per_kind[name][kind]:.1f} %'
                                           for kind in OBJECT_TYPES) + ' |')
    print()


def main() -> None:
    """Run the timing and the accuracy benchmarks and print markdown tables."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--source', default='geometric', choices=sorted(SCENE_SOURCES))
    parser.add_argument('--per-type', type=int, default=60, help='evaluation scenes per type')
    parser.add_argument('--seed', type=int, default=3,
                        help='evaluation seed (training uses 1 and 2)')
    parser.add_argument('--noise', type=float, nargs=2, default=(0.1, 0.3),
                        metavar=('LOW', 'HIGH'), help='disparity noise sigma range [px]')
    parser.add_argument('--repeats', type=int, default=50, help='timing runs per cell')
    parser.add_argument('--skip-timing', action='store_true')
    args = parser.parse_args()
    if args.seed in (1, 2):
        parser.error('seeds 1 and 2 are the training and validation scenes')
    if not args.skip_timing:
        timing_table(args.repeats)
    accuracy_tables(args.source, args.per_type, args.seed, tuple(args.noise))


if __name__ == '__main__':
    main()
