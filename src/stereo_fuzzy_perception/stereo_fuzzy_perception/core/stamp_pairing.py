"""Group messages of several streams by header stamp: exact or approximate (within a slop).

ROS-free: items are anything, each given with its stamp in integer nanoseconds and the index
of its stream. stereo_sync_node runs it over four streams (left image, left camera_info, right
image, right camera_info), as stereo_image_proc synchronises its four inputs with
message_filters, so every image travels with the calibration stamped for it.

Semantics, those of message_filters' synchronisers as the README compares them:

- A set holds one item of every stream, and its stamps span at most `slop_ns`
  (`slop_ns == 0` is exact-stamp pairing, message_filters' ExactTime).
- Every item is used in at most one set.
- Each stream keeps at most `queue_size` unmatched items; when a stream overflows, its oldest
  item (by stamp) is evicted and reported, so the caller can count and explain it.
- Sets are searched when an item arrives, among the sets that contain it (as rclpy's
  ApproximateTimeSynchronizer does), so items arriving out of stamp order are still paired.
  Of the candidate sets within the slop, the one with the smallest span is emitted, which for
  two streams is the partner closest in time.
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass, field
from typing import Any, Generic, TypeVar

Item = TypeVar('Item')


class StampPairingError(ValueError):
    """A synchroniser set-up or input that cannot work, with the bad value named."""


@dataclass(frozen=True, order=True)
class Stamped(Generic[Item]):
    """One item waiting in a stream's queue.

    Attributes:
        stamp_ns: Header stamp [ns].
        sequence: Arrival number, which keeps items with equal stamps apart.
        item: The payload (a message, a frame, anything).
    """

    stamp_ns: int
    sequence: int
    item: Item = field(compare=False)


@dataclass(frozen=True)
class Evicted(Generic[Item]):
    """An item dropped unmatched because its stream's queue overflowed."""

    stream: int
    stamp_ns: int
    item: Item


@dataclass(frozen=True)
class MatchedSet(Generic[Item]):
    """One item per stream, their stamps within the slop.

    Attributes:
        stamps_ns: Stamp of each stream's item, in stream order [ns].
        items: Each stream's item, in stream order.
    """

    stamps_ns: tuple[int, ...]
    items: tuple[Item, ...]

    @property
    def span_ns(self) -> int:
        """Largest stamp difference inside the set [ns]."""
        return max(self.stamps_ns) - min(self.stamps_ns)


@dataclass
class PairingResult(Generic[Item]):
    """What one `add` produced: a matched set or None, and the items evicted meanwhile."""

    matched: MatchedSet[Item] | None = None
    evicted: list[Evicted[Item]] = field(default_factory=list)


