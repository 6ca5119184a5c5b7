"""ParameterSpec: the allowed values of a node parameter, in words and as a check."""

import pytest
from stereo_fuzzy_parameters.spec import ParameterSpec

WINDOW = ParameterSpec('window_size', 9, 'Side of the window [px]', minimum=3, maximum=31)
METHOD = ParameterSpec('method', 'zncc', 'Measure', choices=('zncc', 'plain'), read_only=True)


@pytest.mark.parametrize('value', [3, 9, 31])
def test_values_inside_the_range_are_allowed(value):
    assert WINDOW.check(value) is None


@pytest.mark.parametrize(('value', 'words'), [(2, 'below the minimum 3'),
                                              (32, 'above the maximum 31')])
def test_values_outside_the_range_are_refused_with_name_value_and_limit(value, words):
    reason = WINDOW.check(value)
    assert reason is not None
    assert 'window_size' in reason and str(value) in reason and words in reason


def test_a_string_outside_its_choices_is_refused_naming_the_choices():
    reason = METHOD.check('foo')
    assert reason is not None and "'foo'" in reason and 'zncc, plain' in reason
    assert METHOD.check('plain') is None


def test_constraint_text_lists_range_choices_and_read_only():
    assert WINDOW.constraint_text() == '[3, 31]'
    assert METHOD.constraint_text() == 'one of zncc, plain; read-only'
