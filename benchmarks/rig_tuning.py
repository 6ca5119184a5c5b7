#!/usr/bin/env python3
"""DEVELOPMENT ONLY: tune the correlation area on the train and validation splits.

Never run this on the evaluation split (it refuses to): rig_generalisation_benchmark.py
measures there, once, what was tuned here. This renders and matches scenes of the train split
(simulation/scene_distribution.py, split 'train': rigs and scene seeds of their own) or, with
--split validation, of the validation split (the train split's rigs, seeds of their own: a
change chosen on one split is checked on the other) at one point stride with correlation_node's
default settings, caches the matched points (pickle, --cache), and grades the centroid and
fuzzy_fitted selectors with the AreaConfig defaults; per scene it lists the error or why no
point was chosen (the correlation area's status and reason), worst first. --oversampling 3
renders the images antialiased (SceneRenderer.render), as rig_generalisation_benchmark.py can.

A change chosen on some scenes is checked on others: `--from-scene K` grades only each type's
scenes K and later (with --per-type above K: the cache of the larger set holds the smaller
one's scenes first). `--save FILE` keeps the fuzzy_fitted outcome of every scene (JSON), and
`--against FILE` lists the scenes whose outcome changed since (within --tolerance-mm, within
10 mm, over 10 mm, no point) with the counts of both: a change that moves a dozen scenes each
way for a net gain of two is noise, which the totals alone do not show.

    nice python benchmarks/rig_tuning.py --per-type 50 --from-scene 20 --save /tmp/before.json
    # ... change the code ...
    nice python benchmarks/rig_tuning.py --per-type 50 --from-scene 20 --against /tmp/before.json

`--second-look` (with `--point-stride 3`) grades what fuzzy_best_point_node gives by default: a
face found too thin at that stride is decided again on the same pair's stride-1 matches
(second_look_stride_one), taken from the split's stride-1 cache (rendered once if missing).

`--rig-pool-seed N` draws the split's rigs from the pool of seed N instead of the one tuning and
the evaluation split share (14): 30 rigs that neither ever used, with the split's scene seeds.
A change chosen on the splits is checked there on rigs it cannot have been shaped by, without
looking at the evaluation split (benchmarks/EXPERIMENTS.md, twenty-second session).

    nice python benchmarks/rig_tuning.py --per-type 50 --split validation --rig-pool-seed 17

`--encoding rgb8` renders the splits with colour cameras (a cache of their own): the matches
carry both colour images, and the top from the colour silhouette is looked for first
(colour_silhouette.py).

`--by-rig` adds the outcomes of the rigs that resolve depth to at most 1 mm per 0.1 px of
disparity and of the others (rig_breakdown.py gives the same split of the evaluation run).

`--true-outline` adds on how many scenes the true top's outline in the left image, cut at the
median height of its own matches (true_top.py, the evaluation's diagnosis row), lies within the
tolerance, and the fitted rules' outcomes on those scenes and on the others: what the chain
loses finding the top, apart from what the matches lose. With `--looks` as well, the looks'
outcomes are given again for the scenes whose matches hold the top.

`--looks` adds the outcomes of each look at the pair that gave the points (the matches' own
face, or one of the looks point_selectors.decision_area takes after it was refused:
correlation_area.LOOK_*) and of each refusal status: where the points within 3 mm and the
errors come from, look by look.

`--decompose` tells where the error comes from. The matched pixels whose rays meet the true
top face ("true pixels") and the correlation area's pixels ("area pixels") are each cut with a
plane (the true top height, or the area's) and their centroid graded: area pixels at the true
height show what choosing the pixels costs, true pixels at the area's height what the top
height costs, true pixels at the true height what is left to the matcher's coverage of the top.

    source scripts/env.sh
    nice python benchmarks/rig_tuning.py --per-type 15
    nice python benchmarks/rig_tuning.py --per-type 15 --split validation
    nice python benchmarks/rig_tuning.py --per-type 15 --decompose

`--coverage` compares, for each scene given a point, the final area's pixels (the face outlined
from the image, as every selector gets it) with the pixels that see the true top face: the
share of the top it misses and the share of the area that is not the top, by outcome and by
rig group, with where the missed pixels' matches stand (on the top, below it, above it,
unmatched).

    nice python benchmarks/rig_tuning.py --per-type 50 --coverage
"""

