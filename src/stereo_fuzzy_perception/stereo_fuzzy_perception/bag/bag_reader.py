"""Read rosbag2 MCAP bags through the mcap library: their summary and their messages.

Single .mcap files (without metadata.yaml) and files without a summary section open too.
Messages stay CDR bytes: the player publishes them as they are.

ROS-free: mcap, rosbags, PyYAML and the standard library only.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml
from rosbags.interfaces import Qos
from rosbags.rosbag2.errors import ReaderError
from rosbags.rosbag2.metadata import parse_qos

from stereo_fuzzy_perception.bag.bag_format import BagError
from stereo_fuzzy_perception.bag.bag_summary import BagInfo, TopicInfo


@dataclass(frozen=True)
class BagMessage:
    """One message of a bag."""

    topic: str
    msgtype: str
    timestamp_ns: int
    data: bytes


@dataclass(frozen=True)
class _Source:
    """Where a bag's messages are: its MCAP files, and its metadata.yaml if it has one."""

    path: Path
    files: tuple[Path, ...]
    metadata: dict[str, Any] | None


def _open_source(path: Path | str) -> _Source:
    """Return the MCAP files of a rosbag2 directory or of a single .mcap file.

    A directory without metadata.yaml is read from its .mcap files (as `ros2 bag reindex`
    would describe them).

    Raises:
        BagError: When the path is neither, uses another storage or a compression mode other
            than MCAP chunk compression, or lists files that are missing.
    """
    bag = Path(path)
    if bag.is_file():
        if bag.suffix != '.mcap':
            raise BagError(f'{bag} is neither a rosbag2 directory nor an .mcap file')
        return _Source(bag, (bag,), None)
    if not bag.is_dir():
        raise BagError(f'{bag} does not exist (expected a rosbag2 directory or an .mcap file)')
    metadata_file = bag / 'metadata.yaml'
    if not metadata_file.is_file():
        files = tuple(sorted(bag.glob('*.mcap')))
        if not files:
            raise BagError(f'{bag} is not a rosbag2 directory (no metadata.yaml) and holds no '
                           '.mcap file')
        return _Source(bag, files, None)
    try:
        document = yaml.safe_load(metadata_file.read_text())
        metadata = document['rosbag2_bagfile_information']
    except (OSError, yaml.YAMLError, KeyError, TypeError) as error:
        raise BagError(f'{metadata_file}: not rosbag2 metadata ({error})') from None
    storage = metadata.get('storage_identifier', '')
    if storage != 'mcap':
        raise BagError(f'{bag} uses the {storage!r} storage; this tool reads MCAP bags only '
                       '(convert with `ros2 bag convert` or rosbags-convert)')
    mode = str(metadata.get('compression_mode') or '').lower()
    if mode not in ('', 'none'):
        raise BagError(f'{bag} is compressed per {mode} ({metadata.get("compression_format")});'
                       ' only MCAP chunk compression (storage preset zstd_fast) is read here')
    files = tuple(bag / name for name in metadata.get('relative_file_paths', []))
    missing = [str(file) for file in files if not file.is_file()]
    if missing:
        raise BagError(f'{bag}: metadata.yaml lists missing file(s) {", ".join(missing)}')
    return _Source(bag, files, metadata)


def _mcap_summary(path: Path) -> Any:
    from mcap.reader import make_reader

    try:
        with path.open('rb') as stream:
            return make_reader(stream).get_summary()
    except Exception as error:  # the mcap library raises several kinds for a damaged file
        raise BagError(f'cannot read {path}: {error}') from None


def _iter_mcap(path: Path, topics: set[str] | None = None,
               start_ns: int | None = None) -> Iterator[tuple[Any, Any, Any]]:
    """Yield (schema, channel, message) of one MCAP file in log-time order."""
    from mcap.reader import make_reader

    with path.open('rb') as stream:
        reader = make_reader(stream)
        try:
            yield from reader.iter_messages(topics=None if topics is None else list(topics),
                                            starting_at=start_ns, log_time_order=True)
        except BagError:
            raise
        except Exception as error:  # a damaged or truncated file
            raise BagError(f'cannot read {path}: {error}') from None


@dataclass
class _TopicAccumulator:
    msgtype: str
    msgdef: str
    encoding: str
    qos: tuple[Qos, ...]
    type_hash: str
    count: int = 0


def _channel_qos(channel: Any) -> tuple[Qos, ...]:
    text = channel.metadata.get('offered_qos_profiles', '')
    try:
        return tuple(parse_qos(text)) if text else ()
    except ReaderError:
        return ()


