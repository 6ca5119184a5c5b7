"""Settings of fuzzy_best_point_node: its parameters' names, defaults, ranges and docs, once.

ROS-free, so the README table, the config file test and the node read the same specs.
"""

from __future__ import annotations

from dataclasses import dataclass

from stereo_fuzzy_parameters.spec import parameter, parameter_group, parameter_specs
from stereo_fuzzy_parameters.world import WorldSettings

from stereo_fuzzy_perception.core.best_point.correlation_area import AreaConfig
from stereo_fuzzy_perception.core.best_point.point_selectors import SELECTORS
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
    # --- correlation area (step 1)
    surface_margin_m: float = parameter(
        _AREA.surface_margin_m, 'Object points must be this far above the work surface z = 0 '
        '[m]', 0.0, 0.05)
    cluster_gap_m: float = parameter(
        _AREA.cluster_gap_m, 'Cell size of the clustering grid: points closer are joined [m]',
        0.001, 0.1)
    keep_largest_cluster: bool = parameter(
        _AREA.keep_largest_cluster,
        'Keep only the largest cluster of object points (else all of them)')
    top_band_m: float = parameter(
        _AREA.top_band_m, 'Height of the band below the object top that forms the correlation '
        'area [m]', 0.0005, 0.1)
    min_points: int = parameter(
        _AREA.min_points, 'Fewer points in the correlation area means no best point',
        1, 1_000_000)
    # --- rig pose (read-only; must match the calibration the matches were made with)
    rig: RigSettings = parameter_group(RigSettings)
    # --- reporting
    diagnostics_period_s: float = parameter(
        1.0, 'Period of the /diagnostics report [s]', 0.1, 60.0, read_only=True)

    def area_config(self) -> AreaConfig:
        """Return how the correlation area is found, as these settings describe."""
        return AreaConfig(
            workspace_min=self.world.workspace_min_m, workspace_max=self.world.workspace_max_m,
            surface_margin_m=self.surface_margin_m, cluster_gap_m=self.cluster_gap_m,
            keep_largest_cluster=self.keep_largest_cluster, top_band_m=self.top_band_m,
            min_points=self.min_points)

    def problem(self) -> str | None:
        """Return why the correlation area settings cannot work, or None."""
        return self.area_config().problem()


PARAMETERS = parameter_specs(FuzzyBestPointSettings)
