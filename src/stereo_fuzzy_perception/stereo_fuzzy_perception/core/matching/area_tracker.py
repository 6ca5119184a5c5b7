"""When to match the whole image and when only the previous decision's area (area_search.py).

A pair is matched on the whole image at start, when no decision has found the object (or the
last one did not), when the newest area is older than `max_age_s` (pair stamps, so a replayed
bag behaves as it did live), every `full_frame_every`-th pair, and when the area gives no region
(`AreaProjectionError`). Otherwise it is matched in the area's search region, and the region is
checked on the result (area_search.region_problem); the caller matches the whole image again
when the check fails and tells the tracker (`region_failed`), which then forgets the area. The
pair after a failed region waits up to `decision_wait_s` for the decision on the failed one
(matched on the whole image, so it finds the object where it is now) instead of being matched
on the whole image too: after a scene change, one pair is matched twice instead of every pair
until that decision arrives.

Thread-safe: decisions arrive on one thread, pairs are matched on another. ROS-free.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass

import numpy as np

from stereo_fuzzy_perception.core.camera_model import StereoCalibration
from stereo_fuzzy_perception.core.matching.area_search import (
    AreaProjectionError,
    SearchRegion,
    TrackedArea,
    search_region,
)

# Why a pair was matched on the whole image.
TRACKING_OFF = 'tracking_off'
NO_AREA = 'no_area'
STALE_AREA = 'stale_area'
PERIODIC = 'periodic'
NO_REGION = 'no_region'
FULL_FRAME_REASONS = (TRACKING_OFF, NO_AREA, STALE_AREA, PERIODIC, NO_REGION)


@dataclass(frozen=True)
class TrackingConfig:
    """How the area is tracked.

    Attributes:
        enabled: Match in the previous area's region at all.
        full_frame_every: Match every n-th pair on the whole image (1 = every pair).
        max_age_s: Oldest area used, by pair stamps [s].
        margin_object_sizes: Region margin on each side in object extents [-].
        margin_m: Smallest region margin on each side [m].
        decision_wait_s: Longest wait for the decision on a pair whose region failed before
            the next pair is planned [s]; 0 does not wait.
    """

    enabled: bool = True
    full_frame_every: int = 30
    max_age_s: float = 0.5
    margin_object_sizes: float = 1.0
    margin_m: float = 0.02
    decision_wait_s: float = 0.015


@dataclass(frozen=True)
class SearchPlan:
    """Where one pair is matched: in `region`, or on the whole image for `reason`."""

    region: SearchRegion | None
    reason: str = ''


class AreaTracker:
    """Keep the newest decided area and plan where each pair is matched."""

    def __init__(self, config: TrackingConfig | None = None) -> None:
        self.config = config or TrackingConfig()
        self._lock = threading.Lock()
        self._decided = threading.Condition(self._lock)
        self._area: TrackedArea | None = None
        self._since_full = 0
        self._newest_decision_s = -math.inf  # stamp of the newest pair decided [s]
        self._awaited_s: float | None = None  # the failed region's pair stamp [s]
        self.last_problem = ''

    def observe(self, area: TrackedArea | None, stamp_s: float | None = None) -> None:
        """Take a decision's area (None: the decision found no object: search everywhere).

        Args:
            area: The decision's area, or None.
            stamp_s: Stamp of the pair decided [s] (the area's when None).
        """
        decided_s = area.stamp_s if stamp_s is None and area is not None else stamp_s
        if area is not None and area.problem() is not None:
            area = None
        with self._lock:
            if area is None or self._area is None or area.stamp_s >= self._area.stamp_s:
                self._area = area
            if decided_s is not None:
                self._newest_decision_s = max(self._newest_decision_s, decided_s)
                self._decided.notify_all()

    def region_failed(self, problem: str, stamp_s: float | None = None) -> None:
        """Forget the area: its region did not hold the object (area_search.region_problem).

        Args:
            problem: Why the region failed.
            stamp_s: Stamp of the pair [s]: the next plan waits for its decision
                (`wait_for_decision`); None does not wait.
        """
        with self._lock:
            self._area = None
            self.last_problem = problem
            self._awaited_s = stamp_s
            self._since_full = 0  # the pair is matched on the whole image

    def wait_for_decision(self) -> bool | None:
        """Wait up to `decision_wait_s` for the decision on the last failed region's pair.

        Returns:
            None when no decision was awaited, else whether it arrived in time. Either way the
            next call waits only after another failed region.
        """
        with self._decided:
            awaited = self._awaited_s
            self._awaited_s = None
            if awaited is None or not self.config.enabled or self.config.decision_wait_s <= 0.0:
                return None
            return self._decided.wait_for(lambda: self._newest_decision_s >= awaited,
                                          timeout=self.config.decision_wait_s)

    def plan(self, stamp_s: float, calibration: StereoCalibration,
             world_from_camera: np.ndarray | None, full_range: tuple[int, int]) -> SearchPlan:
        """Return where the pair stamped `stamp_s` [s] is matched.

        Args:
            stamp_s: The pair's stamp [s].
            calibration: Its (rectified) calibration.
            world_from_camera: Left optical frame in world, or None when unknown.
            full_range: (min_disparity, disparity_range) of the whole-image search [px].
        """
        config = self.config
        with self._lock:
            area = self._area
            periodic = self._since_full + 1 >= config.full_frame_every
        if not config.enabled or world_from_camera is None:
            return self._full(TRACKING_OFF)
        if area is None:
            return self._full(NO_AREA)
        if not 0.0 <= stamp_s - area.stamp_s <= config.max_age_s:
            return self._full(STALE_AREA)
        if periodic:
            return self._full(PERIODIC)
        try:
            region = search_region(area, calibration, world_from_camera, full_range,
                                   config.margin_object_sizes, config.margin_m)
        except AreaProjectionError as error:
            with self._lock:
                self.last_problem = str(error)
            return self._full(NO_REGION)
        with self._lock:
            self._since_full += 1
        return SearchPlan(region)

    def _full(self, reason: str) -> SearchPlan:
        with self._lock:
            self._since_full = 0
        return SearchPlan(None, reason)
