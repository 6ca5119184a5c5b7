"""Rule base and weights files as a hostile peer would set them: refused with a reason, or usable.

Issue #15 items 1, 5 and 7: every malformed file gives the loader's own error (a ValueError
naming the file and the entry), never TypeError, AttributeError or a hang; special files
(FIFO, /dev/zero, directories) are refused without being read; the property tests feed random
YAML documents and random .npz contents and require 'refused with a reason or accepted and
usable'.
"""

from __future__ import annotations

import copy
import io
import math
import os
import zipfile
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from stereo_fuzzy_perception.core.best_point.correlation_area import AreaConfig
from stereo_fuzzy_perception.core.best_point.fuzzy_inference import infer
from stereo_fuzzy_perception.core.best_point.neural_baseline import (
    FEATURE_COUNT,
    NeuralBaseline,
    NeuralBaselineError,
)
from stereo_fuzzy_perception.core.best_point.point_selectors import (
    NON_FINITE_POINT,
    OUTSIDE_WORKSPACE,
    BestPointChooser,
    SelectorError,
    load_selector_files,
)
from stereo_fuzzy_perception.core.best_point.rule_base import (
    RuleBaseError,
    data_path,
    load_rule_base,
    rule_base_from_dict,
    rule_base_to_dict,
)
from stereo_fuzzy_perception.core.camera_calibration_file import (
    CalibrationFileError,
    read_calibration_yaml,
)
from stereo_fuzzy_perception.core.rig_geometry import StereoRig
from stereo_fuzzy_perception.core.yaml_file import MAX_DATA_FILE_BYTES, read_file_bytes

PACKAGED = rule_base_to_dict(load_rule_base(data_path('fuzzy_fitted.yaml')))
WEIGHTS = NeuralBaseline.load(data_path('neural_baseline.npz'))


def weights_arrays() -> dict[str, np.ndarray]:
    return {'input_mean': WEIGHTS.input_mean, 'input_std': WEIGHTS.input_std, 'w1': WEIGHTS.w1,
            'b1': WEIGHTS.b1, 'w2': WEIGHTS.w2, 'b2': WEIGHTS.b2,
            'output_scale': np.array(WEIGHTS.output_scale)}


def write_yaml(tmp_path: Path, document: object, name: str = 'rules.yaml') -> Path:
    path = tmp_path / name
    path.write_text(yaml.safe_dump(document))
    return path


def scene_decision(chooser: BestPointChooser):
    from stereo_fuzzy_perception.simulation.synthetic_scenes import GeometricSceneSource

    scene = GeometricSceneSource().scene(np.random.default_rng(3), 'cubic_square')
    return chooser.decide(scene.points, scene.left, scene.right)


# --- item 7: special and oversized files -----------------------------------------------------

def test_a_fifo_is_refused_at_once_not_waited_on(tmp_path):
    fifo = tmp_path / 'rules.fifo'
    os.mkfifo(fifo)
    with pytest.raises(RuleBaseError, match='not a regular file .a FIFO'):
        load_rule_base(fifo)  # a blocking open() would hang here: no writer ever comes


@pytest.mark.parametrize(('path', 'kind'), [('/dev/zero', 'a character device'),
                                            ('/dev/null', 'a character device')])
def test_devices_are_refused_without_reading(path, kind):
    if not Path(path).exists():
        pytest.skip(f'{path} missing on this machine')
    with pytest.raises(RuleBaseError, match=f'not a regular file .{kind}'):
        load_rule_base(path)
    with pytest.raises(NeuralBaselineError, match='not a regular file'):
        NeuralBaseline.load(path)


def test_a_directory_a_missing_file_and_a_nul_byte_are_refused(tmp_path):
    with pytest.raises(RuleBaseError, match='a directory'):
        load_rule_base(tmp_path)
    with pytest.raises(RuleBaseError, match='cannot read'):
        load_rule_base(tmp_path / 'missing.yaml')
    with pytest.raises(RuleBaseError, match='cannot read'):
        load_rule_base('bad\0name.yaml')


