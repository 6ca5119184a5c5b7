"""benchmarks/rig_tuning.py's comparison of two runs scene by scene (--save, --against)."""

import math

import pytest

from benchmarks.rig_tuning import (
    changed_outcomes,
    outcome,
    outcome_counts,
    outcomes_by_look,
    outcomes_by_resolution,
)


@pytest.mark.parametrize(('error', 'expected'), [
    (None, 'no point'), (math.nan, 'no point'), (0.4, 'within'), (3.0, 'within'),
    (3.01, '<= 10 mm'), (10.0, '<= 10 mm'), (10.5, '> 10 mm')])
def test_each_scene_falls_in_one_outcome(error, expected):
    assert outcome(error, 3.0) == expected


def test_the_changes_are_listed_scene_by_scene_and_the_totals_of_both_runs_kept():
    before = {'a': 1.0, 'b': None, 'c': 2.0, 'd': 12.0, 'only before': 1.0}
    after = {'a': 1.2, 'b': 2.5, 'c': 3.5, 'd': 9.0, 'only after': None}
    lines = changed_outcomes(before, after, 3.0)
    # 'a' moved 0.2 mm within its class: not a change; the rest changed class
    assert [line.split(':')[0].strip() for line in lines] == ['b', 'c', 'd']
    assert 'none ->     2.5' in lines[0]
    assert outcome_counts(before, 3.0) == 'within 3, <= 10 mm 0, > 10 mm 1, no point 1'
    assert outcome_counts(after, 3.0) == 'within 2, <= 10 mm 2, > 10 mm 0, no point 1'


def test_a_move_of_more_than_a_millimetre_within_a_class_is_listed():
    assert changed_outcomes({'a': 0.5}, {'a': 2.0}, 3.0) == ['  a:     0.5 ->     2.0 mm']
    assert changed_outcomes({'a': None}, {'a': None}, 3.0) == []


def test_the_outcomes_are_split_by_the_rigs_depth_resolution():
    errors = {'seed 1 rig 3 top 40 px wood': 1.0, 'seed 2 rig 3 top 40 px wood': None,
              'seed 3 rig 12 top 30 px granite': 12.0, 'seed 4 rig 7 top 30 px speckle': 2.0}
    lines = outcomes_by_resolution(errors, {3: 0.5, 7: 1.0, 12: 2.4}, 3.0)
    assert lines == [
        '  rigs at most 1 mm per 0.1 px (2 rigs, 3 scenes): '
        'within 2, <= 10 mm 0, > 10 mm 0, no point 1',
        '  rigs over 1 mm per 0.1 px (1 rig, 1 scene): '
        'within 0, <= 10 mm 0, > 10 mm 1, no point 0']
    assert outcomes_by_resolution({'seed 1 rig 3 top 40 px wood': 1.0}, {3: 0.5}, 3.0) == [
        '  rigs at most 1 mm per 0.1 px (1 rig, 1 scene): '
        'within 1, <= 10 mm 0, > 10 mm 0, no point 0']


def test_the_outcomes_are_split_by_the_look_that_decided_each_scene():
    errors = {'a': 1.0, 'b': 4.0, 'c': None, 'd': 2.0, 'e': 12.0}
    looks = {'a': 'matches', 'b': 'matches', 'c': 'refused: no_object', 'd': 'matches',
             'e': 'plain object in the image'}
    lines = outcomes_by_look(errors, looks, 3.0)
    # most scenes first, ties by name; the names padded to one column
    assert lines == [
        '  matches                   (  3): within 2, <= 10 mm 1, > 10 mm 0, no point 0',
        '  plain object in the image (  1): within 0, <= 10 mm 0, > 10 mm 1, no point 0',
        '  refused: no_object        (  1): within 0, <= 10 mm 0, > 10 mm 0, no point 1']
    assert outcomes_by_look({}, {}, 3.0) == []
