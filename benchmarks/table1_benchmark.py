#!/usr/bin/env python3
"""Measure the chapter's Table 1 on rendered scenes: success rate of each best-point selector.

The chapter's Table 1 gives, per object type (circle, cylinder, cubic rectangle, cubic square),
the share of trials in which the neural network and the fuzzy system found the right point
(97-98 % and 100 %). This benchmark measures it through the full perception path:

    random_scene -> pybullet render (SceneRenderer, 1 grey level noise)
      -> correlation (StereoMatchingPipeline, ZNCC, disparities 32..95 px, every
         --point-stride-th row and column as correlation_node publishes them)
      -> every selector on the same matched points (BestPointChooser.decide)

Every selector also decides on perfect 3D points of the same pixels, from the renderer's depth
buffer (`ceiling:` rows): the gap between a selector and its ceiling is the matcher's loss, the
gap between the ceiling and 100 % the selector's own.

A trial succeeds when the best point lies within --tolerance-mm (3D) of the centre of the
object's top face; a scene without a best point is a miss. Each scene is rendered and matched
once. Scene seeds are drawn from --seed (default 3) the way selector_training.make_scenes draws
them; the training scripts use seeds 1 (training) and 2 (validation), and the benchmark checks
that none of its scene seeds occurs among the first 1000 per type of those.

    source scripts/env.sh
    python benchmarks/table1_benchmark.py                        # 50 scenes per type
    python benchmarks/table1_benchmark.py --scenes-per-type 10 --output /tmp/t1
    python benchmarks/table1_benchmark.py \\
        --compare 'fuzzy_fitted (geometric)=/tmp/fuzzy_fitted_geometric.yaml'

Prints markdown tables (Table 1 and the error details) and writes them to <output>/table1.md
with a plot of the error distributions, <output>/table1_errors.png.
"""

from __future__ import annotations

import argparse
import os
import shlex
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / 'src' / 'stereo_fuzzy_perception'))
for variable in ('OMP_NUM_THREADS', 'OPENBLAS_NUM_THREADS', 'MKL_NUM_THREADS'):
    os.environ.setdefault(variable, '1')

import matplotlib  # noqa: E402
import yaml  # noqa: E402

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from stereo_fuzzy_perception.core.best_point.correlation_area import AreaConfig  # noqa: E402
from stereo_fuzzy_perception.core.best_point.point_selectors import SELECTORS, BestPointChooser  # noqa: E402
from stereo_fuzzy_perception.simulation.distribution_source import perfect_points  # noqa: E402
from stereo_fuzzy_perception.simulation.rendered_scenes import RenderedSceneSource  # noqa: E402
from stereo_fuzzy_perception.simulation.selector_training import score_errors  # noqa: E402
from stereo_fuzzy_perception.simulation.synthetic_scenes import OBJECT_TYPES  # noqa: E402

SELECTOR_ORDER = ('fuzzy_chapter', 'fuzzy_fitted', 'centroid', 'max_score', 'neural_network')
assert set(SELECTOR_ORDER) == set(SELECTORS)
TRAINING_SEEDS = (1, 2)
TYPE_TITLES = {'circle': 'Circle', 'cylinder': 'Cylinder', 'cubic_rectangle': 'Cubic Rectangle',
               'cubic_square': 'Cubic Square'}
DEMO_PARAMS = ROOT / 'chain' / 'demo_params.yaml'
CEILING = 'ceiling: '
"""Label prefix of a selector's row on perfect 3D points (the renderer's depth buffer)."""
CHAPTER_TABLE1 = {'neural network (chapter)': (98.3, 98.0, 97.0, 97.2),
                  'fuzzy system (chapter)': (100.0, 100.0, 100.0, 100.0)}


def scene_seeds(seed: int, per_type: int) -> dict[str, list[int]]:
    """Return the scene seeds per type that make_scenes(RenderedSceneSource, ...) draws."""
    rng = np.random.default_rng(seed)
    seeds: dict[str, list[int]] = {kind: [] for kind in OBJECT_TYPES}
    for _ in range(per_type):
        for kind in OBJECT_TYPES:
            seeds[kind].append(int(rng.integers(0, 2**31 - 1)))
    return seeds


def check_disjoint_from_training(seeds: dict[str, list[int]]) -> None:
    """Raise SystemExit when an evaluation scene seed is also a training or validation seed."""
    used = {value for training_seed in TRAINING_SEEDS
            for values in scene_seeds(training_seed, 1000).values() for value in values}
    shared = used.intersection(value for values in seeds.values() for value in values)
    if shared:
        raise SystemExit(f'evaluation scenes {sorted(shared)} are also training scenes')


