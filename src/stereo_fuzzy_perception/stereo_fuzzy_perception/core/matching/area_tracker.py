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

With `detect_scene_change`, each pair's block means (scene_change.py) are compared before
anything is matched: a region whose blocks changed since the previous pair beyond
`change_share` is not tried (the pair goes to the whole image at once, and the area is
forgotten as after a failed region), and a periodic whole-image pair whose image did not change
outside the region since the last whole-image pair is matched in the region.

With `regions_from_matches`, a pair matched on the whole image while no area is tracked (after
a failed or changed region) gives a region of its own (area_search.region_from_matches, with
the surface of the last region planned): the next pairs are matched in it until a decision
arrives, instead of waiting for that decision or being matched whole.

Thread-safe: decisions arrive on one thread, pairs are matched on another. ROS-free.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from stereo_fuzzy_perception.core.camera_model import StereoCalibration
from stereo_fuzzy_perception.core.matching.area_search import (
    AreaProjectionError,
    SearchRegion,
    TrackedArea,
    region_from_matches,
    search_region,
)
from stereo_fuzzy_perception.core.matching.scene_change import (
    Box,
    changed_outside,
    changed_share_inside,
)
from stereo_fuzzy_perception.core.matching.window_matcher import DisparityMap

# Why a pair was matched on the whole image.
TRACKING_OFF = 'tracking_off'
NO_AREA = 'no_area'
STALE_AREA = 'stale_area'
PERIODIC = 'periodic'
NO_REGION = 'no_region'
SCENE_CHANGED = 'scene_changed'
FULL_FRAME_REASONS = (TRACKING_OFF, NO_AREA, STALE_AREA, PERIODIC, NO_REGION, SCENE_CHANGED)

