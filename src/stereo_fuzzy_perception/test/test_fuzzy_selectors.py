"""BestPointChooser: every selector, the decision's bookkeeping and its properties."""

import dataclasses

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.optimize import nnls
from stereo_fuzzy_perception.core.best_point import point_selectors
from stereo_fuzzy_perception.core.best_point.correlation_area import (
    DEGENERATE_AREA,
    NO_POINTS,
    STATUS_OK,
    AreaConfig,
)
from stereo_fuzzy_perception.core.best_point.point_selectors import (
    SELECTORS,
    BestPointChooser,
    SelectorError,
)
from stereo_fuzzy_perception.core.matched_points import MatchedPoints
from stereo_fuzzy_perception.core.rig_geometry import StereoRig, transform_points
from stereo_fuzzy_perception.simulation.synthetic_scenes import OBJECT_TYPES, GeometricSceneSource

RIG = StereoRig()
SOURCE = GeometricSceneSource(point_spacing_m=0.002)
CHOOSERS = {name: BestPointChooser.create(name, AreaConfig(), RIG) for name in SELECTORS}
SCENES = [SOURCE.scene(np.random.default_rng(seed), OBJECT_TYPES[seed % 4])
          for seed in range(40)]


def horizontal_errors(name):
    chooser = CHOOSERS[name]
    errors = []
    for scene in SCENES:
        decision = chooser.decide(scene.points, scene.left, scene.right)
        assert decision.has_best_point, decision.status_text()
        errors.append(np.hypot(*(decision.best_point_world[:2] - scene.target_world[:2])))
    return 1000.0 * np.array(errors)


def test_fitted_rule_base_beats_the_chapter_and_the_centroid():
    fitted, chapter, centroid = (horizontal_errors(name) for name in (
        'fuzzy_fitted', 'fuzzy_chapter', 'centroid'))
    assert fitted.mean() < 1.5, f'fitted mean error {fitted.mean():.2f} mm'
    assert fitted.mean() < centroid.mean() < chapter.mean()


def test_neural_network_baseline_finds_the_top_centre():
    errors = horizontal_errors('neural_network')
    assert errors.mean() < 2.0, f'neural network mean error {errors.mean():.2f} mm'


def test_decision_is_consistent_with_the_scene():
    scene = SCENES[3]
    decision = CHOOSERS['fuzzy_chapter'].decide(scene.points, scene.left, scene.right)
    assert decision.status == STATUS_OK and decision.rule_base == 'chapter'
    assert len(decision.rule_names) == len(decision.firing_strengths) == 12
    np.testing.assert_allclose(decision.membership_degrees, decision.firing_strengths)
    assert decision.points_in == len(scene.points)
    assert decision.points_used == int(decision.area_point_counts.sum())
    assert decision.best_point_world[2] == pytest.approx(decision.top_height)
    camera = transform_points(RIG.world_from_left_camera(), decision.best_point_camera[None])
    np.testing.assert_allclose(camera[0], decision.best_point_world, atol=1e-12)
    np.testing.assert_allclose(decision.ratio, decision.d1 / decision.d2)
    weights = decision.firing_strengths / decision.firing_strengths.sum()
    np.testing.assert_allclose(weights @ decision.consequent_points, decision.eq10_point)


def test_max_score_picks_the_best_scored_point_of_the_area():
    scene = SCENES[0]
    points = scene.points.subset(np.arange(len(scene.points)))
    decision = CHOOSERS['centroid'].decide(points, scene.left, scene.right)
    world = transform_points(RIG.world_from_left_camera(), points.xyz)
    in_area = np.flatnonzero(np.abs(world[:, 2] - decision.top_height) < 0.001)
    points.score[in_area[5]] = 2.0
    best = CHOOSERS['max_score'].decide(points, scene.left, scene.right)
    np.testing.assert_allclose(best.best_point_world[:2], world[in_area[5], :2])


def test_unknown_selector_and_bad_files_are_refused(tmp_path):
    with pytest.raises(SelectorError, match="'median' is not one of"):
        BestPointChooser.create('median', AreaConfig(), RIG)
    bad = tmp_path / 'bad.yaml'
    bad.write_text('name: x\nmembership_functions: []\nrules: []\n')
    with pytest.raises(SelectorError, match='membership_functions: expected a non-empty'):
        BestPointChooser.create('fuzzy_fitted', AreaConfig(), RIG, rule_base_file=str(bad))
    with pytest.raises(SelectorError, match='cannot read network weights'):
        BestPointChooser.create('neural_network', AreaConfig(), RIG,
                                weights_file=str(tmp_path / 'none.npz'))


@pytest.mark.parametrize('name', SELECTORS)
def test_empty_input_yields_a_reason_not_an_exception(name):
    scene = SCENES[0]
    decision = CHOOSERS[name].decide(MatchedPoints.empty(), scene.left, scene.right)
    assert not decision.has_best_point
    assert decision.status == NO_POINTS
    assert decision.status_text().startswith('no_points: ')


@pytest.mark.parametrize('name', ['fuzzy_fitted', 'fuzzy_chapter', 'neural_network'])
def test_points_on_one_image_column_are_degenerate(name, monkeypatch):
    scene = SCENES[0]
    found = point_selectors.find_correlation_area(scene.points, RIG.world_from_left_camera(),
                                                  AreaConfig())
    assert found.status == STATUS_OK
    one_column = dataclasses.replace(found, u_left=np.full(found.points_used, 300.0))
    monkeypatch.setattr(point_selectors, 'find_correlation_area',
                        lambda *args: one_column)
    decision = CHOOSERS[name].decide(scene.points, scene.left, scene.right)
    assert not decision.has_best_point
    assert decision.status == DEGENERATE_AREA, decision.status_text()


