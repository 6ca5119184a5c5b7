#!/usr/bin/env python3
"""Count the best points the chain gives on bare tables: randomized scenes without their object.

Every scene of a split of simulation/scene_distribution.py (the evaluation split by default:
held-out rigs, seeds of its own) is rendered with its object moved out of every camera's view
(scene_distribution.bare_table): the same table, textures, light, sensor noise and rig, and
nothing on the table. Each pair is matched with correlation_node's default settings and
decided by fuzzy_fitted as fuzzy_best_point_node does (at a stride above 1, a face too thin is
matched again at stride 1). Every point given is a move to where nothing is: the goal is none.
Beside it, in the same run, the plain OpenCV pipeline of rig_generalisation_benchmark.py
(StereoSGBM + height mask + largest connected component + top band) on the same pairs.

    source scripts/env.sh
    nice python benchmarks/bare_table_benchmark.py                    # 50 scenes per type
    nice python benchmarks/bare_table_benchmark.py --split train      # where changes are tuned
    nice python benchmarks/bare_table_benchmark.py --split train --rig-pool-seed 15
    nice python benchmarks/bare_table_benchmark.py --encoding rgb8    # colour cameras

`--rig-pool-seed N` (train or validation only) draws the split's rigs from the pool of seed N,
as rig_tuning.py does: bare tables seen by rigs neither tuning nor the evaluation split used,
for a change that must give no point where nothing is to be checked on many more tables.

`--cache DIR` (development) keeps the rendered and matched tables of a split in DIR and reads
them back on the next run with the same split, scenes per type, pool and strides: a change to
the decision is then checked on the same tables in a fraction of the time. A change to
rendering or matching needs a new DIR.

Prints markdown and writes <output>/bare_tables[_<split>].md.
"""

from __future__ import annotations

import argparse
import collections
import os
import pickle
import shlex
import sys
import time
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / 'src' / 'stereo_fuzzy_perception'))
for variable in ('OMP_NUM_THREADS', 'OPENBLAS_NUM_THREADS', 'MKL_NUM_THREADS'):
    os.environ.setdefault(variable, '1')

from stereo_fuzzy_perception.core.best_point.correlation_area import (  # noqa: E402
    STATUS_OK,
    AreaConfig,
)
from stereo_fuzzy_perception.core.best_point.point_selectors import BestPointChooser  # noqa: E402
from stereo_fuzzy_perception.core.best_point.second_look import decide_with_second_look  # noqa: E402
from stereo_fuzzy_perception.core.rig_geometry import StereoRig  # noqa: E402
from stereo_fuzzy_perception.simulation.distribution_source import (  # noqa: E402
    MatchedDistributionScene,
    match_scene,
)
from stereo_fuzzy_perception.simulation.scene_distribution import (  # noqa: E402
    DEFAULT_SETTINGS,
    SPLITS,
    DistributionSettings,
    bare_table,
    split_plan,
)

OPENCV = 'opencv'


def matched_tables(split: str, per_type: int, strides: list[int],
                   settings: DistributionSettings, cache: Path | None, encoding: str = 'mono8'
                   ) -> Iterator[MatchedDistributionScene]:
    """Yield the split's scenes without their object, rendered and matched at every stride
    (with the OpenCV pipeline's point); with a cache directory, from the file a run with the
    same split, scenes per type, pool and strides left there, or into it."""
    path = None
    if cache is not None:
        pool = ('' if settings.rig_pool_seed == DEFAULT_SETTINGS.rig_pool_seed
                else f'_pool{settings.rig_pool_seed}')
        colour = '' if encoding == 'mono8' else f'_{encoding}'
        path = cache / (f'bare_tables_{split}_{per_type}_stride{"-".join(map(str, strides))}'
                        f'{pool}{colour}.pickle')
        if path.is_file():
            yield from pickle.loads(path.read_bytes())
            return
    kept = []
    for planned in split_plan(split, per_type, settings):
        matched = match_scene(bare_table(planned.draw()), strides, opencv=True,
                              encoding=encoding)
        if path is not None:
            kept.append(matched)
        yield matched
    if path is not None:
        # written whole, then renamed: a run stopped half-way leaves no half a cache
        path.parent.mkdir(parents=True, exist_ok=True)
        partial = path.with_suffix('.partial')
        partial.write_bytes(pickle.dumps(kept))
        partial.replace(path)


