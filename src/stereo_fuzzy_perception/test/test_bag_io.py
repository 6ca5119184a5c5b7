"""Bags without ROS: write, read, summarise, custom types, QoS, remaps, the committed bags.

Messages are serialized with rosbags' typestore here, so these tests need no sourced workspace.
"""

from pathlib import Path

import numpy as np
import pytest
from stereo_fuzzy_perception.bag.bag_io import (
    BagError,
    BagWriter,
    absolute_topic,
    format_info,
    make_qos,
    parse_remaps,
    playback_delay_s,
    read_info,
    read_messages,
)
from stereo_fuzzy_perception.bag.message_types import (
    MessageTypeError,
    import_message_class,
    project_typestore,
    split_type_name,
)
from stereo_fuzzy_perception.simulation.scene_model import OBJECT_TYPES, WORKSPACE

REPO_ROOT = Path(__file__).resolve().parents[3]
BAGS = REPO_ROOT / 'bags'
DECISION = 'stereo_fuzzy_msgs/msg/FuzzyDecision'
STRING = 'std_msgs/msg/String'


@pytest.fixture(scope='module')
def typestore():
    return project_typestore([DECISION])


def string_message(typestore, text):
    return bytes(typestore.serialize_cdr(typestore.types[STRING](data=text), STRING))


def decision_message(typestore, selector):
    decision_type = typestore.types[DECISION]
    header_type = typestore.types['std_msgs/msg/Header']
    time_type = typestore.types['builtin_interfaces/msg/Time']
    point = typestore.types['geometry_msgs/msg/Point']
    zero = point(x=0.0, y=0.0, z=0.0)
    message = decision_type(
        header=header_type(stamp=time_type(sec=5, nanosec=7), frame_id='world'),
        selector=selector, rule_base='fitted', has_best_point=True, status='ok',
        best_point_world=point(x=0.1, y=0.2, z=0.03), best_point_camera=zero,
        camera_frame_id='left_camera_optical_frame', points_in=10, points_valid=9,
        clusters_found=1, points_used=4, top_height=0.03, surface_source='measured',
        surface_offset_m=0.0, surface_tilt_deg=0.0,
        surface_normal=typestore.types['geometry_msgs/msg/Vector3'](x=0.0, y=0.0, z=1.0),
        surface_points=100, disparity_sigma_px=0.1, object_height_sigmas=20.0,
        border_points=[zero] * 4,
        border_distances=np.zeros(6), area_centres=[zero] * 4,
        area_centres_u_left=np.zeros(4), area_centres_v_left=np.zeros(4),
        area_centres_u_right=np.zeros(4), area_point_counts=np.zeros(4, dtype=np.uint32),
        d1=np.zeros(4), d2=np.zeros(4), ratio=np.ones(4), rule_names=['a', 'b'],
        membership_degrees=np.array([0.5, 0.25]), firing_strengths=np.array([0.5, 0.25]))
    return bytes(typestore.serialize_cdr(message, DECISION))


@pytest.fixture
def small_bag(tmp_path, typestore):
    """A bag with /chatter (3 strings, 0.5 s apart) and /decision (1 custom message)."""
    path = tmp_path / 'small'
    with BagWriter(path, typestore=typestore) as bag:
        bag.add_topic('/chatter', STRING, [make_qos(reliable=False, depth=5)])
        bag.add_topic('/decision', DECISION, [make_qos(transient_local=True, depth=1)])
        for k in range(3):
            bag.write('/chatter', 1_000_000_000 + k * 500_000_000,
                      string_message(typestore, f'hello {k}'))
        bag.write('/decision', 1_200_000_000, decision_message(typestore, 'fuzzy_fitted'))
    return path


def test_a_written_bag_reads_back_in_time_order_with_its_summary(small_bag, typestore):
    messages = list(read_messages(small_bag))
    assert [(m.topic, m.timestamp_ns) for m in messages] == [
        ('/chatter', 1_000_000_000), ('/decision', 1_200_000_000),
        ('/chatter', 1_500_000_000), ('/chatter', 2_000_000_000)]
    assert messages[0].data == string_message(typestore, 'hello 0')
    assert messages[1].data == decision_message(typestore, 'fuzzy_fitted')
    info = read_info(small_bag)
    assert (info.message_count, info.start_ns, info.end_ns) == (4, 1_000_000_000, 2_000_000_000)
    assert info.duration_ns == 1_000_000_000
    assert info.storage == 'mcap' and info.compression == 'zstd'
    assert [t.name for t in info.topics] == ['/chatter', '/decision']
    assert info.topic('/chatter').message_count == 3
    assert info.topic('/decision').msgtype == DECISION
    report = format_info(info)
    assert 'Topic: /chatter | Type: std_msgs/msg/String | Count: 3' in report
    assert 'best_effort, volatile, keep_last 5' in report


def test_custom_types_and_qos_are_stored_for_any_reader(small_bag, typestore):
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    decision = read_info(small_bag).topic('/decision')
    assert decision.offered_qos[0].durability.name == 'TRANSIENT_LOCAL'
    assert decision.offered_qos[0].depth == 1
    assert decision.type_hash == typestore.hash_rihs01(DECISION)
    # A reader that has never seen the type learns it from the bag itself.
    fresh = get_typestore(Stores.ROS2_JAZZY)
    with Reader(small_bag) as reader:
        for connection in reader.connections:
            if connection.msgtype == DECISION:
                fresh.register(get_types_from_msg(connection.msgdef.data, DECISION))
        decoded = [fresh.deserialize_cdr(data, c.msgtype)
                   for c, _, data in reader.messages()
                   if c.msgtype == DECISION]
    assert decoded[0].selector == 'fuzzy_fitted'
    assert decoded[0].best_point_world.z == pytest.approx(0.03)
    assert list(decoded[0].rule_names) == ['a', 'b']


