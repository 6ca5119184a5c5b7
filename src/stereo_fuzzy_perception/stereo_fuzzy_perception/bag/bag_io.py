"""rosbag2 bags with the MCAP storage plugin: write, read, summarise; playback timing; remaps.

Bags are rosbag2 directories (metadata.yaml + .mcap files) written with rosbags, so `ros2 bag`,
rosbags and Foxglove all open them. Reading goes through the mcap library, so single .mcap files
(without metadata.yaml) and files without a summary section open too. Messages stay CDR bytes
throughout: the player publishes them as they are and the recorder stores what it receives.

ROS-free: rosbags, mcap, PyYAML and the standard library only.
"""

from __future__ import annotations

import contextlib
import functools
import math
import re
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml
from rosbags.interfaces import (
    Connection,
    Qos,
    QosDurability,
    QosHistory,
    QosLiveliness,
    QosReliability,
    QosTime,
)
from rosbags.rosbag2 import (
    CompressionFormat,
    CompressionMode,
    StoragePlugin,
    Writer,
)
from rosbags.rosbag2.errors import ReaderError, WriterError
from rosbags.rosbag2.metadata import parse_qos
from rosbags.typesys.store import Typestore

from stereo_fuzzy_perception.bag.message_types import project_typestore

try:  # Python 3.14 has it in the standard library; rosbags depends on the backport before.
    from compression import zstd  # type: ignore[import-not-found]
except ImportError:  # pragma: no cover
    from backports import zstd

COMPRESSIONS = ('zstd', 'none')
_NO_TIME = QosTime(sec=0, nsec=0)


class BagError(RuntimeError):
    """A bag that cannot be read or written, with the path and the reason in the message."""


def make_qos(reliable: bool = True, depth: int = 10, transient_local: bool = False) -> Qos:
    """Return a rosbags QoS profile (keep last `depth`; default deadline, lifespan, liveliness)."""
    return Qos(
        history=QosHistory.KEEP_LAST, depth=depth,
        reliability=QosReliability.RELIABLE if reliable else QosReliability.BEST_EFFORT,
        durability=QosDurability.TRANSIENT_LOCAL if transient_local else QosDurability.VOLATILE,
        deadline=_NO_TIME, lifespan=_NO_TIME, liveliness=QosLiveliness.AUTOMATIC,
        liveliness_lease_duration=_NO_TIME, avoid_ros_namespace_conventions=False)


DEFAULT_QOS = make_qos()


# --- writing ---------------------------------------------------------------------------------


