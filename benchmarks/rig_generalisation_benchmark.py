#!/usr/bin/env python3
"""Grade every best-point selector on randomized scenes from rigs never seen in training.

Scenes come from the evaluation split of simulation/scene_distribution.py: rigs from the
held-out part of the rig pool (0.30-0.80 m up, 40-120 mm baseline, 0-50 deg tilt, pan, 0-4 deg
toe-in per camera, 40-70 deg field of view), seven texture families, random light, 0-4 grey
levels of noise, right camera gain 0.7-1.3 and offset -30..+30; scene seeds of their own range.
The selectors' data files were fitted on the train split (other rigs, other seeds); nothing here
is tuned on these scenes. Only the rig pose and the calibration are given: correlation runs with
correlation_node's default settings, under which the node derives its disparity search from the
rig pose, the calibration and the workspace box (core/matching/disparity_range.py).

Per scene (rendered once, matched once, at every --point-stride):

* every selector on the matched points (what the chain does);
* every selector on perfect 3D points of the same pixels from the renderer's depth buffer
  (`ceiling:` rows): the gap between a selector and its ceiling is the matcher's loss, the gap
  between the ceiling and 0 the selector's own;
* a plain OpenCV pipeline (opencv_reference.py: StereoSGBM + height mask + largest connected
  component + top band, centroid) on the same pair; it uses every pixel whatever the stride;
* a diagnosis row: the top face's true outline in the left image, cut at the median height
  of the matches inside it (true_top.true_outline_point). It is no selector (it knows the
  outline); it is what the matches' own heights allow when the top is found perfectly, so the
  gap between it and a selector is the loss of finding the top, and the gap between it and
  the ceiling the matcher's.

A best point succeeds within --tolerance-mm (3D) of the centre of the top face; no point is a
miss. Mean and max are over the scenes with a point.

    source scripts/env.sh
    nice python benchmarks/rig_generalisation_benchmark.py           # 50 scenes per type
    nice python benchmarks/rig_generalisation_benchmark.py --quick   # 6 per type, stride 3
    nice python benchmarks/rig_generalisation_benchmark.py --oversampling 3 --per-type 25 \
        --point-stride 1    # antialiased images, as a camera's pixels integrate light
    nice python benchmarks/rig_generalisation_benchmark.py --encoding rgb8   # colour cameras

TinyRenderer does not antialias: every texture edge falls on whole pixels, in each camera
independently, and the disparities of a textured table scatter by a few tenths of a pixel
from that alone. --oversampling K renders each pixel as the mean of K x K rendered ones (the
scenes are the same; the results go to files named ..._oversampledK).

Each scene is also labelled with how far the bare table's own matches are off around the
object at the scale of its top (benchmarks/table_bias.py, the `table_bias` column: the moire of
the renderer's unfiltered textures, in mm of depth at the object), for the breakdown by it.

Prints markdown and writes <output>/rig_generalisation.md and rig_generalisation_scenes.csv
(one row per scene and selector, for analysis).
"""

from __future__ import annotations

import argparse
import csv
import os
import shlex
import sys
import time
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / 'src' / 'stereo_fuzzy_perception'))
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))
for variable in ('OMP_NUM_THREADS', 'OPENBLAS_NUM_THREADS', 'MKL_NUM_THREADS'):
    os.environ.setdefault(variable, '1')

import numpy as np  # noqa: E402
from stereo_fuzzy_perception.core.best_point.correlation_area import AreaConfig  # noqa: E402
from stereo_fuzzy_perception.core.best_point.point_selectors import SELECTORS, BestPointChooser  # noqa: E402
from stereo_fuzzy_perception.core.best_point.second_look import decide_with_second_look  # noqa: E402
from stereo_fuzzy_perception.core.matching.matcher_config import MatcherConfig  # noqa: E402
from stereo_fuzzy_perception.core.rig_geometry import StereoRig  # noqa: E402
from stereo_fuzzy_perception.simulation.distribution_source import (  # noqa: E402
    MatchedDistributionScene,
    match_plan,
)
from stereo_fuzzy_perception.simulation.scene_distribution import (  # noqa: E402
    DEFAULT_SETTINGS,
    SCENE_SEED_BASE,
    split_plan,
    split_rigs,
)
from stereo_fuzzy_perception.simulation.scene_model import OBJECT_TYPES  # noqa: E402
from stereo_fuzzy_perception.simulation.synthetic_scenes import SyntheticScene  # noqa: E402

from benchmarks.table_bias import table_bias_mm  # noqa: E402
from benchmarks.true_top import DIAGNOSIS_ROW, true_outline_point  # noqa: E402

