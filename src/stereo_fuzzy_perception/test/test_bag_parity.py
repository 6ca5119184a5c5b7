"""The bag tool reads what other writers write and does what `ros2 bag` does, without ROS.

Bags here are written by rosbags itself (rosbags.rosbag2.Writer with the MCAP storage plugin:
the rosbag2 layout), by the mcap library's ROS 2 writer (a single .mcap file, no metadata.yaml)
and by the bare mcap writer without chunks or summary (an "old" file whose messages can only be
found by reading it through).
"""

from __future__ import annotations

import math

import pytest
import yaml
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore
from stereo_fuzzy_perception.bag.bag_io import (
    BagError,
    BagWriter,
    PlaybackClock,
    format_info,
    read_info,
    read_messages,
    select_topics,
)

STRING = 'std_msgs/msg/String'
STRING_DEF = 'string data'


@pytest.fixture(scope='module')
def typestore():
    return get_typestore(Stores.ROS2_JAZZY)


def cdr_string(typestore, text: str) -> bytes:
    message = typestore.types[STRING](data=text)
    return bytes(typestore.serialize_cdr(message, STRING))


@pytest.fixture
def rosbags_bag(tmp_path, typestore):
    """A rosbag2 directory written by rosbags: /chatter (3), /tf_static of an odd type (2)."""
    path = tmp_path / 'by_rosbags'
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        chatter = writer.add_connection('/chatter', STRING, typestore=typestore)
        tf = writer.add_connection('/tf_static', 'tf2_msgs/msg/TFMessage', typestore=typestore)
        for k in range(3):
            writer.write(chatter, 1_000 + k * 500, cdr_string(typestore, f'hello {k}'))
        for k in range(2):
            writer.write(tf, 1_200 + k * 500, b'\x00\x01\x00\x00\x00\x00\x00\x00')
        writer.set_custom_data('recorded_by', 'the parity test')
    return path


def mcap_ros2_file(path, typestore, count: int = 20) -> None:
    """Write a single .mcap file with the mcap library's ROS 2 writer."""
    from mcap_ros2.writer import Writer as Ros2Writer

    with path.open('wb') as stream:
        writer = Ros2Writer(stream)
        schema = writer.register_msgdef(STRING, STRING_DEF)
        for k in range(count):
            writer.write_message('/chatter', schema, {'data': f'm{k}'}, log_time=10_000 + k,
                                 publish_time=10_000 + k)
        writer.finish()


def unindexed_mcap_file(path, typestore, count: int = 20) -> None:
    """Write an .mcap file without chunks, statistics or summary."""
    from mcap.writer import IndexType
    from mcap.writer import Writer as McapWriter

    with path.open('wb') as stream:
        writer = McapWriter(stream, use_chunking=False, use_statistics=False,
                            use_summary_offsets=False, index_types=IndexType.NONE,
                            repeat_channels=False, repeat_schemas=False)
        writer.start(profile='ros2', library='old writer')
        schema = writer.register_schema(STRING, 'ros2msg', STRING_DEF.encode())
        channel = writer.register_channel('/chatter', 'cdr', schema)
        for k in range(count):
            writer.add_message(channel, log_time=5_000 + k, data=cdr_string(typestore, f'o{k}'),
                               publish_time=5_000 + k)
        writer.finish()


def test_a_rosbags_bag_reads_with_counts_types_qos_and_custom_data(rosbags_bag, typestore):
    info = read_info(rosbags_bag)
    assert {(t.name, t.msgtype, t.message_count) for t in info.topics} == {
        ('/chatter', STRING, 3), ('/tf_static', 'tf2_msgs/msg/TFMessage', 2)}
    assert info.message_count == 5 and info.start_ns == 1_000 and info.end_ns == 2_000
    assert dict(info.custom_data) == {'recorded_by': 'the parity test'}
    report = format_info(info)
    assert 'Custom data:\n  recorded_by: the parity test' in report
    messages = list(read_messages(rosbags_bag))
    assert [m.timestamp_ns for m in messages] == sorted(m.timestamp_ns for m in messages)
    chatter = [m.data for m in messages if m.topic == '/chatter']
    assert chatter == [cdr_string(typestore, f'hello {k}') for k in range(3)]


def test_a_single_mcap_file_without_metadata_reads(tmp_path, typestore):
    path = tmp_path / 'single.mcap'
    mcap_ros2_file(path, typestore)
    info = read_info(path)
    assert not info.has_metadata and info.files == (path,)
    assert [(t.name, t.msgtype, t.message_count) for t in info.topics] == [
        ('/chatter', STRING, 20)]
    assert (info.start_ns, info.end_ns) == (10_000, 10_019)
    decoded = [typestore.deserialize_cdr(m.data, m.msgtype).data for m in read_messages(path)]
    assert decoded == [f'm{k}' for k in range(20)]
    assert 'no metadata.yaml' in format_info(info)


def test_an_unindexed_mcap_file_yields_every_message(tmp_path, typestore):
    path = tmp_path / 'old.mcap'
    unindexed_mcap_file(path, typestore)
    info = read_info(path)
    assert info.message_count == 20 and info.topics[0].message_count == 20
    assert len(list(read_messages(path))) == 20
    assert len(list(read_messages(path, start_offset_ns=10))) == 10