def _scan(source: _Source) -> tuple[dict[str, _TopicAccumulator], int, int, set[str]]:
    """Return topics, first and last log time and chunk compressions from the MCAP files,
    from their summaries where they have one and by reading the messages otherwise."""
    topics: dict[str, _TopicAccumulator] = {}
    first, last = None, None
    compressions: set[str] = set()

    def learn(schema: Any, channel: Any) -> _TopicAccumulator:
        known = topics.get(channel.topic)
        if known is None:
            known = topics[channel.topic] = _TopicAccumulator(
                msgtype=schema.name if schema is not None else '',
                msgdef=schema.data.decode(errors='replace') if schema is not None else '',
                encoding=channel.message_encoding, qos=_channel_qos(channel),
                type_hash=channel.metadata.get('topic_type_hash', ''))
        return known

    for path in source.files:
        summary = _mcap_summary(path)
        if summary is not None and summary.statistics is not None and summary.chunk_indexes:
            compressions.update(index.compression for index in summary.chunk_indexes)
            counts = summary.statistics.channel_message_counts
            for channel_id, channel in summary.channels.items():
                learn(summary.schemas.get(channel.schema_id), channel).count += counts.get(
                    channel_id, 0)
            if summary.statistics.message_count:
                start = summary.statistics.message_start_time
                end = summary.statistics.message_end_time
                first = start if first is None else min(first, start)
                last = end if last is None else max(last, end)
            continue
        # No index (an old or unfinished file): read it through.
        for schema, channel, message in _iter_mcap(path):
            learn(schema, channel).count += 1
            first = message.log_time if first is None else min(first, message.log_time)
            last = message.log_time if last is None else max(last, message.log_time)
    return topics, first or 0, last or 0, compressions


def read_info(path: Path | str) -> BagInfo:
    """Return the summary of the bag at `path` (a rosbag2 MCAP directory or one .mcap file).

    Counts, times and QoS come from metadata.yaml when the bag has one (what `ros2 bag info`
    shows), from the MCAP files otherwise.

    Raises:
        BagError: When it is not a readable bag.
    """
    source = _open_source(path)
    scanned, first_ns, last_ns, compressions = _scan(source)
    metadata = source.metadata
    recorded: dict[str, dict[str, Any]] = {}
    if metadata is not None:
        for entry in metadata.get('topics_with_message_count', []):
            topic = entry.get('topic_metadata', {})
            recorded[topic.get('name', '')] = {**topic, 'count': entry.get('message_count', 0)}
    topics = []
    for name in sorted(set(scanned) | set(recorded)):
        found, listed = scanned.get(name), recorded.get(name)
        qos: tuple[Qos, ...] = found.qos if found else ()
        if listed is not None and listed.get('offered_qos_profiles'):
            with contextlib.suppress(ReaderError):
                qos = tuple(parse_qos(listed['offered_qos_profiles']))
        topics.append(TopicInfo(
            name=name,
            msgtype=listed['type'] if listed else found.msgtype if found else '',
            message_count=int(listed['count']) if listed else found.count if found else 0,
            serialization_format=(listed or {}).get('serialization_format')
            or (found.encoding if found else 'cdr'),
            offered_qos=qos, msgdef=found.msgdef if found else '',
            type_hash=(listed or {}).get('type_description_hash')
            or (found.type_hash if found else '')))
    message_count = sum(topic.message_count for topic in topics)
    if metadata is not None and message_count:
        start_ns = int(metadata.get('starting_time', {}).get('nanoseconds_since_epoch', 0))
        end_ns = start_ns + int(metadata.get('duration', {}).get('nanoseconds', 0))
    else:
        start_ns, end_ns = first_ns, last_ns
    custom = (metadata or {}).get('custom_data') or {}
    bag = source.path
    size = sum(p.stat().st_size for p in (bag.iterdir() if bag.is_dir() else [bag]))
    return BagInfo(
        path=bag, files=source.files, size_bytes=size, storage='mcap',
        compression=', '.join(sorted(c for c in compressions if c)) or 'none',
        start_ns=start_ns, end_ns=end_ns, message_count=message_count,
        topics=tuple(topics),
        custom_data=tuple(sorted((str(k), str(v)) for k, v in custom.items())),
        has_metadata=metadata is not None)


def read_messages(path: Path | str, topics: Iterable[str] | None = None,
                  start_offset_ns: int = 0) -> Iterator[BagMessage]:
    """Yield the bag's messages in time order (bytes as stored), file after file.

    Args:
        path: The bag directory or .mcap file.
        topics: Only these topics (all when None).
        start_offset_ns: Skip messages earlier than the bag's start plus this [ns].

    Raises:
        BagError: When the bag cannot be read or a requested topic is not in it.
    """
    source = _open_source(path)
    wanted = None if topics is None else set(topics)
    start = None
    if wanted is not None or start_offset_ns > 0:
        info = read_info(path)
        if wanted is not None:
            missing = wanted - {topic.name for topic in info.topics}
            if missing:
                raise BagError(f'{path} has no topic(s) {", ".join(sorted(missing))}; it has '
                               + ', '.join(topic.name for topic in info.topics))
        if start_offset_ns > 0:
            start = info.start_ns + start_offset_ns
    if wanted is not None and not wanted:
        return
    for file in source.files:
        for schema, channel, message in _iter_mcap(file, wanted, start):
            yield BagMessage(channel.topic, schema.name if schema is not None else '',
                             message.log_time, bytes(message.data))
