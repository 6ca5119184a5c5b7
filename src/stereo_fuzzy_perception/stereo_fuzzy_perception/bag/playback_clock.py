"""Playback timing: when each message is due, and bag time that runs at a rate and pauses.

ROS-free: the standard library only.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

from stereo_fuzzy_perception.bag.bag_format import BagError


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
