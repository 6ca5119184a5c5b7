"""Training sets, consequent fitting and evaluation of the best-point selectors. ROS-free.

Used by scripts/train_fuzzy_rule_base.py, scripts/train_neural_baseline.py (which share the
scene recipe below) and benchmarks/fuzzy_benchmark.py, so training and evaluation see scenes
the same way the node does (steps 1-3 of correlation_area.py with the same AreaConfig).

Fitting the fuzzy consequents is zero-order Takagi-Sugeno consequent estimation (the least-squares
half of ANFIS's hybrid rule): with the membership functions fixed, Eq. 10 is linear in the rule
offsets o_l,

    y* = sum_l wn_l (b_l + o_l),   wn_l = w_l / sum(w),  b_l = centre of the rule's areas,

so the offsets that best move y* onto the ground truth t over S training scenes solve the linear
least-squares problem  Wn o = t - Wn b  (one column of Wn per rule), per coordinate, with a small
ridge term for rules that rarely fire. The height offset of step 6 is the mean of t_z - top height.
"""

from __future__ import annotations

import argparse
import math
import pickle
import time
from collections.abc import Iterable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from stereo_fuzzy_perception.core.best_point.correlation_area import AreaConfig
from stereo_fuzzy_perception.core.best_point.fuzzy_inference import (
    consequent_base_points,
    normalized_firing_strengths,
)
from stereo_fuzzy_perception.core.best_point.neural_baseline import (
    neural_base_point,
    neural_features,
)
from stereo_fuzzy_perception.core.best_point.point_selectors import BestPointChooser, area_features
from stereo_fuzzy_perception.core.best_point.rule_base import FuzzyRule, RuleBase
from stereo_fuzzy_perception.simulation.synthetic_scenes import (
    OBJECT_TYPES,
    SCENE_SOURCES,
    SceneSource,
    SyntheticScene,
)


@dataclass(frozen=True)
class TrainingSet:
    """Steps 1-3 of S scenes with their ground truth.

    Attributes:
        ratios: (S, 4) r_k.
        centres: (S, 4, 3) area centres in `world` [m].
        counts: (S, 4) weight of each area's points (FourAreas.weights; points per area
            when the points are unweighted).
        top_height: (S,) [m].
        features: (S, F) neural-network inputs.
        nn_base: (S, 3) the point the network's offset is added to [m].
        targets: (S, 3) top-face centres in `world` [m].
        object_types: (S,) object type names.
        skipped: Scenes without a usable area (not in the arrays).
    """

    ratios: np.ndarray
    centres: np.ndarray
    counts: np.ndarray
    top_height: np.ndarray
    features: np.ndarray
    nn_base: np.ndarray
    targets: np.ndarray
    object_types: np.ndarray
    skipped: int

    def __len__(self) -> int:
        return int(len(self.targets))


def make_scenes(source: SceneSource, per_type: int, seed: int) -> list[SyntheticScene]:
    """Return `per_type` scenes of each object type from one seed (reproducible)."""
    rng = np.random.default_rng(seed)
    return [source.scene(rng, kind) for _ in range(per_type) for kind in OBJECT_TYPES]


def build_training_set(scenes: Iterable[SyntheticScene], config: AreaConfig) -> TrainingSet:
    """Run steps 1-3 on every scene and collect the fuzzy inputs and network features."""
    rows: dict[str, list[np.ndarray]] = {name: [] for name in (
        'ratios', 'centres', 'counts', 'top_height', 'features', 'nn_base', 'targets')}
    kinds: list[str] = []
    skipped = 0
    for scene in scenes:
        area, areas = area_features(scene.points, scene.left, scene.right,
                                    scene.rig.world_from_left_camera(), config)
        if areas is None:
            skipped += 1
            continue
        rows['ratios'].append(areas.ratio)
        rows['centres'].append(areas.centres)
        rows['counts'].append(areas.weights)  # what inference weights the centres by
        rows['top_height'].append(np.array(area.top_height))
        rows['features'].append(neural_features(area, areas))
        rows['nn_base'].append(neural_base_point(area, areas))
        rows['targets'].append(scene.target_world)
        kinds.append(scene.object_type)
    arrays = {name: np.array(values, dtype=float) for name, values in rows.items()}
    return TrainingSet(arrays['ratios'], arrays['centres'], arrays['counts'],
                       arrays['top_height'], arrays['features'], arrays['nn_base'],
                       arrays['targets'], np.array(kinds), skipped)


