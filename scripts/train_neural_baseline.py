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
~0.5 s per scene), or `distribution`: the train split of the randomized scene distribution
(simulation/scene_distribution.py; training rigs only). The packaged neural_baseline.npz
comes from:

    nice python scripts/train_neural_baseline.py --source distribution --per-type 60 \
        --validation-per-type 10 --max-residual-mm 10 --hidden 8 --weight-decay 1

(16 hidden units and weight decay 1e-4 reached 55 % within 3 mm on its training scenes and 5 %
on the validation split; 8 units and weight decay 1 reached 30 % and 25 %.) Add
`--scene-cache /tmp/distribution_scenes.pkl` to both scripts to render the scenes once.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / 'src' / 'stereo_fuzzy_perception'))

from stereo_fuzzy_perception.core.best_point.correlation_area import AreaConfig  # noqa: E402
from stereo_fuzzy_perception.core.best_point.neural_baseline import train_neural_baseline  # noqa: E402
from stereo_fuzzy_perception.core.best_point.point_selectors import BestPointChooser  # noqa: E402
from stereo_fuzzy_perception.core.best_point.rule_base import data_path  # noqa: E402
from stereo_fuzzy_perception.simulation.selector_training import (  # noqa: E402
    add_recipe_arguments,
    make_training_scenes,
    print_scores,
)


def main() -> None:
    """Train, report train/validation errors, write the weights."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_recipe_arguments(parser)
    parser.add_argument('--hidden', type=int, default=16)
    parser.add_argument('--iterations', type=int, default=4000)
    parser.add_argument('--weight-decay', type=float, default=1e-4,
                        help='L2 penalty on the weights (choose it on the validation split)')
    parser.add_argument('--init-seed', type=int, default=0)
    parser.add_argument('--output', default=str(data_path('neural_baseline.npz')))
    args = parser.parse_args()

    config = AreaConfig()
    start = time.perf_counter()
    scenes = make_training_scenes(parser, args, config)
    train = scenes.train
    network = train_neural_baseline(train.features, train.targets - train.nn_base,
                                    hidden=args.hidden, iterations=args.iterations,
                                    weight_decay=args.weight_decay, seed=args.init_seed)
    residual = network.predict(train.features) - (train.targets - train.nn_base)
    print(f'training RMS error {1000 * np.sqrt(np.mean(residual ** 2)):.3f} mm per coordinate')
    chooser = BestPointChooser('neural_network', config,
                               scenes.train_scenes[0].rig.world_from_left_camera(),
                               network=network)
    print_scores({'neural_network': chooser}, scenes)
    network.save(args.output)
    print(f'wrote {args.output} ({time.perf_counter() - start:.0f} s in all)')


if __name__ == '__main__':
    main()