def test_files_above_the_size_cap_are_refused_before_reading(tmp_path):
    big = tmp_path / 'big.yaml'
    with open(big, 'wb') as file:
        file.truncate(MAX_DATA_FILE_BYTES + 1)  # sparse: no disk used
    with pytest.raises(RuleBaseError, match='more than'):
        load_rule_base(big)
    small = tmp_path / 'small.bin'
    small.write_bytes(b'x' * 100)
    assert read_file_bytes(small, ValueError, 'data', max_bytes=100) == b'x' * 100
    with pytest.raises(ValueError, match='more than the 99 allowed'):
        read_file_bytes(small, ValueError, 'data', max_bytes=99)


def test_calibration_files_use_the_same_safe_reader(tmp_path):
    fifo = tmp_path / 'left.fifo'
    os.mkfifo(fifo)
    with pytest.raises(CalibrationFileError, match='a FIFO'):
        read_calibration_yaml(fifo)


def test_deeply_nested_yaml_is_a_yaml_error_not_a_crash(tmp_path):
    path = tmp_path / 'deep.yaml'
    path.write_text('[' * 5000 + ']' * 5000)
    with pytest.raises(RuleBaseError):
        load_rule_base(path)


# --- item 1: malformed rule bases and weights ------------------------------------------------

def with_change(change) -> dict:
    document = copy.deepcopy(PACKAGED)
    change(document)
    return document


MALFORMED_RULE_BASES = [
    ('non-string key', lambda d: d.update({1: 'x'}), 'not a string'),
    ('list premise', lambda d: d['rules'][0].update({'if': ['less']}), 'premise term'),
    ('dict premise', lambda d: d['rules'][0].update({'if': {'a': 1}}), 'premise term'),
    ('dict name', lambda d: d.update({'name': {'a': 1}}), 'not a non-empty string'),
    ('list term name', lambda d: d['membership_functions'][0].update({'name': [1]}),
     'not a non-empty string'),
    ('list area', lambda d: d['rules'][0].update({'area': [1]}), 'not one of 1, 2, 3, 4'),
    ('nested consequent area', lambda d: d['rules'][0]['then'].update({'areas': [[1], 2]}),
     'distinct areas'),
    ('huge offset', lambda d: d['rules'][0]['then'].update({'offset_m': [1e300, 0, 0]}),
     'beyond the allowed'),
    ('infinite offset', lambda d: d['rules'][0]['then'].update({'offset_m': [math.inf, 0, 0]}),
     'not a finite number'),
    ('huge integer offset', lambda d: d['rules'][0]['then'].update({'offset_m': [10**400, 0, 0]}),
     'not a finite number'),
    ('NaN break point', lambda d: d['membership_functions'][0].update(
        {'points': [math.nan, 1, 2]}), 'not a finite number'),
    ('string height offset', lambda d: d.update({'height_offset_m': 'high'}), 'not a number'),
    ('rule as a list', lambda d: d['rules'].__setitem__(0, [1, 2]), 'expected a mapping'),
    ('then as a list', lambda d: d['rules'][0].update({'then': [1]}), 'expected'),
    ('list description', lambda d: d.update({'description': ['x']}), 'not a string'),
]


@pytest.mark.parametrize(('change', 'message'), [case[1:] for case in MALFORMED_RULE_BASES],
                         ids=[case[0] for case in MALFORMED_RULE_BASES])
def test_malformed_rule_bases_are_refused_with_the_entry_named(tmp_path, change, message):
    document = with_change(change)
    with pytest.raises(RuleBaseError, match=message):
        rule_base_from_dict(document, 'test')
    path = tmp_path / 'rules.yaml'
    path.write_text(yaml.dump(document))  # yaml.dump: non-string keys survive the file
    with pytest.raises(RuleBaseError):
        load_rule_base(path)


def save_npz(path: Path, **arrays) -> Path:
    np.savez(path, **arrays)
    return path


def test_an_npy_file_is_refused_as_network_weights(tmp_path):
    path = tmp_path / 'weights.npy'
    np.save(path, np.zeros(3))
    with pytest.raises(NeuralBaselineError, match=r'not an \.npz archive'):
        NeuralBaseline.load(path)
    with pytest.raises(SelectorError, match=r'not an \.npz archive'):
        load_selector_files('', str(path))  # checked while another selector is active


