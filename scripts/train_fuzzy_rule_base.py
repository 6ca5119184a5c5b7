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
~0.5 s per scene). On rendered scenes (about 4 min):

    python scripts/train_fuzzy_rule_base.py --source rendered --per-type 80 \
        --validation-per-type 20 --train-seed 1 --validation-seed 2 --max-residual-mm 10
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / 'src' / 'stereo_fuzzy_perception'))

from stereo_fuzzy_perception.correlation_area import AreaConfig  # noqa: E402
from stereo_fuzzy_perception.point_selectors import BestPointChooser  # noqa: E402
from stereo_fuzzy_perception.rule_base import (  # noqa: E402
    data_path,
    load_rule_base,
    save_rule_base,
)
from stereo_fuzzy_perception.selector_training import (  # noqa: E402
    best_point_errors,
    build_training_set,
    fit_rule_offsets,
    inlier_scenes,
    make_scenes,
    score_errors,
    subset,
    with_consequent_areas,
)
from stereo_fuzzy_perception.synthetic_scenes import SCENE_SOURCES  # noqa: E402


def main() -> None:
    """Fit, report train/validation errors, write the rule base file."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--source', default='geometric', choices=sorted(SCENE_SOURCES))
    parser.add_argument('--per-type', type=int, default=300,
                        help='training scenes per object type')
    parser.add_argument('--validation-per-type', type=int, default=60)
    parser.add_argument('--train-seed', type=int, default=1)
    parser.add_argument('--validation-seed', type=int, default=2)
    parser.add_argument('--ridge', type=float, default=1e-3)
    parser.add_argument('--base-areas', default='1,2,3,4',
                        help='areas whose union centre every consequent starts from')
    parser.add_argument('--template', default=str(data_path('fuzzy_chapter.yaml')),
                        help='rule base whose membership functions and premises are kept')
    parser.add_argument('--max-residual-mm', type=float, default=math.inf,
                        help='train only on scenes whose target is within this horizontal '
                        'distance of the correlation-area centre (inf: all)')
    parser.add_argument('--output', default=str(data_path('fuzzy_fitted.yaml')))
    args = parser.parse_args()
    if args.train_seed == args.validation_seed:
        parser.error('training and validation scenes must come from different seeds')

    config = AreaConfig()
    source = SCENE_SOURCES[args.source]()
    template = load_rule_base(args.template)
    base_areas = tuple(int(k) for k in args.base_areas.split(','))
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
    description = (
        f'chapter structure, consequents = centre of areas {list(base_areas)} + offset fitted '
        f'by least squares on {len(train)} {args.source} scenes (seed {args.train_seed}, '
        f'ridge {args.ridge}, max residual {args.max_residual_mm} mm); '
        'scripts/train_fuzzy_rule_base.py')
    fitted = fit_rule_offsets(with_consequent_areas(template, base_areas), train, args.ridge,
                              name='fitted', description=description)
    rig = train_scenes[0].rig
    print('| rule base | set | horizontal mean [mm] | horizontal p95 [mm] | '
          'vertical mean [mm] | within 3 mm |')
    print('|---|---|---|---|---|---|')
    for label, rule_base in (('chapter', template), ('fitted', fitted)):
        chooser = BestPointChooser('fuzzy_fitted', config, rig.world_from_left_camera(),
                                   rule_base)
        for set_name, scenes in (('train', train_scenes), ('validation', validation_scenes)):
            score = score_errors(best_point_errors(chooser, scenes))
            print(f'| {label} | {set_name} | {score.horizontal_mean:.2f} | '
                  f'{score.horizontal_p95:.2f} | {score.vertical_mean:.2f} | '
                  f'{100 * score.success_rate:.1f} % |')
    header = (f'Fitted rule base of fuzzy_best_point_node: written by '
              f'scripts/train_fuzzy_rule_base.py\n'
              f'  --source {args.source} --per-type {args.per_type} --train-seed '
              f'{args.train_seed} --ridge {args.ridge} --base-areas {args.base_areas}'
              f' --max-residual-mm {args.max_residual_mm}\n'
              'Same structure as fuzzy_chapter.yaml (areas, ratios, membership functions, '
              'Eq. 10);\nconsequent = centre of the listed areas + offset_m [m] in world, '
              'fitted by least squares.')
    save_rule_base(fitted, args.output, header)
    print(f'wrote {args.output} ({time.perf_counter() - start:.0f} s in all)')


if __name__ == '__main__':
    main()
