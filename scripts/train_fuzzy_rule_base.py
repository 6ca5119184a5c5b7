#!/usr/bin/env python3
"""Fit the consequents of the fuzzy best-point rule base on simulated scenes.

Keeps the chapter's structure (four areas, r_k = d1_k / d2_k, the chapter file's triangular
membership functions and premises, Eq. 10) and estimates each rule's consequent, the centre of
the rule's areas plus an offset, by least squares over training scenes (zero-order Takagi-Sugeno
consequent estimation, as ANFIS does it). Training and validation scenes come from different
seeds. Writes stereo_fuzzy_perception/data/fuzzy_fitted.yaml by default.

    source scripts/env.sh
    python scripts/train_fuzzy_rule_base.py                 # geometric scenes, seed 1 / 2
    python scripts/train_fuzzy_rule_base.py --source geometric --per-type 400

`--source` names a scene source in synthetic_scenes.SCENE_SOURCES: `geometric` (perfect surface
samples + disparity noise) or `rendered` (pybullet images through the real correlation stage,
~0.5 s per scene), or `distribution`: the train split of the randomized scene distribution
(simulation/scene_distribution.py; training rigs only, so
benchmarks/rig_generalisation_benchmark.py grades on rigs never seen here). The packaged
fuzzy_fitted.yaml comes from:

    nice python scripts/train_fuzzy_rule_base.py --source distribution --per-type 60 \
        --validation-per-type 10 --max-residual-mm 10 --scene-cache /tmp/distribution_scenes.pkl

(about 5 min on 2 shared cores; the cache holds the matched scenes, so the neural baseline's
script and a retraining after a change of the fuzzy stage render nothing.)
"""

from __future__ import annotations

import argparse
import shlex
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / 'src' / 'stereo_fuzzy_perception'))

from stereo_fuzzy_perception.core.best_point.correlation_area import AreaConfig  # noqa: E402
from stereo_fuzzy_perception.core.best_point.point_selectors import BestPointChooser  # noqa: E402
from stereo_fuzzy_perception.core.best_point.rule_base import (  # noqa: E402
    data_path,
    load_rule_base,
    save_rule_base,
)
from stereo_fuzzy_perception.simulation.selector_training import (  # noqa: E402
    add_recipe_arguments,
    fit_rule_offsets,
    make_training_scenes,
    print_scores,
    with_consequent_areas,
)


def main() -> None:
    """Fit, report train/validation errors, write the rule base file."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_recipe_arguments(parser)
    parser.add_argument('--ridge', type=float, default=1e-3)
    parser.add_argument('--base-areas', default='1,2,3,4',
                        help='areas whose union centre every consequent starts from')
    parser.add_argument('--template', default=str(data_path('fuzzy_chapter.yaml')),
                        help='rule base whose membership functions and premises are kept')
    parser.add_argument('--output', default=str(data_path('fuzzy_fitted.yaml')))
    args = parser.parse_args()

    config = AreaConfig()
    template = load_rule_base(args.template)
    base_areas = tuple(int(k) for k in args.base_areas.split(','))
    start = time.perf_counter()
    scenes = make_training_scenes(parser, args, config)
    train = scenes.train
    origin = (f'{args.source} source, train split (training rigs), point stride '
              f'{args.point_stride}' if args.source == 'distribution'
              else f'{args.source} source, seed {args.train_seed}')
    description = (
        f'chapter structure, consequents = centre of areas {list(base_areas)} + offset fitted '
        f'by least squares on {len(train)} scenes ({origin}, ridge {args.ridge}, max residual '
        f'{args.max_residual_mm} mm); scripts/train_fuzzy_rule_base.py')
    fitted = fit_rule_offsets(with_consequent_areas(template, base_areas), train, args.ridge,
                              name='fitted', description=description)
    camera_pose = scenes.train_scenes[0].rig.world_from_left_camera()
    print_scores({label: BestPointChooser('fuzzy_fitted', config, camera_pose, rule_base)
                  for label, rule_base in (('chapter', template), ('fitted', fitted))}, scenes)
    header = (f'Fitted rule base of fuzzy_best_point_node: written by '
              f'scripts/train_fuzzy_rule_base.py\n'
              f'  {shlex.join(sys.argv[1:])}\n'
              'Same structure as fuzzy_chapter.yaml (areas, ratios, membership functions, '
              'Eq. 10);\nconsequent = centre of the listed areas + offset_m [m] in world, '
              'fitted by least squares.')
    save_rule_base(fitted, args.output, header)
    print(f'wrote {args.output} ({time.perf_counter() - start:.0f} s in all)')


if __name__ == '__main__':
    main()
