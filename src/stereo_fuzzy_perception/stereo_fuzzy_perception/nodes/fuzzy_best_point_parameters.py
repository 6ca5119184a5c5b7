"""Parameters of fuzzy_best_point_node: the one place their names, defaults and ranges live.

ROS-free, so the README table, the config file test and the node read the same specs.
"""

from __future__ import annotations

from stereo_fuzzy_parameters.spec import ParameterSpec, ParameterValue

from stereo_fuzzy_perception.core.best_point.correlation_area import AreaConfig
from stereo_fuzzy_perception.core.best_point.point_selectors import SELECTORS
from stereo_fuzzy_perception.nodes.rig_parameters import (
    RIG_PARAMETERS,
    WORKSPACE_PARAMETERS,
    stereo_rig,
    workspace_box,
)

_AREA = AreaConfig()

PARAMETERS = [
    ParameterSpec('selector', 'fuzzy_fitted', 'How the best point is chosen',
                  choices=SELECTORS),
    ParameterSpec('rule_base_file', '',
                  'Rule base YAML of a fuzzy selector; empty = the packaged one '
                  '(data/fuzzy_fitted.yaml or data/fuzzy_chapter.yaml)'),
    ParameterSpec('network_file', '',
                  'Weights (.npz) of the neural_network selector; empty = '
                  'data/neural_baseline.npz'),
    # --- correlation area (step 1): thresholds in sigmas of each point's own height noise
    *WORKSPACE_PARAMETERS,
    ParameterSpec('surface_search_m', _AREA.surface_search_m,
                  'The work surface plane is measured from the points within this of z = 0 '
                  '[m]', 0.001, 0.2),
    ParameterSpec('surface_margin_sigmas', _AREA.surface_margin_sigmas,
                  'Object candidates stand this many sigmas of their height noise above the '
                  'measured surface', 0.5, 50.0),
    ParameterSpec('object_sigmas', _AREA.object_sigmas,
                  'A region of candidates is an object when its median height is this many '
                  'sigmas (else: no object, no best point)', 0.5, 100.0),
    ParameterSpec('top_band_sigmas', _AREA.top_band_sigmas,
                  "The correlation area is the object's points within this many sigmas of its "
                  'top face', 0.1, 20.0),
    ParameterSpec('smoothing_px', _AREA.smoothing_px,
                  'Heights are averaged over a square of this side in the left image before the '
                  'object test [px]', 1.0, 200.0),
    ParameterSpec('min_disparity_sigma_px', _AREA.min_disparity_sigma_px,
                  'Lower bound of the disparity noise measured on the surface [px]', 0.001, 5.0),
    ParameterSpec('assumed_disparity_sigma_px', _AREA.assumed_disparity_sigma_px,
                  'Disparity noise when too few surface points are seen to measure it [px]',
                  0.001, 5.0),
    ParameterSpec('min_points', _AREA.min_points,
                  'Fewer points in the correlation area means no best point', 1, 1_000_000),
    # --- rig pose (the chapter's alpha, theta, z0 generalised; must match the calibration)
    *RIG_PARAMETERS,
    # --- wiring and reporting
    ParameterSpec('world_frame', 'world', 'Frame of best_point and the decision',
                  read_only=True),
    ParameterSpec('diagnostics_period', 1.0, 'Period of the /diagnostics report [s]', 0.1,
                  60.0, read_only=True),
]


def area_config(values: dict[str, ParameterValue]) -> AreaConfig:
    """Return the AreaConfig described by parameter values."""
    low, high = workspace_box(values)
    return AreaConfig(
        workspace_min=low, workspace_max=high,
        surface_search_m=float(values['surface_search_m']),
        surface_margin_sigmas=float(values['surface_margin_sigmas']),
        object_sigmas=float(values['object_sigmas']),
        top_band_sigmas=float(values['top_band_sigmas']),
        smoothing_px=float(values['smoothing_px']),
        min_disparity_sigma_px=float(values['min_disparity_sigma_px']),
        assumed_disparity_sigma_px=float(values['assumed_disparity_sigma_px']),
        min_points=int(values['min_points']),  # type: ignore[arg-type]
    )


__all__ = ['PARAMETERS', 'area_config', 'stereo_rig']