def test_topic_selection_and_start_offset(small_bag):
    assert {m.topic for m in read_messages(small_bag, ['/decision'])} == {'/decision'}
    late = list(read_messages(small_bag, start_offset_ns=300_000_000))
    assert [m.timestamp_ns for m in late] == [1_500_000_000, 2_000_000_000]
    with pytest.raises(BagError, match='/missing'):
        list(read_messages(small_bag, ['/missing']))


def test_an_uncompressed_bag_and_refusals(tmp_path, typestore):
    path = tmp_path / 'plain'
    with BagWriter(path, compression='none', typestore=typestore) as bag:
        bag.add_topic('/chatter', STRING)
        bag.write('/chatter', 5, string_message(typestore, 'x'))
        with pytest.raises(BagError, match='not added'):
            bag.write('/other', 6, b'')
        with pytest.raises(BagError, match='already'):
            bag.add_topic('/chatter', DECISION)
    info = read_info(path)
    assert info.compression == 'none' and info.message_count == 1
    assert info.topic('/chatter').offered_qos[0].reliability.name == 'RELIABLE'
    with pytest.raises(BagError, match='exists'):
        BagWriter(path)
    with pytest.raises(BagError, match='compression'):
        BagWriter(tmp_path / 'other', compression='lz5')
    with pytest.raises(BagError, match='not a rosbag2 directory'):
        read_info(tmp_path)


def test_remaps_timing_and_type_names():
    assert parse_remaps(['a:=/b', '/c/d:=e']) == {'/a': '/b', '/c/d': '/e'}
    for bad in ('a=b', ':=b', 'a:='):
        with pytest.raises(BagError, match='old_topic:=new_topic'):
            parse_remaps([bad])
    assert absolute_topic('x/y') == '/x/y' and absolute_topic('/x') == '/x'
    assert playback_delay_s(3_000_000_000, 1_000_000_000, 2.0) == pytest.approx(1.0)
    assert playback_delay_s(3_000_000_000, 1_000_000_000, 0.5) == pytest.approx(4.0)
    with pytest.raises(BagError, match='positive'):
        playback_delay_s(1, 0, 0.0)
    assert split_type_name(DECISION) == ('stereo_fuzzy_msgs', 'msg', 'FuzzyDecision')
    with pytest.raises(MessageTypeError):
        split_type_name('Image')
    with pytest.raises(MessageTypeError, match='cannot import'):
        import_message_class('no_such_pkg/msg/Thing')
    with pytest.raises(MessageTypeError, match='no definition'):
        project_typestore(['no_such_pkg/msg/Thing'])


@pytest.mark.parametrize('name, scenes', [('demo_scenes', 12), ('sensor_effects_scenes', 4)])
def test_committed_bags_hold_every_object_type_with_consistent_ground_truth(name, scenes):
    path = BAGS / name
    info = read_info(path)
    assert {t.name: t.message_count for t in info.topics} == {
        '/left/image_raw': scenes, '/right/image_raw': scenes, '/left/camera_info': scenes,
        '/right/camera_info': scenes, '/ground_truth/target': scenes,
        '/ground_truth/object': scenes, '/tf_static': 1}
    assert info.compression == 'zstd'
    # Each scene carries its own textures; 12 mono8 scenes compress to about 4.4 MB.
    assert info.size_bytes < 5_000_000, f'{name} grew to {info.size_bytes} bytes'
    typestore = project_typestore()
    stamps: dict[int, set[str]] = {}
    targets, objects = [], []
    for message in read_messages(path):
        decoded = typestore.deserialize_cdr(message.data, message.msgtype)
        if message.topic == '/tf_static':  # the rig, once: world -> left -> right
            assert [(t.header.frame_id, t.child_frame_id) for t in decoded.transforms] == [
                ('world', 'left_camera_optical_frame'),
                ('left_camera_optical_frame', 'right_camera_optical_frame')]
            continue
        stamp = decoded.header.stamp.sec * 1_000_000_000 + decoded.header.stamp.nanosec
        stamps.setdefault(stamp, set()).add(message.topic)
        if message.topic == '/left/image_raw':
            assert (decoded.width, decoded.height, decoded.encoding) == (640, 480, 'mono8')
            assert decoded.header.frame_id == 'left_camera_optical_frame'
        elif message.topic == '/right/camera_info':
            assert decoded.p[3] < 0.0
        elif message.topic == '/ground_truth/target':
            assert decoded.header.frame_id == 'world'
            targets.append(np.array([decoded.point.x, decoded.point.y, decoded.point.z]))
        elif message.topic == '/ground_truth/object':
            objects.append(decoded)
    assert len(stamps) == scenes and all(len(topics) == 6 for topics in stamps.values()), (
        'every scene must have its six messages on one stamp')
    assert {marker.text for marker in objects} == {kind.value for kind in OBJECT_TYPES}
    for target, marker in zip(targets, objects, strict=True):
        assert target[2] == pytest.approx(marker.scale.z)
        assert target[0] == pytest.approx(marker.pose.position.x)
        assert target[1] == pytest.approx(marker.pose.position.y)
        assert marker.pose.position.z == pytest.approx(marker.scale.z / 2.0)
        assert WORKSPACE.x_min <= target[0] <= WORKSPACE.x_max
        assert WORKSPACE.y_min <= target[1] <= WORKSPACE.y_max
