"""benchmarks/rig_breakdown.py: the evaluation's per-scene CSV broken down by rig."""

import math

from benchmarks.rig_breakdown import (
    ROWS,
    column_table,
    depth_per_disparity_mm,
    table,
    within_counts,
)


def _row(name, stride, rig, error, top_px='24-40 px'):
    return {'row': ROWS[name], 'stride': str(stride), 'rig': str(rig), 'error_mm': error,
            'top_px': top_px}


def test_a_scene_without_a_point_counts_but_is_never_within():
    rows = [_row('fitted rules', 1, 30, '1.0'), _row('fitted rules', 1, 30, 'nan'),
            _row('fitted rules', 1, 30, ''), _row('fitted rules', 1, 30, '3.5'),
            _row('fitted rules', 3, 30, '2.9')]
    counts = within_counts(rows, 3.0)
    assert counts[(ROWS['fitted rules'], 1, 30)] == (1, 4)
    assert counts[(ROWS['fitted rules'], 3, 30)] == (1, 1)


def test_rigs_are_listed_by_resolution_and_grouped_on_either_side_of_the_split():
    rows = [_row('fitted rules', 1, 31, '1.0'), _row('fitted rules', 1, 31, '9.0'),
            _row('fitted rules', 1, 30, '20.0'), _row('ceiling', 1, 30, '0.5'),
            _row('ceiling', 1, 31, '0.5'), _row('ceiling', 1, 31, '0.5')]
    lines = table(rows, {30: 2.0, 31: 0.5}, 3.0, 1.0)
    body = lines[2:]
    assert body[0].startswith('| 31 | 0.50 | 1/2 (50 %) | - | 2/2 (100 %) | - |')
    assert body[1].startswith('| 30 | 2.00 | 0/1 (0 %) | - | 1/1 (100 %) | - |')
    assert body[2].startswith('| **rigs at most 1 mm** (1) |  | 1/2 (50 %)')
    assert body[3].startswith('| **rigs over 1 mm** (1) |  | 0/1 (0 %)')


def test_a_farther_narrower_rig_resolves_depth_worse():
    # rig 35: 0.48 m away, 87 mm baseline; rig 37: 0.79 m, 50 mm (scene_distribution.py)
    near, far = depth_per_disparity_mm(35), depth_per_disparity_mm(37)
    assert math.isfinite(near) and math.isfinite(far)
    assert 0.0 < near < far


def test_scenes_are_grouped_by_any_column_a_line_per_value():
    rows = [_row('fitted rules', 1, 30, '1.0', '40-60 px'), _row('fitted rules', 1, 31, 'nan'),
            _row('fitted rules', 1, 31, '2.0'), _row('ceiling', 1, 30, '0.5', '40-60 px'),
            _row('fitted rules', 3, 30, '4.0', '40-60 px')]
    lines = column_table(rows, 'top_px', 3.0)
    assert lines[0].startswith('| top_px | fitted rules, stride 1 | true outline, stride 1 | '
                               'ceiling, stride 1 |')
    # two rigs, one value: the 24-40 px scenes of both rigs together
    assert lines[2] == ('| 24-40 px | 1/2 (50 %) | - | - | - | - | - | - | - |')
    assert lines[3] == ('| 40-60 px | 1/1 (100 %) | - | 1/1 (100 %) | - | 0/1 (0 %) | - | - | - |')
