"""When to match the whole image and when only the previous decision's area (area_search.py).

A pair is matched on the whole image at start, when no decision has found the object (or the
last one did not), when the newest area is older than `max_age_s` (pair stamps, so a replayed
bag behaves as it did live), every `full_frame_every`-th pair, and when the area gives no region
(`AreaProjectionError`). Otherwise it is matched in the area's search region, and the region is
checked on the result (area_search.region_problem); the caller matches the whole image again
when the check fails and tells the tracker (`region_failed`), which then forgets the area.

Thread-safe: decisions arrive on one thread, pairs are matched on another. ROS-free.
"""

from __future__ import annotations

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
    """

    enabled: bool = True
    full_frame_every: int = 30
    max_age_s: float = 0.5
    margin_object_sizes: float = 1.0
    margin_m: float = 0.02


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
        self._area: TrackedArea | None = None
        self._since_full = 0
        self.last_problem = ''

    def observe(self, area: TrackedArea | None) -> None:
        """Take a decision's area (None: the decision found no object: search everywhere)."""
        if area is not None and area.problem() is not None:
            area = None
        with self._lock:
            if area is None or self._area is None or area.stamp_s >= self._area.stamp_s:
                self._area = area

    def region_failed(self, problem: str) -> None:
        """Forget the area: its region did not hold the object (area_search.region_problem)."""
        with self._lock:
            self._area = None
            self.last_problem = problem

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
