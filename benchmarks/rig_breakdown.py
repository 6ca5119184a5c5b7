#!/usr/bin/env python3
"""Break the randomized evaluation down by rig (how far each rig's depth resolution explains it)
or by any column of its per-scene CSV (`--by`: the top's width in the image, its texture, ...).

Reads the per-scene CSV that rig_generalisation_benchmark.py wrote (no rendering, no matching:
seconds) and, for every rig of the split, the rig's depth resolution at the table: the change of
depth [mm] per 0.1 px of disparity where the left camera's optical axis meets z = 0,
Z^2 / (f B) * 0.1 (0.1 px: the order of the matcher's noise on a textured table). Beside it,
per point stride, the scenes within the tolerance for the fitted rules, the true top's outline
at its matches' median height (the benchmark's diagnosis: what the matches allow), the
perfect-depth ceiling and the plain OpenCV pipeline, rig by rig and for the rigs on either
side of --resolution-mm.

    source scripts/env.sh
    python benchmarks/rig_breakdown.py
    python benchmarks/rig_breakdown.py --by top_px      # or object_texture, noise, table_bias
    python benchmarks/rig_breakdown.py \
        --csv benchmarks/results/rig_generalisation_oversampled3_scenes.csv
"""

from __future__ import annotations

import argparse
import csv
import math
import sys
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / 'src' / 'stereo_fuzzy_perception'))
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402
from stereo_fuzzy_perception.simulation.scene_distribution import (  # noqa: E402
    DEFAULT_SETTINGS,
    DistributionSettings,
    draw_rig,
)

from benchmarks.true_top import DIAGNOSIS_ROW  # noqa: E402

ROWS = {'fitted rules': 'fuzzy_fitted',
        'true outline': DIAGNOSIS_ROW,
        'ceiling': 'ceiling: fuzzy_fitted',
        'OpenCV': 'opencv (SGBM + largest component + top band)'}
"""Columns of the table: the CSV's row names (rig_generalisation_benchmark.py). `true outline`
is its diagnosis: the matches' own heights on a top found perfectly."""

DISPARITY_STEP_PX = 0.1
"""The disparity error the resolution is given for [px]."""


def depth_per_disparity_mm(rig_index: int,
                           settings: DistributionSettings = DEFAULT_SETTINGS) -> float:
    """Return the depth change [mm] per DISPARITY_STEP_PX where the rig looks at z = 0."""
    drawn = draw_rig(rig_index, settings)
    pose = drawn.rig.world_from_left_camera()
    centre, axis = pose[:3, 3], pose[:3, 2]
    if axis[2] >= 0.0:
        return math.inf  # the optical axis never meets the table
    depth = -centre[2] / axis[2]
    return 1000.0 * depth ** 2 / (drawn.camera.focal_px * drawn.rig.baseline_m) * DISPARITY_STEP_PX


def group_counts(rows: list[dict[str, str]], tolerance_mm: float, column: str
                 ) -> dict[tuple[str, int, str], tuple[int, int]]:
    """Return (row name, stride, the scene's value in column) -> (scenes within tolerance_mm,
    scenes)."""
    counts: dict[tuple[str, int, str], list[int]] = defaultdict(lambda: [0, 0])
    for row in rows:
        key = (row['row'], int(row['stride']), row[column])
        error = float(row['error_mm']) if row['error_mm'] not in ('', 'nan') else math.nan
        counts[key][0] += int(error <= tolerance_mm)  # NaN (no point) is never within
        counts[key][1] += 1
    return {key: (value[0], value[1]) for key, value in counts.items()}


def within_counts(rows: list[dict[str, str]], tolerance_mm: float
                  ) -> dict[tuple[str, int, int], tuple[int, int]]:
    """Return (row name, stride, rig) -> (scenes within tolerance_mm, scenes)."""
    return {(name, stride, int(rig)): value
            for (name, stride, rig), value in group_counts(rows, tolerance_mm, 'rig').items()}


def share(counts: tuple[int, int]) -> str:
    """Return 'within/total (percent)', or '-' for no scenes."""
    within, total = counts
    return f'{within}/{total} ({100.0 * within / total:.0f} %)' if total else '-'