from __future__ import annotations

import argparse
import json
import math
import os
import pickle
import sys
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / 'src' / 'stereo_fuzzy_perception'))
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))
for variable in ('OMP_NUM_THREADS', 'OPENBLAS_NUM_THREADS', 'MKL_NUM_THREADS'):
    os.environ.setdefault(variable, '1')

import numpy as np  # noqa: E402
from stereo_fuzzy_perception.core.best_point.correlation_area import (  # noqa: E402
    AreaConfig,
    find_correlation_area,
)
from stereo_fuzzy_perception.core.best_point.point_selectors import (  # noqa: E402
    BestPointChooser,
    decision_area,
    disparity_shift,
)
from stereo_fuzzy_perception.core.best_point.second_look import (  # noqa: E402
    decide_with_second_look,
)
from stereo_fuzzy_perception.core.rig_geometry import StereoRig  # noqa: E402
from stereo_fuzzy_perception.simulation.distribution_source import match_plan  # noqa: E402
from stereo_fuzzy_perception.simulation.scene_distribution import (  # noqa: E402
    DEFAULT_SETTINGS,
    OBJECT_TYPES,
    DistributionSettings,
    split_plan,
)
from stereo_fuzzy_perception.simulation.synthetic_scenes import SyntheticScene  # noqa: E402

from benchmarks.rig_breakdown import depth_per_disparity_mm  # noqa: E402
from benchmarks.true_top import top_face_pixels, true_outline_point  # noqa: E402

SPLITS = ('train', 'validation')
"""The only splits this script reads: never the evaluation split."""

RESOLUTION_SPLIT_MM = 1.0
"""Rigs resolving depth to at most this per 0.1 px of disparity are the near ones [mm]."""


def scenes(split: str, per_type: int, stride: int, cache: Path, jobs: int,
           oversampling: int = 1, settings: DistributionSettings = DEFAULT_SETTINGS,
           encoding: str = 'mono8') -> list[tuple[str, SyntheticScene]]:
    """Return (label, matched scene) of the split's scenes (cached after the first run).

    With settings of another rig_pool_seed, the split's rigs are drawn from that pool: rigs
    that neither tuning nor the evaluation split ever used (--rig-pool-seed)."""
    if split not in SPLITS:
        raise ValueError(f'split {split!r}: tuning reads only {", ".join(SPLITS)}')
    rendering = f'_oversampled{oversampling}' if oversampling > 1 else ''
    pool = ('' if settings.rig_pool_seed == DEFAULT_SETTINGS.rig_pool_seed
            else f'_pool{settings.rig_pool_seed}')
    size = ('' if (settings.image_width, settings.image_height)
            == (DEFAULT_SETTINGS.image_width, DEFAULT_SETTINGS.image_height)
            else f'_{settings.image_width}x{settings.image_height}')
    colour = '' if encoding == 'mono8' else f'_{encoding}'
    path = cache / (f'rig_tuning_{split}_{per_type}_{stride}{rendering}{pool}{size}{colour}'
                    '.pickle')
    if path.exists():
        loaded: list[tuple[str, SyntheticScene]] = pickle.loads(path.read_bytes())
        return loaded
    plan = split_plan(split, per_type, settings)
    result = [(f'seed {item.scene.seed} rig {item.scene.rig.index} '
               f'top {item.scene.top_width_px:.0f} px {item.scene.scene.object_texture_family}',
               item.matched[stride])
              for item in match_plan(plan, (stride,), jobs=jobs, oversampling=oversampling,
                                     encoding=encoding)]
    cache.mkdir(parents=True, exist_ok=True)
    path.write_bytes(pickle.dumps(result))
    return result