SELECTOR_ORDER = ('fuzzy_fitted', 'fuzzy_chapter', 'centroid', 'max_score', 'neural_network')
assert set(SELECTOR_ORDER) == set(SELECTORS)
OPENCV_ROW = 'opencv (SGBM + largest component + top band)'
ORACLE_ROW = DIAGNOSIS_ROW
TABLE_BIAS_EDGES_MM = (0.0, 0.5, 1.0, 2.0)
"""Buckets of the bare table's disparity error around the object at the scale of its top, in
millimetres of depth (table_bias.py): the renderer's moire, which no averaging takes out."""
GOALS = {'within': 95.0, 'mean': 1.5, 'max': 10.0}
TYPE_TITLES = {'circle': 'Circle', 'cylinder': 'Cylinder', 'cubic_rectangle': 'Cubic Rectangle',
               'cubic_square': 'Cubic Square'}


GREY_LOOKS_ROW = 'fuzzy_fitted, grey looks only (colour_silhouette false)'
"""With colour cameras, the fitted rules without the colour look: its gain on the same pairs."""


def base_choosers(compare: list[str], colour: bool = False) -> dict[str, BestPointChooser]:
    """Return the packaged selectors and the extra rule bases / weights to compare (with colour
    cameras, the fitted rules with the colour look off too)."""
    rig = StereoRig()
    result = {name: BestPointChooser.create(name, AreaConfig(), rig) for name in SELECTOR_ORDER}
    if colour:
        result[GREY_LOOKS_ROW] = BestPointChooser.create(
            'fuzzy_fitted', AreaConfig(colour_silhouette=False), rig)
    for item in compare:
        label, _, path = item.partition('=')
        neural = path.endswith('.npz')
        result[label] = BestPointChooser.create(
            'neural_network' if neural else 'fuzzy_fitted', AreaConfig(), rig,
            rule_base_file='' if neural else path, weights_file=path if neural else '')
    return result


def decide(chooser: BestPointChooser, scene: SyntheticScene, matcher: MatcherConfig | None = None,
           stride: int = 0) -> np.ndarray:
    """Return best point - target [m] of one scene with the scene's rig pose (NaN: no point).

    With the matcher settings and the points' stride, a face too thin at a stride above 1 is
    looked at again at stride 1, as fuzzy_best_point_node does (second_look_stride_one).
    """
    posed = replace(chooser, world_from_camera=scene.rig.world_from_left_camera())
    point = decide_with_second_look(posed, scene.points, scene.left, scene.right, matcher,
                                    stride).decision.best_point_world
    return np.full(3, np.nan) if point is None else point - scene.target_world


def grade(matched: MatchedDistributionScene, choosers: dict[str, BestPointChooser],
          second_look: bool = True) -> dict[tuple[str, int], np.ndarray]:
    """Return the error [m] of every row (selector, ceiling, OpenCV) at every stride."""
    errors: dict[tuple[str, int], np.ndarray] = {}
    target = next(iter(matched.matched.values())).target_world
    matcher = matched.matcher if second_look else None
    for stride, scene in matched.matched.items():
        for name, chooser in choosers.items():
            errors[(name, stride)] = decide(chooser, scene, matcher, stride)
        for name in SELECTOR_ORDER:
            errors[(f'ceiling: {name}', stride)] = decide(choosers[name],
                                                         matched.perfect[stride])
        errors[(OPENCV_ROW, stride)] = (np.full(3, np.nan) if matched.opencv_point is None
                                        else matched.opencv_point - target)
        errors[(ORACLE_ROW, stride)] = true_outline_point(scene) - target
    return errors


def summary(errors_m: np.ndarray, tolerance_mm: float) -> tuple[float, float, float, int]:
    """Return (% within tolerance, mean [mm], max [mm], scenes without a point)."""
    millimetres = 1000.0 * np.linalg.norm(errors_m, axis=1)
    decided = np.isfinite(millimetres)
    within = 100.0 * float(np.sum(millimetres[decided] <= tolerance_mm)) / len(millimetres)
    if not decided.any():
        return within, float('nan'), float('nan'), len(millimetres)
    return (within, float(millimetres[decided].mean()), float(millimetres[decided].max()),
            int(np.sum(~decided)))


def cell(values: tuple[float, float, float, int]) -> str:
    """Return 'within % / mean / max' with the goals missed in bold."""
    within, mean, maximum, missing = values
    parts = [f'{within:.0f} %', f'{mean:.2f}', f'{maximum:.1f}']
    failed = [within < GOALS['within'], not mean <= GOALS['mean'],
              not maximum <= GOALS['max']]
    text = ' / '.join(f'**{part}**' if bad else part
                      for part, bad in zip(parts, failed, strict=True))
    return text + (f' ({missing} none)' if missing else '')