MAX_PERIODIC_SKIPPED = 9
"""Periodic whole-image pairs skipped in a row at most (an unchanged image): the next one is
matched whole whatever the blocks say (a change too faint for them is still found)."""


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
        detect_scene_change: Compare the pairs' block means before planning (see above).
        change_grey_levels: Change of a block's mean that counts as a change [grey levels].
        change_share: Share of the region's blocks changed since the previous pair above
            which the region is not tried [-].
        regions_from_matches: Track a region found in a whole-image pair's matches until a
            decision arrives (see above).
    """

    enabled: bool = True
    full_frame_every: int = 30
    max_age_s: float = 0.5
    margin_object_sizes: float = 1.0
    margin_m: float = 0.02
    decision_wait_s: float = 0.015
    detect_scene_change: bool = True
    change_grey_levels: float = 8.0
    change_share: float = 0.2
    regions_from_matches: bool = True


@dataclass(frozen=True)
class SearchPlan:
    """Where one pair is matched: in `region`, or on the whole image for `reason`.

    `periodic_skipped`: the pair was due on the whole image (`full_frame_every`) but is matched
    in the region, its image unchanged outside it since the last whole-image pair.
    """

    region: SearchRegion | None
    reason: str = ''
    periodic_skipped: bool = False
    from_matches: bool = False


class AreaTracker:
    """Keep the newest decided area and plan where each pair is matched."""

    def __init__(self, config: TrackingConfig | None = None) -> None:
        self.config = config or TrackingConfig()
        self._lock = threading.Lock()
        self._decided = threading.Condition(self._lock)
        self._area: TrackedArea | None = None
        self._since_full = 0
        self._periodic_skipped = 0  # in a row, since the last whole-image pair
        self._newest_decision_s = -math.inf  # stamp of the newest pair decided [s]
        self._awaited_s: float | None = None  # the failed region's pair stamp [s]
        # decisions on pairs older than the last failed region's are not tracked: they would
        # bring back the area that failed [s]
        self._failed_s = -math.inf
        # block means (scene_change.block_means) of the pair planned last, of the one before
        # it, and of the last pair matched on the whole image
        self._planned_blocks: np.ndarray | None = None
        self._previous_blocks: np.ndarray | None = None
        self._whole_blocks: np.ndarray | None = None
        # the last region planned (its surface plane), and a region found in a whole-image
        # pair's matches with that pair's stamp [s]
        self._reference: SearchRegion | None = None
        self._found: tuple[float, SearchRegion] | None = None
        # whether the last pair planned was in a found region, and whether whole-image
        # matches may give one (not after a found region failed, until the next decision)
        self._planned_from_matches = False
        self._search_matches = True
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
            stale = area is not None and area.stamp_s < self._failed_s
            if not stale and (area is None or self._area is None
                              or area.stamp_s >= self._area.stamp_s):
                self._area = area
            if (not stale and self._found is not None and decided_s is not None
                    and decided_s >= self._found[0]):
                self._found = None  # a decision on that pair (or a later one) replaces it
            if not stale and decided_s is not None and decided_s >= self._failed_s:
                self._search_matches = True
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
            self._found = None
            if self._planned_from_matches:
                self._search_matches = False  # no second try before a decision arrives
            self.last_problem = problem
            self._awaited_s = stamp_s
            if stamp_s is not None:
                self._failed_s = max(self._failed_s, stamp_s)
            self._since_full = 0  # the pair is matched on the whole image
            self._periodic_skipped = 0
            self._whole_blocks = self._planned_blocks

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
            if self._found is not None and self._found[0] >= awaited:
                return None  # that pair's matches gave a region: nothing to wait for
            return self._decided.wait_for(lambda: self._newest_decision_s >= awaited,
                                          timeout=self.config.decision_wait_s)

    def plan(self, stamp_s: float, calibration: StereoCalibration,
             world_from_camera: np.ndarray | None, full_range: tuple[int, int],
             blocks: np.ndarray | None = None,
             raw_box: Callable[[tuple[int, int, int, int]], Box] | None = None) -> SearchPlan:
        """Return where the pair stamped `stamp_s` [s] is matched.

        Args:
            stamp_s: The pair's stamp [s].
            calibration: Its (rectified) calibration.
            world_from_camera: Left optical frame in world, or None when unknown.
            full_range: (min_disparity, disparity_range) of the whole-image search [px].
            blocks: The pair's block means (scene_change.block_means of the raw left image),
                or None: no scene-change detection for this pair.
            raw_box: The box (x0, y0, x1, y1) of the raw left image a rectified region
                (x, y, width, height) is made from [px] (needed with `blocks`).
        """
        config = self.config
        with self._lock:
            area = self._area
            periodic = self._since_full + 1 >= config.full_frame_every
            previous = self._previous_blocks
            whole = self._whole_blocks
            self._planned_blocks = self._previous_blocks = blocks
        if not config.enabled or world_from_camera is None:
            return self._full(TRACKING_OFF)
        with self._lock:
            found = self._found if config.regions_from_matches else None
        if found is not None and area is None and 0.0 <= stamp_s - found[0] <= config.max_age_s:
            return self._in_region(found[1], stamp_s, periodic, blocks, previous, whole,
                                   raw_box, from_matches=True)
        if area is None:
            return self._full(NO_AREA)
        if not 0.0 <= stamp_s - area.stamp_s <= config.max_age_s:
            return self._full(STALE_AREA)
        detect = config.detect_scene_change and blocks is not None and raw_box is not None
        if periodic and not detect:
            return self._full(PERIODIC)
        try:
            region = search_region(area, calibration, world_from_camera, full_range,
                                   config.margin_object_sizes, config.margin_m)
        except AreaProjectionError as error:
            with self._lock:
                self.last_problem = str(error)
            return self._full(NO_REGION)
        return self._in_region(region, stamp_s, periodic, blocks, previous, whole, raw_box)

    def _in_region(self, region: SearchRegion, stamp_s: float, periodic: bool,
                   blocks: np.ndarray | None, previous: np.ndarray | None,
                   whole: np.ndarray | None,
                   raw_box: Callable[[tuple[int, int, int, int]], Box] | None,
                   from_matches: bool = False) -> SearchPlan:
        """Plan the pair in `region` unless its blocks say otherwise (or it is due whole)."""
        config = self.config
        with self._lock:
            self._reference = region
            self._planned_from_matches = from_matches
        detect = config.detect_scene_change and blocks is not None and raw_box is not None
        if periodic and not detect:
            return self._full(PERIODIC)
        if detect and blocks is not None and raw_box is not None:
            box = raw_box(region.roi)
            share = changed_share_inside(blocks, previous, box, config.change_grey_levels)
            if share > config.change_share:
                # as after a failed region: forget the area, the next pair waits for this
                # pair's decision (also when the pair was due on the whole image anyway)
                self.region_failed(f'{share:.0%} of the region changed since the previous pair',
                                   stamp_s)
                return SearchPlan(None, SCENE_CHANGED)
            if periodic and (self._periodic_skipped >= MAX_PERIODIC_SKIPPED or changed_outside(
                    blocks, whole, box, config.change_grey_levels)):
                return self._full(PERIODIC)
        with self._lock:
            self._since_full = 0 if periodic else self._since_full + 1
            self._periodic_skipped += int(periodic)
        return SearchPlan(region, periodic_skipped=periodic, from_matches=from_matches)

    def matched_whole(self, disparity_map: DisparityMap, stamp_s: float,
                      calibration: StereoCalibration, point_stride: int,
                      full_range: tuple[int, int]) -> SearchRegion | None:
        """Take a pair matched on the whole image: while no area is tracked, find a region.

        Args:
            disparity_map: The pair's whole-image matches.
            stamp_s: The pair's stamp [s].
            calibration: Its rectified calibration.
            point_stride: Rows and columns the points keep.
            full_range: (min_disparity, disparity_range) of the whole-image search [px].

        Returns:
            The region found (area_search.region_from_matches), tracked until a decision on
            this pair or a later one arrives; None when none was looked for or found.
        """
        config = self.config
        with self._lock:
            reference = self._reference
            wanted = (config.enabled and config.regions_from_matches and self._area is None
                      and self._search_matches and reference is not None
                      and stamp_s >= self._failed_s
                      and stamp_s > self._newest_decision_s)
        if not wanted or reference is None:
            return None
        region = region_from_matches(disparity_map, reference, calibration, point_stride,
                                     full_range, config.margin_object_sizes)
        if region is None:
            return None
        with self._lock:
            if self._area is not None or stamp_s <= self._newest_decision_s:
                return None  # a decision arrived meanwhile
            self._found = (stamp_s, region)
        return region

    def _full(self, reason: str) -> SearchPlan:
        with self._lock:
            self._since_full = 0
            self._periodic_skipped = 0
            self._planned_from_matches = False
            self._whole_blocks = self._planned_blocks
        return SearchPlan(None, reason)
