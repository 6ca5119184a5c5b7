#!/usr/bin/env python3
"""Matching where the object is: accuracy and time of the area search against the whole image.

For each rendered scene of the chapter's Table 1 set-up (table1_benchmark's scene seeds and
rig, the demo's point stride), in one run:

1. whole image: the correlation stage (rectify, match, triangulate) on the pair, then the
   fitted fuzzy rules decide (the chain's default selector);
2. area search: the decision's correlation area gives the search region of the next pair
   (area_search.search_region, correlation_node's default margins); the same pair is matched
   in it (a static scene) and decided again. A region whose check fails is matched again on
   the whole image, as correlation_node does (counted);
3. wrong area: the region of the previous scene (another object elsewhere) on this pair: the
   check must send it to the whole image, or the decision must be as good;
4. found in the matches: the region area_search.region_from_matches finds in the pair's own
   whole-image matches, with the previous scene's region as the surface reference (what
   correlation_node tracks after a scene change until the new object's first decision); the
   same pair is matched in it and decided again (a failed check: the whole image's decision).
   The scene change itself: whether the previous scene's region changed in the block means
   (scene_change.py, correlation_node's defaults) between the previous scene's pair and this one.

Success = best point within --tolerance-mm of the top face's centre (as table1_benchmark).
Stage times are medians of the calls, against StereoBM (block 9, the whole-image disparities)
on the same rectified pair. Markdown to stdout. Timings on a shared machine are noisy.

--randomized matches scenes of the randomized distribution's evaluation split instead (rigs that
training never saw, 0.30-0.80 m up, tilted, toed in; simulation/scene_distribution.py), each in
both modes with correlation_node's default matcher settings for its rig, at --point-stride: the
tracked area must not cost accuracy on rigs other than the demo's.

--sequence N replays the chain latency benchmark's four scenes, N pairs each, through
correlation_node's tracker in this one process (each decision seen --lag pairs later, as the
chain's decisions arrive), with and without issue #18's block means and regions from matches:
the work per pair (stage and fuzzy decision) by its place after a scene change, free of DDS and
of the other processes' scheduling.

--bags replays the committed bags instead (bags/*, each with its chain parameters as
tests/test_whole_chain.py takes them), scene after scene as correlation_node would with
roi.max_age_s long enough to track every scene's area into the next (a different object
elsewhere): the points are compared with the whole image's, and each scene is also matched in
its own decision's region. The block means are compared as correlation_node does: a previous
scene's region whose blocks changed is not matched (`scene_changed` in the table).

    source scripts/env.sh
    nice python benchmarks/area_search_benchmark.py --scenes-per-type 10
    nice python benchmarks/area_search_benchmark.py --bags
    nice python benchmarks/area_search_benchmark.py --randomized --scenes-per-type 25
"""

from __future__ import annotations

import argparse
import functools
import os
import statistics
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / 'src' / 'stereo_fuzzy_perception'))
sys.path.insert(0, str(ROOT / 'benchmarks'))

import cv2  # noqa: E402
import numpy as np  # noqa: E402
from stereo_fuzzy_perception.core.best_point.correlation_area import AreaConfig  # noqa: E402
from stereo_fuzzy_perception.core.best_point.point_selectors import (  # noqa: E402
    BestPointChooser,
    BestPointDecision,
)
from stereo_fuzzy_perception.core.image_encoding import to_gray  # noqa: E402
from stereo_fuzzy_perception.core.matching.area_search import (  # noqa: E402
    AreaProjectionError,
    SearchRegion,
    TrackedArea,
    region_from_matches,
    search_region,
)
from stereo_fuzzy_perception.core.matching.area_tracker import TrackingConfig  # noqa: E402
from stereo_fuzzy_perception.core.matching.scene_change import (  # noqa: E402
    block_means,
    changed_share_inside,
)
from stereo_fuzzy_perception.core.matching.stereo_matching import StereoMatchResult  # noqa: E402
from stereo_fuzzy_perception.simulation.rendered_scenes import RenderedSceneSource  # noqa: E402
from stereo_fuzzy_perception.simulation.synthetic_scenes import OBJECT_TYPES  # noqa: E402
from table1_benchmark import demo_point_stride, scene_seeds  # noqa: E402