def table(results: dict[tuple[str, int], dict[str, list[np.ndarray]]], rows: list[str],
          stride: int, tolerance_mm: float) -> str:
    """Return one stride's markdown table: rows x object types (within / mean / max)."""
    titles = [TYPE_TITLES[kind] for kind in OBJECT_TYPES]
    lines = [f'| point stride {stride}: within {tolerance_mm:g} mm / mean [mm] / max [mm] | '
             + ' | '.join(titles) + ' | All |', '|---|' + '---:|' * (len(titles) + 1)]
    for row in rows:
        per_type = results[(row, stride)]
        cells = [cell(summary(np.array(per_type[kind]).reshape(-1, 3), tolerance_mm))
                 for kind in OBJECT_TYPES]
        everything = np.array([e for kind in OBJECT_TYPES for e in per_type[kind]])
        cells.append(cell(summary(everything.reshape(-1, 3), tolerance_mm)))
        lines.append(f'| {row} | ' + ' | '.join(cells) + ' |')
    return '\n'.join(lines)


def breakdown(records: list[dict[str, object]], row: str, stride: int, key: str,
              tolerance_mm: float) -> str:
    """Return within-tolerance share and mean error of one row by a scene property."""
    groups: dict[str, list[float]] = {}
    for record in records:
        if record['row'] == row and record['stride'] == stride:
            groups.setdefault(str(record[key]), []).append(float(record['error_mm']))
    lines = [f'| {key} | scenes | within {tolerance_mm:g} mm | mean [mm] |',
             '|---|---:|---:|---:|']
    for value in sorted(groups):
        errors = np.array(groups[value])
        decided = errors[np.isfinite(errors)]
        within = 100.0 * float(np.sum(decided <= tolerance_mm)) / len(errors)
        mean = float(decided.mean()) if len(decided) else float('nan')
        lines.append(f'| {value} | {len(errors)} | {within:.0f} % | {mean:.2f} |')
    return '\n'.join(lines)


def bucket(value: float, edges: tuple[float, ...], unit: str) -> str:
    """Return the bucket label of `value` ('a-b unit')."""
    for low, high in zip(edges[:-1], edges[1:], strict=True):
        if value < high:
            return f'{low:g}-{high:g} {unit}'
    return f'>= {edges[-1]:g} {unit}'


