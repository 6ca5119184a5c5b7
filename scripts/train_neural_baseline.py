#!/usr/bin/env python3
"""Train the neural-network baseline (the chapter's comparison method) on simulated scenes.

A one-hidden-layer perceptron over the fuzzy system's features (log r_k, area centres relative to
the area's centre, that centre's x, y) predicting the offset of the best point from (centre x,
centre y, top height). Full-batch Adam, seeded; training and validation scenes come from different
seeds. Writes stereo_fuzzy_perception/data/neural_baseline.npz by default.

    source scripts/env.sh
    python scripts/train_neural_baseline.py
    python scripts/train_neural_baseline.py --source geometric --per-type 400 --hidden 16

`--source` names a scene source in synthetic_scenes.SCENE_SOURCES: `geometric` (perfect surface
samples + disparity noise) or `rendered` (pybullet images through the real correlation stage,
~0.5 s per scene). On rendered scenes (about 4 min):

    python scripts/train_neural_baseline.py --source rendered --per-type 80 \
        --validation-per-type 20 --train-seed 1 --validation-seed 2 --max-residual-mm 10
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / 'src' / 'stereo_fuzzy_perception'))

from stereo_fuzzy_perception.correlation_area import AreaConfig  # noqa: E402
from stereo_fuzzy_perception.neural_baseline import train_neural_baseline  # noqa: E402
from stereo_fuzzy_perception.point_selectors import BestPointChooser  # noqa: E402
from stereo_fuzzy_perception.rule_base import data_path  # noqa: E402
from stereo_fuzzy_perception.selector_training import (  # noqa: E402
    best_point_errors,
    build_training_set,
    inlier_scenes,
    make_scenes,
    score_errors,
    subset,
)
from stereo_fuzzy_perception.synthetic_scenes import SCENE_SOURCES  # noqa: E402


def main() -> None:
    """Train, report train/validation errors, write the weights."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--source', default='geometric', choices=sorted(SCENE_SOURCES))
    parser.add_argument('--per-type', type=int, default=300,
                        help='training scenes per object type')
    parser.add_argument('--validation-per-type', type=int, default=60)
    parser.add_argument('--train-seed', type=int, default=1)
    parser.add_argument('--validation-seed', type=int, default=2)
    parser.add_argument('--hidden', type=int, default=16)
    parser.add_argument('--iterations', type=int, default=4000)
    parser.add_argument('--init-seed', type=int, default=0)
    parser.add_argument('--max-residual-mm', type=float, default=math.inf,
                        help='train only on scenes whose target is within this horizontal '
                        'distance of the correlation-area centre (inf: all)')
    parser.add_argument('--output', default=str(data_path('neural_baseline.npz')))
    args = parser.parse_args()
    if args.train_seed == args.validation_seed:
        parser.error('training and validation scenes must come from different seeds')

    config = AreaConfig()
    source = SCENE_SOURCES[args.source]()
    print(f'making {4 * args.per_type} training scenes (seed {args.train_seed}) and '
          f'{4 * args.validation_per_type} validation scenes (seed {args.validation_seed}) '
          f'from the {args.source} source')
    start = time.perf_counter()
    train_scenes = make_scenes(source, args.per_type, args.train_seed)
    validation_scenes = make_scenes(source, args.validation_per_type, args.validation_seed)
    train = build_training_set(train_scenes, config)
    train = subset(train, inlier_scenes(train, args.max_residual_mm / 1000.0))
    print(f'{len(train)} training scenes used, {train.skipped} left out (no area, or target '
          f'more than {args.max_residual_mm} mm from the area centre)')
    print(f'scenes made in {time.perf_counter() - start:.0f} s')
    network = train_neural_baseline(train.features, train.targets - train.nn_base,
                                    hidden=args.hidden, iterations=args.iterations,
                                    seed=args.init_seed)
    residual = network.predict(train.features) - (train.targets - train.nn_base)
    print(f'training RMS error {1000 * np.sqrt(np.mean(residual ** 2)):.3f} mm per coordinate')
    chooser = BestPointChooser('neural_network', config,
                               train_scenes[0].rig.world_from_left_camera(), network=network)
    print('| set | horizontal mean [mm] | horizontal p95 [mm] | vertical mean [mm] | '
          'within 3 mm |')
    print('|---|---|---|---|---|')
    for set_name, scenes in (('train', train_scenes), ('validation', validation_scenes)):
        score = score_errors(best_point_errors(chooser, scenes))
        print(f'| {set_name} | {score.horizontal_mean:.2f} | {score.horizontal_p95:.2f} | '
              f'{score.vertical_mean:.2f} | {100 * score.success_rate:.1f} % |')
    network.save(args.output)
    print(f'wrote {args.output} ({time.perf_counter() - start:.0f} s in all)')


if __name__ == '__main__':
    main()
