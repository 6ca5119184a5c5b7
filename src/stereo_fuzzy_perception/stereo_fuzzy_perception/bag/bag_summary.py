"""What a bag holds (its topics, counts, times, QoS) and the text `bag info` prints for it.

ROS-free: rosbags and the standard library only.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from rosbags.interfaces import Qos


@dataclass(frozen=True)
class TopicInfo:
    """One topic of a bag."""

    name: str
    msgtype: str
    message_count: int
    serialization_format: str = 'cdr'
    offered_qos: tuple[Qos, ...] = ()
    msgdef: str = ''
    type_hash: str = ''


@dataclass(frozen=True)
class BagInfo:
    """Summary of a bag, what `bag info` prints."""

    path: Path
    files: tuple[Path, ...]
    size_bytes: int
    storage: str
    compression: str
    start_ns: int
    end_ns: int
    message_count: int
    topics: tuple[TopicInfo, ...] = field(default_factory=tuple)
    custom_data: tuple[tuple[str, str], ...] = ()
    has_metadata: bool = True

    @property
    def duration_ns(self) -> int:
        """Return end - start [ns]."""
        return max(0, self.end_ns - self.start_ns)

    def topic(self, name: str) -> TopicInfo:
        """Return the topic called `name`.

        Raises:
            KeyError: When the bag has no such topic.
        """
        for topic in self.topics:
            if topic.name == name:
                return topic
        raise KeyError(f'no topic {name} in {self.path}; topics: '
                       + ', '.join(t.name for t in self.topics))


def _human_size(size: float) -> str:
    for unit in ('B', 'KiB', 'MiB', 'GiB'):
        if size < 1024.0 or unit == 'GiB':
            return f'{size:.1f} {unit}' if unit != 'B' else f'{int(size)} B'
        size /= 1024.0
    return f'{size:.1f} GiB'


def _qos_summary(profiles: Sequence[Qos]) -> str:
    if not profiles:
        return 'unknown'
    return '; '.join(f'{p.reliability.name.lower()}, {p.durability.name.lower()}, '
                     f'{p.history.name.lower()} {p.depth}' for p in profiles)


def _seconds(time_ns: int) -> str:
    return f'{time_ns // 1_000_000_000}.{time_ns % 1_000_000_000:09d}'


def format_info(info: BagInfo) -> str:
    """Return the text `bag info` prints, laid out like `ros2 bag info`."""
    lines = [
        f'Files:             {", ".join(p.name for p in info.files)}',
        f'Bag size:          {_human_size(info.size_bytes)}',
        f'Storage id:        {info.storage}',
        f'Compression:       {info.compression}',
        f'Duration:          {_seconds(info.duration_ns)} s',
        f'Start:             {_seconds(info.start_ns)} ({info.start_ns} ns)',
        f'End:               {_seconds(info.end_ns)} ({info.end_ns} ns)',
        f'Messages:          {info.message_count}',
        'Topic information:',
    ]
    for topic in info.topics:
        lines.append(f'  Topic: {topic.name} | Type: {topic.msgtype} | '
                     f'Count: {topic.message_count} | Serialization Format: '
                     f'{topic.serialization_format} | QoS: {_qos_summary(topic.offered_qos)}')
    if info.custom_data:
        lines.append('Custom data:')
        for key, value in info.custom_data:
            lines.append(f'  {key}: ' + value.replace('\n', '\n    '))
    if not info.has_metadata:
        lines.append('(no metadata.yaml: counts and times read from the MCAP file)')
    return '\n'.join(lines)
