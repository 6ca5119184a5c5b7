"""fuzzy_best_point_node as a process, attacked as a hostile peer on the ROS domain would.

Issue #15 items 1, 5, 7, 8 and 10 against the installed executable: malformed files set through
the real set_parameters service are refused with a reason and the node lives on; no non-finite
or out-of-workspace best point is ever published; inconsistent PointCloud2 layouts give
`malformed_input`; gaps in StereoMatches sequence numbers are counted on /diagnostics; and a
hypothesis property test sets random values on every parameter.
"""

from __future__ import annotations

import copy
import math
import os
from pathlib import Path

import numpy as np
import pytest
import yaml
from hostile_probe import HostileProbe
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

pytestmark = pytest.mark.ros

NODE = 'fuzzy_best_point_node'


def matches_message(sequence: int = 0, seed: int = 3):
    from std_msgs.msg import Header
    from stereo_fuzzy_perception.nodes.conversions import (
        calibration_to_camera_info,
        matched_points_to_cloud,
    )
    from stereo_fuzzy_perception.simulation.synthetic_scenes import GeometricSceneSource

    from stereo_fuzzy_msgs.msg import StereoMatches

    scene = GeometricSceneSource().scene(np.random.default_rng(seed), 'cubic_square')
    header = Header(frame_id='left_camera_optical_frame')
    header.stamp.sec = sequence
    msg = StereoMatches(header=header, method='zncc', window_size=9, sequence=sequence)
    msg.left_info = calibration_to_camera_info(scene.left, header)
    msg.right_info = calibration_to_camera_info(scene.right, header)
    msg.points = matched_points_to_cloud(scene.points, header)
    return msg


class FuzzyTarget(HostileProbe):
    """The probe plus a StereoMatches publisher and best_point / decision recorders."""

    def __init__(self, context, process):
        super().__init__(context, process, NODE)
        from geometry_msgs.msg import PointStamped
        from stereo_fuzzy_perception.nodes import qos

        from stereo_fuzzy_msgs.msg import FuzzyDecision, StereoMatches

        self.points: list = []
        self.decisions: list = []
        self.node.create_subscription(PointStamped, 'best_point', self.points.append,
                                      qos.RESULTS)
        self.node.create_subscription(FuzzyDecision, 'best_point/decision',
                                      self.decisions.append, qos.RESULTS)
        self.publisher = self.node.create_publisher(StereoMatches, 'matches',
                                                    qos.RESULTS)
        self.wait(lambda: self.publisher.get_subscription_count() > 0,
                  f'{NODE} to subscribe matches (numba warm-up)', timeout=120.0)
        self.wait(lambda: self.node.count_publishers('best_point/decision') > 0,
                  'the decision publisher')

    def decide(self, msg):
        """Publish one StereoMatches and return its decision."""
        count = len(self.decisions)
        self.publisher.publish(msg)
        self.wait(lambda: len(self.decisions) > count, 'a decision')
        return self.decisions[count]


@pytest.fixture
def target(ros_context, start_ros_process):
    process = start_ros_process('stereo_fuzzy_perception', NODE)
    probe = FuzzyTarget(ros_context, process)
    yield probe
    probe.close()
    assert process.interrupt() == 0, process.output()[-3000:]


def packaged_document() -> dict:
    from stereo_fuzzy_perception.core.best_point.rule_base import (
        packaged_rule_base,
        rule_base_to_dict,
    )

    return rule_base_to_dict(packaged_rule_base('fuzzy_fitted'))


def weights() -> dict:
    from stereo_fuzzy_perception.core.best_point.neural_baseline import NeuralBaseline
    from stereo_fuzzy_perception.core.best_point.rule_base import data_path

    network = NeuralBaseline.load(data_path('neural_baseline.npz'))
    return {'input_mean': network.input_mean, 'input_std': network.input_std, 'w1': network.w1,
            'b1': network.b1, 'w2': network.w2, 'b2': network.b2,
            'output_scale': np.array(network.output_scale)}


def rule_file(tmp_path: Path, name: str, change) -> Path:
    document = copy.deepcopy(packaged_document())
    change(document)
    path = tmp_path / f'{name}.yaml'
    path.write_text(yaml.dump(document))  # yaml.dump keeps non-string keys
    return path


def weights_file(tmp_path: Path, name: str, **changes) -> Path:
    path = tmp_path / f'{name}.npz'
    np.savez(path, **{**weights(), **changes})
    return path


def malformed_files(tmp_path: Path) -> list[tuple[str, str, str]]:
    """(parameter, value, what the reason must say) for every malformed file of issue #15."""
    fifo = tmp_path / 'rules.fifo'
    os.mkfifo(fifo)
    npy = tmp_path / 'weights.npy'
    np.save(npy, np.zeros(3))
    hidden = weights()['w1'].shape[1]
    return [
        ('rule_base_file', str(rule_file(tmp_path, 'int_key', lambda d: d.update({7: 'x'}))),
         'not a string'),
        ('rule_base_file', str(rule_file(tmp_path, 'list_if',
                                         lambda d: d['rules'][0].update({'if': ['less']}))),
         'premise term'),
        ('rule_base_file', str(rule_file(tmp_path, 'dict_if',
                                         lambda d: d['rules'][0].update({'if': {'a': 1}}))),
         'premise term'),
        ('rule_base_file', str(rule_file(
            tmp_path, 'huge_offset',
            lambda d: d['rules'][0]['then'].update({'offset_m': [1e300, 0.0, 0.0]}))),
         'beyond the allowed'),
        ('rule_base_file', str(fifo), 'a FIFO'),
        ('rule_base_file', '/dev/zero', 'a character device'),
        ('rule_base_file', str(tmp_path), 'a directory'),
        ('network_file', str(npy), 'not an .npz archive'),
        ('network_file', str(weights_file(tmp_path, 'scale', output_scale=np.ones(3))),
         'output_scale has shape'),
        ('network_file', str(weights_file(tmp_path, 'nan', w1=np.full((14, hidden), math.nan))),
         'w1 holds NaN'),
        ('network_file', '/dev/zero', 'a character device'),
    ]


