"""Settings of fuzzy_best_point_node: its parameters' names, defaults, ranges and docs, once.

ROS-free, so the README table, the config file test and the node read the same specs.
"""

from __future__ import annotations

from dataclasses import dataclass

from stereo_fuzzy_parameters.spec import parameter, parameter_group, parameter_specs
from stereo_fuzzy_parameters.world import WorldSettings

from stereo_fuzzy_perception.core.best_point.correlation_area import AreaConfig
from stereo_fuzzy_perception.core.best_point.point_selectors import SELECTORS
from stereo_fuzzy_perception.core.best_point.second_look import SECOND_LOOK_FEWEST_POINTS
from stereo_fuzzy_perception.nodes.rig_parameters import RigSettings

_AREA = AreaConfig()


@dataclass(frozen=True)
class FuzzyBestPointSettings:
    """Parameters of fuzzy_best_point_node, typed."""

    selector: str = parameter('fuzzy_fitted', 'How the best point is chosen', choices=SELECTORS)
    rule_base_file: str = parameter(
        '', 'Rule base YAML of a fuzzy selector; empty = the packaged one '
        '(data/fuzzy_fitted.yaml or data/fuzzy_chapter.yaml)')
    network_file: str = parameter(
        '', 'Weights (.npz) of the neural_network selector; empty = data/neural_baseline.npz')
    # --- world frame and workspace box (shared with gantry_driver_node)
    world: WorldSettings = parameter_group(WorldSettings, prefix='')
    # --- correlation area (step 1): thresholds in sigmas of each point's own height noise
    surface_search_m: float = parameter(
        _AREA.surface_search_m, 'The work surface plane is measured from the points within this '
        'of z = 0 [m]', 0.001, 0.2)
    surface_margin_sigmas: float = parameter(
        _AREA.surface_margin_sigmas, 'Object candidates stand this many sigmas of their height '
        'noise above the measured surface', 0.5, 50.0)
    object_sigmas: float = parameter(
        _AREA.object_sigmas, 'A region of candidates is an object when its median height is '
        'this many sigmas (else: no object, no best point)', 0.5, 100.0)
    area_top_sigmas: float = parameter(
        _AREA.area_top_sigmas, 'A region whose median height is below object_sigmas is still '
        'an object when, over the n squares of smoothing_px it covers (independent averages of '
        'the noise), its median times sqrt(n) is object_sigmas and its top stands this many '
        'sigmas of its points above the surface; 0 = no such area test', 0.0, 100.0)
    plausible_average: bool = parameter(
        _AREA.plausible_average, 'Average for the object test only the matches no higher than '
        'max_object_height_m above the surface (mismatches on a plain table drown a real '
        "object's average); the top face is still found on the average of all")
    top_band_sigmas: float = parameter(
        _AREA.top_band_sigmas, "The correlation area is the object's points within this many "
        'sigmas of its top face', 0.1, 20.0)
    smoothing_px: float = parameter(
        _AREA.smoothing_px, 'Heights are averaged over a square of this side in the left image '
        'before the object test [px]; when no object stands out, over a square twice as wide',
        1.0, 200.0)
    min_disparity_sigma_px: float = parameter(
        _AREA.min_disparity_sigma_px,
        'Lower bound of the disparity noise measured on the surface [px]', 0.001, 5.0)
    assumed_disparity_sigma_px: float = parameter(
        _AREA.assumed_disparity_sigma_px,
        'Disparity noise when too few surface points are seen to measure it [px]', 0.001, 5.0)
    min_points: int = parameter(
        _AREA.min_points, 'Fewer points in the correlation area means no best point',
        1, 1_000_000)
    max_object_across_m: float = parameter(
        _AREA.max_object_across_m, 'A top face longer than this on the surface (its principal '
        'axis) is no object: refused, not taken [m]', 0.001, 10.0)
    min_object_across_m: float = parameter(
        _AREA.min_object_across_m, 'A top face narrower than this on the surface (across its '
        'principal axis) is no object but a sliver of one: refused, not taken [m]; 0 = no '
        'limit; below max_object_across_m', 0.0, 10.0)
    max_object_height_m: float = parameter(
        _AREA.max_object_height_m, 'A top face higher than this above the work surface is no '
        'object: refused, not taken; matches higher than this by more than 3 sigmas of their '
        'noise are mismatches, left out [m]', 0.001, 10.0)
    min_object_height_m: float = parameter(
        _AREA.min_object_height_m, 'A region whose top stands lower than this above the work '
        'surface is no object, however far it stands out of the noise [m]; 0 = no limit; '
        'below max_object_height_m', 0.0, 10.0)
    max_top_spread_m: float = parameter(
        _AREA.max_top_spread_m, 'A top face whose heights scatter more than this beyond what '
        "its points' noise explains (standard deviations, subtracted in squares) is not "
        'measured well enough for a point: refused as uncertain_top, not taken [m]; 0 = no '
        'limit', 0.0, 1.0)
    min_top_fill: float = parameter(
        _AREA.min_top_fill, "Share of the top face's outline in the left image (the convex hull "
        'of its matches) that must hold matches; less is a face in pieces: refused as '
        'uncertain_top unless the image shows it whole (outline_from_image) [-]; 0 = no '
        'limit', 0.0, 1.0)
    outline_from_image: bool = parameter(
        _AREA.outline_from_image, "Take the top face's outline from the edges of the left "
        'rectified image that comes with the matches (StereoMatches.left_rectified) rather than '
        'from the matches alone: the matches place the rim only to within half a correlation '
        'window; and take a face in pieces (min_top_fill) whole when the image shows it as one '
        'plain region around its matches (a low-texture top matched only at its rim) or, one '
        'piece with holes filling at least 0.8 of min_top_fill, within its rim in the image (a '
        'textured top matched in blotches)')
    min_surface_score: float = parameter(
        _AREA.min_surface_score, 'When the matches near the work surface score below this '
        '(median correlation score), the surface is plain and matched on sensor noise: only the '
        'matches scoring this are used, and the surface is z = 0 of world as the rig pose puts '
        "it (surface_source 'plain'); 0 = never", 0.0, 0.99)
    fit_top_shape: bool = parameter(
        _AREA.fit_top_shape, 'Fit the top face as a disc or a rectangle to both rectified images '
        'pixel by pixel (top_shape_fit.py: no correlation window straddles its rim) and move the '
        'best point to the fitted centre where the fit lowered its cost clearly and is found '
        'again from starts 2 mm off: 0.7 of the way within 7 mm (whole where every start '
        'ended within 0.25 mm of it), whole within 12 mm when every start found it. A face '
        'refused as in pieces, or as smaller in the image than any top, is given its fitted '
        'centre when the fit is clearer still. Fitted '
        'once per object: the pairs that follow with a point within 4 mm of the first reuse the '
        "fit, so only the first pair of each object waits for it (its cost: the main README's "
        'benchmark table)')
    colour_silhouette: bool = parameter(
        _AREA.colour_silhouette, 'When the cameras give colour (the matches carry '
        'StereoMatches.left_rectified_colour and right_rectified_colour), look first for the '
        "object's silhouette in the left image: the largest region of another chromaticity than "
        "the table's (which lighting does not change) whose matches stand above the table around "
        "it. Its top is the footprint that both the top's plane and the surface show inside the "
        "silhouette, at its matches' median height, and the best point its centre; a top whose "
        'matches scatter too much is not taken, nor one whose rim both images put on the table '
        '(a patch of colour printed on it). The grey looks decide otherwise '
        '(colour_silhouette.py)')
    second_look_stride_one: bool = parameter(
        True, 'When matches of a point_stride above 1 find the object but refuse its top face '
        'as too thin (too_few_points, uncertain_top), or give its point on fewer than '
        f'{SECOND_LOOK_FEWEST_POINTS} matches, match the pair again at point stride 1 from the '
        'rectified images and settings that come with them (StereoMatches) and decide again: '
        'a printed, low-texture or small top keeps too few matches at a coarse stride. Costs '
        'one stride-1 match and decision on those pairs only')
    # --- rig pose: a pose file (static_transform_publisher form), /tf_static, or the chapter's
    # alpha, theta, z0 (+ x0, y0, vergence) converted to the same transform (core/rig_pose.py)
    rig_pose_file: str = parameter(
        '', 'Pose file with the left camera optical frame in world (the form '
        'static_transform_publisher takes); overrides the rig.* pose numbers; empty = use them',
        read_only=True)
    rig: RigSettings = parameter_group(RigSettings)
    left_calibration_file: str = parameter(
        '', 'Left camera calibration YAML; with the right one, a rig.baseline_m > 0 that '
        'disagrees with them ends the node at start; empty = checked against the first '
        'matches message instead: one ERROR, /diagnostics ERROR, every decision refused as '
        'rig_mismatch', read_only=True)
    right_calibration_file: str = parameter(
        '', 'Right camera calibration YAML (its P gives the baseline)', read_only=True)
    # --- reporting
    diagnostics_period_s: float = parameter(
        1.0, 'Period of the /diagnostics report [s]', 0.1, 60.0, read_only=True)

    def area_config(self) -> AreaConfig:
        """Return how the correlation area is found, as these settings describe."""
        return AreaConfig(
            workspace_min=self.world.workspace_min_m, workspace_max=self.world.workspace_max_m,
            surface_search_m=self.surface_search_m,
            surface_margin_sigmas=self.surface_margin_sigmas, object_sigmas=self.object_sigmas,
            area_top_sigmas=self.area_top_sigmas, plausible_average=self.plausible_average,
            top_band_sigmas=self.top_band_sigmas, smoothing_px=self.smoothing_px,
            min_disparity_sigma_px=self.min_disparity_sigma_px,
            assumed_disparity_sigma_px=self.assumed_disparity_sigma_px,
            min_points=self.min_points, max_object_across_m=self.max_object_across_m,
            min_object_across_m=self.min_object_across_m,
            max_object_height_m=self.max_object_height_m,
            min_object_height_m=self.min_object_height_m,
            max_top_spread_m=self.max_top_spread_m, min_top_fill=self.min_top_fill,
            outline_from_image=self.outline_from_image,
            min_surface_score=self.min_surface_score, fit_top_shape=self.fit_top_shape,
            colour_silhouette=self.colour_silhouette)

    def problem(self) -> str | None:
        """Return why the correlation area settings cannot work, or None."""
        return self.area_config().problem()


PARAMETERS = parameter_specs(FuzzyBestPointSettings)