class BagWriter:
    """Write a new rosbag2 directory with the MCAP storage plugin (use as a context manager).

    Topics may be added at any time before the messages written to them. Compression 'zstd'
    compresses MCAP chunks (storage-level, what `ros2 bag record --storage-preset-profile
    zstd_fast` does), so every MCAP reader opens the file without a rosbag2 decompressor.
    With a size or duration limit the bag is split as rosbag2 splits it: files
    <name>_0.mcap, <name>_1.mcap, ... listed in one metadata.yaml.
    """

    def __init__(self, path: Path | str, compression: str = 'zstd',
                 compression_level: int | None = None,
                 typestore: Typestore | None = None, max_bag_size: int = 0,
                 max_bag_duration_ns: int = 0) -> None:
        """Create the bag directory.

        Args:
            path: The bag directory to create; must not exist.
            compression: 'zstd' (chunk compression) or 'none'.
            compression_level: zstd level (1-22); rosbags' default (3) when None.
            typestore: Types to take definitions from (Jazzy's plus this project's when None).
            max_bag_size: Start a new file once the current one holds about this many bytes
                (0: no limit; the chunk in memory counts uncompressed).
            max_bag_duration_ns: Start a new file once a message is this much later than the
                file's first [ns] (0: no limit).

        Raises:
            BagError: When the directory exists, the compression is unknown or a limit is
                negative.
        """
        if compression not in COMPRESSIONS:
            raise BagError(f'unknown compression {compression!r}; expected one of '
                           + ', '.join(COMPRESSIONS))
        if max_bag_size < 0 or max_bag_duration_ns < 0:
            raise BagError('split limits must not be negative, got '
                           f'{max_bag_size} bytes, {max_bag_duration_ns} ns')
        self.path = Path(path)
        if self.path.exists():
            raise BagError(f'{self.path} exists already, not overwriting')
        self.typestore = typestore or project_typestore()
        self.compression = compression
        self.compression_level = compression_level
        self.max_bag_size = max_bag_size
        self.max_bag_duration_ns = max_bag_duration_ns
        self._splitting = bool(max_bag_size or max_bag_duration_ns)
        self._topics: dict[str, tuple[str, tuple[Qos, ...], str | None, str | None]] = {}
        self._custom_data: dict[str, str] = {}
        self._finished_splits: list[dict[str, Any]] = []
        self._closed = False
        if self._splitting:
            self.path.mkdir(parents=True)
        self._open_file()

    def _open_file(self) -> None:
        target = (self.path / f'{self.path.name}_{len(self._finished_splits)}'
                  if self._splitting else self.path)
        try:
            self._writer = Writer(target, version=9, storage_plugin=StoragePlugin.MCAP)
        except WriterError as error:
            raise BagError(str(error)) from None
        if self.compression == 'zstd':
            self._writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
        self._writer.open()
        storage = self._writer.storage
        if self.compression == 'zstd' and self.compression_level is not None:
            # rosbags compresses each chunk with storage.compressor; only the level changes.
            storage.compressor = functools.partial(  # type: ignore[union-attr]
                zstd.compress, level=self.compression_level)
        self._file_path = target / f'{target.name}.mcap'
        self._file_start_ns: int | None = None
        self._connections: dict[str, Connection] = {}
        for topic, (msgtype, qos, msgdef, type_hash) in self._topics.items():
            self._connections[topic] = self._writer.add_connection(
                topic, msgtype, typestore=self.typestore, msgdef=msgdef, rihs01=type_hash,
                offered_qos_profiles=list(qos))

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, exc_type: object, *rest: object) -> None:
        self.close()

    def add_topic(self, topic: str, msgtype: str, offered_qos: Sequence[Qos] = (DEFAULT_QOS,),
                  msgdef: str | None = None, type_hash: str | None = None) -> None:
        """Declare `topic` of `msgtype` with the offered QoS profiles recorded in the metadata.

        Args:
            topic: Absolute topic name.
            msgtype: 'pkg/msg/Type'; its definition comes from the typestore unless `msgdef`
                and `type_hash` are given (as when copying from another bag).
            offered_qos: QoS profiles of the topic's publishers.
            msgdef: Full message definition text (ros2msg with dependencies).
            type_hash: RIHS01 hash of the type.

        Raises:
            BagError: When the topic exists with another type or the type is unknown.
        """
        known = self._topics.get(topic)
        if known is not None:
            if known[0] != msgtype:
                raise BagError(f'topic {topic} is already in {self.path} as {known[0]}, '
                               f'cannot add it as {msgtype}')
            return
        if msgdef is None or type_hash is None:
            from stereo_fuzzy_perception.bag.message_types import register_types
            register_types(self.typestore, [msgtype])
        self._connections[topic] = self._writer.add_connection(
            topic, msgtype, typestore=self.typestore, msgdef=msgdef, rihs01=type_hash,
            offered_qos_profiles=list(offered_qos))
        self._topics[topic] = (msgtype, tuple(offered_qos), msgdef, type_hash)

    def set_custom_data(self, key: str, value: str) -> None:
        """Store `key: value` under custom_data in metadata.yaml (e.g. how the bag was made)."""
        self._custom_data[key] = value
        self._writer.set_custom_data(key, value)

    def _file_full(self, timestamp_ns: int) -> bool:
        if self._file_start_ns is None:
            return False
        if self.max_bag_duration_ns and (
                timestamp_ns - self._file_start_ns >= self.max_bag_duration_ns):
            return True
        return bool(self.max_bag_size) and self._file_size() >= self.max_bag_size

    def _file_size(self) -> int:
        """Return the current file's size, counting the chunk still in memory uncompressed."""
        storage = self._writer.storage
        try:
            return int(storage.bio.tell() + storage.chunk.bio.tell())  # type: ignore[union-attr]
        except AttributeError:  # another rosbags version: what reached the disk
            return self._file_path.stat().st_size

    def write(self, topic: str, timestamp_ns: int, data: bytes) -> None:
        """Append one serialized (CDR) message received or stamped at `timestamp_ns` [ns].

        Raises:
            BagError: When the topic was not added.
        """
        if topic not in self._topics:
            raise BagError(f'topic {topic} was not added to {self.path}')
        if self._splitting and self._file_full(timestamp_ns):
            self._finish_file()
            self._open_file()
        if self._file_start_ns is None:
            self._file_start_ns = int(timestamp_ns)
        self._writer.write(self._connections[topic], int(timestamp_ns), data)

    def _finish_file(self) -> None:
        """Close the current split and move its file up into the bag directory."""
        self._writer.close()
        folder = self._file_path.parent
        metadata_file = folder / 'metadata.yaml'
        information = yaml.safe_load(metadata_file.read_text())['rosbag2_bagfile_information']
        self._file_path.replace(self.path / self._file_path.name)
        metadata_file.unlink()
        folder.rmdir()
        self._finished_splits.append(information)

    def close(self) -> None:
        """Finish the MCAP file(s) and write metadata.yaml (safe to call twice)."""
        if self._closed:
            return
        self._closed = True
        if not self._splitting:
            self._writer.close()
            return
        self._finish_file()
        merged = _merge_split_metadata(self._finished_splits)
        merged['custom_data'] = dict(self._custom_data) or None
        (self.path / 'metadata.yaml').write_text(yaml.safe_dump(
            {'rosbag2_bagfile_information': merged}, default_flow_style=False, sort_keys=False))