def inlier_scenes(data: TrainingSet, max_residual_m: float = math.inf) -> np.ndarray:
    """Return which scenes' targets lie within `max_residual_m` (horizontally) of the centroid.

    On rendered scenes the correlation area is sometimes not the object's top at all (a thin disc
    lost in the surface, mismatches above it); no consequent can correct that, and a least-squares
    fit or a network trained on it is pulled away from the scenes it can correct.
    """
    residual = data.targets[:, :2] - data.nn_base[:, :2]
    inliers: np.ndarray = np.hypot(residual[:, 0], residual[:, 1]) <= max_residual_m
    return inliers


def subset(data: TrainingSet, keep: np.ndarray) -> TrainingSet:
    """Return the scenes of `data` where `keep` is True."""
    return TrainingSet(data.ratios[keep], data.centres[keep], data.counts[keep],
                       data.top_height[keep], data.features[keep], data.nn_base[keep],
                       data.targets[keep], data.object_types[keep],
                       data.skipped + int(np.sum(~keep)))


def fit_rule_offsets(template: RuleBase, data: TrainingSet, ridge: float = 1e-3,
                     name: str = 'fitted', description: str = '') -> RuleBase:
    """Return `template` with each rule's offset fitted by least squares (x, y) on `data`.

    Args:
        template: Membership functions, premises and consequent areas to keep.
        data: Training scenes.
        ridge: Tikhonov weight relative to the mean squared firing strength; keeps offsets of
            rarely firing rules near zero.
        name: Name of the fitted rule base.
        description: Its description.

    Returns:
        The fitted rule base (z offsets 0: the height rule sets z; height_offset_m fitted).
    """
    bases = consequent_base_points(template, data.centres, data.counts)  # (S, L, 3)
    firing = normalized_firing_strengths(template, data.ratios, bases)  # (S, L)
    fired = firing.sum(axis=1) > 0.0
    firing = firing[fired]
    bases = np.nan_to_num(bases[fired])
    eq10 = np.einsum('sl,slj->sj', firing, bases)
    residual = data.targets[fired] - eq10
    rule_count = firing.shape[1]
    gram = firing.T @ firing
    penalty = ridge * float(np.trace(gram)) / rule_count
    offsets = np.zeros((rule_count, 3))
    offsets[:, :2] = np.linalg.solve(gram + penalty * np.eye(rule_count),
                                     firing.T @ residual[:, :2])
    height_offset = float(np.mean(data.targets[:, 2] - data.top_height))
    rules = tuple(replace(rule, offset_m=(round(float(o[0]), 7), round(float(o[1]), 7), 0.0))
                  for rule, o in zip(template.rules, offsets, strict=True))
    return RuleBase(name, description, template.terms, rules, round(height_offset, 7))


def with_consequent_areas(template: RuleBase, areas: tuple[int, ...]) -> RuleBase:
    """Return `template` with every rule's consequent base set to the union of `areas`."""
    rules = tuple(FuzzyRule(rule.name, rule.area, rule.term, areas) for rule in template.rules)
    return RuleBase(template.name, template.description, template.terms, rules,
                    template.height_offset_m)


@dataclass(frozen=True)
class SelectorScore:
    """Best-point errors of one selector over evaluation scenes [mm].

    Attributes:
        horizontal_mean: Mean horizontal error [mm].
        horizontal_p95: 95th percentile horizontal error [mm].
        vertical_mean: Mean absolute vertical error [mm].
        vertical_p95: 95th percentile absolute vertical error [mm].
        success_rate: Share of scenes with a point within `tolerance_mm` in 3D (no point: a miss).
        decided: Scenes with a best point.
        scenes: Scenes evaluated.
    """

    horizontal_mean: float
    horizontal_p95: float
    vertical_mean: float
    vertical_p95: float
    success_rate: float
    decided: int
    scenes: int