class StampSynchronizer(Generic[Item]):
    """Match items of `stream_count` streams whose stamps lie within `slop_ns` of each other.

    Args:
        stream_count: Number of streams (2 or more).
        slop_ns: Largest stamp span of a set [ns]; 0 pairs identical stamps only.
        queue_size: Unmatched items kept per stream (1 or more).

    Raises:
        StampPairingError: For fewer than two streams, a negative slop or a queue below 1.
    """

    def __init__(self, stream_count: int, slop_ns: int = 0, queue_size: int = 10) -> None:
        if stream_count < 2:
            raise StampPairingError(f'stream_count={stream_count}: need at least 2 streams')
        self._queues: list[list[Stamped[Item]]] = [[] for _ in range(stream_count)]
        self._sequence = 0
        self._slop_ns = 0
        self._queue_size = 1
        self.slop_ns = slop_ns
        self.queue_size = queue_size

    @property
    def stream_count(self) -> int:
        """Number of streams matched."""
        return len(self._queues)

    @property
    def slop_ns(self) -> int:
        """Largest stamp span of a set [ns]."""
        return self._slop_ns

    @slop_ns.setter
    def slop_ns(self, value: int) -> None:
        if value < 0:
            raise StampPairingError(f'slop_ns={value} must not be negative')
        self._slop_ns = int(value)

    @property
    def queue_size(self) -> int:
        """Unmatched items kept per stream; lowering it evicts on the next `add`."""
        return self._queue_size

    @queue_size.setter
    def queue_size(self, value: int) -> None:
        if value < 1:
            raise StampPairingError(f'queue_size={value} must be at least 1')
        self._queue_size = int(value)

    def queue_lengths(self) -> tuple[int, ...]:
        """Return how many unmatched items each stream holds."""
        return tuple(len(queue) for queue in self._queues)

    def clear(self) -> None:
        """Forget every queued item."""
        for queue in self._queues:
            queue.clear()

    def add(self, stream: int, stamp_ns: int, item: Item) -> PairingResult[Item]:
        """Queue `item` of `stream`, emit the tightest set containing it, then bound the queues.

        Args:
            stream: Index of the item's stream, 0 <= stream < stream_count.
            stamp_ns: The item's stamp [ns].
            item: The payload.

        Returns:
            The matched set (None when the item completes none) and the items evicted.

        Raises:
            StampPairingError: For a stream index out of range.
        """
        if not 0 <= stream < len(self._queues):
            raise StampPairingError(
                f'stream {stream} is out of range 0..{len(self._queues) - 1}')
        entry = Stamped(int(stamp_ns), self._sequence, item)
        self._sequence += 1
        bisect.insort(self._queues[stream], entry)
        result: PairingResult[Item] = PairingResult()
        chosen = self._tightest_set(stream, entry)
        if chosen is not None:
            for index, member in enumerate(chosen):
                self._queues[index].remove(member)
            result.matched = MatchedSet(
                stamps_ns=tuple(member.stamp_ns for member in chosen),
                items=tuple(member.item for member in chosen))
        for index, queue in enumerate(self._queues):
            while len(queue) > self._queue_size:
                oldest = queue.pop(0)
                result.evicted.append(Evicted(index, oldest.stamp_ns, oldest.item))
        return result

    def _tightest_set(self, stream: int, entry: Stamped[Item]) -> list[Stamped[Item]] | None:
        """Return the set of smallest span that contains `entry`, within the slop, or None.

        Every set containing `entry` has a lowest stamp `low` in [t - slop, t]. For a given
        `low`, taking in every other stream the first item at or after `low` minimises the
        set's highest stamp, so trying every queued stamp in that interval as `low` finds the
        tightest set (the smallest-range-covering-k-lists sweep).
        """
        t, slop = entry.stamp_ns, self._slop_ns
        others = [index for index in range(len(self._queues)) if index != stream]
        lows = {t}
        for index in others:
            queue = self._queues[index]
            start = bisect.bisect_left(queue, (t - slop), key=_stamp)
            stop = bisect.bisect_right(queue, t, key=_stamp)
            lows.update(member.stamp_ns for member in queue[start:stop])
        best: list[Stamped[Item]] | None = None
        best_key: tuple[int, int] | None = None
        for low in sorted(lows):
            members: list[Stamped[Item]] = []
            for index in range(len(self._queues)):
                if index == stream:
                    members.append(entry)
                    continue
                queue = self._queues[index]
                position = bisect.bisect_left(queue, low, key=_stamp)
                if position == len(queue):
                    break
                members.append(queue[position])
            else:
                stamps = [member.stamp_ns for member in members]
                span = max(stamps) - min(stamps)
                if span > slop:
                    continue
                # Ties: the set whose stamps sit closest to the new item's in total.
                key = (span, sum(abs(stamp - t) for stamp in stamps))
                if best_key is None or key < best_key:
                    best, best_key = members, key
        return best


def _stamp(entry: Stamped[Any]) -> int:
    return entry.stamp_ns


def seconds_to_ns(seconds: float) -> int:
    """Convert a duration [s] to integer nanoseconds [ns], rounding to the nearest."""
    return int(round(seconds * 1e9))
