"""The bag tool's library in one import: reading, writing, summaries, topic selection, timing.

Each name lives in the module that says what it is; this module gathers them for callers:
`bag_format` (the error type, QoS profiles, topic names), `bag_writer` (BagWriter),
`bag_reader` (read_info, read_messages), `bag_summary` (BagInfo, TopicInfo, format_info),
`topic_selection` (select_topics, parse_remaps), `playback_clock` (PlaybackClock,
playback_delay_s) and `message_types` (the typestore with this project's types).

ROS-free: rosbags, mcap, PyYAML and the standard library only.
"""

from stereo_fuzzy_perception.bag.bag_format import DEFAULT_QOS, BagError, absolute_topic, make_qos
from stereo_fuzzy_perception.bag.bag_reader import BagMessage, read_info, read_messages
from stereo_fuzzy_perception.bag.bag_summary import BagInfo, TopicInfo, format_info
from stereo_fuzzy_perception.bag.bag_writer import COMPRESSIONS, BagWriter
from stereo_fuzzy_perception.bag.playback_clock import PlaybackClock, playback_delay_s
from stereo_fuzzy_perception.bag.topic_selection import parse_remaps, select_topics

__all__ = [
    'COMPRESSIONS',
    'DEFAULT_QOS',
    'BagError',
    'BagInfo',
    'BagMessage',
    'BagWriter',
    'PlaybackClock',
    'TopicInfo',
    'absolute_topic',
    'format_info',
    'make_qos',
    'parse_remaps',
    'playback_delay_s',
    'read_info',
    'read_messages',
    'select_topics',
]
