"""Regression without ground truth: compare a run's best points with a reference run's.

A real recording has no ground truth, so the demo cannot score its best points; what it can
check is that they did not move since a reference run. A reference outputs bag holds what the
chain published for each scene (`/best_point` and `/best_point/decision`, keyed by the scene's
header stamp); `compare()` reports per scene the distance between this run's best point and the
reference's, and fails a scene that moved more than the tolerance, that lost or gained a best
point, or that is missing on either side.

  python -m chain.regression compare bags/reference_outputs/demo_scenes output/demo/outputs_bag
  python -m chain.regression reference output/demo/outputs_bag bags/reference_outputs/demo_scenes

ROS-free: the bags are read with the bag tool's reader and decoded with rosbags.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from stereo_fuzzy_perception.bag.bag_io import DEFAULT_QOS, BagWriter, read_info, read_messages
from stereo_fuzzy_perception.bag.message_types import project_typestore

BEST_POINT = '/best_point'
DECISION = '/best_point/decision'
REFERENCE_TOPICS = (BEST_POINT, DECISION)
# Runs of the same code on the same bag give the same best points to the micrometre; a change
# of the algorithm or its parameters that moves a best point by more than this fails.
DEFAULT_TOLERANCE_MM = 1.0


@dataclass(frozen=True)
class SceneOutcome:
    """What the chain decided for one scene: its best point [m], or why there was none."""

    stamp_ns: int
    best_point: tuple[float, float, float] | None
    status: str


@dataclass(frozen=True)
class SceneComparison:
    """One scene of a comparison."""

    stamp_ns: int
    reference: tuple[float, float, float] | None
    current: tuple[float, float, float] | None
    distance_mm: float | None
    passed: bool
    verdict: str


def _stamp_ns(header: object) -> int:
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)


def scene_outcomes(bag: Path) -> dict[int, SceneOutcome]:
    """Return each scene's outcome in an outputs bag, keyed by header stamp [ns].

    A scene is known by its decision (every pair gets one) or its best point.
    """
    info = read_info(bag)
    topics = [topic.name for topic in info.topics if topic.name in REFERENCE_TOPICS]
    typestore = project_typestore([topic.msgtype for topic in info.topics
                                   if topic.name in topics])
    points: dict[int, tuple[float, float, float]] = {}
    statuses: dict[int, str] = {}
    for message in read_messages(bag, topics):
        decoded = typestore.deserialize_cdr(message.data, message.msgtype)
        stamp = _stamp_ns(decoded.header)
        if message.topic == BEST_POINT:
            point = decoded.point
            points[stamp] = (float(point.x), float(point.y), float(point.z))
        else:
            statuses[stamp] = str(decoded.status)
    return {stamp: SceneOutcome(stamp, points.get(stamp), statuses.get(stamp, 'ok'))
            for stamp in sorted(set(points) | set(statuses))}


def compare(reference: dict[int, SceneOutcome], current: dict[int, SceneOutcome],
            tolerance_mm: float = DEFAULT_TOLERANCE_MM) -> list[SceneComparison]:
    """Compare two runs scene by scene (by stamp); return one row per scene of either."""
    rows = []
    for stamp in sorted(set(reference) | set(current)):
        before, now = reference.get(stamp), current.get(stamp)
        old = before.best_point if before else None
        new = now.best_point if now else None
        distance = None
        if before is None:
            verdict, passed = 'not in the reference run', False
        elif now is None:
            verdict, passed = 'not decided in this run (pair lost?)', False
        elif old is None and new is None:
            verdict, passed = f'no best point in either run ({now.status})', True
        elif old is None or new is None:
            verdict = ('best point lost: ' + now.status) if new is None else (
                'best point gained (the reference had: ' + before.status + ')')
            passed = False
        else:
            distance = float(np.linalg.norm(np.subtract(new, old)) * 1000)
            passed = distance <= tolerance_mm
            verdict = 'same' if passed else f'moved more than {tolerance_mm:g} mm'
        rows.append(SceneComparison(stamp, old, new, distance, passed, verdict))
    return rows


def format_comparison(rows: Sequence[SceneComparison]) -> str:
    """Return the comparison as a markdown table."""
    def point(value: tuple[float, float, float] | None) -> str:
        return '-' if value is None else '(' + ', '.join(f'{v * 1000:.2f}' for v in value) + ')'

    lines = ['| scene stamp [s] | reference best point [mm] | this run [mm] | distance [mm] | '
             'verdict |', '|---|---|---|---|---|']
    for row in rows:
        distance = '-' if row.distance_mm is None else f'{row.distance_mm:.3f}'
        lines.append(f'| {row.stamp_ns / 1e9:.3f} | {point(row.reference)} | '
                     f'{point(row.current)} | {distance} | '
                     f'{"pass" if row.passed else "FAIL"}: {row.verdict} |')
    return '\n'.join(lines)


def write_reference(outputs_bag: Path, reference: Path, made_by: str) -> int:
    """Copy the best points and decisions of an outputs bag into a new reference bag.

    Returns:
        The number of messages copied.
    """
    info = read_info(outputs_bag)
    kept = [topic for topic in info.topics if topic.name in REFERENCE_TOPICS]
    count = 0
    with BagWriter(reference, compression_level=19) as bag:
        for topic in kept:
            bag.add_topic(topic.name, topic.msgtype, topic.offered_qos or (DEFAULT_QOS,),
                          msgdef=topic.msgdef or None, type_hash=topic.type_hash or None)
        for message in read_messages(outputs_bag, [topic.name for topic in kept]):
            bag.write(message.topic, message.timestamp_ns, message.data)
            count += 1
        bag.set_custom_data('made_by', made_by)
    return count


def main(argv: Sequence[str] | None = None) -> int:
    """Compare two runs, or make a reference bag from a run's outputs bag."""
    parser = argparse.ArgumentParser(prog='python -m chain.regression',
                                     description=__doc__.splitlines()[0])
    commands = parser.add_subparsers(dest='command', required=True)
    compare_parser = commands.add_parser('compare', help='compare a run with a reference')
    compare_parser.add_argument('reference', type=Path, help='reference outputs bag')
    compare_parser.add_argument('outputs', type=Path, help="this run's outputs bag")
    compare_parser.add_argument('--tolerance-mm', type=float, default=DEFAULT_TOLERANCE_MM)
    reference_parser = commands.add_parser('reference', help='make a reference bag')
    reference_parser.add_argument('outputs', type=Path, help="a run's outputs bag")
    reference_parser.add_argument('reference', type=Path, help='reference bag to create')
    args = parser.parse_args(argv)
    if args.command == 'reference':
        count = write_reference(args.outputs, args.reference,
                                f'python -m chain.regression reference {args.outputs} '
                                f'{args.reference}')
        print(f'{count} messages copied into {args.reference}')
        return 0
    rows = compare(scene_outcomes(args.reference), scene_outcomes(args.outputs),
                   args.tolerance_mm)
    print(format_comparison(rows))
    failed = sum(not row.passed for row in rows)
    print(f'\n{len(rows) - failed} of {len(rows)} scenes match the reference '
          f'(tolerance {args.tolerance_mm:g} mm)')
    return 1 if failed or not rows else 0


if __name__ == '__main__':
    sys.exit(main())
