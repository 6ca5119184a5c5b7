"""The second look at point stride 1 (core/best_point/second_look.py, matching/matched_again.py).

A rendered scene of the training split whose printed top keeps too few matches at the demo's
point stride 3, and gives its point at stride 1: matched again from the rectified parts its
stride-3 matches carry, it gives exactly the stride-1 matches, and the decision on them.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pytest
from stereo_fuzzy_perception.core.best_point.correlation_area import (
    NO_OBJECT,
    STATUS_OK,
    TOO_FEW_POINTS,
    UNCERTAIN_TOP,
    AreaConfig,
)
from stereo_fuzzy_perception.core.best_point.point_selectors import (
    BestPointChooser,
    BestPointDecision,
)
from stereo_fuzzy_perception.core.best_point.second_look import (
    SECOND_LOOK_FEWEST_POINTS,
    decide_with_second_look,
)
from stereo_fuzzy_perception.core.camera_model import StereoCalibration
from stereo_fuzzy_perception.core.matched_points import RectifiedImage
from stereo_fuzzy_perception.core.matching.matched_again import matched_again
from stereo_fuzzy_perception.core.matching.matcher_config import MatcherInputError
from stereo_fuzzy_perception.core.rig_geometry import StereoRig

# Training scene 19 (seed 1000019): a 20 mm box with a printed top, 28 px across, on rig 4.
THIN_AT_STRIDE_3 = ('train', 5, 19)
# Training scene 65 (seed 1000065): a cylinder with a wood top 32 px across, on rig 16, whose
# face keeps fewer than SECOND_LOOK_FEWEST_POINTS matches at stride 3.
FEW_AT_STRIDE_3 = ('train', 50, 65)


@dataclass(frozen=True)
class Matched:
    stride_1: object
    stride_3: object
    matcher: object
    chooser: BestPointChooser


def _matched(split: str, per_type: int, index: int) -> Matched:
    from stereo_fuzzy_perception.simulation.distribution_source import match_scene
    from stereo_fuzzy_perception.simulation.scene_distribution import split_plan

    scene = match_scene(split_plan(split, per_type)[index].draw(), (1, 3))
    stride_3 = scene.matched[3]
    chooser = replace(BestPointChooser.create('fuzzy_fitted', AreaConfig(), StereoRig()),
                      world_from_camera=stride_3.rig.world_from_left_camera())
    return Matched(scene.matched[1], stride_3, scene.matcher, chooser)


@pytest.fixture(scope='module')
def matched() -> Matched:
    return _matched(*THIN_AT_STRIDE_3)


def _columns(points) -> np.ndarray:
    return np.column_stack([points.xyz, points.u_left, points.v_left, points.u_right,
                            points.score])


def test_matching_again_gives_the_stride_one_matches(matched):
    s3 = matched.stride_3
    again = matched_again(s3.points, StereoCalibration(s3.left, s3.right), matched.matcher, 1)
    np.testing.assert_array_equal(_columns(again), _columns(matched.stride_1.points))
    assert again.left_image is s3.points.left_image
    assert again.right_image is s3.points.right_image


def test_a_face_too_thin_at_stride_3_gets_its_stride_one_point(matched):
    s1, s3, chooser = matched.stride_1, matched.stride_3, matched.chooser
    first = chooser.decide(s3.points, s3.left, s3.right)
    assert first.status == TOO_FEW_POINTS  # what makes this scene the case
    looked = decide_with_second_look(chooser, s3.points, s3.left, s3.right, matched.matcher, 3)
    assert looked.looked and looked.found and looked.decision.status == STATUS_OK
    at_stride_1 = chooser.decide(s1.points, s1.left, s1.right)
    np.testing.assert_array_equal(looked.decision.best_point_world,
                                  at_stride_1.best_point_world)
    error = np.linalg.norm(looked.decision.best_point_world - s3.target_world)
    assert error < 0.003, f'{1000 * error:.1f} mm from the top-face centre'


def test_stride_one_matches_at_hand_stand_for_matching_again(matched):
    s1, s3 = matched.stride_1, matched.stride_3
    looked = decide_with_second_look(matched.chooser, s3.points, s3.left, s3.right, None, 3,
                                     at_stride_one=s1.points)
    rematched = decide_with_second_look(matched.chooser, s3.points, s3.left, s3.right,
                                        matched.matcher, 3)
    assert looked.looked and looked.decision.status == STATUS_OK
    np.testing.assert_array_equal(looked.decision.best_point_world,
                                  rematched.decision.best_point_world)


@pytest.mark.parametrize('matcher_known, stride', [(True, 1), (True, 0), (False, 3)])
def test_no_second_look_without_a_coarse_stride_or_settings(matched, matcher_known, stride):
    s3 = matched.stride_3
    looked = decide_with_second_look(matched.chooser, s3.points, s3.left, s3.right,
                                     matched.matcher if matcher_known else None, stride)
    assert not looked.looked and looked.decision.status == TOO_FEW_POINTS


def test_parts_outside_the_image_leave_the_first_decision_and_say_so(matched):
    s3 = matched.stride_3
    right = s3.points.right_image
    points = replace(s3.points, right_image=RectifiedImage(right.pixels, 200, right.y,
                                                          right.window_size))
    with pytest.raises(MatcherInputError, match='does not lie inside'):
        matched_again(points, StereoCalibration(s3.left, s3.right), matched.matcher)
    looked = decide_with_second_look(matched.chooser, points, s3.left, s3.right,
                                     matched.matcher, 3)
    assert not looked.looked and looked.decision.status == TOO_FEW_POINTS
    assert 'not matched again at point stride 1' in looked.decision.reason


class _Refusing:
    """A chooser that refuses every pair with one status, counting its calls."""

    def __init__(self, status: str) -> None:
        self.status, self.calls = status, 0

    def decide(self, points, left, right) -> BestPointDecision:
        self.calls += 1
        return BestPointDecision('stub', status=self.status, reason=f'call {self.calls}')


@pytest.mark.parametrize('status, looks', [(TOO_FEW_POINTS, True), (UNCERTAIN_TOP, True),
                                           (NO_OBJECT, False)])
def test_only_a_face_too_thin_is_looked_at_again(matched, status, looks):
    s3 = matched.stride_3
    chooser = _Refusing(status)
    looked = decide_with_second_look(chooser, s3.points, s3.left, s3.right,  # type: ignore
                                     matched.matcher, 3)
    assert looked.looked == looks and chooser.calls == (2 if looks else 1)
    assert looked.decision.status == status
    if looks:  # the first refusal stands, with what the second look found
        assert looked.decision.reason == (f'call 1; matched again at point stride 1: '
                                          f'{status}: call 2')


def test_a_pair_matched_in_a_region_is_matched_again_in_it():
    from stereo_fuzzy_perception.core.matching.window_matcher import MatcherConfig
    from stereo_fuzzy_perception.simulation.distribution_source import match_scene
    from stereo_fuzzy_perception.simulation.scene_distribution import split_plan

    split, per_type, index = THIN_AT_STRIDE_3
    drawn = split_plan(split, per_type)[index].draw()
    region = MatcherConfig(roi=(150, 100, 320, 240))
    coarse = match_scene(drawn, (3,), base_matcher=region)  # only stride 3's rows matched
    fine = match_scene(drawn, (1,), base_matcher=region)
    s3 = coarse.matched[3]
    part = s3.points.left_image
    assert part.pixels.shape[1] < s3.left.width, 'the parts cover the region, not the image'
    again = matched_again(s3.points, StereoCalibration(s3.left, s3.right), coarse.matcher, 1)
    np.testing.assert_array_equal(_columns(again), _columns(fine.matched[1].points))
    assert len(again) > 5 * len(s3.points)


def test_a_face_of_few_matches_at_stride_3_gets_its_stride_one_point():
    # Its outline starts from the hull of a few dozen matches and the point lies a centimetre
    # off; at stride 1 the same top holds nine times as many.
    few = _matched(*FEW_AT_STRIDE_3)
    s1, s3, chooser = few.stride_1, few.stride_3, few.chooser
    first = chooser.decide(s3.points, s3.left, s3.right)
    assert first.status == STATUS_OK and first.points_used < SECOND_LOOK_FEWEST_POINTS
    looked = decide_with_second_look(chooser, s3.points, s3.left, s3.right, few.matcher, 3)
    assert looked.looked
    np.testing.assert_array_equal(looked.decision.best_point_world,
                                  chooser.decide(s1.points, s1.left, s1.right).best_point_world)
    error = np.linalg.norm(looked.decision.best_point_world - s3.target_world)
    assert error < 0.003, f'{1000 * error:.1f} mm from the top-face centre'


class _Scripted:
    """A chooser that gives its decisions in turn."""

    def __init__(self, *decisions: BestPointDecision) -> None:
        self.decisions, self.calls = list(decisions), 0

    def decide(self, points, left, right) -> BestPointDecision:
        self.calls += 1
        return self.decisions[self.calls - 1]


def _point(points_used: int, x: float) -> BestPointDecision:
    return BestPointDecision('stub', points_used=points_used,
                             best_point_world=np.array([x, 0.0, 0.0]))


@pytest.mark.parametrize('points_used, looks', [(SECOND_LOOK_FEWEST_POINTS - 1, True),
                                                (SECOND_LOOK_FEWEST_POINTS, False)])
def test_a_point_on_few_matches_is_looked_at_again(matched, points_used, looks):
    s3 = matched.stride_3
    chooser = _Scripted(_point(points_used, 0.1), _point(500, 0.2))
    looked = decide_with_second_look(chooser, s3.points, s3.left, s3.right,  # type: ignore
                                     matched.matcher, 3)
    assert looked.looked == looks and looked.found == looks
    assert chooser.calls == (2 if looks else 1)
    assert looked.decision.best_point_world[0] == (0.2 if looks else 0.1)


def test_a_point_on_few_matches_stands_when_stride_one_refuses(matched):
    s3 = matched.stride_3
    chooser = _Scripted(_point(SECOND_LOOK_FEWEST_POINTS - 1, 0.1),
                        BestPointDecision('stub', status=UNCERTAIN_TOP, reason='scattered'))
    looked = decide_with_second_look(chooser, s3.points, s3.left, s3.right,  # type: ignore
                                     matched.matcher, 3)
    assert looked.looked and not looked.found and looked.decision.status == STATUS_OK
    assert looked.decision.best_point_world[0] == 0.1