def _merge_split_metadata(splits: list[dict[str, Any]]) -> dict[str, Any]:
    """Return one bag's metadata from the metadata of its files, each written as a bag."""
    merged = dict(splits[0])
    merged['relative_file_paths'] = [name for split in splits
                                     for name in split['relative_file_paths']]
    merged['files'] = [entry for split in splits for entry in split['files']]
    counted = [entry for entry in merged['files'] if entry['message_count']]
    if counted:
        start = min(entry['starting_time']['nanoseconds_since_epoch'] for entry in counted)
        end = max(entry['starting_time']['nanoseconds_since_epoch']
                  + entry['duration']['nanoseconds'] for entry in counted)
        merged['starting_time'] = {'nanoseconds_since_epoch': start}
        merged['duration'] = {'nanoseconds': end - start}
    merged['message_count'] = sum(split['message_count'] for split in splits)
    topics: dict[str, dict[str, Any]] = {}
    for split in splits:
        for entry in split['topics_with_message_count']:
            name = entry['topic_metadata']['name']
            if name in topics:
                topics[name]['message_count'] += entry['message_count']
            else:
                topics[name] = {'topic_metadata': entry['topic_metadata'],
                                'message_count': entry['message_count']}
    merged['topics_with_message_count'] = list(topics.values())
    return merged


# --- reading ---------------------------------------------------------------------------------


@dataclass(frozen=True)
class BagMessage:
    """One message of a bag."""

    topic: str
    msgtype: str
    timestamp_ns: int
    data: bytes


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


# --- reporting -------------------------------------------------------------------------------


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


# --- topic selection -------------------------------------------------------------------------