def test_every_malformed_file_is_refused_with_a_reason_and_the_node_lives(target, tmp_path):
    for name, value, reason in malformed_files(tmp_path):
        for selector in ('fuzzy_fitted', 'neural_network'):
            assert target.set_parameter('selector', selector) == (True, '')
            successful, text = target.set_parameter(name, value)
            assert not successful and reason in text, (name, value, selector, text)
            target.assert_alive()
            assert target.get_parameter(name) == ''
    # A .npy set while a fuzzy selector is active is refused then, not on the switch later.
    assert target.set_parameter('selector', 'fuzzy_fitted')[0]
    assert not target.set_parameter('network_file', str(tmp_path / 'weights.npy'))[0]
    assert target.set_parameter('selector', 'neural_network') == (True, '')
    assert target.decide(matches_message(1)).status == 'ok'
    assert len(target.points) == 1


def test_no_non_finite_or_out_of_workspace_point_is_ever_published(target, tmp_path):
    huge = weights_file(tmp_path, 'huge', w2=np.full_like(weights()['w2'], 1e308),
                        b1=np.full_like(weights()['b1'], 50.0),
                        output_scale=np.array(1.0))
    assert target.set_parameter('network_file', str(huge)) == (True, '')
    assert target.set_parameter('selector', 'neural_network') == (True, '')
    decision = target.decide(matches_message(1))
    assert not decision.has_best_point and decision.status.startswith('non_finite_point'), (
        decision.status)
    far = rule_file(tmp_path, 'far', lambda d: [rule['then'].update({'offset_m': [5.0, 0, 0]})
                                                 for rule in d['rules']])
    assert target.set_parameter('rule_base_file', str(far)) == (True, '')
    assert target.set_parameter('selector', 'fuzzy_fitted') == (True, '')
    decision = target.decide(matches_message(2))
    assert not decision.has_best_point and decision.status.startswith('outside_workspace'), (
        decision.status)
    target.wait_diagnostic('refused non_finite_point', 1)
    target.wait_diagnostic('refused outside_workspace', 1)
    assert target.points == []  # reliable, in order: a published point would be here by now
    assert target.set_parameter('rule_base_file', '') == (True, '')
    assert target.decide(matches_message(3)).status == 'ok'
    target.wait(lambda: len(target.points) == 1, 'the one good best point')
    point = target.points[0].point
    assert all(math.isfinite(value) for value in (point.x, point.y, point.z))


def test_inconsistent_cloud_layouts_are_malformed_input_not_a_wrong_point(target):
    from sensor_msgs.msg import PointField

    wide_x = matches_message(1)
    wide_x.points.fields[0] = PointField(name='x', offset=0, datatype=PointField.FLOAT64,
                                         count=1)
    twice_x = matches_message(2)
    twice_x.points.fields.append(PointField(name='x', offset=8, datatype=PointField.FLOAT32,
                                            count=1))
    outside = matches_message(3)
    outside.points.fields[6] = PointField(name='score', offset=40, datatype=PointField.FLOAT32,
                                          count=1)
    for msg, reason in ((wide_x, "fields 'x' and 'y' overlap"), (twice_x, 'declared twice'),
                        (outside, 'does not fit point_step')):
        decision = target.decide(msg)
        assert not decision.has_best_point
        assert decision.status.startswith('malformed_input') and reason in decision.status
    target.wait_diagnostic('refused malformed_input', 3)
    assert target.points == []


def test_gaps_in_the_matches_sequence_are_counted(target):
    for sequence in (1, 2, 5, 6, 10):
        target.decide(matches_message(sequence))
    target.wait_diagnostic('matches lost (sequence gaps)', 5)
    target.wait_diagnostic('matches received', 5)
    target.decide(matches_message(1))  # a restarted publisher: no loss, one restart
    target.wait_diagnostic('matches sequence restarts', 1)


PARAMETER_NAMES = ['selector', 'rule_base_file', 'network_file', 'workspace_min_m',
                   'surface_margin_m', 'cluster_gap_m', 'keep_largest_cluster', 'top_band_m',
                   'min_points', 'rig.z0_m', 'world_frame', 'diagnostics_period_s', 'unknown']
VALUES = st.one_of(
    st.booleans(), st.integers(-2**63, 2**63 - 1), st.floats(allow_nan=True,
                                                             allow_infinity=True),
    st.text(max_size=20), st.sampled_from(['/dev/zero', '/dev/null', '/', '/proc/self/mem',
                                           'fuzzy_chapter', 'neural_network', 'centroid']),
    st.lists(st.integers(-5, 5), max_size=3), st.lists(st.floats(), max_size=3),
    st.lists(st.text(max_size=3), max_size=3), st.lists(st.booleans(), max_size=3),
    st.lists(st.binary(min_size=1, max_size=1), min_size=1, max_size=4))


@settings(max_examples=120, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(name=st.sampled_from(PARAMETER_NAMES), value=VALUES)
def test_random_parameter_values_are_refused_with_a_reason_or_usable(target, name, value):
    successful, reason = target.set_parameter(name, value)
    assert successful or reason, f'{name}={value!r} refused without a reason'
    target.assert_alive()
    if successful:  # accepted: the node must go on deciding, and publish only sound points
        decision = target.decide(matches_message(0))
        assert decision.status
        if decision.has_best_point:
            point = decision.best_point_world
            assert all(math.isfinite(value) for value in (point.x, point.y, point.z))