def tracked_area(decision: BestPointDecision) -> TrackedArea | None:
    """Return the decision's area as correlation_node takes it from FuzzyDecision."""
    if not decision.has_best_point:
        return None
    surface = decision.surface
    area = TrackedArea(0.0, np.asarray(decision.border_points, dtype=float),
                       float(decision.top_height), (0.0, 0.0, float(surface.offset_m)),
                       tuple(float(value) for value in surface.normal),
                       float(surface.disparity_sigma_px))
    return None if area.problem() else area


def error_mm(decision: BestPointDecision, target: np.ndarray) -> float:
    """Return the 3D error of the best point [mm], inf without one."""
    point = decision.best_point_world
    return float('inf') if point is None else 1e3 * float(np.linalg.norm(point - target))


def total_ms(result: StereoMatchResult) -> float:
    """Return the stage's time for the pair [ms] (including a failed region's)."""
    return sum(result.timings_ms.values())


def main() -> None:
    """Run the three modes on every scene and print the tables."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--scenes-per-type', type=int, default=10)
    parser.add_argument('--seed', type=int, default=3)
    parser.add_argument('--tolerance-mm', type=float, default=3.0)
    parser.add_argument('--bags', action='store_true',
                        help='replay the committed bags in both modes instead')
    parser.add_argument('--randomized', action='store_true',
                        help="the randomized distribution's evaluation split instead")
    parser.add_argument('--point-stride', type=int, default=1, help='with --randomized')
    parser.add_argument('--sequence', type=int, metavar='PAIRS_PER_SCENE',
                        help="replay the chain benchmark's scenes, this many pairs each, "
                        'through the tracker in one process instead (work per pair)')
    parser.add_argument('--pairs', type=int, default=600, help='with --sequence')
    parser.add_argument('--lag', type=int, default=2,
                        help='with --sequence: pairs until a decision is seen')
    args = parser.parse_args()
    if args.sequence:
        sequence(args.sequence, args.pairs, args.lag)
        return
    if args.bags:
        replay_bags()
        return
    if args.randomized:
        randomized(args.scenes_per_type, args.point_stride, args.tolerance_mm)
        return
    load = os.getloadavg()[0]
    stride = demo_point_stride()
    tracking = TrackingConfig()
    seeds = scene_seeds(args.seed, args.scenes_per_type)
    rows: list[dict[str, object]] = []
    with RenderedSceneSource(point_stride=stride) as source:
        chooser = BestPointChooser.create('fuzzy_fitted', AreaConfig(), source.rig)
        pose = source.rig.world_from_left_camera()
        pipeline = source.pipeline()
        full_range = (pipeline.config.min_disparity, pipeline.config.disparity_range)
        bm = cv2.StereoBM_create(numDisparities=16 * -(-full_range[1] // 16), blockSize=9)
        bm.setMinDisparity(full_range[0])
        previous: SearchRegion | None = None
        previous_blocks: np.ndarray | None = None
        for kind in OBJECT_TYPES:
            for seed in seeds[kind]:
                frame = source.render(seed, kind)
                target = np.asarray(frame.ground_truth.target_world, dtype=float)
                left = to_gray(frame.left, frame.encoding)
                right = to_gray(frame.right, frame.encoding)
                full = pipeline.process(left, right, frame.calibration)
                decided = chooser.decide(full.points, full.rectified.left, full.rectified.right)
                left_rect, right_rect, _ = pipeline.rectifier.rectify(left, right,
                                                                      frame.calibration)
                start = time.perf_counter()
                bm.compute(left_rect, right_rect)
                row: dict[str, object] = {
                    'kind': kind, 'full_mm': error_mm(decided, target),
                    'full_ms': total_ms(full), 'bm_ms': 1e3 * (time.perf_counter() - start)}
                area = tracked_area(decided)
                region = None
                if area is not None:
                    try:
                        region = search_region(area, frame.calibration, pose, full_range,
                                               tracking.margin_object_sizes, tracking.margin_m)
                    except AreaProjectionError as error:
                        row['no_region'] = str(error)
                if region is not None:
                    tracked = pipeline.process(left, right, frame.calibration, region=region)
                    again = chooser.decide(tracked.points, tracked.rectified.left,
                                           tracked.rectified.right)
                    row.update(region_mm=error_mm(again, target), region_ms=total_ms(tracked),
                               region_problem=tracked.region_problem,
                               region_share=region.roi[2] * region.roi[3] / left.size,
                               region_disparities=region.disparity_range)
                if previous is not None:
                    wrong = pipeline.process(left, right, frame.calibration, region=previous)
                    other = chooser.decide(wrong.points, wrong.rectified.left,
                                           wrong.rectified.right)
                    row.update(wrong_mm=error_mm(other, target),
                               wrong_problem=wrong.region_problem)
                    blocks = block_means(left)
                    box = pipeline.rectifier.raw_box(frame.calibration, previous.roi)
                    row['wrong_changed'] = changed_share_inside(
                        blocks, previous_blocks, box,
                        tracking.change_grey_levels) > tracking.change_share
                    found_region = region_from_matches(
                        full.disparity_map, previous, full.rectified, stride, full_range,
                        tracking.margin_object_sizes)
                    if found_region is not None:
                        found = pipeline.process(left, right, frame.calibration,
                                                 region=found_region)
                        found_decided = decided if found.region_problem else chooser.decide(
                            found.points, found.rectified.left, found.rectified.right)
                        row.update(found_mm=error_mm(found_decided, target),
                                   found_problem=found.region_problem,
                                   found_ms=total_ms(found),
                                   found_share=found_region.roi[2] * found_region.roi[3]
                                   / left.size)
                previous = region or previous
                previous_blocks = block_means(left)
                rows.append(row)
                print(f'{kind} {seed}: {row}', file=sys.stderr)
    report(rows, args.tolerance_mm, stride, load)


def report(rows: list[dict[str, object]], tolerance: float, stride: int, load: float) -> None:
    """Print the accuracy and time tables."""
    def share(values: list[float]) -> str:
        return (f'{100 * sum(value <= tolerance for value in values) / len(values):.1f} %'
                if values else '-')

    def mean_finite(values: list[float]) -> str:
        finite = [value for value in values if np.isfinite(value)]
        return f'{statistics.fmean(finite):.2f}' if finite else '-'

    print(f'\n### Area search (point stride {stride}, fitted rules; {os.cpu_count()} CPUs, '
          f'1-min load {load:.1f} before, {os.getloadavg()[0]:.1f} after)\n')
    print(f'| object | scenes | whole image within {tolerance:g} mm / mean [mm] | area search '
          'within / mean [mm] | region kept / checked | same point (within 0.5 mm) | '
          'wrong area: kept / checked, within |')
    print('|---|---:|---:|---:|---:|---:|---:|')
    for kind in (*OBJECT_TYPES, 'all'):
        chosen = [row for row in rows if kind in ('all', row['kind'])]
        full = [float(row['full_mm']) for row in chosen]  # type: ignore[arg-type]
        tracked = [row for row in chosen if 'region_mm' in row]
        # a rejected region falls back to the whole image: its decision is the whole image's
        region = [float(row['region_mm']) for row in tracked]  # type: ignore[arg-type]
        kept = [row for row in tracked if not row['region_problem']]
        same = sum(abs(float(row['region_mm']) - float(row['full_mm'])) <= 0.5  # type: ignore[arg-type]
                   or row['region_mm'] == row['full_mm'] for row in tracked)
        wrong = [row for row in chosen if 'wrong_mm' in row]
        wrong_kept = [row for row in wrong if not row['wrong_problem']]
        print(f'| {kind} | {len(chosen)} | {share(full)} / {mean_finite(full)} '
              f'| {share(region)} / {mean_finite(region)} | {len(kept)} / {len(tracked)} '
              f'| {same} / {len(tracked)} | {len(wrong_kept)} / {len(wrong)}, '
              f'{share([float(row["wrong_mm"]) for row in wrong])} |')  # type: ignore[arg-type]
    print(f"\n| object | scene changes seen in the previous region's blocks | region found in "
          f'the matches / scenes | found region kept / found | whole image within '
          f'{tolerance:g} mm | found region within {tolerance:g} mm (failed: whole image) | '
          'same point (within 0.5 mm) |')
    print('|---|---:|---:|---:|---:|---:|---:|')
    for kind in (*OBJECT_TYPES, 'all'):
        wrong = [row for row in rows if kind in ('all', row['kind']) and 'wrong_mm' in row]
        found = [row for row in wrong if 'found_mm' in row]
        found_kept = [row for row in found if not row['found_problem']]
        same = sum(abs(float(row['found_mm']) - float(row['full_mm'])) <= 0.5  # type: ignore[arg-type]
                   or row['found_mm'] == row['full_mm'] for row in found)
        print(f'| {kind} | {sum(bool(row["wrong_changed"]) for row in wrong)} / {len(wrong)} '
              f'| {len(found)} / {len(wrong)} | {len(found_kept)} / {len(found)} '
              f'| {share([float(row["full_mm"]) for row in found])} '  # type: ignore[arg-type]
              f'| {share([float(row["found_mm"]) for row in found])} '  # type: ignore[arg-type]
              f'| {same} / {len(found)} |')
    kept_rows = [row for row in rows if 'region_mm' in row and not row['region_problem']]
    print('\n| stage time per pair, median [ms] | whole image | area search (kept regions) | '
          'StereoBM, whole image | region share of the image | disparities searched |')
    print('|---|---:|---:|---:|---:|---:|')
    if kept_rows:
        print(f'| 640x480 | {statistics.median(float(r["full_ms"]) for r in rows):.1f} '  # type: ignore[arg-type]
              f'| {statistics.median(float(r["region_ms"]) for r in kept_rows):.1f} '  # type: ignore[arg-type]
              f'| {statistics.median(float(r["bm_ms"]) for r in rows):.1f} '  # type: ignore[arg-type]
              f'| {statistics.median(float(r["region_share"]) for r in kept_rows):.2f} '  # type: ignore[arg-type]
              f'| {statistics.median(int(r["region_disparities"]) for r in kept_rows):.0f} |')  # type: ignore[call-overload]
    found_rows = [row for row in rows if 'found_mm' in row and not row['found_problem']]
    if found_rows:
        print(f'\nRegions found in the matches, kept: median stage time '
              f'{statistics.median(float(r["found_ms"]) for r in found_rows):.1f} ms, '  # type: ignore[arg-type]
              f'median share of the image '
              f'{statistics.median(float(r["found_share"]) for r in found_rows):.2f}.')  # type: ignore[arg-type]


def randomized(per_type: int, stride: int, tolerance: float) -> None:
    """Match evaluation-split scenes in both modes (their own decision's region); print a row."""
    from stereo_fuzzy_perception.core.matching.stereo_matching import StereoMatchingPipeline
    from stereo_fuzzy_perception.simulation.distribution_source import matcher_for
    from stereo_fuzzy_perception.simulation.scene_distribution import split_plan
    from stereo_fuzzy_perception.simulation.scene_renderer import SceneRenderer

    load = os.getloadavg()[0]
    tracking = TrackingConfig()
    rows: list[dict[str, object]] = []
    for planned in split_plan('evaluation', per_type):
        scene = planned.draw()
        rig = scene.rig
        with SceneRenderer(camera=rig.camera, rig=rig.rig, encoding='mono8') as renderer:
            frame = renderer.render(scene.scene, lighting=scene.lighting, sensor=scene.sensor())
        config = matcher_for(frame.calibration, scene)
        pipeline = StereoMatchingPipeline(config, point_stride=stride)
        chooser = BestPointChooser.create('fuzzy_fitted', AreaConfig(), rig.rig)
        pose = rig.rig.world_from_left_camera()
        target = np.asarray(frame.ground_truth.target_world, dtype=float)
        left, right = to_gray(frame.left, frame.encoding), to_gray(frame.right, frame.encoding)
        full = pipeline.process(left, right, frame.calibration)
        decided = chooser.decide(full.points, full.rectified.left, full.rectified.right)
        row: dict[str, object] = {'kind': scene.object_type,
                                  'full_mm': error_mm(decided, target)}
        area = tracked_area(decided)
        if area is not None:
            try:
                region = search_region(area, frame.calibration, pose,
                                       (config.min_disparity, config.disparity_range),
                                       tracking.margin_object_sizes, tracking.margin_m)
            except AreaProjectionError:
                region = None
            if region is not None:
                tracked = pipeline.process(left, right, frame.calibration, region=region)
                again = (decided if tracked.region_problem else chooser.decide(
                    tracked.points, tracked.rectified.left, tracked.rectified.right))
                row.update(region_mm=error_mm(again, target),
                           region_problem=tracked.region_problem)
        rows.append(row)
        print(f'{planned.seed}: {row}', file=sys.stderr)
    full_errors = [float(row['full_mm']) for row in rows]  # type: ignore[arg-type]
    # No region (no decision) or a refused one: the node matches the whole image again.
    tracked_errors = [float(row.get('region_mm', row['full_mm'])) for row in rows]  # type: ignore[arg-type]
    kept = sum(1 for row in rows if 'region_mm' in row and not row['region_problem'])
    tried = sum(1 for row in rows if 'region_mm' in row)
    same = sum(1 for row in rows if 'region_mm' in row and (
        row['region_mm'] == row['full_mm']
        or abs(float(row['region_mm']) - float(row['full_mm'])) <= 0.5))  # type: ignore[arg-type]

    def within(values: list[float]) -> str:
        return f'{100 * sum(value <= tolerance for value in values) / len(values):.1f} %'

    print(f'\n### Area search on the randomized evaluation split (point stride {stride}, fitted '
          f'rules; 1-min load {load:.1f} before, {os.getloadavg()[0]:.1f} after)\n')
    print(f'| scenes | whole image within {tolerance:g} mm | tracked area within {tolerance:g} mm '
          '| region kept / tried | same point (within 0.5 mm) |')
    print('|---:|---:|---:|---:|---:|')
    print(f'| {len(rows)} | {within(full_errors)} | {within(tracked_errors)} | {kept} / {tried} '
          f'| {same} / {tried} |')


def bag_scenes(bag: Path) -> list[tuple[float, np.ndarray, np.ndarray, Any]]:
    """Return the bag's pairs in stamp order: (stamp [s], left grey, right grey, calibration)."""
    from stereo_fuzzy_perception.bag.stereo_pairs import read_stereo_pairs

    return [(pair.stamp_ns * 1e-9, pair.left, pair.right, pair.calibration)
            for pair in read_stereo_pairs(bag)]


def replay_bags() -> None:
    """Match every committed bag's scenes tracked and whole; print a table."""
    import dataclasses

    import yaml
    from stereo_fuzzy_perception.core.matching.area_tracker import SCENE_CHANGED, AreaTracker
    from stereo_fuzzy_perception.core.matching.disparity_range import workspace_disparity_range
    from stereo_fuzzy_perception.core.matching.stereo_matching import StereoMatchingPipeline
    from stereo_fuzzy_perception.core.matching.window_matcher import MatcherConfig
    from stereo_fuzzy_perception.core.rig_geometry import StereoRig

    print("\n| bag | scenes | previous scene's region: kept / tried, same point as the whole "
          "image | own region: kept / tried, distance to the whole image's point [mm] | "
          "where (previous scene's region) |")
    print('|---|---:|---:|---:|---|')
    for bag in sorted(path for path in (ROOT / 'bags').iterdir()
                      if (path / 'metadata.yaml').exists()):
        own_params = bag / 'chain_params.yaml'
        params = yaml.safe_load((own_params if own_params.exists()
                                 else ROOT / 'chain' / 'demo_params.yaml').read_text())
        correlation = params['correlation_node']['ros__parameters']
        fuzzy = params.get('fuzzy_best_point_node', {}).get('ros__parameters', {})
        rig = StereoRig(**fuzzy.get('rig', {}))
        pose = rig.world_from_left_camera()
        pipeline = StereoMatchingPipeline(point_stride=int(correlation.get('point_stride', 1)))
        chooser = BestPointChooser.create(fuzzy.get('selector', 'fuzzy_fitted'), AreaConfig(),
                                          rig)
        area_config = AreaConfig()
        tracker = AreaTracker(dataclasses.replace(TrackingConfig(), max_age_s=60.0,
                                                  full_frame_every=10**6))
        where: dict[str, int] = {}
        same = tried = own_kept = own_tried = 0
        distances: list[float] = []
        pairs = bag_scenes(bag)
        for stamp, left, right, calibration in pairs:
            derived = workspace_disparity_range(calibration, pose, area_config.workspace_min,
                                                area_config.workspace_max)
            full_range = (derived.min_disparity, derived.disparity_range)
            pipeline.config = MatcherConfig(min_disparity=full_range[0],
                                            disparity_range=full_range[1])
            whole = pipeline.process(left, right, calibration)
            decided = chooser.decide(whole.points, whole.rectified.left, whole.rectified.right)
            plan = tracker.plan(stamp, calibration, pose, full_range, block_means(left),
                                functools.partial(pipeline.rectifier.raw_box, calibration))
            if plan.reason == SCENE_CHANGED:  # not matched in it: the whole image's point
                tried += 1
                same += 1
                where[SCENE_CHANGED] = where.get(SCENE_CHANGED, 0) + 1
            elif plan.region is not None:
                tracked = pipeline.process(left, right, calibration, region=plan.region)
                again = chooser.decide(tracked.points, tracked.rectified.left,
                                       tracked.rectified.right)
                tried += 1
                reason = tracked.region_problem or 'kept'
                where[reason] = where.get(reason, 0) + 1
                first, second = again.best_point_world, decided.best_point_world
                same += int((first is None and second is None) or (
                    first is not None and second is not None
                    and bool(np.allclose(first, second, atol=1e-4))))
            area = tracked_area(decided)
            tracker.observe(None if area is None else dataclasses.replace(area, stamp_s=stamp))
            if area is None:
                continue
            try:
                region = search_region(area, calibration, pose, full_range,
                                       TrackingConfig().margin_object_sizes,
                                       TrackingConfig().margin_m)
            except AreaProjectionError:
                continue
            own = pipeline.process(left, right, calibration, region=region)
            own_tried += 1
            own_kept += int(not own.region_problem)
            point = chooser.decide(own.points, own.rectified.left,
                                   own.rectified.right).best_point_world
            if point is not None and decided.best_point_world is not None:
                distances.append(1e3 * float(np.linalg.norm(point - decided.best_point_world)))
        spread = (f'{min(distances):.2f}-{max(distances):.2f}' if distances else '-')
        print(f'| {bag.name} | {len(pairs)} | {where.get("kept", 0)} / {tried}, {same} / {tried} '
              f'| {own_kept} / {own_tried}, {spread} '
              f'| {", ".join(f"{key}: {count}" for key, count in sorted(where.items()))} |')


SEQUENCE_OBJECTS = ('cubic_square', 'cylinder', 'cubic_rectangle', 'circle')
"""The chain latency benchmark's scenes (render_scene seeds 100, 101, ... in this order)."""


def sequence(pairs_per_scene: int, pairs: int, lag: int) -> None:
    """Replay the chain benchmark's scene sequence through the tracker in one process; print
    the work per pair by its place after a scene change, with and without issue #18's changes.
    """
    import dataclasses

    from stereo_fuzzy_perception.core.matching.area_tracker import AreaTracker
    from stereo_fuzzy_perception.core.matching.disparity_range import workspace_disparity_range
    from stereo_fuzzy_perception.core.matching.stereo_matching import StereoMatchingPipeline
    from stereo_fuzzy_perception.core.matching.window_matcher import MatcherConfig
    from stereo_fuzzy_perception.core.rig_geometry import StereoRig
    from stereo_fuzzy_perception.simulation.scene_renderer import render_scene

    load = os.getloadavg()[0]
    stride = demo_point_stride()
    frames = [render_scene(100 + index, kind, encoding='mono8')
              for index, kind in enumerate(SEQUENCE_OBJECTS)]
    rig = StereoRig()
    pose = rig.world_from_left_camera()
    area_config = AreaConfig()
    chooser = BestPointChooser.create('fuzzy_fitted', area_config, rig)
    calibration = frames[0].calibration
    derived = workspace_disparity_range(calibration, pose, area_config.workspace_min,
                                        area_config.workspace_max)
    full_range = (derived.min_disparity, derived.disparity_range)
    warm = StereoMatchingPipeline(
        MatcherConfig(min_disparity=full_range[0], disparity_range=full_range[1]),
        point_stride=stride).process(frames[0].left, frames[0].right, calibration)
    chooser.decide(warm.points, warm.rectified.left, warm.rectified.right)  # kernels compiled
    configs = {
        'before (no block means, no regions from matches)': dataclasses.replace(
            TrackingConfig(), detect_scene_change=False, regions_from_matches=False,
            decision_wait_s=0.0),
        'issue #18 defaults': dataclasses.replace(TrackingConfig(), decision_wait_s=0.0)}
    print(f"\n### The chain benchmark's scenes in one process: {pairs} pairs at 30 Hz stamps, "
          f'{pairs_per_scene} per scene, each decision seen {lag} pairs later (point stride '
          f'{stride}; 1-min load {load:.1f})\n')
    print('| tracking | whole image | matched twice | region from matches | mean work per pair '
          '[ms]: 1st / 2nd / 3rd / 4th of a scene, the rest | p99 work [ms] |')
    print('|---|---:|---:|---:|---|---:|')
    for label, config in configs.items():
        pipeline = StereoMatchingPipeline(
            MatcherConfig(min_disparity=full_range[0], disparity_range=full_range[1]),
            point_stride=stride)
        tracker = AreaTracker(config)
        pending: list[tuple[int, TrackedArea | None, float]] = []
        work: dict[int, list[float]] = {}
        every: list[float] = []
        whole = twice = found = 0
        for index in range(pairs):
            frame = frames[(index // pairs_per_scene) % len(frames)]
            stamp = index / 30.0
            for item in [item for item in pending if item[0] <= index]:
                tracker.observe(item[1], item[2])
                pending.remove(item)
            start = time.perf_counter()
            blocks = block_means(frame.left) if config.detect_scene_change else None
            plan = tracker.plan(stamp, frame.calibration, pose, full_range, blocks,
                                functools.partial(pipeline.rectifier.raw_box, frame.calibration))
            result = pipeline.process(frame.left, frame.right, frame.calibration,
                                      region=plan.region)
            if result.region_problem:
                tracker.region_failed(result.region_problem, stamp)
            if result.region is None:
                tracker.matched_whole(result.disparity_map, stamp, result.rectified, stride,
                                      full_range)
            decided = chooser.decide(result.points, result.rectified.left,
                                     result.rectified.right)
            elapsed = 1e3 * (time.perf_counter() - start)
            whole += int(result.region is None)
            twice += int(bool(result.region_problem))
            found += int(plan.from_matches and result.region is not None)
            area = tracked_area(decided)
            pending.append((index + lag, None if area is None
                            else dataclasses.replace(area, stamp_s=stamp), stamp))
            work.setdefault(min(index % pairs_per_scene, 4), []).append(elapsed)
            every.append(elapsed)
        means = ' / '.join(f'{statistics.fmean(work[place]):.1f}' for place in range(4))
        print(f'| {label} | {whole} | {twice} | {found} | {means}, '
              f'{statistics.fmean(work[4]):.1f} | {float(np.percentile(every, 99)):.1f} |')


if __name__ == '__main__':
    main()