def choosers(compare: list[str]) -> dict[str, BestPointChooser]:
    """Return the selectors (packaged files) and the extra rule bases / weights to compare."""
    rig = RenderedSceneSource().rig
    result = {name: BestPointChooser.create(name, AreaConfig(), rig) for name in SELECTOR_ORDER}
    for item in compare:
        label, _, path = item.partition('=')
        selector = 'neural_network' if path.endswith('.npz') else 'fuzzy_fitted'
        result[label] = BestPointChooser.create(
            selector, AreaConfig(), rig, rule_base_file='' if selector == 'neural_network'
            else path, weights_file=path if selector == 'neural_network' else '')
    return result


def demo_point_stride() -> int:
    """Return correlation_node's point_stride in the demo parameters (the chain as shipped)."""
    parameters = yaml.safe_load(DEMO_PARAMS.read_text())
    return int(parameters['correlation_node']['ros__parameters'].get('point_stride', 1))


def evaluate(seeds: dict[str, list[int]], selectors: dict[str, BestPointChooser],
             point_stride: int = 1) -> tuple[dict[str, dict[str, np.ndarray]], float]:
    """Render and match every scene once; return errors [m] per selector per type, and the time."""
    rows = [*selectors, *(CEILING + name for name in selectors)]
    errors: dict[str, dict[str, list[np.ndarray]]] = {
        name: {kind: [] for kind in OBJECT_TYPES} for name in rows}
    start = time.perf_counter()
    with RenderedSceneSource(point_stride=point_stride) as source:
        for kind in OBJECT_TYPES:
            for seed in seeds[kind]:
                frame = source.render(seed, kind, with_maps=True)
                result = source.match(frame)
                scene = source.scene_of_frame(frame, result)
                perfect = perfect_points(frame, result.rectified, point_stride)
                for name, chooser in selectors.items():
                    for label, points in ((name, scene.points), (CEILING + name, perfect)):
                        decision = chooser.decide(points, scene.left, scene.right)
                        point = decision.best_point_world
                        errors[label][kind].append(np.full(3, np.nan) if point is None
                                                   else point - scene.target_world)
            print(f'{kind}: {len(seeds[kind])} scenes, {time.perf_counter() - start:.0f} s',
                  file=sys.stderr)
    arrays = {name: {kind: np.array(values).reshape(-1, 3) for kind, values in per_type.items()}
              for name, per_type in errors.items()}
    return arrays, time.perf_counter() - start


def table1(errors: dict[str, dict[str, np.ndarray]], tolerance_mm: float) -> str:
    """Return Table 1 as markdown: success rate per selector (rows) and object type (columns)."""
    titles = [TYPE_TITLES[kind] for kind in OBJECT_TYPES]
    lines = [f'| Selector (within {tolerance_mm:g} mm) | ' + ' | '.join(titles) + ' | All |',
             '|---|' + '---:|' * (len(titles) + 1)]
    for name, per_type in errors.items():
        rates = [score_errors(per_type[kind], tolerance_mm).success_rate for kind in OBJECT_TYPES]
        overall = score_errors(np.vstack(list(per_type.values())), tolerance_mm).success_rate
        lines.append(f'| {name} | ' + ' | '.join(f'{100 * rate:.1f} %' for rate in rates)
                     + f' | {100 * overall:.1f} % |')
    for name, rates in CHAPTER_TABLE1.items():
        lines.append(f'| *{name}* | ' + ' | '.join(f'*{rate:.1f} %*' for rate in rates)
                     + ' | |')
    return '\n'.join(lines)


def detail_table(errors: dict[str, dict[str, np.ndarray]], tolerance_mm: float) -> str:
    """Return the horizontal / vertical error mean and p95 [mm] per selector and type."""
    lines = ['| Selector | Object | horizontal mean [mm] | horizontal p95 [mm] | '
             'vertical mean [mm] | vertical p95 [mm] | success | decided |',
             '|---|---|---:|---:|---:|---:|---:|---:|']
    for name, per_type in errors.items():
        for kind in (*OBJECT_TYPES, 'all'):
            values = np.vstack(list(per_type.values())) if kind == 'all' else per_type[kind]
            score = score_errors(values, tolerance_mm)
            lines.append(
                f'| {name} | {kind} | {score.horizontal_mean:.2f} | {score.horizontal_p95:.2f} | '
                f'{score.vertical_mean:.2f} | {score.vertical_p95:.2f} | '
                f'{100 * score.success_rate:.1f} % | {score.decided}/{score.scenes} |')
    return '\n'.join(lines)