def select_topics(available: Iterable[str], topics: Iterable[str] | None = None,
                  regex: str | None = None, exclude_topics: Iterable[str] = (),
                  exclude_regex: str | None = None) -> tuple[str, ...]:
    """Return the topics of `available` that a selection keeps, in the order of `available`.

    As `ros2 bag play|record`: a topic is kept when it is named in `topics` or matches `regex`
    (everything when neither is given), and then dropped when it is in `exclude_topics` or
    matches `exclude_regex`. Names are made absolute; regexes match anywhere (re.search).

    Raises:
        BagError: For a regex that does not compile.
    """
    def compiled(pattern: str | None, option: str) -> re.Pattern[str] | None:
        if pattern is None:
            return None
        try:
            return re.compile(pattern)
        except re.error as error:
            raise BagError(f'{option} {pattern!r} is not a regular expression ({error})') \
                from None

    include = compiled(regex, '--regex')
    exclude = compiled(exclude_regex, '--exclude-regex')
    named = None if topics is None else {absolute_topic(name) for name in topics}
    excluded = {absolute_topic(name) for name in exclude_topics}
    kept = []
    for topic in available:
        wanted = (named is None and include is None) or (named is not None and topic in named) \
            or (include is not None and include.search(topic) is not None)
        if wanted and topic not in excluded and not (exclude and exclude.search(topic)):
            kept.append(topic)
    return tuple(kept)


# --- playback --------------------------------------------------------------------------------


def parse_remaps(rules: Iterable[str]) -> dict[str, str]:
    """Parse 'old:=new' rules into {old: new}, both made absolute.

    Raises:
        BagError: For a rule without ':=' or with an empty side.
    """
    remaps = {}
    for rule in rules:
        old, separator, new = rule.partition(':=')
        if not separator or not old.strip() or not new.strip():
            raise BagError(f'remap rule {rule!r} is not of the form old_topic:=new_topic')
        remaps[absolute_topic(old.strip())] = absolute_topic(new.strip())
    return remaps


def absolute_topic(name: str) -> str:
    """Return `name` with a leading '/' (bags store absolute topic names)."""
    return name if name.startswith('/') else '/' + name


def playback_delay_s(timestamp_ns: int, first_ns: int, rate: float) -> float:
    """Return when a message is due after playback starts [s] at `rate` times real time.

    Raises:
        BagError: For a rate that is not positive.
    """
    if not rate > 0.0:
        raise BagError(f'playback rate must be positive, got {rate}')
    return max(0, timestamp_ns - first_ns) / 1e9 / rate


class PlaybackClock:
    """Bag time during playback: runs at `rate` times real time, stands still while paused.

    Bag time `first_ns` is "now" when the clock is made; pausing freezes it, resuming goes on
    from where it stood, and jump_to() moves it (a step to the next message while paused).
    """

    def __init__(self, first_ns: int, rate: float, paused: bool = False,
                 now: Callable[[], float] = time.monotonic) -> None:
        """Start the clock at bag time `first_ns`, paused or running.

        Raises:
            BagError: For a rate that is not positive.
        """
        if not rate > 0.0:
            raise BagError(f'playback rate must be positive, got {rate}')
        self._now = now
        self.rate = rate
        self._anchor_bag_ns = first_ns
        self._anchor_wall = now()
        self._paused = paused

    @property
    def paused(self) -> bool:
        """Return True while the clock stands still."""
        return self._paused

    def bag_time_ns(self) -> int:
        """Return the current bag time [ns]."""
        if self._paused:
            return self._anchor_bag_ns
        return self._anchor_bag_ns + round((self._now() - self._anchor_wall) * self.rate * 1e9)

    def pause(self) -> None:
        """Stop the clock where it stands (no effect when paused)."""
        if not self._paused:
            self._anchor_bag_ns = self.bag_time_ns()
            self._paused = True

    def resume(self) -> None:
        """Run the clock on from where it stood (no effect when running)."""
        if self._paused:
            self._anchor_wall = self._now()
            self._paused = False

    def jump_to(self, bag_ns: int) -> None:
        """Set the current bag time to `bag_ns` [ns], paused or running."""
        self._anchor_bag_ns = bag_ns
        self._anchor_wall = self._now()

    def seconds_until(self, bag_ns: int) -> float:
        """Return the wall time until bag time `bag_ns` [s] (inf while paused, 0 if past)."""
        if self._paused:
            return math.inf
        return max(0.0, (bag_ns - self.bag_time_ns()) / 1e9 / self.rate)
