"""Counting lost messages from the sequence numbers their publisher gives them. ROS-free.

StereoPair and StereoMatches carry `sequence` = 1, 2, 3, ... per publisher. A subscriber that
feeds every received number to a SequenceGaps knows how many messages never reached it,
whatever dropped them (DDS history overwritten, best-effort loss, a slow subscriber):

    gaps = SequenceGaps()
    gaps.observe(msg.sequence)
    gaps.lost, gaps.before_first, gaps.restarts, gaps.unnumbered

Not thread-safe: call it under the caller's lock.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class SequenceGaps:
    """Received, lost (gaps), restarted and unnumbered counts of one sequence-numbered stream.

    Attributes:
        received: Messages observed.
        lost: Numbers skipped between consecutive observed numbers (messages never received).
        before_first: Numbers below the first one observed from a publisher (at start, and
            after each restart): sent before this subscription matched the publisher, which
            DDS does not deliver to a volatile subscription.
        restarts: Times a number was not above the previous one: the publisher restarted, a
            second publisher shares the topic, or a message was duplicated or reordered.
        unnumbered: Messages with sequence 0 (a publisher that does not number them); they
            cannot be checked for gaps.
        last: The last non-zero number observed (0: none yet).
    """

    received: int = 0
    lost: int = 0
    before_first: int = 0
    restarts: int = 0
    unnumbered: int = 0
    last: int = 0

    def observe(self, sequence: int) -> int:
        """Count one received message numbered `sequence` and return how many it shows lost.

        The first number seen, and the first after a restart, count the numbers below it as
        `before_first` (sent before the subscription matched), not as `lost`.
        """
        self.received += 1
        if sequence <= 0:
            self.unnumbered += 1
            return 0
        missed = 0
        if self.last and sequence > self.last:
            missed = sequence - self.last - 1
            self.lost += missed
        else:
            self.restarts += int(bool(self.last))
            self.before_first += sequence - 1
        self.last = sequence
        return missed

    def report(self, stream: str) -> dict[str, int]:
        """Return the counts as /diagnostics key-values, prefixed with `stream`."""
        return {f'{stream} received': self.received, f'{stream} lost (sequence gaps)': self.lost,
                f'{stream} sent before the first received': self.before_first,
                f'{stream} sequence restarts': self.restarts,
                f'{stream} unnumbered': self.unnumbered}