def best_point_errors(chooser: BestPointChooser, scenes: Iterable[SyntheticScene]
                      ) -> np.ndarray:
    """Return (S, 3) errors best point - target [m] per scene (NaN rows: no point).

    Each scene is decided with its own rig's pose (scenes of the distribution differ in rig).
    """
    errors = []
    for scene in scenes:
        posed = replace(chooser, world_from_camera=scene.rig.world_from_left_camera())
        decision = posed.decide(scene.points, scene.left, scene.right)
        if decision.best_point_world is None:
            errors.append(np.full(3, math.nan))
        else:
            errors.append(decision.best_point_world - scene.target_world)
    return np.array(errors).reshape(-1, 3)


def score_errors(errors: np.ndarray, tolerance_mm: float = 3.0) -> SelectorScore:
    """Summarise (S, 3) errors [m] as a SelectorScore [mm]."""
    decided = np.all(np.isfinite(errors), axis=1)
    millimetres = errors[decided] * 1000.0
    horizontal = np.hypot(millimetres[:, 0], millimetres[:, 1])
    vertical = np.abs(millimetres[:, 2])
    total = np.linalg.norm(millimetres, axis=1)
    if not len(millimetres):
        return SelectorScore(math.nan, math.nan, math.nan, math.nan, 0.0, 0, len(errors))
    return SelectorScore(float(horizontal.mean()), float(np.percentile(horizontal, 95)),
                         float(vertical.mean()), float(np.percentile(vertical, 95)),
                         float(np.sum(total <= tolerance_mm)) / len(errors),
                         int(decided.sum()), len(errors))


# --- the training recipe shared by scripts/train_*.py ------------------------------------------

DISTRIBUTION_SOURCE = 'distribution'

CACHE_FORMAT = 2
"""Version of what a scene cache holds; caches of another are made anew. 2: the matches carry
the left rectified image (MatchedPoints.left_image), from which the areas' outlines come."""
"""`--source` value for the randomized scene distribution (scene_distribution.py)."""


