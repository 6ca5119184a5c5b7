"""Rule base files load, round-trip, and name the bad entry when they are wrong."""

import copy

import pytest
import yaml
from stereo_fuzzy_perception.core.best_point.rule_base import (
    RuleBaseError,
    load_rule_base,
    packaged_rule_base,
    rule_base_from_dict,
    rule_base_to_dict,
    save_rule_base,
)


def test_packaged_chapter_rule_base_is_the_chapters_twelve_rules():
    chapter = packaged_rule_base('fuzzy_chapter')
    assert [term.name for term in chapter.terms] == ['less', 'equal', 'greater']
    assert len(chapter.rules) == 12
    expected = {'greater': (1, 2), 'equal': (1, 2, 3, 4), 'less': (3, 4)}
    for area in range(1, 5):
        rules = [rule for rule in chapter.rules if rule.area == area]
        assert {rule.term: rule.consequent_areas for rule in rules} == expected
        assert all(rule.offset_m == (0.0, 0.0, 0.0) for rule in rules)
    assert chapter.height_offset_m == 0.0


def test_packaged_fitted_rule_base_keeps_the_chapter_structure():
    chapter = packaged_rule_base('fuzzy_chapter')
    fitted = packaged_rule_base('fuzzy_fitted')
    assert fitted.terms == chapter.terms
    assert [(r.area, r.term) for r in fitted.rules] == [(r.area, r.term) for r in chapter.rules]
    assert any(rule.offset_m != (0.0, 0.0, 0.0) for rule in fitted.rules)


def test_rule_base_round_trips_through_a_file(tmp_path):
    fitted = packaged_rule_base('fuzzy_fitted')
    path = tmp_path / 'copy.yaml'
    save_rule_base(fitted, path, 'a header\nsecond line')
    assert path.read_text().startswith('# a header\n# second line\n')
    assert load_rule_base(path) == fitted


def mutate(path, value):
    def apply(document):
        target = document
        for key in path[:-1]:
            target = target[key]
        if value is DELETE:
            del target[path[-1]]
        else:
            target[path[-1]] = value
        return document
    return apply


DELETE = object()
BAD_ENTRIES = [
    (mutate(('membership_functions', 1, 'points'), [1.0, 0.5, 2.0]),
     r"membership function 'equal': break points 1.0, 0.5, 2.0"),
    (mutate(('membership_functions', 0, 'points'), [0.5, 0.5]),
     r"membership function 'less': points \[0.5, 0.5\]"),
    (mutate(('rules', 4, 'if'), 'huge'), r"rule 'area2_equal': premise term 'huge'"),
    (mutate(('rules', 0, 'area'), 5), r"rule 'area1_greater': area 5"),
    (mutate(('rules', 2, 'then', 'areas'), [3, 3]), r"rule 'area1_less': then.areas"),
    (mutate(('rules', 2, 'then', 'offset_m'), [0, 'x', 0]),
     r"rule 'area1_less' then.offset_m: 'x'"),
    (mutate(('rules', 3, 'then'), DELETE), r"rule 'area2_greater': missing key\(s\) then"),
    (mutate(('height_offset_m',), float('nan')), 'height_offset_m: nan'),
    (mutate(('colour',), 'red'), r'unknown key\(s\) colour'),
]


@pytest.mark.parametrize(('change', 'message'), BAD_ENTRIES)
def test_bad_entry_is_named(tmp_path, change, message):
    document = change(copy.deepcopy(rule_base_to_dict(packaged_rule_base('fuzzy_chapter'))))
    path = tmp_path / 'bad.yaml'
    path.write_text(yaml.safe_dump(document))
    with pytest.raises(RuleBaseError, match=message) as error:
        load_rule_base(path)
    assert str(path) in str(error.value)


def test_missing_file_and_bad_yaml_are_reported(tmp_path):
    with pytest.raises(RuleBaseError, match='cannot read'):
        load_rule_base(tmp_path / 'missing.yaml')
    (tmp_path / 'bad.yaml').write_text('rules: [\n')
    with pytest.raises(RuleBaseError, match='not valid YAML'):
        load_rule_base(tmp_path / 'bad.yaml')
    with pytest.raises(RuleBaseError, match='expected a mapping'):
        rule_base_from_dict(['not', 'a', 'mapping'])
