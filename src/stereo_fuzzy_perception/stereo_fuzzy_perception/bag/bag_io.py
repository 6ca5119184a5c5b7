"""rosbag2 bags with the MCAP storage plugin: write, read, summarise; playback timing; remaps.

Bags are rosbag2 directories (metadata.yaml + one .mcap file), written and read with rosbags,
so `ros2 bag`, rosbags and Foxglove all open them. Messages stay CDR bytes throughout: the player
publishes them as they are and the recorder stores what it receives.

ROS-free: rosbags and the standard library only.
"""

from __future__ import annotations

import functools
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from rosbags.interfaces import (
    Connection,
    ConnectionExtRosbag2,
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
    Reader,
    StoragePlugin,
    Writer,
)
from rosbags.rosbag2.errors import ReaderError, WriterError
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
    """

    def __init__(self, path: Path | str, compression: str = 'zstd',
                 compression_level: int | None = None,
                 typestore: Typestore | None = None) -> None:
        """Create the bag directory.

        Args:
            path: The bag directory to create; must not exist.
            compression: 'zstd' (chunk compression) or 'none'.
            compression_level: zstd level (1-22); rosbags' default (3) when None.
            typestore: Types to take definitions from (Jazzy's plus this project's when None).

        Raises:
            BagError: When the directory exists or the compression is unknown.
        """
        if compression not in COMPRESSIONS:
            raise BagError(f'unknown compression {compression!r}; expected one of '
                           + ', '.join(COMPRESSIONS))
        self.path = Path(path)
        self.typestore = typestore or project_typestore()
        try:
            self._writer = Writer(self.path, version=9, storage_plugin=StoragePlugin.MCAP)
        except WriterError as error:
            raise BagError(str(error)) from None
        if compression == 'zstd':
            self._writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
        self._writer.open()
        storage = self._writer.storage
        if compression == 'zstd' and compression_level is not None:
            # rosbags compresses each chunk with storage.compressor; only the level changes.
            storage.compressor = functools.partial(  # type: ignore[union-attr]
                zstd.compress, level=compression_level)
        self._connections: dict[str, Connection] = {}
        self._closed = False

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
        known = self._connections.get(topic)
        if known is not None:
            if known.msgtype != msgtype:
                raise BagError(f'topic {topic} is already in {self.path} as {known.msgtype}, '
                               f'cannot add it as {msgtype}')
            return
        if msgdef is None or type_hash is None:
            from stereo_fuzzy_perception.bag.message_types import register_types
            register_types(self.typestore, [msgtype])
        self._connections[topic] = self._writer.add_connection(
            topic, msgtype, typestore=self.typestore, msgdef=msgdef, rihs01=type_hash,
            offered_qos_profiles=list(offered_qos))

    def set_custom_data(self, key: str, value: str) -> None:
        """Store `key: value` under custom_data in metadata.yaml (e.g. how the bag was made)."""
        self._writer.set_custom_data(key, value)

    def write(self, topic: str, timestamp_ns: int, data: bytes) -> None:
        """Append one serialized (CDR) message received or stamped at `timestamp_ns` [ns].

        Raises:
            BagError: When the topic was not added.
        """
        connection = self._connections.get(topic)
        if connection is None:
            raise BagError(f'topic {topic} was not added to {self.path}')
        self._writer.write(connection, int(timestamp_ns), data)

    def close(self) -> None:
        """Finish the MCAP file and write metadata.yaml (safe to call twice)."""
        if not self._closed:
            self._closed = True
            self._writer.close()


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


def _open_reader(path: Path | str) -> Reader:
    bag = Path(path)
    if not (bag / 'metadata.yaml').is_file():
        raise BagError(f'{bag} is not a rosbag2 directory (no metadata.yaml)')
    try:
        reader = Reader(bag)
        reader.open()
    except ReaderError as error:
        raise BagError(f'cannot open {bag}: {error}') from None
    return reader


def _storage_compression(files: Iterable[Path]) -> str:
    """Return the MCAP chunk compression of the first chunk ('' when uncompressed)."""
    for path in files:
        if path.suffix != '.mcap':
            continue
        from mcap.reader import make_reader
        with path.open('rb') as stream:
            summary = make_reader(stream).get_summary()
        if summary and summary.chunk_indexes:
            return summary.chunk_indexes[0].compression
    return ''


def read_info(path: Path | str) -> BagInfo:
    """Return the summary of the bag at `path`.

    Raises:
        BagError: When it is not a readable rosbag2 directory.
    """
    reader = _open_reader(path)
    try:
        counts: dict[str, int] = {}
        topics = []
        for connection in reader.connections:
            counts[connection.topic] = counts.get(connection.topic, 0) + connection.msgcount
        seen = set()
        for connection in reader.connections:
            if connection.topic in seen:
                continue
            seen.add(connection.topic)
            ext = connection.ext
            qos = tuple(ext.offered_qos_profiles) if isinstance(ext, ConnectionExtRosbag2) else ()
            topics.append(TopicInfo(
                name=connection.topic, msgtype=connection.msgtype,
                message_count=counts[connection.topic],
                serialization_format=getattr(ext, 'serialization_format', 'cdr'),
                offered_qos=qos, msgdef=connection.msgdef.data, type_hash=connection.digest))
        bag = Path(path)
        files = tuple(sorted(p for p in bag.iterdir() if p.name != 'metadata.yaml'))
        compression = reader.compression_format or _storage_compression(files)
        empty = reader.message_count == 0
        return BagInfo(
            path=bag, files=files, size_bytes=sum(p.stat().st_size for p in bag.iterdir()),
            storage='mcap' if any(p.suffix == '.mcap' for p in files) else 'sqlite3',
            compression=compression or 'none',
            start_ns=0 if empty else reader.start_time,
            end_ns=0 if empty else reader.end_time - 1,
            message_count=reader.message_count,
            topics=tuple(sorted(topics, key=lambda t: t.name)))
    finally:
        reader.close()


def read_messages(path: Path | str, topics: Iterable[str] | None = None,
                  start_offset_ns: int = 0) -> Iterator[BagMessage]:
    """Yield the bag's messages in time order (bytes as stored).

    Args:
        path: The bag directory.
        topics: Only these topics (all when None).
        start_offset_ns: Skip messages earlier than the bag's start plus this [ns].

    Raises:
        BagError: When the bag cannot be read or a requested topic is not in it.
    """
    reader = _open_reader(path)
    try:
        connections = list(reader.connections)
        if topics is not None:
            wanted = set(topics)
            missing = wanted - {c.topic for c in connections}
            if missing:
                raise BagError(f'{path} has no topic(s) {", ".join(sorted(missing))}; it has '
                               + ', '.join(sorted({c.topic for c in connections})))
            connections = [c for c in connections if c.topic in wanted]
        start = reader.start_time + start_offset_ns if start_offset_ns > 0 else None
        if not connections:
            return
        for connection, timestamp, data in reader.messages(connections, start=start):
            yield BagMessage(connection.topic, connection.msgtype, timestamp, bytes(data))
    finally:
        reader.close()


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
    return '\n'.join(lines)


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