def add_cached_split_arguments(parser: argparse.ArgumentParser) -> None:
    """Add what a development probe reads a tuning split's matched scenes by: --split,
    --per-type, --cache (this script's cache, made by its first run on the split) and
    --oversampling (the split rendered antialiased)."""
    parser.add_argument('--split', default='train', choices=SPLITS)
    parser.add_argument('--per-type', type=int, default=50)
    parser.add_argument('--cache', default='/tmp/rig_tuning_cache',
                        help="rig_tuning.py's cache of matched scenes")
    parser.add_argument('--oversampling', type=int, default=1, choices=(1, 3),
                        help="the split rendered antialiased (rig_tuning.py's cache of it)")


def outcome(error_mm: float | None, tolerance_mm: float) -> str:
    """Return the class of one scene's result: 'within', '<= 10 mm', '> 10 mm' or 'no point'."""
    if error_mm is None or math.isnan(error_mm):
        return 'no point'
    if error_mm <= tolerance_mm:
        return 'within'
    return '<= 10 mm' if error_mm <= 10.0 else '> 10 mm'


def outcome_counts(errors: dict[str, float | None], tolerance_mm: float) -> str:
    """Return the counts of the four outcome classes of {label: error [mm] or None}."""
    classes = [outcome(error, tolerance_mm) for error in errors.values()]
    return ', '.join(f'{name} {classes.count(name)}'
                     for name in ('within', '<= 10 mm', '> 10 mm', 'no point'))


def rig_of(label: str) -> int:
    """Return the rig index of a scene label as scenes() makes it ('seed S rig K top ...')."""
    return int(label.split(' rig ')[1].split()[0])


def outcomes_by_resolution(errors: dict[str, float | None], resolutions: dict[int, float],
                           tolerance_mm: float, split_mm: float = RESOLUTION_SPLIT_MM
                           ) -> list[str]:
    """Return the outcome counts of the scenes of rigs at most split_mm and over it.

    errors: {label: error [mm] or None}, labels as scenes() makes them ('... rig K ...');
    resolutions: rig index -> depth change per 0.1 px of disparity [mm]
    (rig_breakdown.depth_per_disparity_mm).
    """
    groups: dict[str, dict[str, float | None]] = {'near': {}, 'far': {}}
    for label, error in errors.items():
        groups['near' if resolutions[rig_of(label)] <= split_mm else 'far'][label] = error
    lines = []
    for name, group in groups.items():
        if group:
            count = len({rig_of(label) for label in group})
            side = 'at most' if name == 'near' else 'over'
            counted = outcome_counts(group, tolerance_mm)
            lines.append(f'  rigs {side} {split_mm:g} mm per 0.1 px ({count} rig'
                         f'{"s" if count > 1 else ""}, {len(group)} scene'
                         f'{"s" if len(group) > 1 else ""}): {counted}')
    return lines


def outcomes_by_look(errors: dict[str, float | None], looks: dict[str, str],
                     tolerance_mm: float) -> list[str]:
    """Return the outcome counts of the scenes each look at the pair decided (or refused),
    most scenes first.

    errors: {label: error [mm] or None}; looks: {label: the decision's look
    (correlation_area.LOOK_*) for a scene given a point, 'refused: <status>' for the others}.
    """
    groups: dict[str, dict[str, float | None]] = {}
    for label, error in errors.items():
        groups.setdefault(looks[label], {})[label] = error
    width = max((len(look) for look in groups), default=0)
    return [f'  {look:{width}s} ({len(group):3d}): {outcome_counts(group, tolerance_mm)}'
            for look, group in sorted(groups.items(), key=lambda item: (-len(item[1]),
                                                                       item[0]))]


def held_by_true_outline(matched: list[tuple[str, SyntheticScene]], tolerance_mm: float
                         ) -> set[str]:
    """Return the labels of the scenes whose true top's outline at its matches' median height
    (true_top.true_outline_point) lies within tolerance_mm: those whose matches hold the top."""
    return {label for label, scene in matched
            if 1000.0 * float(np.linalg.norm(true_outline_point(scene) - scene.target_world))
            <= tolerance_mm}


