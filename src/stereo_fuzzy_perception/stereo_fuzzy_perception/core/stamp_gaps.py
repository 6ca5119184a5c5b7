"""Estimating messages a stream lost from gaps in its header stamps. ROS-free.

Camera images and camera_infos carry no sequence number, and DDS does not report a message
overwritten in a subscription's keep-last queue before the callback took it. What the
subscriber still sees is the stamps: a camera stamps its frames at a steady period, so an
interval of about k periods between two consecutive received stamps means k - 1 frames never
reached the callback, whatever dropped them. A StampGaps per stream measures that period from
the stream itself and counts the frames the gaps imply:

    gaps = StampGaps()
    gaps.observe(stamp_ns)
    gaps.estimated_lost, gaps.period_ns, gaps.restarts, gaps.unstamped

It is an estimate, not a count:
- The period is learned from the first `learn_intervals` intervals (the median of those
  within 1.5 times the smallest), then follows the median of the last `period_window`
  intervals within 1.5 periods. A stream that starts inside a loss learns too long a period
  until enough single-frame intervals arrive, and counts too few meanwhile.
- A pause of the camera, or a camera switched to a lower rate, is counted as lost frames.
- A stream that only ever delivers every n-th frame from the start looks like a slower camera.
- Frames lost before the first or after the last received stamp show no gap.

Not thread-safe: call it under the caller's lock.
"""

from __future__ import annotations

import statistics
from collections import deque
from dataclasses import dataclass, field

# An interval shorter than this many periods is one frame (no loss); longer ones are gaps.
SINGLE_FRAME_LIMIT = 1.5


@dataclass
class StampGaps:
    """Received, estimated-lost, restarted and unstamped counts of one stamped stream.

    Attributes:
        learn_intervals: Intervals held before the period is first measured.
        period_window: Single-frame intervals the period is the median of.
        received: Messages observed.
        estimated_lost: Frames the stamp gaps imply were never received (an estimate).
        restarts: Times a stamp was not after the previous one (a publisher restarted, a bag
            looped, a message duplicated or reordered); the next interval starts from it.
        unstamped: Messages with a zero stamp; they are not checked for gaps.
        period_ns: The measured frame period [ns] (0 until `learn_intervals` intervals).
        last_ns: The last non-zero stamp observed [ns] (0: none yet).
    """

    learn_intervals: int = 8
    period_window: int = 32
    received: int = 0
    estimated_lost: int = 0
    restarts: int = 0
    unstamped: int = 0
    period_ns: float = 0.0
    last_ns: int = 0
    _held: list[int] = field(default_factory=list, repr=False)
    _singles: deque[int] = field(default_factory=deque, repr=False)

    def __post_init__(self) -> None:
        if self.learn_intervals < 1 or self.period_window < 1:
            raise ValueError(f'learn_intervals ({self.learn_intervals}) and period_window '
                             f'({self.period_window}) must be at least 1')
        self._singles = deque(self._singles, maxlen=self.period_window)

    def observe(self, stamp_ns: int) -> int:
        """Count one message stamped `stamp_ns` [ns]; return the frames newly estimated lost.

        Intervals seen while the period is still being learned are held and counted once it
        is known, so the return value can cover several earlier gaps.
        """
        self.received += 1
        if stamp_ns <= 0:
            self.unstamped += 1
            return 0
        previous, self.last_ns = self.last_ns, stamp_ns
        if not previous:
            return 0
        if stamp_ns <= previous:
            self.restarts += 1
            return 0
        interval = stamp_ns - previous
        if not self.period_ns:
            self._held.append(interval)
            if len(self._held) < self.learn_intervals:
                return 0
            shortest = min(self._held)
            self._singles.extend(d for d in self._held
                                 if d < SINGLE_FRAME_LIMIT * shortest)
            self.period_ns = float(statistics.median(self._singles))
            held, self._held = self._held, []
            missed = sum(self._frames_missed(d) for d in held)
        else:
            missed = self._frames_missed(interval)
            if interval < SINGLE_FRAME_LIMIT * self.period_ns:
                self._singles.append(interval)
                self.period_ns = float(statistics.median(self._singles))
        self.estimated_lost += missed
        return missed

    def _frames_missed(self, interval_ns: int) -> int:
        return max(0, round(interval_ns / self.period_ns) - 1)

    def report(self, stream: str) -> dict[str, int | str]:
        """Return the counts as /diagnostics key-values, prefixed with `stream`."""
        period = f'{self.period_ns * 1e-9:.6f}' if self.period_ns else 'not yet measured'
        return {f'{stream} estimated lost (stamp gaps)': self.estimated_lost,
                f'{stream} stamp period [s]': period,
                f'{stream} stamp restarts': self.restarts,
                f'{stream} unstamped': self.unstamped}