@pytest.mark.parametrize(('name', 'value', 'message'), [
    ('output_scale', np.ones(3), 'output_scale has shape'),
    ('output_scale', np.array(0.0), 'output_scale 0 must be in'),
    ('output_scale', np.array(1e6), 'must be in'),
    ('w1', np.full((FEATURE_COUNT, 4), np.nan), 'w1 holds NaN'),
    ('b2', np.array([np.inf, 0, 0]), 'b2 holds NaN'),
    ('w2', np.zeros((3, 3)), 'w2 has shape'),
    ('input_std', np.zeros(FEATURE_COUNT), 'input_std holds zeros'),
    ('b1', np.array(['a'] * 16), 'expected real numbers'),
    ('w1', np.zeros((FEATURE_COUNT, 0)), 'H hidden units'),
])
def test_malformed_weights_are_refused_with_the_array_named(tmp_path, name, value, message):
    arrays = weights_arrays()
    arrays[name] = value
    with pytest.raises(NeuralBaselineError, match=message):
        NeuralBaseline.load(save_npz(tmp_path / 'weights.npz', **arrays))


def test_pickled_objects_and_decompression_bombs_are_refused(tmp_path):
    arrays = weights_arrays()
    arrays['b1'] = np.array([object()] * 16, dtype=object)
    with pytest.raises(NeuralBaselineError, match='cannot read|real numbers'):
        NeuralBaseline.load(save_npz(tmp_path / 'objects.npz', **arrays))
    bomb = tmp_path / 'bomb.npz'
    with zipfile.ZipFile(bomb, 'w', zipfile.ZIP_DEFLATED) as archive:
        archive.writestr('w1.npy', b'\0' * (MAX_DATA_FILE_BYTES + 1))
    assert bomb.stat().st_size < 100_000
    with pytest.raises(NeuralBaselineError, match='uncompressed'):
        NeuralBaseline.load(bomb)


# --- item 5: every best point finite and inside the workspace --------------------------------

def chooser_with_network(network: NeuralBaseline) -> BestPointChooser:
    chooser = BestPointChooser.create('centroid', AreaConfig(), StereoRig())
    chooser.selector, chooser.network = 'neural_network', network
    return chooser


def test_overflowing_weights_give_no_point_but_a_reason():
    arrays = weights_arrays()
    arrays['w2'] = np.full_like(arrays['w2'], 1e308)
    arrays['b1'] = np.full_like(arrays['b1'], 50.0)  # every tanh = 1: the sum overflows
    arrays['output_scale'] = np.array(1.0)
    decision = scene_decision(chooser_with_network(NeuralBaseline.from_arrays(arrays)))
    assert not decision.has_best_point
    assert decision.status == NON_FINITE_POINT, decision.status_text()


def test_large_but_finite_offsets_outside_the_workspace_give_no_point(tmp_path):
    document = with_change(lambda d: [rule['then'].update({'offset_m': [5.0, 0.0, 0.0]})
                                      for rule in d['rules']])
    chooser = BestPointChooser.create('fuzzy_fitted', AreaConfig(), StereoRig(),
                                      rule_base_file=str(write_yaml(tmp_path, document)))
    decision = scene_decision(chooser)
    assert not decision.has_best_point
    assert decision.status == OUTSIDE_WORKSPACE and 'x = ' in decision.reason


def test_the_packaged_selectors_still_choose_a_point_inside_the_workspace():
    for selector in ('fuzzy_fitted', 'fuzzy_chapter', 'centroid', 'max_score', 'neural_network'):
        decision = scene_decision(BestPointChooser.create(selector, AreaConfig(), StereoRig()))
        assert decision.has_best_point, (selector, decision.status_text())


# --- property tests: any YAML document, any .npz content -------------------------------------

yaml_scalars = (st.none() | st.booleans() | st.integers(-10**30, 10**30)
                | st.floats(allow_nan=True, allow_infinity=True) | st.text(max_size=8)
                | st.sampled_from(['less', 'equal', 'greater', 'x', 'name', 'rules']))
yaml_values = st.recursive(
    yaml_scalars,
    lambda children: (st.lists(children, max_size=4)
                      | st.dictionaries(st.sampled_from(
                          ['name', 'area', 'if', 'then', 'areas', 'offset_m', 'points',
                           'rules', 'membership_functions', 'height_offset_m', 'description'])
                          | yaml_scalars.filter(lambda v: v is not None), children,
                          max_size=5)),
    max_leaves=25)


