"""Regression without ground truth: a run's best points against a committed reference run's.

The comparison itself is tested on made-up outcomes; the committed reference bags are checked
to hold a decision per scene of their input bags; and the committed sensor-effects bag, with its
ground truth stripped as a real recording would lack it, is replayed through the whole chain by
the demo with `--compare` against its committed reference.
"""

from __future__ import annotations

import pytest

from chain.processes import REPO_ROOT
from chain.regression import (
    SceneOutcome,
    compare,
    format_comparison,
    scene_outcomes,
    write_reference,
)

BAGS = REPO_ROOT / 'bags'
REFERENCES = BAGS / 'reference_outputs'
SCENES = {'demo_scenes': 12, 'sensor_effects_scenes': 4}


def outcome(stamp: int, point=None, status='ok') -> SceneOutcome:
    return SceneOutcome(stamp, point, status)


def test_compare_passes_the_same_points_and_fails_every_kind_of_change():
    reference = {1: outcome(1, (0.1, 0.2, 0.03)), 2: outcome(2, (0.1, 0.2, 0.03)),
                 3: outcome(3, (0.1, 0.2, 0.03)), 4: outcome(4, None, 'no cluster'),
                 5: outcome(5, None, 'no cluster'), 6: outcome(6, (0.0, 0.0, 0.0))}
    current = {1: outcome(1, (0.1, 0.2, 0.0305)), 2: outcome(2, (0.1, 0.2, 0.032)),
               3: outcome(3, None, 'too few points'), 4: outcome(4, None, 'no cluster'),
               5: outcome(5, (0.1, 0.1, 0.01)), 7: outcome(7, (0.0, 0.0, 0.0))}
    rows = {row.stamp_ns: row for row in compare(reference, current, tolerance_mm=1.0)}
    assert rows[1].passed and rows[1].distance_mm == pytest.approx(0.5)
    assert not rows[2].passed and rows[2].distance_mm == pytest.approx(2.0)
    assert not rows[3].passed and 'lost' in rows[3].verdict
    assert rows[4].passed and rows[4].distance_mm is None
    assert not rows[5].passed and 'gained' in rows[5].verdict
    assert not rows[6].passed and 'not decided in this run' in rows[6].verdict
    assert not rows[7].passed and 'not in the reference' in rows[7].verdict
    table = format_comparison(list(rows.values()))
    assert '| 0.000 | (100.00, 200.00, 30.00) | (100.00, 200.00, 30.50) | 0.500 | pass' in table


@pytest.mark.parametrize(('name', 'scenes'), SCENES.items())
def test_each_committed_bag_has_a_small_reference_with_every_scene(name, scenes):
    from stereo_fuzzy_perception.bag.bag_io import read_info, read_messages
    from stereo_fuzzy_perception.bag.message_types import project_typestore

    reference = REFERENCES / name
    info = read_info(reference)
    assert {t.name for t in info.topics} == {'/best_point', '/best_point/decision'}
    assert info.size_bytes < 200_000, f'{reference} grew to {info.size_bytes} bytes'
    assert 'scripts/demo.sh' in dict(info.custom_data).get('made_by', ''), (
        'the reference should say how it was made')
    outcomes = scene_outcomes(reference)
    assert len(outcomes) == scenes
    # The reference's scenes are the input bag's scenes, by stamp.
    typestore = project_typestore()
    stamps = set()
    for message in read_messages(BAGS / name, ['/left/camera_info']):
        header = typestore.deserialize_cdr(message.data, message.msgtype).header
        stamps.add(header.stamp.sec * 1_000_000_000 + header.stamp.nanosec)
    assert set(outcomes) == stamps
    assert all(o.best_point is not None for o in outcomes.values()), outcomes
    assert all(row.passed for row in compare(outcomes, outcomes))


def test_write_reference_keeps_best_points_and_decisions_only(tmp_path):
    from stereo_fuzzy_perception.bag.bag_io import read_info

    copy = tmp_path / 'copy'
    count = write_reference(REFERENCES / 'sensor_effects_scenes', copy, 'a test')
    assert count == read_info(REFERENCES / 'sensor_effects_scenes').message_count
    assert scene_outcomes(copy) == scene_outcomes(REFERENCES / 'sensor_effects_scenes')
    assert dict(read_info(copy).custom_data) == {'made_by': 'a test'}


@pytest.mark.ros
@pytest.mark.system
def test_an_unlabelled_bag_runs_the_chain_and_matches_its_reference(ros_domain_id, tmp_path):
    from stereo_fuzzy_perception.bag.bag_io import BagWriter, read_info, read_messages

    from chain.demo import main

    # The committed bag as a real recording would be: cameras only, no ground truth.
    source = BAGS / 'sensor_effects_scenes'
    unlabelled = tmp_path / 'unlabelled'
    kept = [t for t in read_info(source).topics if not t.name.startswith('/ground_truth')]
    with BagWriter(unlabelled) as bag:
        for topic in kept:
            bag.add_topic(topic.name, topic.msgtype, topic.offered_qos, topic.msgdef,
                          topic.type_hash)
        for message in read_messages(source, [t.name for t in kept]):
            bag.write(message.topic, message.timestamp_ns, message.data)

    output = tmp_path / 'run'
    code = main(['--bag', str(unlabelled), '--output', str(output), '--rate', '0.5',
                 '--timeout', '300', '--compare', str(REFERENCES / 'sensor_effects_scenes')])
    report = (output / 'results.md').read_text()
    assert code == 0, report
    assert report.count('ok (no ground truth: reached)') == SCENES['sensor_effects_scenes'], report
    assert report.count('| pass: same |') == SCENES['sensor_effects_scenes'], report
    assert len(sorted(output.glob('object_*.png'))) == SCENES['sensor_effects_scenes']
    assert len(sorted(output.glob('disparity_*.png'))) == SCENES['sensor_effects_scenes']
    assert (output / 'outputs_bag' / 'metadata.yaml').is_file()