def plot(errors: dict[str, dict[str, np.ndarray]], tolerance_mm: float, path: Path) -> None:
    """Box-plot the horizontal and vertical errors [mm] per selector, one column per type."""
    names = list(errors)
    figure, axes = plt.subplots(2, len(OBJECT_TYPES), figsize=(4.2 * len(OBJECT_TYPES), 8),
                                sharey='row')
    for column, kind in enumerate(OBJECT_TYPES):
        for row, label in enumerate(('horizontal', 'vertical')):
            data = []
            for name in names:
                millimetres = 1000.0 * errors[name][kind]
                millimetres = millimetres[np.all(np.isfinite(millimetres), axis=1)]
                value = (np.hypot(millimetres[:, 0], millimetres[:, 1]) if row == 0
                         else np.abs(millimetres[:, 2]))
                data.append(np.maximum(value, 1e-2))
            axis = axes[row, column]
            axis.boxplot(data, whis=(5, 95), showfliers=True, flierprops={'markersize': 3})
            axis.set_yscale('log')
            axis.axhline(tolerance_mm, color='tab:red', linestyle='--', linewidth=1)
            axis.set_xticks(range(1, len(names) + 1), names, rotation=35, ha='right',
                            fontsize=8)
            axis.grid(True, axis='y', which='both', alpha=0.3)
            if row == 0:
                axis.set_title(TYPE_TITLES[kind])
            if column == 0:
                axis.set_ylabel(f'{label} error [mm]')
    per_type = len(errors[names[0]][OBJECT_TYPES[0]])
    figure.suptitle(f'Best-point error on rendered scenes ({per_type} per type; '
                    f'whiskers 5-95 %; red: {tolerance_mm:g} mm)')
    figure.tight_layout()
    figure.savefig(path, dpi=110)
    plt.close(figure)


def main() -> None:
    """Render, match, decide with every selector; print and write the tables and the plot."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--scenes-per-type', type=int, default=50)
    parser.add_argument('--seed', type=int, default=3,
                        help=f'evaluation seed; training uses {TRAINING_SEEDS}')
    parser.add_argument('--tolerance-mm', type=float, default=3.0,
                        help='a best point within this 3D distance of the target succeeds')
    parser.add_argument('--output', default=str(ROOT / 'benchmarks' / 'results'),
                        help='directory for table1.md and table1_errors.png')
    parser.add_argument('--point-stride', type=int, default=demo_point_stride(),
                        help="correlation_node's point_stride (default: the demo's, "
                        'chain/demo_params.yaml)')
    parser.add_argument('--compare', action='append', default=[], metavar='LABEL=PATH',
                        help='also evaluate a rule base (.yaml) or network weights (.npz)')
    args = parser.parse_args()
    if args.seed in TRAINING_SEEDS:
        parser.error(f'seed {args.seed} is a training seed ({TRAINING_SEEDS})')
    seeds = scene_seeds(args.seed, args.scenes_per_type)
    check_disjoint_from_training(seeds)
    errors, elapsed = evaluate(seeds, choosers(args.compare), args.point_stride)
    command = shlex.join(['python', 'benchmarks/table1_benchmark.py', *sys.argv[1:]])
    report = '\n\n'.join([
        '# Table 1 on rendered scenes',
        f'`{command}`: {args.scenes_per_type} rendered scenes per object type (seed '
        f'{args.seed}; training used seeds {TRAINING_SEEDS[0]} and {TRAINING_SEEDS[1]}), '
        'pybullet render -> correlation (ZNCC, disparities 32..95 px, point stride '
        f'{args.point_stride}) -> selector; success = '
        f'best point within {args.tolerance_mm:g} mm (3D) of the top-face centre, no point = '
        f'miss. Render + match + all selectors: {elapsed:.0f} s. Selectors without a label use '
        'the packaged data files; labelled rows are --compare files; `ceiling:` rows are the '
        "same selectors on perfect 3D points of the same pixels (the renderer's depth buffer), "
        "so a row's gap to its ceiling is the matcher's loss. Chapter figures in italics.",
        table1(errors, args.tolerance_mm),
        '## Best-point error per selector and object type',
        detail_table(errors, args.tolerance_mm),
        '![error distributions](table1_errors.png)'])
    print(report)
    output = Path(args.output)
    output.mkdir(parents=True, exist_ok=True)
    (output / 'table1.md').write_text(report + '\n')
    plot({name: per_type for name, per_type in errors.items() if not name.startswith(CEILING)},
         args.tolerance_mm, output / 'table1_errors.png')
    print(f'\nwrote {output / "table1.md"} and {output / "table1_errors.png"}', file=sys.stderr)


if __name__ == '__main__':
    main()