def column_table(rows: list[dict[str, str]], column: str, tolerance_mm: float) -> list[str]:
    """Return the markdown lines of the scenes within tolerance_mm by their value in column
    (top_px, object_texture, surface_texture, noise, object_type, ...), a line per value."""
    counts = group_counts(rows, tolerance_mm, column)
    strides = sorted({int(row['stride']) for row in rows})
    header = [column] + [f'{name}, stride {stride}' for stride in strides for name in ROWS]
    lines = ['| ' + ' | '.join(header) + ' |', '|' + '---|' * len(header)]
    for value in sorted({row[column] for row in rows}):
        lines.append('| ' + ' | '.join([value] + [
            share(counts.get((name, stride, value), (0, 0)))
            for stride in strides for name in ROWS.values()]) + ' |')
    return lines


def table(rows: list[dict[str, str]], resolutions: dict[int, float], tolerance_mm: float,
          split_mm: float) -> list[str]:
    """Return the markdown lines: one per rig, then the rigs on either side of split_mm."""
    counts = within_counts(rows, tolerance_mm)
    strides = sorted({int(row['stride']) for row in rows})
    header = ['rig', f'depth per {DISPARITY_STEP_PX:g} px [mm]'] + [
        f'{name}, stride {stride}' for stride in strides for name in ROWS]
    lines = ['| ' + ' | '.join(header) + ' |', '|' + '---|' * len(header)]

    def cells(rigs: list[int]) -> list[str]:
        out = []
        for stride in strides:
            for name in ROWS.values():
                out.append(share((
                    sum(counts.get((name, stride, rig), (0, 0))[0] for rig in rigs),
                    sum(counts.get((name, stride, rig), (0, 0))[1] for rig in rigs))))
        return out

    ordered = sorted(resolutions, key=lambda rig: (resolutions[rig], rig))
    for rig in ordered:
        lines.append('| ' + ' | '.join([str(rig), f'{resolutions[rig]:.2f}'] + cells([rig]))
                     + ' |')
    for label, rigs in ((f'rigs at most {split_mm:g} mm', [r for r in ordered
                                                          if resolutions[r] <= split_mm]),
                        (f'rigs over {split_mm:g} mm', [r for r in ordered
                                                       if resolutions[r] > split_mm])):
        if rigs:
            lines.append('| ' + ' | '.join([f'**{label}** ({len(rigs)})', ''] + cells(rigs))
                         + ' |')
    return lines


def main() -> None:
    """Print the per-rig table of one rig_generalisation CSV."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--csv', default=str(ROOT / 'benchmarks' / 'results'
                                             / 'rig_generalisation_scenes.csv'))
    parser.add_argument('--tolerance-mm', type=float, default=3.0)
    parser.add_argument('--resolution-mm', type=float, default=1.0,
                        help='rigs are grouped on either side of this depth resolution')
    parser.add_argument('--by', metavar='COLUMN',
                        help='group the scenes by this CSV column instead of by rig '
                             '(top_px, object_texture, surface_texture, noise, object_type)')
    args = parser.parse_args()
    path = Path(args.csv)
    if not path.is_file():
        parser.error(f'--csv {path}: no such file (rig_generalisation_benchmark.py writes it)')
    with path.open(newline='') as stream:
        rows = [row for row in csv.DictReader(stream) if row['row'] in ROWS.values()]
    if not rows:
        parser.error(f'--csv {path}: no rows of {", ".join(ROWS.values())}')
    if args.by is not None:
        if args.by not in rows[0]:
            parser.error(f'--by {args.by}: no such column; the CSV has {", ".join(rows[0])}')
        print(f'{path.name}: scenes within {args.tolerance_mm:g} mm by {args.by}\n')
        print('\n'.join(column_table(rows, args.by, args.tolerance_mm)))
        return
    resolutions = {rig: depth_per_disparity_mm(rig) for rig in
                   sorted({int(row['rig']) for row in rows})}
    print(f'{path.name}: scenes within {args.tolerance_mm:g} mm by rig '
          f'(median depth per {DISPARITY_STEP_PX:g} px '
          f'{float(np.median(list(resolutions.values()))):.2f} mm)\n')
    print('\n'.join(table(rows, resolutions, args.tolerance_mm, args.resolution_mm)))


if __name__ == '__main__':
    main()