def true_outline_outcomes(errors: dict[str, float | None],
                          matched: list[tuple[str, SyntheticScene]], tolerance_mm: float,
                          held_labels: set[str] | None = None) -> list[str]:
    """Return the lines of --true-outline: on how many scenes the matches hold the top
    (held_by_true_outline, or held_labels when given), and the fitted rules' outcomes
    ({label: error [mm] or None}) on those scenes and on the others."""
    if held_labels is None:
        held_labels = held_by_true_outline(matched, tolerance_mm)
    held = {label: errors[label] for label, _ in matched if label in held_labels}
    missed = {label: errors[label] for label, _ in matched if label not in held_labels}
    return [f"the true top's outline at its matches' median height: within {tolerance_mm:g} mm "
            f'on {len(held)} of {len(matched)} scenes',
            f'  fitted rules on those {len(held)}: {outcome_counts(held, tolerance_mm)}',
            f'  fitted rules on the other {len(missed)}: {outcome_counts(missed, tolerance_mm)}']


def changed_outcomes(before: dict[str, float | None], after: dict[str, float | None],
                     tolerance_mm: float) -> list[str]:
    """Return a line per scene of both runs whose outcome class changed, or whose error moved
    by more than 1 mm."""
    lines = []
    for label in sorted(set(before) & set(after)):
        old, new = before[label], after[label]
        moved = old is not None and new is not None and abs(old - new) > 1.0
        if outcome(old, tolerance_mm) != outcome(new, tolerance_mm) or moved:
            shown = ['   none' if error is None else f'{error:7.1f}' for error in (old, new)]
            lines.append(f'  {label}: {shown[0]} -> {shown[1]} mm')
    return lines


def on_plane(world: np.ndarray, centre: np.ndarray, height: float) -> np.ndarray:
    """Return where the rays from `centre` through (N, 3) `world` points meet z = height."""
    scale = (height - centre[2]) / (world[:, 2] - centre[2])
    cut: np.ndarray = centre + (world - centre) * scale[:, None]
    return cut


def centroid_error(points: np.ndarray, centre: np.ndarray, level: float, target: np.ndarray
                   ) -> float:
    """Return the distance [mm] from target of the centroid of points cut with z = level."""
    if not len(points) or not np.isfinite(level):
        return float('nan')
    return 1000.0 * float(np.linalg.norm(on_plane(points, centre, level).mean(axis=0) - target))


def decompose(matched: list[tuple[str, SyntheticScene]], config: AreaConfig,
              tolerance_mm: float) -> None:
    """Print the share within tolerance of the four centroids of the module docstring."""
    rows = []
    for _, scene in matched:
        pose = scene.rig.world_from_left_camera()
        centre, target, height = pose[:3, 3], scene.target_world, scene.prism.height
        world = scene.points.xyz.astype(float) @ pose[:3, :3].T + centre
        true_pixels = world[scene.prism.contains_xy(on_plane(world, centre, height)[:, :2])]
        area = find_correlation_area(scene.points, pose, config,
                                     disparity_shift(scene.left, scene.right))

        found = area.top_height if area.ok else float('nan')
        rows.append((centroid_error(area.xyz_world, centre, height, target),
                     centroid_error(true_pixels, centre, found, target),
                     1000.0 * abs(found - height),
                     centroid_error(true_pixels, centre, height, target)))
    errors = np.array(rows)
    names = ('area pixels at the true height', 'true pixels at the area height',
             'area height - true height (|dz|)', 'true pixels at the true height')
    print(f'{len(errors)} scenes; no area or no true pixel counts as a miss')
    for name, column in zip(names, errors.T, strict=True):
        within = 100.0 * float(np.sum(column[np.isfinite(column)] <= tolerance_mm)) / len(column)
        print(f'  {name:34s} within {tolerance_mm:g} mm {within:5.1f} %, median '
              f'{np.nanmedian(column):.2f} mm')


TOP_LEVEL_M = 0.002
"""A missed top pixel's match within this of the true top height stands on the top."""


