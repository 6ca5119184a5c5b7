"""A second look at point stride 1, for a pair whose object's face is too thin at a coarser one,
or decided on few matches there.

At the demo's point_stride 3 the correlation area can find the object and still refuse its top
face: too few matches on it (`too_few_points`), or too few to tell its scatter from a side
wall's (`uncertain_top`). Printed and low-texture tops are matched only in places, and a small
top keeps a ninth of those places. The same pair at stride 1 often gives a point, so the
pair is matched again at stride 1 from the rectified parts its matches carry
(core/matching/matched_again.py) and decided again. A face decided on fewer than
SECOND_LOOK_FEWEST_POINTS matches gets the same second look: its outline starts from the hull
of a few dozen matches, and on a small top that can put the point a centimetre off. Only
those get a second look: a pair where no object stands out (`no_object`) is refused at stride 1
as it is at stride 3 on most pairs, and where it is not the points were no better (the package
README, "A second look at point stride 1").
ROS-free.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from stereo_fuzzy_perception.core.best_point.correlation_area import STATUS_OK
from stereo_fuzzy_perception.core.best_point.point_selectors import (
    FACE_TOO_THIN,
    BestPointChooser,
    BestPointDecision,
)
from stereo_fuzzy_perception.core.camera_model import CameraCalibration, StereoCalibration
from stereo_fuzzy_perception.core.matched_points import MatchedPoints
from stereo_fuzzy_perception.core.matching.matched_again import matched_again
from stereo_fuzzy_perception.core.matching.matcher_config import MatcherInputError
from stereo_fuzzy_perception.core.matching.window_matcher import MatcherConfig

SECOND_LOOK_STATUSES = FACE_TOO_THIN
"""Refusals of a face found too thin at a coarse stride: the ones a second look can change."""

SECOND_LOOK_FEWEST_POINTS = 40
"""A face given a point at a coarse stride on fewer matches than this is decided again at
stride 1 too, where the same top holds about stride^2 times as many; the stride-1 point is
taken when there is one, and a refusal there leaves the first point (why, measured: the
package README, "A second look at point stride 1")."""


@dataclass(frozen=True)
class SecondLook:
    """A decision and whether the pair was matched again for it.

    Attributes:
        decision: The decision to publish: the second look's when it gave a point, else the
            first (a refusal's reason then ends with the second look's).
        looked: The pair was matched again at stride 1.
        found: The decision is the second look's point.
    """

    decision: BestPointDecision
    looked: bool = False
    found: bool = False


def decide_with_second_look(chooser: BestPointChooser, points: MatchedPoints,
                            left: CameraCalibration, right: CameraCalibration,
                            matcher: MatcherConfig | None, point_stride: int,
                            threads: int | None = None,
                            at_stride_one: MatchedPoints | None = None) -> SecondLook:
    """Decide on the matches; at a point stride above 1, look again at stride 1 when the face
    found is refused as too thin (SECOND_LOOK_STATUSES), or given a point on fewer than
    SECOND_LOOK_FEWEST_POINTS matches.

    Args:
        chooser: The best-point chooser, posed.
        points: The matches, with the rectified parts the matcher read.
        left: Rectified calibration of the left image.
        right: Rectified calibration of the right image.
        matcher: The matcher settings the points were produced with; None: no second look
            (unless at_stride_one is given).
        point_stride: The points' stride; 0 (unknown) or 1: no second look.
        threads: The matcher's threads for the second look (None: its default).
        at_stride_one: The same pair's stride-1 matches when already at hand (a tool that
            matched both strides), used instead of matching again.

    Returns:
        The decision, and whether the pair was matched again. Image parts or a region that do
        not fit the rectified images leave the first decision, its reason saying so.
    """
    decision = chooser.decide(points, left, right)
    few_points = (decision.status == STATUS_OK
                  and decision.points_used < SECOND_LOOK_FEWEST_POINTS)
    if point_stride <= 1 or (decision.status not in SECOND_LOOK_STATUSES and not few_points):
        return SecondLook(decision)
    again = at_stride_one
    if again is None:
        if matcher is None or points.left_image is None or points.right_image is None:
            return SecondLook(decision)
        try:
            again = matched_again(points, StereoCalibration(left, right), matcher, 1, threads)
        except MatcherInputError as error:  # parts or a region that do not fit the images
            return SecondLook(replace(decision, reason=f'{decision.reason}; not matched again '
                                                       f'at point stride 1: {error}'))
        if again is None:
            return SecondLook(decision)
    second = chooser.decide(again, left, right)
    if second.status == STATUS_OK:
        return SecondLook(second, looked=True, found=True)
    if few_points:
        return SecondLook(decision, looked=True)
    return SecondLook(_with_second_reason(decision, second), looked=True)


def _with_second_reason(first: BestPointDecision, second: BestPointDecision
                        ) -> BestPointDecision:
    return replace(first, reason=f'{first.reason}; matched again at point stride 1: '
                                 f'{second.status}: {second.reason}')
