"""Fuzzification and Eq. 10 agree with simpful (zero-order Sugeno) and keep their properties."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import nnls
from stereo_fuzzy_perception.core.best_point.correlation_area import STATUS_OK
from stereo_fuzzy_perception.core.best_point.four_areas import FourAreas
from stereo_fuzzy_perception.core.best_point.fuzzy_inference import infer, triangular_degree
from stereo_fuzzy_perception.core.best_point.rule_base import (
    FuzzyRule,
    RuleBase,
    TriangularTerm,
    packaged_rule_base,
)

simpful = pytest.importorskip('simpful')


def random_rule_base(rng: np.random.Generator) -> RuleBase:
    """The chapter's structure with random break points, consequent areas and offsets."""
    low = rng.uniform(0.2, 0.9)
    high = rng.uniform(1.1, 3.0)
    terms = (TriangularTerm('less', low, low, 1.0), TriangularTerm('equal', low, 1.0, high),
             TriangularTerm('greater', 1.0, high, high))
    rules = []
    for area in range(1, 5):
        for term in ('greater', 'equal', 'less'):
            count = int(rng.integers(1, 5))
            areas = tuple(int(k) for k in rng.choice([1, 2, 3, 4], count, replace=False))
            offset = tuple(float(o) for o in rng.normal(0.0, 0.005, 3))
            rules.append(FuzzyRule(f'area{area}_{term}', area, term, areas, offset))
    return RuleBase('random', '', terms, tuple(rules))


def four_areas(ratios: np.ndarray, centres: np.ndarray, counts: np.ndarray) -> FourAreas:
    nan4 = np.full(4, np.nan)
    return FourAreas(STATUS_OK, '', np.zeros((4, 3)), np.zeros(6), centres.mean(axis=0),
                     centres, nan4, nan4, nan4, counts, np.asarray(counts, dtype=float), nan4,
                     nan4, ratios)


def simpful_eq10(rule_base: RuleBase, ratios: np.ndarray, consequents: np.ndarray
                 ) -> tuple[np.ndarray, dict[str, float]]:
    """Eq. 10 per coordinate with simpful: three zero-order Sugeno outputs x, y, z."""
    system = simpful.FuzzySystem(show_banner=False, verbose=False)
    for area in range(1, 5):
        sets = [simpful.TriangleFuzzySet(t.a, t.b, t.c, term=t.name) for t in rule_base.terms]
        system.add_linguistic_variable(f'r{area}', simpful.LinguisticVariable(
            sets, universe_of_discourse=[0.0, 10.0]))
        system.set_variable(f'r{area}', float(ratios[area - 1]))
    rules = []
    for index, rule in enumerate(rule_base.rules):
        for axis, coordinate in enumerate('xyz'):
            name = f'{coordinate}{index}'
            system.set_crisp_output_value(name, float(consequents[index, axis]))
            rules.append(f'IF (r{rule.area} IS {rule.term}) THEN ({coordinate} IS {name})')
    system.add_rules(rules)
    output = system.Sugeno_inference(['x', 'y', 'z'])
    degrees = {}
    for term in rule_base.terms:
        fuzzy_set = simpful.TriangleFuzzySet(term.a, term.b, term.c, term=term.name)
        for area in range(1, 5):
            degrees[f'{area}{term.name}'] = float(fuzzy_set.get_value(ratios[area - 1]))
    return np.array([output['x'], output['y'], output['z']]), degrees


def union_centre(centres: np.ndarray, counts: np.ndarray, areas: tuple[int, ...]) -> np.ndarray:
    index = np.array(areas) - 1
    return (counts[index, None] * centres[index]).sum(axis=0) / counts[index].sum()


def test_membership_and_eq10_match_simpful_on_random_inputs_and_break_points():
    rng = np.random.default_rng(7)
    compared = 0
    for case in range(2500):
        rule_base = packaged_rule_base('fuzzy_chapter') if case % 5 == 0 else random_rule_base(
            rng)
        breaks = np.array([[t.a, t.b, t.c] for t in rule_base.terms]).ravel()
        ratios = rng.uniform(0.0, 3.5, 4)
        if case % 3 == 0:  # exactly on break points, where off-by-one comparisons would show
            ratios = rng.choice(breaks, 4)
        centres = rng.uniform(-0.2, 0.4, (4, 3))
        counts = rng.integers(1, 500, 4).astype(float)
        result = infer(rule_base, four_areas(ratios, centres, counts))
        consequents = np.array([union_centre(centres, counts, rule.consequent_areas)
                                + np.array(rule.offset_m) for rule in rule_base.rules])
        np.testing.assert_allclose(result.consequent_points, consequents, atol=1e-12)
        if result.point is None:
            assert all(triangular_degree(r, t) == 0.0 for r in ratios for t in rule_base.terms)
            continue
        expected, degrees = simpful_eq10(rule_base, ratios, consequents)
        for index, rule in enumerate(rule_base.rules):
            assert result.membership_degrees[index] == pytest.approx(
                degrees[f'{rule.area}{rule.term}'], abs=1e-12), (rule, ratios)
        np.testing.assert_allclose(result.point, expected, atol=1e-12, err_msg=str(ratios))
        compared += 1
    assert compared > 2000


@pytest.mark.parametrize(('x', 'expected'), [
    (0.0, 1.0), (0.5, 1.0), (0.75, 0.5), (1.0, 0.0), (2.0, 0.0), (np.nan, 0.0)])
def test_left_shoulder_degrees(x, expected):
    assert float(triangular_degree(x, TriangularTerm('less', 0.5, 0.5, 1.0))) == pytest.approx(
        expected)


@pytest.mark.parametrize(('x', 'expected'), [
    (0.4, 0.0), (0.5, 0.0), (0.75, 0.5), (1.0, 1.0), (1.5, 0.5), (2.0, 0.0), (np.inf, 0.0)])
def test_triangle_degrees(x, expected):
    assert float(triangular_degree(x, TriangularTerm('equal', 0.5, 1.0, 2.0))) == pytest.approx(
        expected)


ratio_values = st.floats(min_value=0.0, max_value=5.0, allow_nan=False)
coordinate = st.floats(min_value=-1.0, max_value=1.0, allow_nan=False)


@settings(max_examples=300, deadline=None)
@given(ratios=st.lists(ratio_values, min_size=4, max_size=4),
       centres=st.lists(st.lists(coordinate, min_size=3, max_size=3), min_size=4, max_size=4),
       counts=st.lists(st.integers(1, 1000), min_size=4, max_size=4),
       seed=st.integers(0, 2**32 - 1))
def test_eq10_point_is_a_convex_combination_of_the_consequents(ratios, centres, counts, seed):
    rule_base = random_rule_base(np.random.default_rng(seed))
    result = infer(rule_base, four_areas(np.array(ratios), np.array(centres),
                                         np.array(counts, dtype=float)))
    if result.point is None:
        assert not np.any(result.firing_strengths > 0.0)
        return
    points = result.consequent_points
    assert np.all(result.point >= points.min(axis=0) - 1e-12)
    assert np.all(result.point <= points.max(axis=0) + 1e-12)
    # lambda >= 0 with sum(lambda) = 1 and sum(lambda y_l) = y*: a convex combination
    system = np.vstack([points.T, 100.0 * np.ones(len(points))])
    target = np.concatenate([result.point, [100.0]])
    _, residual = nnls(system, target)
    assert residual < 1e-9
