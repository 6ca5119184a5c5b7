"""ParameterSpec and settings types: the allowed values of node parameters, in words and as
checks, and the typed, frozen settings object built from them."""

from dataclasses import FrozenInstanceError, dataclass

import pytest
from stereo_fuzzy_parameters.spec import (
    ParameterSpec,
    SettingsError,
    parameter,
    parameter_group,
    parameter_specs,
    settings_from_values,
    settings_values,
)
from stereo_fuzzy_parameters.world import WorldSettings

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


# --- settings types: the fields are the parameters ---------------------------------------------



@dataclass(frozen=True)
class Area:
    x: int = parameter(0, 'Left column [px]', 0, 100)
    width: int = parameter(0, 'Width [px]', 0, 100)


@dataclass(frozen=True)
class Example:
    window_size: int = parameter(9, 'Side of the window [px]', 3, 31)
    method: str = parameter('zncc', 'Measure', choices=('zncc', 'plain'), read_only=True)
    area: Area = parameter_group(Area)
    world: WorldSettings = parameter_group(WorldSettings, prefix='')
    device: str = parameter('', 'Device', dynamic_typing=True)

    def problem(self):
        return None if self.window_size % 2 else f'window_size={self.window_size} must be odd'


def test_specs_are_the_fields_in_order_groups_dotted_or_flat():
    names = [spec.name for spec in parameter_specs(Example)]
    assert names == ['window_size', 'method', 'area.x', 'area.width', 'world_frame',
                     'workspace_min_m', 'workspace_max_m', 'device']
    workspace = parameter_specs(Example)[5]
    assert workspace.default == [0.0, 0.0, 0.0] and workspace.size == 3 and workspace.read_only


def test_settings_round_trip_through_values_typed_and_frozen():
    values = settings_values(Example())
    values.update({'window_size': 11, 'area.x': 5, 'workspace_max_m': [1.0, 2.0, 3.0],
                   'device': 0})
    settings = settings_from_values(Example, values)
    assert settings.window_size == 11 and settings.area.x == 5
    assert settings.world.workspace_max_m == (1.0, 2.0, 3.0)
    assert settings.device == '0', 'a dynamically typed integer is read as its text'
    with pytest.raises(FrozenInstanceError):
        settings.window_size = 3


@pytest.mark.parametrize(('change', 'words'), [
    ({'window_size': 10}, 'window_size=10 must be odd'),
    ({'window_size': 33}, 'window_size=33 is above the maximum 31 (allowed [3, 31])'),
    ({'method': 'foo'}, "method='foo' is not one of zncc, plain"),
    ({'area.width': -1}, 'area.width=-1 is below the minimum 0'),
    ({'workspace_max_m': [1.0, 1.0]}, 'has 2 values; allowed: 3 values'),
    ({'workspace_max_m': [1.0, 1.0, 11.0]}, 'element 11.0 is above the maximum 10.0'),
    ({'workspace_max_m': [1.0, 1.0, -1.0]}, 'must exceed workspace_min_m'),
])
def test_bad_values_are_refused_naming_parameter_value_and_what_is_allowed(change, words):
    values = {**settings_values(Example()), **change}
    with pytest.raises(SettingsError) as raised:
        settings_from_values(Example, values)
    assert words in str(raised.value)


def test_a_name_declared_twice_through_flat_groups_is_refused():
    @dataclass(frozen=True)
    class Twice:
        first: WorldSettings = parameter_group(WorldSettings, prefix='')
        second: WorldSettings = parameter_group(WorldSettings, prefix='')

    twice = 'declares workspace_max_m, workspace_min_m, world_frame twice'
    with pytest.raises(TypeError, match=twice):
        parameter_specs(Twice)