def main() -> None:
    """Render, match and decide every bare table; print and write the counts."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--split', choices=SPLITS, default='evaluation')
    parser.add_argument('--per-type', type=int, default=50,
                        help='scenes per object type of the split (each without its object)')
    parser.add_argument('--point-stride', type=int, nargs='+', default=[1, 3])
    parser.add_argument('--output', default=str(ROOT / 'benchmarks' / 'results'))
    parser.add_argument('--rig-pool-seed', type=int,
                        help="draw the split's rigs from the pool of this seed (train or "
                        'validation only): rigs neither tuning nor the evaluation split used')
    parser.add_argument('--cache', metavar='DIR',
                        help='keep the rendered and matched tables here and read them back on '
                             'the next run (development: module docstring)')
    parser.add_argument('--encoding', default='mono8', choices=('mono8', 'rgb8'),
                        help='grey cameras (mono8) or colour ones (rgb8: the colour silhouette '
                             'is looked for too)')
    args = parser.parse_args()
    settings = DEFAULT_SETTINGS
    if args.rig_pool_seed is not None:
        if args.split == 'evaluation':
            parser.error('--rig-pool-seed draws other rigs for the train or validation split; '
                         'the evaluation split keeps its held-out rigs')
        settings = replace(DEFAULT_SETTINGS, rig_pool_seed=args.rig_pool_seed)
    strides = sorted(set(args.point_stride))
    chooser = BestPointChooser.create('fuzzy_fitted', AreaConfig(), StereoRig())
    given: dict[object, list[str]] = collections.defaultdict(list)
    refusals: dict[int, collections.Counter[str]] = collections.defaultdict(collections.Counter)
    by_table: dict[tuple[object, str], int] = collections.Counter()
    tables: collections.Counter[str] = collections.Counter()
    count = len(split_plan(args.split, args.per_type, settings))
    start = time.perf_counter()
    for index, matched in enumerate(matched_tables(
            args.split, args.per_type, strides, settings,
            Path(args.cache) if args.cache else None, args.encoding)):
        scene = matched.scene
        table = scene.scene.surface_texture_family
        tables[table] += 1
        where = f'seed {scene.seed} (rig {scene.rig.index}, {table} table)'
        for stride, synthetic in matched.matched.items():
            posed = replace(chooser, world_from_camera=synthetic.rig.world_from_left_camera())
            decision = decide_with_second_look(posed, synthetic.points, synthetic.left,
                                               synthetic.right, matched.matcher,
                                               stride).decision
            if decision.status == STATUS_OK and decision.best_point_world is not None:
                height_mm = 1000.0 * float(decision.best_point_world[2])
                given[stride].append(f'{where}: {height_mm:.1f} mm above the table')
                by_table[(stride, table)] += 1
            else:
                refusals[stride][decision.status] += 1
        if matched.opencv_point is not None:
            given[OPENCV].append(where)
            by_table[(OPENCV, table)] += 1
        if (index + 1) % 20 == 0:
            print(f'{index + 1}/{count} scenes, {time.perf_counter() - start:.0f} s',
                  file=sys.stderr)
    elapsed = time.perf_counter() - start
    command = shlex.join(['python', 'benchmarks/bare_table_benchmark.py', *sys.argv[1:]])
    rows = [*strides, OPENCV]
    names = {row: f'fuzzy_fitted, point stride {row}' if row != OPENCV
             else 'OpenCV pipeline (SGBM + largest component + top band)' for row in rows}
    lines = [
        '# Best points on bare tables',
        '',
        f'`{command}`: the {count} scenes of the {args.split} split ({args.per_type} per object '
        "type) rendered with the object out of view; correlation_node's default settings. A "
        f'point given is a point where nothing is (goal: none). {elapsed:.0f} s.'
        + (f' Cameras rendered {args.encoding}.' if args.encoding != 'mono8' else ''),
        '',
        '| decided by | points given | share | refusals |',
        '|---|---:|---:|---|']
    for row in rows:
        why = ', '.join(f'{status} {number}' for status, number in refusals[row].most_common()
                        ) if row != OPENCV else ''
        lines.append(f'| {names[row]} | {len(given[row])} of {count} | '
                     f'{100.0 * len(given[row]) / count:.1f} % | {why} |')
    lines += ['', '| table texture | scenes | ' + ' | '.join(
        f'points at stride {row}' if row != OPENCV else 'OpenCV points' for row in rows) + ' |',
              '|---|---:|' + '---:|' * len(rows)]
    for table, number in sorted(tables.items()):
        lines.append(f'| {table} | {number} | ' + ' | '.join(
            str(by_table[(row, table)]) for row in rows) + ' |')
    for row in strides:
        if given[row]:
            lines += ['', f'Points given at stride {row}:', '']
            lines += [f'- {item}' for item in given[row]]
    report = '\n'.join(lines)
    print(report)
    output = Path(args.output)
    output.mkdir(parents=True, exist_ok=True)
    suffix = '' if args.split == 'evaluation' else f'_{args.split}'
    if args.rig_pool_seed is not None:
        suffix += f'_pool{args.rig_pool_seed}'
    if args.encoding != 'mono8':
        suffix += f'_{args.encoding}'
    (output / f'bare_tables{suffix}.md').write_text(report + '\n')
    print(f'\nwrote {output / f"bare_tables{suffix}.md"}', file=sys.stderr)


if __name__ == '__main__':
    main()