def coverage_shares(area_pixels: set[tuple[int, int]], top_pixels: set[tuple[int, int]]
                    ) -> tuple[float, float]:
    """Return (share of the top's pixels the area misses, share of the area's pixels that are
    not the top); NaN for an empty top or area."""
    missed = len(top_pixels - area_pixels) / len(top_pixels) if top_pixels else math.nan
    extra = len(area_pixels - top_pixels) / len(area_pixels) if area_pixels else math.nan
    return missed, extra


def coverage(matched: list[tuple[str, SyntheticScene]], config: AreaConfig,
             tolerance_mm: float) -> None:
    """Print how the final areas of the scenes given a point cover the true top face."""
    chooser = BestPointChooser.create('fuzzy_fitted', config, StereoRig())
    groups: dict[tuple[str, str], list[tuple[float, float, np.ndarray]]] = {}
    for label, scene in matched:
        pose = scene.rig.world_from_left_camera()
        posed = replace(chooser, world_from_camera=pose)
        decision = posed.decide(scene.points, scene.left, scene.right)
        if decision.best_point_world is None:
            continue
        error = 1000.0 * float(np.linalg.norm(decision.best_point_world - scene.target_world))
        area = decision_area(scene.points, scene.left, scene.right, pose, config)
        columns, rows = np.rint(area.u_left).astype(int), np.rint(area.v_left).astype(int)
        box_u, box_v = np.meshgrid(np.arange(columns.min() - 40, columns.max() + 41),
                                   np.arange(rows.min() - 40, rows.max() + 41))
        box_u, box_v = box_u.ravel(), box_v.ravel()
        seen = top_face_pixels(scene, box_u.astype(float), box_v.astype(float))
        top = set(zip(box_u[seen].tolist(), box_v[seen].tolist(), strict=True))
        area_set = set(zip(columns.tolist(), rows.tolist(), strict=True))
        missed, extra = coverage_shares(area_set, top)
        # where the missed pixels' own matches put them
        heights = dict(zip(zip(np.rint(scene.points.u_left).astype(int).tolist(),
                               np.rint(scene.points.v_left).astype(int).tolist(), strict=True),
                           (scene.points.xyz.astype(float) @ pose[2, :3] + pose[2, 3]).tolist(),
                           strict=True))
        levels = np.zeros(4)
        for pixel in top - area_set:
            z = heights.get(pixel)
            levels[3 if z is None else 0 if abs(z - scene.prism.height) <= TOP_LEVEL_M
                   else 1 if z < scene.prism.height else 2] += 1
        group = 'near' if depth_per_disparity_mm(rig_of(label)) <= RESOLUTION_SPLIT_MM else 'far'
        groups.setdefault((group, outcome(error, tolerance_mm)), []).append(
            (missed, extra, levels))
    print('the area against the true top, per scene: median share of the top missed / of the '
          'area not the top; the missed pixels matched on the top, below, above, unmatched')
    for key in sorted(groups):
        in_group = groups[key]
        missed = np.array([row[0] for row in in_group])
        extra = np.array([row[1] for row in in_group])
        levels = np.sum([row[2] for row in in_group], axis=0)
        share = 100.0 * levels / max(levels.sum(), 1.0)
        print(f'  {key[0]} rigs, {key[1]:8s} ({len(in_group):3d} scenes): missed '
              f'{np.nanmedian(missed):.2f}, not the top {np.nanmedian(extra):.2f}; missed '
              f'pixels {share[0]:.0f} / {share[1]:.0f} / {share[2]:.0f} / {share[3]:.0f} %')


