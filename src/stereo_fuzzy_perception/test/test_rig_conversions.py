"""Transforms <-> TransformStamped / TFMessage, and a decision -> MarkerArray."""

import math

import numpy as np
import pytest

pytestmark = pytest.mark.ros


def test_transform_round_trips_through_tf_message():
    from builtin_interfaces.msg import Time
    from stereo_fuzzy_perception.core.rig_geometry import StereoRig
    from stereo_fuzzy_perception.core.rig_pose import chapter_left_camera_transform
    from stereo_fuzzy_perception.nodes.conversions import (
        tf_message_to_transforms,
        transforms_to_tf_message,
    )

    transform = chapter_left_camera_transform(StereoRig(alpha_deg=30.0, theta_deg=-20.0))
    msg = transforms_to_tf_message([transform], Time(sec=7, nanosec=5))
    assert msg.transforms[0].header.stamp == Time(sec=7, nanosec=5)
    assert msg.transforms[0].header.frame_id == 'world'
    assert tf_message_to_transforms(msg) == [transform]


def test_unusable_transforms_are_left_out_not_raised():
    from builtin_interfaces.msg import Time
    from stereo_fuzzy_perception.core.frame_transforms import Transform
    from stereo_fuzzy_perception.nodes.conversions import (
        tf_message_to_transforms,
        transforms_to_tf_message,
    )

    good = Transform('world', 'a', (0.0, 0.0, 1.0), (0.0, 0.0, 0.0, 1.0))
    msg = transforms_to_tf_message([good, good, good, good], Time())
    msg.transforms[1].transform.rotation.w = 0.0             # not a rotation
    msg.transforms[2].transform.translation.x = math.nan      # unknown
    msg.transforms[3].child_frame_id = 'world'               # parent of itself
    assert tf_message_to_transforms(msg) == [good]


def test_markers_of_a_refused_decision_only_clear_the_previous_ones():
    from std_msgs.msg import Header
    from stereo_fuzzy_perception.core.best_point.point_selectors import BestPointDecision
    from stereo_fuzzy_perception.nodes.conversions import decision_to_markers
    from visualization_msgs.msg import Marker

    refused = BestPointDecision('fuzzy_fitted', status='no_points', reason='none')
    markers = decision_to_markers(refused, Header(frame_id='world')).markers
    assert [marker.action for marker in markers] == [Marker.DELETEALL]


def test_markers_skip_unknown_centres_and_number_the_known_ones():
    from std_msgs.msg import Header
    from stereo_fuzzy_perception.core.best_point.point_selectors import BestPointDecision
    from stereo_fuzzy_perception.nodes.conversions import decision_to_markers
    from visualization_msgs.msg import Marker

    decision = BestPointDecision('centroid')
    decision.area_centres = np.array([[0.1, 0.1, 0.05], [np.nan] * 3, [0.2, 0.1, 0.05],
                                      [0.2, 0.2, 0.05]])
    decision.area_points_world = np.array([[0.1, 0.1, 0.05], [np.nan, 0.0, 0.0]])
    decision.best_point_world = np.array([0.15, 0.15, 0.05])
    markers = decision_to_markers(decision, Header(frame_id='world')).markers
    by_id = {marker.id: marker for marker in markers[1:]}
    assert len(by_id[0].points) == 1                       # the NaN point left out
    assert 1 not in by_id                                  # no border points known
    assert [by_id[i].text for i in (6, 8, 9)] == ['1', '3', '4'] and 7 not in by_id
    assert by_id[10].type == Marker.SPHERE
    assert by_id[10].pose.position.x == pytest.approx(0.15)
    assert all(marker.ns == 'best_point' for marker in markers)