fuzzy_selectors = st.sampled_from(['fuzzy_fitted', 'fuzzy_chapter'])
any_selector = st.sampled_from(SELECTORS)
scene_index = st.integers(0, len(SCENES) - 1)
property_settings = settings(max_examples=40, deadline=None,
                             suppress_health_check=[HealthCheck.too_slow])


def subsample(scene, seed):
    """A random subset (so each example differs) of a scene's points."""
    rng = np.random.default_rng(seed)
    keep = rng.uniform(size=len(scene.points)) < rng.uniform(0.3, 1.0)
    return scene.points.subset(keep)


@property_settings
@given(name=fuzzy_selectors, index=scene_index, seed=st.integers(0, 2**32 - 1))
def test_eq10_point_lies_in_the_convex_hull_of_the_consequents(name, index, seed):
    scene = SCENES[index]
    decision = CHOOSERS[name].decide(subsample(scene, seed), scene.left, scene.right)
    if decision.eq10_point is None:
        assert decision.status != STATUS_OK
        return
    points = decision.consequent_points
    assert np.all(decision.eq10_point >= points.min(axis=0) - 1e-12)
    assert np.all(decision.eq10_point <= points.max(axis=0) + 1e-12)
    _, residual = nnls(np.vstack([points.T, np.ones(len(points))]),
                       np.concatenate([decision.eq10_point, [1.0]]))
    assert residual < 1e-9


def comparable(decision):
    return {
        'status': decision.status,
        'best': None if decision.best_point_world is None else decision.best_point_world,
        'counts': (decision.points_valid, decision.clusters_found, decision.points_used),
        'border_points': decision.border_points,
        'areas': decision.area_point_counts,
        'ratio': decision.ratio,
        'strengths': decision.firing_strengths,
    }


def assert_same(first, second):
    a, b = comparable(first), comparable(second)
    assert a['status'] == b['status'] and a['counts'] == b['counts']
    if a['best'] is None:
        assert b['best'] is None
    else:
        np.testing.assert_allclose(a['best'], b['best'], atol=1e-12, rtol=0)
    for key in ('border_points', 'areas', 'ratio', 'strengths'):
        np.testing.assert_allclose(a[key], b[key], atol=1e-9, rtol=0, err_msg=key)


@property_settings
@given(name=any_selector, index=scene_index, seed=st.integers(0, 2**32 - 1))
def test_permuting_the_points_changes_nothing(name, index, seed):
    scene = SCENES[index]
    points = subsample(scene, seed)
    order = np.random.default_rng(seed).permutation(len(points))
    chooser = CHOOSERS[name]
    assert_same(chooser.decide(points, scene.left, scene.right),
                chooser.decide(points.subset(order), scene.left, scene.right))


@property_settings
@given(name=any_selector, index=scene_index, seed=st.integers(0, 2**32 - 1),
       bad=st.lists(st.tuples(st.integers(0, 4), st.sampled_from([np.nan, np.inf, -np.inf])),
                    min_size=1, max_size=20))
def test_nan_and_infinite_points_are_ignored(name, index, seed, bad):
    scene = SCENES[index]
    points = subsample(scene, seed)
    rng = np.random.default_rng(seed)
    rows = rng.integers(0, len(points), len(bad))
    spoiled = MatchedPoints(points.xyz.copy(), points.u_left.copy(), points.v_left.copy(),
                            points.u_right.copy(), points.score.copy())
    for row, (column, value) in zip(rows, bad, strict=True):
        if column == 0:
            spoiled.xyz[row, rng.integers(0, 3)] = value
        else:
            (spoiled.u_left, spoiled.v_left, spoiled.u_right, spoiled.score)[column - 1][row] = (
                value)
    finite = np.ones(len(points), dtype=bool)
    finite[rows] = False
    chooser = CHOOSERS[name]
    with_bad = chooser.decide(spoiled, scene.left, scene.right)
    without = chooser.decide(points.subset(finite), scene.left, scene.right)
    assert with_bad.points_in == len(points)
    assert_same(with_bad, without)


@property_settings
@given(name=any_selector, count=st.integers(0, 60),
       start=st.tuples(st.floats(0.05, 0.35), st.floats(0.05, 0.25), st.floats(0.01, 0.1)),
       step=st.tuples(st.floats(-1e-3, 1e-3), st.floats(-1e-3, 1e-3)))
def test_points_on_a_line_or_nothing_give_a_decision_never_an_exception(name, count, start,
                                                                        step):
    scene = SCENES[0]
    world = np.array(start) + np.outer(np.arange(count), [step[0], step[1], 0.0])
    camera = transform_points(np.linalg.inv(RIG.world_from_left_camera()), world)
    rectified = camera @ scene.left.R.T
    homogeneous = np.column_stack([rectified, np.ones(count)])
    left = homogeneous @ scene.left.P.T
    right = homogeneous @ scene.right.P.T
    points = MatchedPoints(camera, left[:, 0] / left[:, 2], left[:, 1] / left[:, 2],
                           right[:, 0] / right[:, 2], np.ones(count))
    decision = CHOOSERS[name].decide(points, scene.left, scene.right)
    if decision.has_best_point:
        assert decision.status == STATUS_OK and np.all(np.isfinite(decision.best_point_world))
    else:
        assert decision.status != STATUS_OK and decision.reason