def main() -> None:
    """Render, match, grade every row; print and write the report."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--per-type', type=int, default=50, help='evaluation scenes per type')
    parser.add_argument('--point-stride', type=int, nargs='+', default=[1, 3])
    parser.add_argument('--quick', action='store_true',
                        help='development run: 6 scenes per type, stride 3 only')
    parser.add_argument('--jobs', type=int, default=2, help='rendering/matching processes')
    parser.add_argument('--tolerance-mm', type=float, default=3.0)
    parser.add_argument('--compare', action='append', default=[], metavar='LABEL=PATH',
                        help='also grade a rule base (.yaml) or network weights (.npz)')
    parser.add_argument('--oversampling', type=int, default=1, choices=(1, 3, 5),
                        help='render each pixel as the mean of K x K (antialiased, as a '
                             "camera's pixel integrates light); 1: TinyRenderer as it is")
    parser.add_argument('--encoding', default='mono8', choices=('mono8', 'rgb8'),
                        help='render grey cameras (mono8) or colour ones (rgb8: the matches '
                             'carry the left colour image, for the top from the colour '
                             'silhouette, colour_silhouette.py)')
    parser.add_argument('--no-second-look', action='store_true',
                        help="decide at each stride only, as with fuzzy_best_point_node's "
                             'second_look_stride_one false')
    parser.add_argument('--output', default=str(ROOT / 'benchmarks' / 'results'))
    args = parser.parse_args()
    if args.quick:
        args.per_type, args.point_stride = 6, [3]
    strides = sorted(set(args.point_stride))
    choosers = base_choosers(args.compare, colour=args.encoding != 'mono8')
    rows = [*choosers, *(f'ceiling: {name}' for name in SELECTOR_ORDER), OPENCV_ROW,
            ORACLE_ROW]
    results: dict[tuple[str, int], dict[str, list[np.ndarray]]] = {
        (row, stride): {kind.value: [] for kind in OBJECT_TYPES}
        for row in rows for stride in strides}
    records: list[dict[str, object]] = []
    plan = split_plan('evaluation', args.per_type)
    start = time.perf_counter()
    for index, matched in enumerate(match_plan(plan, strides, ceiling=True, opencv=True,
                                               jobs=args.jobs, oversampling=args.oversampling,
                                               encoding=args.encoding)):
        scene = matched.scene
        table_bias = table_bias_mm(matched.matched[strides[0]])
        for (row, stride), error in grade(matched, choosers,
                                          not args.no_second_look).items():
            results[(row, stride)][scene.object_type].append(error)
            records.append({
                'row': row, 'stride': stride, 'seed': scene.seed, 'rig': scene.rig.index,
                'object_type': scene.object_type,
                'error_mm': round(1000.0 * float(np.linalg.norm(error)), 3),
                'dx_mm': round(1000.0 * float(error[0]), 3),
                'dy_mm': round(1000.0 * float(error[1]), 3),
                'dz_mm': round(1000.0 * float(error[2]), 3),
                'top_px': bucket(scene.top_width_px, (24, 40, 60, 100), 'px'),
                'object_texture': scene.scene.object_texture_family,
                'surface_texture': scene.scene.surface_texture_family,
                'noise': bucket(scene.noise_std, (0, 1, 2, 3, 4), 'grey levels'),
                'table_bias': (bucket(table_bias, TABLE_BIAS_EDGES_MM, 'mm')
                               if np.isfinite(table_bias) else 'table unmatched (plain)')})
        if (index + 1) % 20 == 0:
            print(f'{index + 1}/{len(plan)} scenes, {time.perf_counter() - start:.0f} s',
                  file=sys.stderr)
    elapsed = time.perf_counter() - start
    command = shlex.join(['python', 'benchmarks/rig_generalisation_benchmark.py',
                          *sys.argv[1:]])
    rigs = split_rigs('evaluation')
    training_rigs = split_rigs('train')
    sections = [
        '# Best points on randomized scenes from unseen rigs',
        f'`{command}`: {args.per_type} scenes per object type from the evaluation split '
        f'(scene seeds from {SCENE_SEED_BASE["evaluation"]}; held-out rigs '
        f'{rigs[0].index}-{rigs[-1].index} of the pool of {DEFAULT_SETTINGS.rig_pool_size}, '
        f'seed {DEFAULT_SETTINGS.rig_pool_seed}; selectors fitted on rigs '
        f'{training_rigs[0].index}-{training_rigs[-1].index}), '
        f'{DEFAULT_SETTINGS.image_width}x{DEFAULT_SETTINGS.image_height} px. Cells: share '
        f'within {args.tolerance_mm:g} mm (3D) of the top-face centre (no point = miss) / mean '
        '/ max error [mm] over the scenes with a point; goals (>= 95 %, <= 1.5 mm, <= 10 mm) '
        f'missed in bold. Render + match + grade: {elapsed:.0f} s with {args.jobs} processes.'
        + (f' Images rendered antialiased ({args.oversampling}x{args.oversampling} samples a '
           'pixel); the depth maps of the ceiling are not.' if args.oversampling > 1 else '')
        + (' Colour cameras (rgb8): the selectors look for the colour silhouette first '
           f'(`{GREY_LOOKS_ROW}`: without it, on the same pairs); the ceiling rows have perfect '
           'depth and no image.' if args.encoding != 'mono8' else '')]
    for stride in strides:
        sections.append(table(results, rows, stride, args.tolerance_mm))
    focus_stride = strides[0]
    for key in ('object_texture', 'top_px', 'noise', 'table_bias', 'rig'):
        sections.append(f'### fuzzy_fitted at stride {focus_stride} (and its ceiling) by {key}')
        sections.append(breakdown(records, 'fuzzy_fitted', focus_stride, key, args.tolerance_mm))
        sections.append(breakdown(records, 'ceiling: fuzzy_fitted', focus_stride, key,
                                  args.tolerance_mm))
    sections.append('Held-out rigs:\n\n' + '\n'.join(f'- {rig.describe()}' for rig in rigs))
    report = '\n\n'.join(sections)
    print(report)
    output = Path(args.output)
    output.mkdir(parents=True, exist_ok=True)
    suffix = ('_quick' if args.quick else '') + (
        f'_oversampled{args.oversampling}' if args.oversampling > 1 else '') + (
        f'_{args.encoding}' if args.encoding != 'mono8' else '')
    (output / f'rig_generalisation{suffix}.md').write_text(report + '\n')
    with (output / f'rig_generalisation{suffix}_scenes.csv').open('w', newline='') as stream:
        writer = csv.DictWriter(stream, fieldnames=list(records[0]))
        writer.writeheader()
        writer.writerows(records)
    print(f'\nwrote {output / f"rig_generalisation{suffix}.md"}', file=sys.stderr)


if __name__ == '__main__':
    main()
