"""The matches published and not decided yet: how far the fuzzy stage is behind the matcher.

correlation_node publishes one StereoMatches per pair and fuzzy_best_point_node answers each
with one decision (best_point/decision, stamped with the pair's stamp). When deciding takes
longer than matching (two processes sharing two cores with other work), every new match would
wait in the fuzzy node's queue behind the earlier ones, and latency would grow with the queue.
With a limit on the matches in flight, the matcher starts a pair only when fewer than the limit
are undecided; the pairs arriving meanwhile replace each other (the newest wins), so latency
stays bounded by about `limit` decisions. A match whose decision never comes (a lost message, a
stopped fuzzy node) stops counting after a timeout, so the matcher never stalls.
"""

from __future__ import annotations

from collections import OrderedDict


class UndecidedMatches:
    """Stamps of published matches without a decision yet, oldest first."""

    def __init__(self) -> None:
        self._published: OrderedDict[int, float] = OrderedDict()  # stamp [ns] -> sent at [s]
        self.expired = 0

    def __len__(self) -> int:
        return len(self._published)

    def published(self, stamp_ns: int, now_s: float) -> None:
        """Count matches stamped `stamp_ns` [ns] as sent at `now_s` (a monotonic clock) [s]."""
        self._published[stamp_ns] = now_s
        self._published.move_to_end(stamp_ns)

    def decided(self, stamp_ns: int) -> None:
        """Forget the matches stamped `stamp_ns` [ns] and any sent before them.

        Decisions come in the order of the matches, so the earlier matches' decisions were
        lost (or belong to another run): they are no longer waited for.
        """
        if stamp_ns not in self._published:
            return
        while self._published:
            stamp, _ = self._published.popitem(last=False)
            if stamp == stamp_ns:
                break

    def expire(self, now_s: float, timeout_s: float) -> None:
        """Forget matches sent more than `timeout_s` [s] before `now_s`, counting them."""
        while self._published:
            stamp, sent = next(iter(self._published.items()))
            if now_s - sent <= timeout_s:
                break
            del self._published[stamp]
            self.expired += 1

    def wait_s(self, now_s: float, limit: int, timeout_s: float) -> float:
        """Return how long a new match must wait [s]: 0 when fewer than `limit` are undecided
        (after expiring old ones), else until the oldest expires. `limit` 0 never waits.
        """
        self.expire(now_s, timeout_s)
        if limit <= 0 or len(self._published) < limit:
            return 0.0
        oldest = next(iter(self._published.values()))
        return max(oldest + timeout_s - now_s, 1e-4)