def main() -> None:
    """Grade the selectors on the cached scenes of the split and list the failures."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--per-type', type=int, default=15, help='scenes per type')
    parser.add_argument('--split', default='train', choices=SPLITS,
                        help='train (tune here) or validation (check here)')
    parser.add_argument('--oversampling', type=int, default=1, choices=(1, 3, 5),
                        help='render each pixel as the mean of K x K (antialiased)')
    parser.add_argument('--encoding', default='mono8', choices=('mono8', 'rgb8'),
                        help='grey cameras, or colour ones (the top from the colour '
                             'silhouette is looked for first)')
    parser.add_argument('--point-stride', type=int, default=1)
    parser.add_argument('--jobs', type=int, default=2)
    parser.add_argument('--tolerance-mm', type=float, default=3.0)
    parser.add_argument('--cache', default='/tmp/rig_tuning_cache')
    parser.add_argument('--show', type=int, default=25, help='worst scenes listed')
    parser.add_argument('--decompose', action='store_true',
                        help='where the error comes from (module docstring)')
    parser.add_argument('--coverage', action='store_true',
                        help='how the final areas cover the true top face (module docstring)')
    parser.add_argument('--area', action='append', default=[], metavar='NAME=VALUE',
                        help='an AreaConfig value other than its default (float)')
    parser.add_argument('--from-scene', type=int, default=0, metavar='K',
                        help="grade only each type's scenes K and later (not chosen on)")
    parser.add_argument('--save', metavar='FILE', help="write each scene's fuzzy_fitted error")
    parser.add_argument('--against', metavar='FILE',
                        help='list the scenes whose outcome changed since a --save')
    parser.add_argument('--second-look', action='store_true',
                        help='at a --point-stride above 1, look again at stride 1 at a face '
                             'too thin, as fuzzy_best_point_node does (second_look_stride_one); '
                             "the split's stride-1 matches (cached too) stand for matching again")
    parser.add_argument('--rig-pool-seed', type=int, default=DEFAULT_SETTINGS.rig_pool_seed,
                        help="draw the split's rigs from the pool of this seed instead: rigs "
                             'that neither tuning nor the evaluation split used')
    parser.add_argument('--image-size', default=None, metavar='WxH',
                        help='render every rig at this image size instead of '
                             f'{DEFAULT_SETTINGS.image_width}x{DEFAULT_SETTINGS.image_height} '
                             '(the same fields of view: finer pixels)')
    parser.add_argument('--by-rig', action='store_true',
                        help='the outcomes of rigs on either side of 1 mm of depth per 0.1 px '
                             '(rig_breakdown.py)')
    parser.add_argument('--true-outline', action='store_true',
                        help="on how many scenes the true top's outline at its matches' median "
                             'height lies within the tolerance (true_top.py: what the matches '
                             'allow when the top is found perfectly), and the fitted rules on '
                             'those scenes and on the others')
    parser.add_argument('--looks', action='store_true',
                        help='the outcomes of each look at the pair that gave the points '
                             '(correlation_area.LOOK_*), and of each refusal')
    args = parser.parse_args()
    if not 0 <= args.from_scene < args.per_type:
        parser.error(f'--from-scene {args.from_scene} must be in 0..{args.per_type - 1}')
    if args.against and not Path(args.against).is_file():
        parser.error(f'--against {args.against}: no such file (write one with --save)')
    settings = replace(DEFAULT_SETTINGS, rig_pool_seed=args.rig_pool_seed)
    if args.image_size:
        width, _, height = args.image_size.partition('x')
        if not (width.isdigit() and height.isdigit() and int(width) >= 64
                and int(height) >= 48):
            parser.error(f'--image-size {args.image_size}: expected WIDTHxHEIGHT in pixels, '
                         'at least 64x48')
        settings = replace(settings, image_width=int(width), image_height=int(height))
    matched = scenes(args.split, args.per_type, args.point_stride, Path(args.cache), args.jobs,
                     args.oversampling, settings, args.encoding)[
                         args.from_scene * len(OBJECT_TYPES):]
    at_stride_one = (dict(scenes(args.split, args.per_type, 1, Path(args.cache), args.jobs,
                                 args.oversampling, settings, args.encoding))
                     if args.second_look and args.point_stride > 1 else {})
    config = replace(AreaConfig(), **{item.partition('=')[0]: float(item.partition('=')[2])
                                      for item in args.area})
    if args.decompose:
        decompose(matched, config, args.tolerance_mm)
        return
    if args.coverage:
        coverage(matched, config, args.tolerance_mm)
        return
    for name in ('centroid', 'fuzzy_fitted'):
        chooser = BestPointChooser.create(name, config, StereoRig())
        rows = []
        for label, scene in matched:
            posed = replace(chooser, world_from_camera=scene.rig.world_from_left_camera())
            fine = at_stride_one.get(label)
            decision = decide_with_second_look(
                posed, scene.points, scene.left, scene.right, None,
                args.point_stride if fine is not None else 1,
                at_stride_one=fine.points if fine is not None else None).decision
            point = decision.best_point_world
            error = (float('nan') if point is None
                     else 1000.0 * float(np.linalg.norm(point - scene.target_world)))
            offset = (np.full(3, np.nan) if point is None
                      else 1000.0 * (point - scene.target_world))
            rows.append((error, label, scene, decision, offset))
        errors = np.array([row[0] for row in rows])
        decided = np.isfinite(errors)
        within = 100.0 * float(np.sum(errors[decided] <= args.tolerance_mm)) / len(errors)
        offsets = np.array([row[4] for row in rows])
        median_abs = np.nanmedian(np.abs(offsets), axis=0)
        print(f'{name}: median |dx|, |dy|, |dz| {median_abs[0]:.2f}, {median_abs[1]:.2f}, '
              f'{median_abs[2]:.2f} mm')
        print(f'{name}: {len(errors)} {args.split} scenes, within {args.tolerance_mm:g} mm '
              f'{within:.0f} %'
              f', mean {np.mean(errors[decided]):.2f} mm, max {np.max(errors[decided]):.1f} mm,'
              f' {int(np.sum(~decided))} without a point')
        if name == 'fuzzy_fitted':
            by_scene = {row[1]: (None if math.isnan(row[0]) else row[0]) for row in rows}
            compare(by_scene, args)
            if args.by_rig:
                rigs = {rig_of(label) for label in by_scene}
                print('\n'.join(outcomes_by_resolution(
                    by_scene, {rig: depth_per_disparity_mm(rig, settings) for rig in rigs},
                    args.tolerance_mm)))
            held = (held_by_true_outline(matched, args.tolerance_mm) if args.true_outline
                    else None)
            if held is not None:
                print('\n'.join(true_outline_outcomes(by_scene, matched, args.tolerance_mm,
                                                       held)))
            if args.looks:
                looks = {row[1]: (row[3].look if np.isfinite(row[0])
                                  else f'refused: {row[3].status}') for row in rows}
                print('\n'.join(outcomes_by_look(by_scene, looks, args.tolerance_mm)))
                if held is not None:
                    print('the same, on the scenes whose matches hold the top (--true-outline):')
                    print('\n'.join(outcomes_by_look(
                        {label: error for label, error in by_scene.items() if label in held},
                        looks, args.tolerance_mm)))
        if name != 'centroid':
            continue
        rows.sort(key=lambda row: -np.inf if np.isnan(row[0]) else -row[0])
        for error, label, scene, decision, offset in rows[:args.show]:
            print(f'  {error:7.1f} mm ({offset[0]:6.1f} {offset[1]:6.1f} {offset[2]:6.1f}) '
                  f'{scene.object_type:16s} {label} '
                  f'{decision.status}: {decision.reason[:160]}')


def compare(errors: dict[str, float | None], args: argparse.Namespace) -> None:
    """Save the scenes' errors (--save) and list what changed since a saved run (--against)."""
    if args.against:
        before = json.loads(Path(args.against).read_text())
        print(f'changed since {args.against}:')
        print('\n'.join(changed_outcomes(before, errors, args.tolerance_mm)) or '  none')
        shared = set(before) & set(errors)
        print(f'  before: {outcome_counts({k: before[k] for k in shared}, args.tolerance_mm)}')
        print(f'  now:    {outcome_counts({k: errors[k] for k in shared}, args.tolerance_mm)}')
    if args.save:
        Path(args.save).write_text(json.dumps(errors, indent=0))


if __name__ == '__main__':
    main()