def test_a_directory_of_mcap_files_without_metadata_reads(tmp_path, typestore):
    folder = tmp_path / 'reindex_me'
    folder.mkdir()
    mcap_ros2_file(folder / 'part_0.mcap', typestore, 4)
    assert read_info(folder).message_count == 4


def test_unreadable_inputs_are_refused_with_the_reason(tmp_path):
    text = tmp_path / 'notes.txt'
    text.write_text('hello')
    with pytest.raises(BagError, match='neither a rosbag2 directory nor an .mcap file'):
        read_info(text)
    with pytest.raises(BagError, match='does not exist'):
        read_info(tmp_path / 'missing')
    broken = tmp_path / 'broken.mcap'
    broken.write_bytes(b'\x89MCAP0\r\n' + b'\x00' * 10)
    with pytest.raises(BagError, match='cannot read'):
        list(read_messages(broken))
    sqlite = tmp_path / 'sqlite_bag'
    sqlite.mkdir()
    (sqlite / 'metadata.yaml').write_text(yaml.safe_dump({'rosbag2_bagfile_information': {
        'storage_identifier': 'sqlite3', 'relative_file_paths': ['x.db3']}}))
    with pytest.raises(BagError, match='sqlite3'):
        read_info(sqlite)


def test_a_split_bag_lists_every_file_and_reads_back_whole(tmp_path, typestore):
    path = tmp_path / 'split'
    with BagWriter(path, compression='none', typestore=typestore,
                   max_bag_duration_ns=1_000) as bag:
        bag.add_topic('/chatter', STRING)
        for k in range(10):
            bag.write('/chatter', 10_000 + k * 300, cdr_string(typestore, str(k)))
        bag.set_custom_data('split', 'by duration')
    files = sorted(p.name for p in path.iterdir())
    assert files == ['metadata.yaml', 'split_0.mcap', 'split_1.mcap', 'split_2.mcap']
    metadata = yaml.safe_load((path / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert metadata['relative_file_paths'] == ['split_0.mcap', 'split_1.mcap', 'split_2.mcap']
    assert [f['message_count'] for f in metadata['files']] == [4, 4, 2]
    assert metadata['message_count'] == 10
    assert metadata['topics_with_message_count'][0]['message_count'] == 10
    assert metadata['custom_data'] == {'split': 'by duration'}
    info = read_info(path)
    assert info.start_ns == 10_000 and info.end_ns == 12_700 and info.message_count == 10
    decoded = [typestore.deserialize_cdr(m.data, STRING).data for m in read_messages(path)]
    assert decoded == [str(k) for k in range(10)]
    # rosbags, as rosbag2 would, opens the split bag through its metadata.yaml.
    from rosbags.rosbag2 import Reader

    with Reader(path) as reader:
        assert reader.message_count == 10 and len(list(reader.messages())) == 10


def test_a_bag_split_by_size_starts_new_files(tmp_path, typestore):
    path = tmp_path / 'by_size'
    payload = cdr_string(typestore, 'x' * 4000)
    with BagWriter(path, compression='none', typestore=typestore, max_bag_size=1) as bag:
        bag.add_topic('/chatter', STRING)
        for k in range(3):
            bag.write('/chatter', k, payload)
    assert read_info(path).message_count == 3
    assert len(read_info(path).files) >= 2


def test_topic_selection_as_ros2_bag():
    topics = ['/left/image_raw', '/left/camera_info', '/right/image_raw', '/tf_static']
    assert select_topics(topics) == tuple(topics)
    assert select_topics(topics, ['left/image_raw']) == ('/left/image_raw',)
    assert select_topics(topics, regex='image') == ('/left/image_raw', '/right/image_raw')
    assert select_topics(topics, ['/tf_static'], regex='^/right') == (
        '/right/image_raw', '/tf_static')
    assert select_topics(topics, exclude_topics=['/tf_static'], exclude_regex='camera_info') == (
        '/left/image_raw', '/right/image_raw')
    assert select_topics(topics, [], regex=None) == ()
    with pytest.raises(BagError, match='not a regular expression'):
        select_topics(topics, regex='(')


class FakeTime:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def test_playback_clock_runs_at_rate_stands_while_paused_and_jumps():
    wall = FakeTime()
    clock = PlaybackClock(1_000_000_000, rate=2.0, now=wall)
    wall.now += 0.5
    assert clock.bag_time_ns() == 2_000_000_000
    assert clock.seconds_until(3_000_000_000) == pytest.approx(0.5)
    clock.pause()
    wall.now += 10.0
    assert clock.bag_time_ns() == 2_000_000_000 and math.isinf(clock.seconds_until(3 * 10**9))
    clock.jump_to(2_500_000_000)
    assert clock.bag_time_ns() == 2_500_000_000 and clock.paused
    clock.resume()
    wall.now += 0.25
    assert clock.bag_time_ns() == 3_000_000_000
    assert clock.seconds_until(1) == 0.0
    started_paused = PlaybackClock(5, rate=1.0, paused=True, now=wall)
    wall.now += 3.0
    assert started_paused.bag_time_ns() == 5
    with pytest.raises(BagError, match='positive'):
        PlaybackClock(0, rate=0.0)
