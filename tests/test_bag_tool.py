"""The installed `bag` and `render_scenes` executables against real rclpy over Fast DDS.

A tiny bag (160x120 images, 2 scenes 1 s apart) is rendered once by `render_scenes`; `bag info`,
`bag play` and `bag record` run as child processes like `ros2 run` would start them, and an
in-process node publishes or subscribes. Every wait is on a condition, never a fixed sleep.
"""

from __future__ import annotations

import subprocess
from collections import defaultdict
from pathlib import Path

import pytest
from ros_fixtures import executable_path
from ros_waiting import wait_until

pytestmark = pytest.mark.ros

PACKAGE = 'stereo_fuzzy_perception'
SCENE_TOPICS = ('/left/image_raw', '/left/camera_info', '/right/image_raw', '/right/camera_info',
                '/ground_truth/target', '/ground_truth/object')
TIMEOUT = 30.0


@pytest.fixture(scope='module')
def tiny_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Render two scenes (a circle and a cube) into a bag with the installed render_scenes."""
    path = tmp_path_factory.mktemp('bags') / 'tiny'
    result = subprocess.run(
        [str(executable_path(PACKAGE, 'render_scenes')), '-o', str(path), '--types', 'circle',
         'cubic_square', '--scenes-per-type', '1', '--seed', '3', '--width', '160',
         '--height', '120', '--encoding', 'rgb8'],
        capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    return path


def dds_padded(data: bytes) -> bytes:
    """Return CDR bytes as DDS delivers them: zero-padded to a multiple of 4 bytes."""
    return data + bytes(-len(data) % 4)


def bag_messages(path: Path, topics=None) -> dict[str, list[bytes]]:
    from stereo_fuzzy_perception.bag.bag_io import read_messages

    recorded: dict[str, list[bytes]] = defaultdict(list)
    for message in read_messages(path, topics):
        recorded[message.topic].append(message.data)
    return recorded


class RawProbe:
    """An in-process node that keeps the raw bytes arriving on some topics, in order."""

    def __init__(self, context, topics: dict[str, str], name: str = 'probe') -> None:
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.qos import QoSProfile, ReliabilityPolicy
        from stereo_fuzzy_perception.bag.message_types import import_message_class

        self.node = rclpy.create_node(name, context=context)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)
        self.received: dict[str, list[bytes]] = defaultdict(list)
        qos = QoSProfile(depth=50, reliability=ReliabilityPolicy.RELIABLE)
        for topic, msgtype in topics.items():
            self.node.create_subscription(
                import_message_class(msgtype), topic,
                lambda data, topic=topic: self.received[topic].append(data), qos, raw=True)

    def count(self) -> int:
        return sum(len(v) for v in self.received.values())

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()


def scene_types() -> dict[str, str]:
    from stereo_fuzzy_perception.simulation.scene_bag_writer import TOPICS

    return dict(TOPICS)


def wait_for_exit(process, executor, what: str) -> int:
    wait_until(lambda: process.process.poll() is not None, TIMEOUT,
               f'{what} to exit:\n{process.output()}', executor)
    return process.process.returncode


def test_bag_info_reports_topics_types_counts_and_duration(tiny_bag):
    result = subprocess.run([str(executable_path(PACKAGE, 'bag')), 'info', str(tiny_bag)],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    for topic, msgtype in scene_types().items():
        assert f'Topic: {topic} | Type: {msgtype} | Count: 2 |' in result.stdout
    # and the rig it was rendered with, once
    assert 'Topic: /tf_static | Type: tf2_msgs/msg/TFMessage | Count: 1 |' in result.stdout
    assert 'Messages:          13' in result.stdout
    assert 'Duration:          1.000005000 s' in result.stdout
    assert 'Compression:       zstd' in result.stdout
    missing = subprocess.run([str(executable_path(PACKAGE, 'bag')), 'info',
                              str(tiny_bag / 'nothing')], capture_output=True, text=True,
                             timeout=60)
    assert missing.returncode == 1 and 'does not exist' in missing.stderr


def test_render_scenes_is_reproducible(tiny_bag, tmp_path):
    again = tmp_path / 'again'
    result = subprocess.run(
        [str(executable_path(PACKAGE, 'render_scenes')), '--types', 'circle', 'cubic_square',
         '--scenes-per-type', '1', '--seed', '3', '--width', '160', '--height', '120',
         '--encoding', 'rgb8', '-o', str(again)], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert bag_messages(again) == bag_messages(tiny_bag)


def test_play_waits_for_subscribers_and_delivers_every_message_in_order(
        tiny_bag, ros_context, start_ros_process):
    from stereo_fuzzy_perception.simulation.scene_bag_writer import RIG_TOPICS

    probe = RawProbe(ros_context, {**scene_types(), **RIG_TOPICS})
    try:
        player = start_ros_process(PACKAGE, 'bag', 'play', str(tiny_bag), '--rate', '4',
                                   '--wait-for-subscribers')
        expected = bag_messages(tiny_bag)
        wait_until(lambda: probe.count() >= 13, TIMEOUT,
                   f'13 messages from bag play:\n{player.output()}', probe.executor)
        assert wait_for_exit(player, probe.executor, 'bag play') == 0
        assert dict(probe.received) == dict(expected), 'played bytes differ from the bag'
        assert 'published 13 messages' in player.output()
    finally:
        probe.close()


def test_play_topic_selection_remap_and_start_offset(tiny_bag, ros_context, start_ros_process):
    topics = scene_types()
    watched = {'/sim/target': topics['/ground_truth/target'],
               '/ground_truth/target': topics['/ground_truth/target'],
               '/left/camera_info': topics['/left/camera_info'],
               '/right/camera_info': topics['/right/camera_info']}
    probe = RawProbe(ros_context, watched)
    try:
        player = start_ros_process(
            PACKAGE, 'bag', 'play', str(tiny_bag), '--topics', '/ground_truth/target',
            'left/camera_info', '--remap', '/ground_truth/target:=/sim/target',
            '--start-offset', '0.5', '--rate', '2', '--wait-for-subscribers')
        assert wait_for_exit(player, probe.executor, 'bag play') == 0
        wait_until(lambda: probe.count() >= 2, TIMEOUT, "the second scene's messages",
                   probe.executor)
        expected = bag_messages(tiny_bag, ['/ground_truth/target', '/left/camera_info'])
        # The offset skips the first scene; the remap moves the target; nothing else plays.
        assert probe.received['/sim/target'] == expected['/ground_truth/target'][1:]
        assert probe.received['/left/camera_info'] == expected['/left/camera_info'][1:]
        assert probe.received['/ground_truth/target'] == []
        assert probe.received['/right/camera_info'] == []
    finally:
        probe.close()


def test_play_publishes_the_bag_clock(tiny_bag, ros_context, start_ros_process):
    from rclpy.serialization import deserialize_message
    from rosgraph_msgs.msg import Clock

    probe = RawProbe(ros_context, {'/clock': 'rosgraph_msgs/msg/Clock',
                                   '/ground_truth/target': scene_types()['/ground_truth/target']})
    try:
        player = start_ros_process(PACKAGE, 'bag', 'play', str(tiny_bag), '--clock', '20',
                                   '--topics', '/ground_truth/target', '--wait-for-subscribers')
        assert wait_for_exit(player, probe.executor, 'bag play') == 0
        wait_until(lambda: len(probe.received['/ground_truth/target']) >= 2, TIMEOUT,
                   'both targets', probe.executor)
        times = [deserialize_message(data, Clock).clock for data in probe.received['/clock']]
        seconds = [t.sec + t.nanosec * 1e-9 for t in times]
        assert seconds, 'no /clock message'
        assert all(1_700_000_000.0 <= s <= 1_700_000_001.001 for s in seconds), seconds
        assert seconds == sorted(seconds), 'bag time must not run backwards'
    finally:
        probe.close()


def test_play_loops_until_interrupted(tiny_bag, ros_context, start_ros_process):
    probe = RawProbe(ros_context, {'/ground_truth/target': scene_types()['/ground_truth/target']})
    try:
        player = start_ros_process(PACKAGE, 'bag', 'play', str(tiny_bag), '--loop', '--rate', '8',
                                   '--topics', '/ground_truth/target', '--wait-for-subscribers')
        wait_until(lambda: len(probe.received['/ground_truth/target']) >= 5, TIMEOUT,
                   'the bag played three times', probe.executor)
        assert player.process.poll() is None, 'a looping player must keep playing'
        assert player.interrupt() == 0, player.output()
        one_pass = bag_messages(tiny_bag, ['/ground_truth/target'])['/ground_truth/target']
        received = probe.received['/ground_truth/target']
        assert received[:4] == one_pass + one_pass
    finally:
        probe.close()


def test_play_refuses_a_bad_rate_or_an_unknown_topic(tiny_bag, ros_context, start_ros_process):
    bad_rate = start_ros_process(PACKAGE, 'bag', 'play', str(tiny_bag), '--rate', '0')
    unknown = start_ros_process(PACKAGE, 'bag', 'play', str(tiny_bag), '--topics', '/nope')
    wait_until(lambda: bad_rate.process.poll() is not None and unknown.process.poll() is not None,
               TIMEOUT, 'both players to give up')
    assert bad_rate.process.returncode == 1 and 'rate must be positive' in bad_rate.output()
    assert unknown.process.returncode == 1 and '/nope' in unknown.output()


def wait_acknowledged(*publishers) -> None:
    """Wait until every subscriber acknowledged every message (reliable QoS)."""
    from rclpy.duration import Duration

    for publisher in publishers:
        assert publisher.wait_for_all_acked(Duration(seconds=TIMEOUT)), (
            f'messages on {publisher.topic_name} not acknowledged')


def test_record_writes_what_was_published_with_custom_types_and_qos(
        ros_context, start_ros_process, tmp_path):
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from rclpy.serialization import deserialize_message, serialize_message
    from std_msgs.msg import String
    from stereo_fuzzy_perception.bag.bag_io import read_info

    from stereo_fuzzy_msgs.msg import FuzzyDecision

    node = rclpy.create_node('recorded_publisher', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    try:
        decisions = node.create_publisher(FuzzyDecision, 'best_point/decision', QoSProfile(
            depth=10, reliability=ReliabilityPolicy.RELIABLE,
            durability=DurabilityPolicy.TRANSIENT_LOCAL))
        chatter = node.create_publisher(String, 'chatter', 10)
        ignored = node.create_publisher(String, 'not_recorded', 10)
        output = tmp_path / 'recorded'
        recorder = start_ros_process(PACKAGE, 'bag', 'record', '-o', str(output),
                                     '/best_point/decision', 'chatter', '--max-messages', '4')
        wait_until(lambda: decisions.get_subscription_count() > 0
                   and chatter.get_subscription_count() > 0, TIMEOUT,
                   f'the recorder to subscribe:\n{recorder.output()}', executor)
        sent_decisions = []
        for k in range(2):
            decision = FuzzyDecision(selector=f'fuzzy_{k}', has_best_point=bool(k),
                                     rule_names=['near', 'far'], firing_strengths=[0.25, k])
            decision.header.frame_id = 'world'
            decision.best_point_world.z = 0.01 * k
            sent_decisions.append(decision)
            decisions.publish(decision)
        ignored.publish(String(data='nobody records me'))
        for text in ('a', 'b'):
            chatter.publish(String(data=text))
        wait_acknowledged(decisions, chatter)
        assert wait_for_exit(recorder, executor, 'bag record') == 0
        assert 'recorded 4 messages' in recorder.output()
    finally:
        executor.shutdown()
        node.destroy_node()
    info = read_info(output)
    counts = {t.name: (t.msgtype, t.message_count) for t in info.topics}
    assert counts == {'/best_point/decision': ('stereo_fuzzy_msgs/msg/FuzzyDecision', 2),
                      '/chatter': ('std_msgs/msg/String', 2)}
    durability = info.topic('/best_point/decision').offered_qos[0].durability.name
    assert durability == 'TRANSIENT_LOCAL'
    # Field equality: rclpy's serializer leaves memory garbage in alignment padding.
    recorded = bag_messages(output)
    assert [deserialize_message(data, FuzzyDecision)
            for data in recorded['/best_point/decision']] == sent_decisions
    assert recorded['/chatter'] == [
        dds_padded(serialize_message(String(data=t))) for t in ('a', 'b')]


def test_record_stops_cleanly_on_sigint(
        ros_context, start_ros_process, tmp_path):
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.serialization import serialize_message
    from std_msgs.msg import String
    from stereo_fuzzy_perception.bag.bag_io import read_info

    node = rclpy.create_node('sigint_publisher', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    output = tmp_path / 'interrupted'
    try:
        chatter = node.create_publisher(String, 'chatter', 10)
        recorder = start_ros_process(PACKAGE, 'bag', 'record', '-o', str(output), '--all')
        wait_until(lambda: chatter.get_subscription_count() > 0, TIMEOUT,
                   f'the recorder to subscribe:\n{recorder.output()}', executor)
        for text in ('one', 'two', 'three'):
            chatter.publish(String(data=text))
        wait_acknowledged(chatter)
        assert recorder.interrupt() == 0, recorder.output()
    finally:
        executor.shutdown()
        node.destroy_node()
    info = read_info(output)
    assert [t.name for t in info.topics] == ['/chatter'], 'rosout and parameter events excluded'
    assert info.topic('/chatter').message_count == 3
    assert bag_messages(output)['/chatter'] == [
        dds_padded(serialize_message(String(data=t))) for t in ('one', 'two', 'three')]


# --- parity with ros2 bag -----------------------------------------------------------------------

UNKNOWN_TYPE = 'not_installed_msgs/msg/Thing'


def _typestore_with_unknown_type():
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    typestore = get_typestore(Stores.ROS2_JAZZY)
    typestore.register(get_types_from_msg('int32 value', UNKNOWN_TYPE))
    return typestore


def chatter_bytes(typestore, text: str) -> bytes:
    return bytes(typestore.serialize_cdr(typestore.types['std_msgs/msg/String'](data=text),
                                         'std_msgs/msg/String'))


@pytest.fixture
def mixed_bag(tmp_path) -> Path:
    """A bag written by rosbags: /chatter (3 strings, 0.1 s apart) and /thing, whose type is
    installed nowhere (as /tf_static's tf2_msgs is not on this machine)."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    typestore = _typestore_with_unknown_type()
    path = tmp_path / 'mixed'
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        chatter = writer.add_connection('/chatter', 'std_msgs/msg/String', typestore=typestore)
        thing = writer.add_connection('/thing', UNKNOWN_TYPE, typestore=typestore)
        for k in range(3):
            writer.write(chatter, 1_000_000_000 + k * 100_000_000,
                         chatter_bytes(typestore, f'hello {k}'))
            writer.write(thing, 1_000_000_001 + k * 100_000_000, bytes(8))
    return path


def test_play_skips_a_type_that_is_not_installed_and_plays_the_rest(
        mixed_bag, ros_context, start_ros_process):
    probe = RawProbe(ros_context, {'/chatter': 'std_msgs/msg/String'})
    try:
        player = start_ros_process(PACKAGE, 'bag', 'play', str(mixed_bag),
                                   '--wait-for-subscribers')
        assert wait_for_exit(player, probe.executor, 'bag play') == 0, player.output()
        wait_until(lambda: probe.count() >= 3, TIMEOUT, 'the three strings', probe.executor)
        assert probe.received['/chatter'] == bag_messages(mixed_bag)['/chatter']
        assert f'skipping /thing: its type {UNKNOWN_TYPE} is not installed' in player.output()
        assert 'published 3 messages' in player.output()
    finally:
        probe.close()


def _write_single_mcap(path: Path, indexed: bool) -> None:
    """20 strings in one .mcap file: by the mcap library's ROS 2 writer, or by the bare mcap
    writer without chunks, index or summary (as old writers left files)."""
    from mcap.writer import IndexType
    from mcap.writer import Writer as McapWriter
    from mcap_ros2.writer import Writer as Ros2Writer

    typestore = _typestore_with_unknown_type()
    with path.open('wb') as stream:
        if indexed:
            writer = Ros2Writer(stream)
            schema = writer.register_msgdef('std_msgs/msg/String', 'string data')
            for k in range(20):
                writer.write_message('/chatter', schema, {'data': f'm{k}'},
                                     log_time=2_000_000_000 + k * 10_000_000)
            writer.finish()
            return
        writer = McapWriter(stream, use_chunking=False, use_statistics=False,
                            use_summary_offsets=False, index_types=IndexType.NONE)
        writer.start(profile='ros2', library='an old writer')
        schema_id = writer.register_schema('std_msgs/msg/String', 'ros2msg', b'string data')
        channel = writer.register_channel('/chatter', 'cdr', schema_id)
        for k in range(20):
            stamp = 2_000_000_000 + k * 10_000_000
            writer.add_message(channel, log_time=stamp, publish_time=stamp,
                               data=chatter_bytes(typestore, f'm{k}'))
        writer.finish()


@pytest.mark.parametrize('indexed', [True, False], ids=['mcap_ros2_writer', 'unindexed'])
def test_play_a_single_mcap_file_written_by_the_mcap_library(
        tmp_path, ros_context, start_ros_process, indexed):
    path = tmp_path / 'single.mcap'
    _write_single_mcap(path, indexed)
    probe = RawProbe(ros_context, {'/chatter': 'std_msgs/msg/String'})
    try:
        player = start_ros_process(PACKAGE, 'bag', 'play', str(path), '--rate', '4',
                                   '--wait-for-subscribers')
        assert wait_for_exit(player, probe.executor, 'bag play') == 0, player.output()
        wait_until(lambda: probe.count() >= 20, TIMEOUT, 'twenty strings', probe.executor)
        from rclpy.serialization import deserialize_message
        from std_msgs.msg import String

        assert [deserialize_message(data, String).data for data in probe.received['/chatter']
                ] == [f'm{k}' for k in range(20)]
        info = subprocess.run([str(executable_path(PACKAGE, 'bag')), 'info', str(path)],
                              capture_output=True, text=True, timeout=60)
        assert 'Topic: /chatter | Type: std_msgs/msg/String | Count: 20 |' in info.stdout
    finally:
        probe.close()


def test_play_fails_when_the_bag_promises_messages_it_cannot_play(
        mixed_bag, ros_context, start_ros_process):
    import yaml

    metadata_file = mixed_bag / 'metadata.yaml'
    metadata = yaml.safe_load(metadata_file.read_text())
    for entry in metadata['rosbag2_bagfile_information']['topics_with_message_count']:
        if entry['topic_metadata']['name'] == '/chatter':
            entry['message_count'] = 5  # the file holds 3
    metadata_file.write_text(yaml.safe_dump(metadata))
    player = start_ros_process(PACKAGE, 'bag', 'play', str(mixed_bag), '--delay', '0')
    wait_until(lambda: player.process.poll() is not None, TIMEOUT, 'bag play to give up')
    assert player.process.returncode == 1, player.output()
    assert 'promises 5 messages on the played topics but only 3' in player.output()


def _call(node, executor, service: str) -> str:
    from std_srvs.srv import Trigger

    client = node.create_client(Trigger, service)
    wait_until(client.service_is_ready, TIMEOUT, f'the service {service}', executor)
    future = client.call_async(Trigger.Request())
    wait_until(future.done, TIMEOUT, f'{service} to answer', executor)
    return future.result().message


def test_start_paused_step_resume_with_a_qos_override_and_an_exclusion(
        mixed_bag, tmp_path, ros_context, start_ros_process):
    from rclpy.qos import DurabilityPolicy

    overrides = tmp_path / 'qos.yaml'
    overrides.write_text('/chatter:\n  history: keep_last\n  depth: 7\n'
                         '  reliability: reliable\n  durability: transient_local\n')
    probe = RawProbe(ros_context, {'/chatter': 'std_msgs/msg/String'})
    try:
        player = start_ros_process(
            PACKAGE, 'bag', 'play', str(mixed_bag), '--start-paused', '--exclude-regex', 'thi',
            '--qos-profile-overrides-path', str(overrides), '--wait-for-subscribers',
            '--progress', 'always')
        node = probe.node
        assert _call(node, probe.executor, '/bag_player/is_paused') == 'paused'
        offered = node.get_publishers_info_by_topic('/chatter')
        # (the graph shows durability and reliability; depth is not announced over DDS)
        assert [i.qos_profile.durability for i in offered] == [DurabilityPolicy.TRANSIENT_LOCAL]
        assert node.get_publishers_info_by_topic('/thing') == [], 'excluded topic published'
        assert probe.count() == 0, 'a paused player published'
        _call(node, probe.executor, '/bag_player/play_next')
        wait_until(lambda: probe.count() == 1, TIMEOUT, 'one stepped message', probe.executor)
        assert _call(node, probe.executor, '/bag_player/is_paused') == 'paused'
        assert probe.count() == 1
        assert _call(node, probe.executor, '/bag_player/resume') == 'playing'
        assert wait_for_exit(player, probe.executor, 'bag play') == 0, player.output()
        wait_until(lambda: probe.count() >= 3, TIMEOUT, 'the rest', probe.executor)
        assert probe.received['/chatter'] == bag_messages(mixed_bag)['/chatter']
        assert '[paused]' in player.output() and 'bag time' in player.output()
    finally:
        probe.close()


def test_play_regex_and_duration(tiny_bag, ros_context, start_ros_process):
    topics = scene_types()
    probe = RawProbe(ros_context, {name: topics[name] for name in
                                   ('/ground_truth/target', '/left/camera_info')})
    try:
        player = start_ros_process(PACKAGE, 'bag', 'play', str(tiny_bag), '--regex',
                                   'target$', '--playback-duration', '0.5',
                                   '--wait-for-subscribers')
        assert wait_for_exit(player, probe.executor, 'bag play') == 0, player.output()
        wait_until(lambda: probe.count() >= 1, TIMEOUT, 'the first target', probe.executor)
        expected = bag_messages(tiny_bag, ['/ground_truth/target'])['/ground_truth/target']
        assert probe.received['/ground_truth/target'] == expected[:1]
        assert probe.received['/left/camera_info'] == []
        assert 'published 1 messages' in player.output()
    finally:
        probe.close()


def test_record_default_name_regex_exclusion_and_split(ros_context, tmp_path):
    import os
    import re

    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from std_msgs.msg import String
    from stereo_fuzzy_perception.bag.bag_io import read_info

    node = rclpy.create_node('split_publisher', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    log = tmp_path / 'record.log'
    with open(log, 'wb') as output:
        recorder = subprocess.Popen(
            [str(executable_path(PACKAGE, 'bag')), 'record', '--regex', '^/chat',
             '--exclude-topics', '/chatter_noise', '--max-bag-size', '1', '--max-messages', '3'],
            cwd=tmp_path, stdout=output, stderr=subprocess.STDOUT,
            env=dict(os.environ, PYTHONUNBUFFERED='1'))
    try:
        chatter = node.create_publisher(String, 'chatter', 10)
        noise = node.create_publisher(String, 'chatter_noise', 10)
        wait_until(lambda: chatter.get_subscription_count() > 0, TIMEOUT,
                   'the recorder to subscribe', executor)
        for text in ('a', 'b', 'c'):
            noise.publish(String(data='noise'))
            chatter.publish(String(data=text))
        wait_acknowledged(chatter)
        wait_until(lambda: recorder.poll() is not None, TIMEOUT, 'the recorder to stop',
                   executor)
    finally:
        if recorder.poll() is None:
            recorder.kill()
        executor.shutdown()
        node.destroy_node()
    assert recorder.returncode == 0, log.read_text()
    made = [p for p in tmp_path.iterdir() if p.is_dir()]
    assert len(made) == 1 and re.fullmatch(r'rosbag2_\d{4}_\d\d_\d\d-\d\d_\d\d_\d\d',
                                           made[0].name), made
    info = read_info(made[0])
    assert [(t.name, t.message_count) for t in info.topics] == [('/chatter', 3)]
    assert len(info.files) == 3, 'every message past the size limit starts a new file'
    assert [f.name for f in info.files] == [f'{made[0].name}_{k}.mcap' for k in range(3)]