def add_recipe_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the scene recipe options both training scripts take (source, counts, seeds)."""
    parser.add_argument('--source', default='geometric',
                        choices=sorted([*SCENE_SOURCES, DISTRIBUTION_SOURCE]),
                        help=f'{DISTRIBUTION_SOURCE}: the train and validation splits of '
                        'simulation/scene_distribution.py (training rigs only; the seeds '
                        'below are then not used)')
    parser.add_argument('--per-type', type=int, default=300,
                        help='training scenes per object type')
    parser.add_argument('--validation-per-type', type=int, default=60)
    parser.add_argument('--train-seed', type=int, default=1)
    parser.add_argument('--validation-seed', type=int, default=2)
    parser.add_argument('--point-stride', type=int, default=3,
                        help=f'{DISTRIBUTION_SOURCE} source: correlation_node point_stride '
                        "(the demo's)")
    parser.add_argument('--scene-cache', default='',
                        help='pickle of the matched scenes: read when it holds this recipe, '
                        'else written (the second training script then renders nothing)')
    parser.add_argument('--jobs', type=int, default=2,
                        help=f'{DISTRIBUTION_SOURCE} source: rendering/matching processes')
    parser.add_argument('--max-residual-mm', type=float, default=math.inf,
                        help='train only on scenes whose target is within this horizontal '
                        'distance of the correlation-area centre (inf: all)')


@dataclass(frozen=True)
class TrainingScenes:
    """The scenes of one training run: all training and validation scenes, and the set used."""

    train_scenes: list[SyntheticScene]
    validation_scenes: list[SyntheticScene]
    train: TrainingSet


def make_training_scenes(parser: argparse.ArgumentParser, args: argparse.Namespace,
                         config: AreaConfig) -> TrainingScenes:
    """Make the scenes the recipe options describe, printing progress to stdout.

    Exits through parser.error when training and validation would use the same seed.
    """
    start = time.perf_counter()
    recipe: dict[str, object] = {name: getattr(args, name) for name in (
        'source', 'per_type', 'validation_per_type', 'train_seed', 'validation_seed',
        'point_stride')}
    recipe['cache_format'] = CACHE_FORMAT
    cache = Path(args.scene_cache) if args.scene_cache else None
    cached = _read_cache(cache, recipe)
    if cached is not None:
        train_scenes, validation_scenes = cached
        print(f'read {len(train_scenes)} training and {len(validation_scenes)} validation '
              f'scenes from {cache}')
    elif args.source == DISTRIBUTION_SOURCE:
        # Imported here: it loads pybullet, which the geometric source never needs.
        from stereo_fuzzy_perception.simulation.distribution_source import distribution_scenes
        from stereo_fuzzy_perception.simulation.scene_distribution import split_plan
        print(f'making {4 * args.per_type} training scenes and {4 * args.validation_per_type} '
              'validation scenes from the train and validation splits of the scene '
              f'distribution (training rigs only), point stride {args.point_stride}')
        train_scenes = list(distribution_scenes(split_plan('train', args.per_type),
                                                args.point_stride, args.jobs))
        validation_scenes = list(distribution_scenes(
            split_plan('validation', args.validation_per_type), args.point_stride, args.jobs))
    else:
        if args.train_seed == args.validation_seed:
            parser.error('training and validation scenes must come from different seeds')
        source = SCENE_SOURCES[args.source]()
        print(f'making {4 * args.per_type} training scenes (seed {args.train_seed}) and '
              f'{4 * args.validation_per_type} validation scenes (seed '
              f'{args.validation_seed}) from the {args.source} source')
        train_scenes = make_scenes(source, args.per_type, args.train_seed)
        validation_scenes = make_scenes(source, args.validation_per_type,
                                        args.validation_seed)
    if cache is not None and cached is None:
        with cache.open('wb') as stream:
            pickle.dump((recipe, train_scenes, validation_scenes), stream)
    train = build_training_set(train_scenes, config)
    train = subset(train, inlier_scenes(train, args.max_residual_mm / 1000.0))
    print(f'{len(train)} training scenes used, {train.skipped} left out (no area, or target '
          f'more than {args.max_residual_mm} mm from the area centre)')
    print(f'scenes made in {time.perf_counter() - start:.0f} s')
    return TrainingScenes(train_scenes, validation_scenes, train)


def _read_cache(path: Path | None, recipe: dict[str, object]
                ) -> tuple[list[SyntheticScene], list[SyntheticScene]] | None:
    """Return the cached (training, validation) scenes when `path` holds `recipe`'s, else None.

    The cache holds matched points (the correlation stage's output), not correlation areas:
    a changed fuzzy stage is trained on it correctly, a changed matcher needs a new cache.
    """
    if path is None or not path.exists():
        return None
    with path.open('rb') as stream:
        stored_recipe, train_scenes, validation_scenes = pickle.load(stream)
    if stored_recipe != recipe:
        print(f'{path} holds scenes of another recipe ({stored_recipe}); making them anew')
        return None
    return train_scenes, validation_scenes


def print_scores(choosers: dict[str, BestPointChooser], scenes: TrainingScenes) -> None:
    """Print a markdown table of each chooser's errors on the training and validation scenes."""
    print('| selector | set | horizontal mean [mm] | horizontal p95 [mm] | '
          'vertical mean [mm] | within 3 mm |')
    print('|---|---|---|---|---|---|')
    for label, chooser in choosers.items():
        for set_name, chosen in (('train', scenes.train_scenes),
                                 ('validation', scenes.validation_scenes)):
            score = score_errors(best_point_errors(chooser, chosen))
            print(f'| {label} | {set_name} | {score.horizontal_mean:.2f} | '
                  f'{score.horizontal_p95:.2f} | {score.vertical_mean:.2f} | '
                  f'{100 * score.success_rate:.1f} % |')