def child(target: object, step: object) -> tuple[bool, object]:
    """Return (True, target[step]) when `step` indexes into `target`, else (False, None)."""
    if isinstance(target, dict) and step in target:
        return True, target[step]
    if isinstance(target, list) and isinstance(step, int) and step < len(target):
        return True, target[step]
    return False, None


def mutated_document(draw_path, value) -> dict:
    """Return the packaged document with the entry at `draw_path` replaced by `value`."""
    document = copy.deepcopy(PACKAGED)
    target: object = document
    for step in draw_path[:-1]:
        found, target = child(target, step)
        if not found:
            return document
    last = draw_path[-1]
    if isinstance(target, dict) or child(target, last)[0]:
        target[last] = value  # type: ignore[index]
    return document


document_paths = st.lists(st.sampled_from(
    ['rules', 'membership_functions', 'then', 'areas', 'offset_m', 'points', 'if', 'area',
     'name', 'height_offset_m', 0, 1, 2]), min_size=1, max_size=5)


def check_usable_or_refused(document: object) -> None:
    """The property: a RuleBaseError, or a rule base that infers without raising."""
    try:
        rule_base = rule_base_from_dict(document, 'random')
    except RuleBaseError as error:
        assert str(error).startswith('random: ')
        return
    from stereo_fuzzy_perception.core.best_point.correlation_area import find_correlation_area
    from stereo_fuzzy_perception.core.best_point.four_areas import split_into_areas
    from stereo_fuzzy_perception.simulation.synthetic_scenes import GeometricSceneSource

    scene = GeometricSceneSource().scene(np.random.default_rng(0), 'cubic_square')
    area = find_correlation_area(scene.points, StereoRig().world_from_left_camera(), AreaConfig())
    areas = split_into_areas(area, (scene.left.P[0, 2], scene.left.P[1, 2]),
                             (scene.right.P[0, 2], scene.right.P[1, 2]))
    result = infer(rule_base, areas)
    assert result.point is None or result.point.shape == (3,)
    assert all(math.isfinite(value) for rule in rule_base.rules for value in rule.offset_m)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(yaml_values)
def test_any_yaml_document_is_refused_with_a_reason_or_usable(document):
    check_usable_or_refused(document)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(document_paths, yaml_values)
def test_any_change_to_a_good_rule_base_is_refused_with_a_reason_or_usable(path, value):
    check_usable_or_refused(mutated_document(path, value))


array_values = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True), st.integers(-10**6, 10**6),
    st.booleans(), st.text(max_size=3))
array_shapes = st.sampled_from([(), (1,), (3,), (14,), (16,), (14, 16), (16, 3), (14, 4), (4, 3),
                                (0,), (14, 0), (2, 2, 2)])


@st.composite
def weight_archives(draw) -> bytes:
    arrays = {name: np.asarray(value) for name, value in weights_arrays().items()}
    for name in draw(st.lists(st.sampled_from(list(arrays) + ['extra']), max_size=4)):
        action = draw(st.sampled_from(['delete', 'replace', 'poison']))
        if action == 'delete':
            arrays.pop(name, None)
        elif action == 'replace':
            shape = draw(array_shapes)
            fill = draw(array_values)
            arrays[name] = np.full(shape, fill)
        elif name in arrays and arrays[name].size and arrays[name].dtype.kind in 'biuf':
            poisoned = arrays[name].astype(float).copy()
            poisoned.flat[draw(st.integers(0, poisoned.size - 1))] = draw(
                st.floats(allow_nan=True, allow_infinity=True))
            arrays[name] = poisoned
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    data = buffer.getvalue()
    if draw(st.booleans()) and draw(st.booleans()):
        cut = draw(st.integers(0, len(data)))
        data = data[:cut]  # truncated archive
    return data


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                  HealthCheck.function_scoped_fixture])
@given(weight_archives())
def test_any_npz_content_is_refused_with_a_reason_or_usable(tmp_path, data):
    path = tmp_path / 'weights.npz'
    path.write_bytes(data)
    try:
        network = NeuralBaseline.load(path)
    except NeuralBaselineError as error:
        assert str(error).startswith(str(path))
        return
    offsets = network.predict(np.zeros(FEATURE_COUNT))
    assert offsets.shape == (3,)
    decision = scene_decision(chooser_with_network(network))
    if decision.has_best_point:
        assert np.all(np.isfinite(decision.best_point_world))
