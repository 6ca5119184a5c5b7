"""Write rosbag2 bags with the MCAP storage plugin: topics, messages, chunk compression, splits.

Bags are rosbag2 directories (metadata.yaml + .mcap files) written with rosbags, so `ros2 bag`,
rosbags and Foxglove all open them. Messages are written as the CDR bytes they are given.

ROS-free: rosbags, PyYAML and the standard library only.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import yaml
from rosbags.interfaces import Connection, Qos
from rosbags.rosbag2 import (
    CompressionFormat,
    CompressionMode,
    StoragePlugin,
    Writer,
)
from rosbags.rosbag2.errors import WriterError
from rosbags.typesys.store import Typestore

from stereo_fuzzy_perception.bag.bag_format import DEFAULT_QOS, BagError
from stereo_fuzzy_perception.bag.message_types import project_typestore

try:  # Python 3.14 has it in the standard library; rosbags depends on the backport before.
    from compression import zstd  # type: ignore[import-not-found]
except ImportError:  # pragma: no cover
    from backports import zstd

COMPRESSIONS = ('zstd', 'none')


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
