"""Settings of correlation_node: its parameters' names, defaults, ranges and docs, once.

The matcher parameters mirror window_matcher.MatcherConfig (whose defaults they take) and can
be changed at run time; `CorrelationSettings.matcher_config()` builds the config, and
`problem()` refuses a combination it rejects (an even window, say) with the reason.
disparity_range 0 (the default) derives the search range from the calibration, the rig pose and
the workspace box (`with_derived_disparities`); the world, workspace and rig parameters are the
same declarations fuzzy_best_point_node makes, so one `/**:` section of a params file gives
them to both.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from stereo_fuzzy_parameters.spec import parameter, parameter_group, parameter_specs
from stereo_fuzzy_parameters.world import WorldSettings

from stereo_fuzzy_perception.core.camera_model import StereoCalibration
from stereo_fuzzy_perception.core.matching.area_tracker import TrackingConfig
from stereo_fuzzy_perception.core.matching.disparity_range import (
    MARGIN_PX,
    workspace_disparity_range,
)
from stereo_fuzzy_perception.core.matching.window_matcher import (
    METHODS,
    PREPROCESS_MODES,
    MatcherConfig,
    MatcherConfigError,
)
from stereo_fuzzy_perception.core.rig_pose import CameraPoseSource
from stereo_fuzzy_perception.nodes.rig_parameters import RigSettings

_DEFAULT = MatcherConfig()
_TRACKING = TrackingConfig()
AUTO_DISPARITY_RANGE = 0
"""disparity_range value that asks for the range derived from the geometry."""


@dataclass(frozen=True)
class RoiSettings:
    """The correlation area (Fig. 2) in the left rectified image; 0 width or height = all.

    With the whole image (the default) and `track` on, each pair is matched where the previous
    decision found the object (core/matching/area_tracker.py); a fixed area turns that off.
    """

    x: int = parameter(0, 'Correlation area (Fig. 2): left column [px]', 0, 65535)
    y: int = parameter(0, 'Correlation area: top row [px]', 0, 65535)
    width: int = parameter(0, 'Correlation area: width [px]; 0 matches the whole image',
                           0, 65535)
    height: int = parameter(0, 'Correlation area: height [px]; 0 matches the whole image',
                            0, 65535)
    track: bool = parameter(
        _TRACKING.enabled, 'Match each pair only around the correlation area of the newest '
        'decision (best_point/decision) with a narrowed disparity range; a pair whose matches '
        "show the object at the region's edge or not at all is matched again on the whole "
        'image')
    full_frame_every: int = parameter(
        _TRACKING.full_frame_every, 'While tracking, match every n-th pair on the whole image '
        '(1 = every pair)', 1, 100000)
    max_age_s: float = parameter(
        _TRACKING.max_age_s, 'Oldest decision tracked, by pair stamps [s]; older: whole image',
        0.0, 60.0)
    margin_object_sizes: float = parameter(
        _TRACKING.margin_object_sizes, 'Margin of the tracked region on each side, in the '
        "object's extents [-] (its motion between decisions)", 0.0, 10.0)
    margin_m: float = parameter(
        _TRACKING.margin_m, 'Smallest margin of the tracked region on each side [m]', 0.0, 1.0)
    decision_wait_s: float = parameter(
        _TRACKING.decision_wait_s, 'After a pair whose region failed its check (matched again on '
        "the whole image), the next pair waits this long at most for that pair's decision, to "
        'be matched in its area rather than on the whole image [s]; 0 does not wait', 0.0, 1.0)

    detect_scene_change: bool = parameter(
        _TRACKING.detect_scene_change, "Compare each pair's 8x8 block means of the left image "
        "with earlier pairs' before matching: a region whose blocks changed since the previous "
        'pair (more than change_share of them) is not tried, the pair goes to the whole image at '
        'once; a periodic whole-image pair whose image is unchanged outside the region since '
        'the last whole-image pair is matched in the region')
    change_grey_levels: float = parameter(
        _TRACKING.change_grey_levels, "Change of a block's mean that counts as a scene change, "
        'after the median change of all blocks is taken off [grey levels, 8-bit]', 1.0, 255.0)
    change_share: float = parameter(
        _TRACKING.change_share, "Share of the region's blocks changed since the previous pair "
        'above which the region is not tried [-]', 0.0, 1.0)

    regions_from_matches: bool = parameter(
        _TRACKING.regions_from_matches, 'While no area is tracked (after a failed or changed '
        'region), find a region around the one object standing out of the surface in a '
        "whole-image pair's own matches and match the next pairs in it (checked as any region) "
        'until a decision arrives, instead of waiting for that decision')

    def tracking_config(self) -> TrackingConfig:
        """Return the tracking settings (tracking only while the area is the whole image)."""
        return TrackingConfig(
            enabled=self.track and (self.width == 0 or self.height == 0),
            full_frame_every=self.full_frame_every, max_age_s=self.max_age_s,
            margin_object_sizes=self.margin_object_sizes, margin_m=self.margin_m,
            decision_wait_s=self.decision_wait_s, detect_scene_change=self.detect_scene_change,
            change_grey_levels=self.change_grey_levels, change_share=self.change_share,
            regions_from_matches=self.regions_from_matches)


@dataclass(frozen=True)
class CorrelationSettings:
    """Parameters of correlation_node, typed."""

    method: str = parameter(
        _DEFAULT.method, 'Correlation measure: Eq. 8 correlation coefficient (zncc) or Eq. 7 '
        'divided by the window energies (plain)', choices=METHODS)
    window_size: int = parameter(
        _DEFAULT.window_size, 'Side of the square correlation window [px], odd', 3, 31)
    min_disparity: int = parameter(
        _DEFAULT.min_disparity, 'Smallest disparity searched [px] (left x minus right x); '
        'unused while disparity_range is 0', -512, 512)
    disparity_range: int = parameter(
        AUTO_DISPARITY_RANGE, 'Number of disparities searched [px]; the largest is '
        'min_disparity + disparity_range - 1. 0 = derive both from the calibration, the rig '
        'pose and the workspace box (the disparities of the box in view of both cameras, '
        f'{MARGIN_PX} px margin)', 0, 512)
    min_score: float = parameter(
        _DEFAULT.min_score, 'Lowest accepted correlation score at the best disparity [-]',
        -1.0, 1.0)
    texture_threshold: float = parameter(
        _DEFAULT.texture_threshold,
        'Lowest accepted standard deviation of the left window [grey levels]', 0.0, 255.0)
    uniqueness_ratio: float = parameter(
        _DEFAULT.uniqueness_ratio, 'Margin by which the best cost (1 - score) must beat every '
        'cost more than 1 px away [-]; 0 disables', 0.0, 10.0)
    lr_check_max_diff: int = parameter(
        _DEFAULT.lr_check_max_diff,
        'Largest left-right disparity difference accepted [px]; negative disables', -1, 64)
    subpixel: bool = parameter(
        _DEFAULT.subpixel, 'Refine disparities by a parabola through the scores around the peak')
    preprocess: str = parameter(
        _DEFAULT.preprocess, 'Preprocessing before correlation (chapter Fig. 8): none, edges '
        '(Sobel magnitude) or binary (Otsu threshold)', choices=PREPROCESS_MODES)
    roi: RoiSettings = parameter_group(RoiSettings)
    point_stride: int = parameter(
        1, 'Publish every n-th row and column of valid matches (1 = all); only those rows are '
        'matched unless disparity has a subscriber', 1, 16)
    max_rate_hz: float = parameter(
        0.0, 'Most pairs matched per second [Hz]; 0 matches every pair it can (the newest pair '
        'always wins)', 0.0, 1000.0)
    input_queue_depth: int = parameter(
        1, 'Pairs waiting while one is matched; when full the oldest is dropped. 1 = the newest '
        'pair always wins (bounded latency); more tolerates bursts in replays', 1, 30)
    max_undecided_matches: int = parameter(
        3, 'Most matches published and not yet answered by a decision (best_point/decision) '
        'before the next pair is matched; meanwhile newer pairs replace the waiting one, so '
        'latency stays bounded when deciding is slower than matching. 0 = never wait (also '
        'while nobody publishes decisions)', 0, 100)
    undecided_timeout_s: float = parameter(
        0.5, 'A match without a decision after this long no longer counts as undecided (a lost '
        'decision never stalls matching) [s]', 0.01, 10.0)
    max_image_pixels: int = parameter(
        4096 * 3072, 'Largest image accepted [px, width x height]; larger pairs are dropped as '
        'image_too_large before they are decoded', 1, 32767 * 32767)
    input_reliability: str = parameter(
        'reliable', 'Reliability of the pair subscription',
        choices=('reliable', 'best_effort'), read_only=True)
    diagnostics_period_s: float = parameter(
        1.0, 'Period of /diagnostics messages [s]', 0.1, 60.0, read_only=True)
    error_log_period_s: float = parameter(
        5.0, 'Shortest interval between two error logs of the same kind [s]', 0.0, 3600.0,
        read_only=True)
    # --- where the workspace is, for disparity_range 0 (the fuzzy node's same declarations)
    world: WorldSettings = parameter_group(WorldSettings, prefix='')
    rig_pose_file: str = parameter(
        '', 'Pose file with the left camera optical frame in world (the form '
        'static_transform_publisher takes); overrides the rig.* pose numbers; empty = use them',
        read_only=True)
    rig: RigSettings = parameter_group(RigSettings)

    @property
    def derives_disparities(self) -> bool:
        """True when the disparity search range is derived from the geometry."""
        return self.disparity_range == AUTO_DISPARITY_RANGE

    def matcher_config(self) -> MatcherConfig:
        """Return the matcher configuration these settings describe.

        Raises:
            MatcherConfigError: When the values make no valid configuration.
        """
        return MatcherConfig(
            method=self.method, window_size=self.window_size, min_disparity=self.min_disparity,
            disparity_range=(_DEFAULT.disparity_range if self.derives_disparities
                             else self.disparity_range),
            min_score=self.min_score,
            texture_threshold=self.texture_threshold, uniqueness_ratio=self.uniqueness_ratio,
            lr_check_max_diff=self.lr_check_max_diff, subpixel=self.subpixel,
            preprocess=self.preprocess,
            roi=(self.roi.x, self.roi.y, self.roi.width, self.roi.height))

    def with_derived_disparities(self, calibration: StereoCalibration) -> MatcherConfig:
        """Return the matcher configuration searching the workspace box's disparities.

        Raises:
            DisparityRangeError: When no part of the box is in view of both cameras.
            RigPoseError: When the pose file or the rig's baseline does not fit the calibration.
        """
        derived = workspace_disparity_range(calibration,
                                            self.pose_source().world_from_camera(calibration),
                                            self.world.workspace_min_m,
                                            self.world.workspace_max_m)
        return dataclasses.replace(self.matcher_config(), min_disparity=derived.min_disparity,
                                   disparity_range=derived.disparity_range)

    def pose_source(self) -> CameraPoseSource:
        """Return where the left camera's pose in world comes from (pose file or rig.*).

        Raises:
            RigPoseError: When the pose file is unusable.
        """
        return CameraPoseSource.from_settings(self.rig.stereo_rig(), self.rig_pose_file,
                                              self.world.world_frame)

    def problem(self) -> str | None:
        """Return why these settings make no valid matcher configuration, or None."""
        try:
            self.matcher_config()
        except MatcherConfigError as error:
            return str(error)
        return None


PARAMETERS = parameter_specs(CorrelationSettings)
