"""Parameters of fuzzy_best_point_node: the one place their names, defaults and ranges live.

ROS-free, so the README table, the config file test and the node read the same specs.
"""

from __future__ import annotations

from stereo_fuzzy_parameters.spec import ParameterSpec, ParameterValue

from stereo_fuzzy_perception.core.best_point.correlation_area import AreaConfig
from stereo_fuzzy_perception.core.best_point.point_selectors import SELECTORS
from stereo_fuzzy_perception.core.rig_geometry import StereoRig

_AREA = AreaConfig()
_RIG = StereoRig()

PARAMETERS = [
    ParameterSpec('selector', 'fuzzy_fitted', 'How the best point is chosen',
                  choices=SELECTORS),
    ParameterSpec('rule_base_file', '',
                  'Rule base YAML of a fuzzy selector; empty = the packaged one '
                  '(data/fuzzy_fitted.yaml or data/fuzzy_chapter.yaml)'),
    ParameterSpec('network_file', '',
                  'Weights (.npz) of the neural_network selector; empty = '
                  'data/neural_baseline.npz'),
    # --- correlation area (step 1)
    ParameterSpec('workspace.min_x', _AREA.workspace_min[0],
                  'Workspace box lower x in world [m]', -10.0, 10.0, read_only=True),
    ParameterSpec('workspace.min_y', _AREA.workspace_min[1],
                  'Workspace box lower y in world [m]', -10.0, 10.0, read_only=True),
    ParameterSpec('workspace.min_z', _AREA.workspace_min[2],
                  'Workspace box lower z in world [m]', -10.0, 10.0, read_only=True),
    ParameterSpec('workspace.max_x', _AREA.workspace_max[0],
                  'Workspace box upper x in world [m]', -10.0, 10.0, read_only=True),
    ParameterSpec('workspace.max_y', _AREA.workspace_max[1],
                  'Workspace box upper y in world [m]', -10.0, 10.0, read_only=True),
    ParameterSpec('workspace.max_z', _AREA.workspace_max[2],
                  'Workspace box upper z in world [m]', -10.0, 10.0, read_only=True),
    ParameterSpec('surface_margin_m', _AREA.surface_margin_m,
                  'Object points must be this far above the work surface z = 0 [m]', 0.0, 0.05),
    ParameterSpec('cluster_gap_m', _AREA.cluster_gap_m,
                  'Cell size of the clustering grid: points closer are joined [m]', 0.001, 0.1),
    ParameterSpec('keep_largest_cluster', _AREA.keep_largest_cluster,
                  'Keep only the largest cluster of object points (else all of them)'),
    ParameterSpec('top_band_m', _AREA.top_band_m,
                  'Height of the band below the object top that forms the correlation area '
                  '[m]', 0.0005, 0.1),
    ParameterSpec('min_points', _AREA.min_points,
                  'Fewer points in the correlation area means no best point', 1, 1_000_000),
    # --- rig pose: a pose file (static_transform_publisher form), /tf_static, or the chapter's
    # alpha, theta, z0 (+ x0, y0, vergence) converted to the same transform (core/rig_pose.py)
    ParameterSpec('rig_pose_file', '',
                  'Pose file with the left camera optical frame in world (the form '
                  'static_transform_publisher takes); overrides the rig.* pose numbers; '
                  'empty = use them', read_only=True),
    ParameterSpec('rig.baseline_m', 0.0,
                  'Distance between the optical centres [m]; 0 = from the calibration (right '
                  'P); a value that disagrees with the calibration is refused', 0.0, 2.0,
                  read_only=True),
    ParameterSpec('rig.alpha_deg', _RIG.alpha_deg,
                  'Rig tilt about its x axis (chapter alpha) [deg]', -90.0, 90.0, read_only=True),
    ParameterSpec('rig.theta_deg', _RIG.theta_deg,
                  'Rig pan about world z (chapter theta) [deg]', -180.0, 180.0, read_only=True),
    ParameterSpec('rig.x0_m', _RIG.x0_m, 'x of the optical centres midpoint in world [m]',
                  -10.0, 10.0, read_only=True),
    ParameterSpec('rig.y0_m', _RIG.y0_m, 'y of the optical centres midpoint in world [m]',
                  -10.0, 10.0, read_only=True),
    ParameterSpec('rig.z0_m', _RIG.z0_m,
                  'Height of the optical centres midpoint (chapter z0) [m]', 0.0, 10.0,
                  read_only=True),
    ParameterSpec('rig.vergence_deg', _RIG.vergence_deg,
                  'Total toe-in between the optical axes [deg]', 0.0, 90.0, read_only=True),
    # --- wiring and reporting
    ParameterSpec('world_frame', 'world', 'Frame of best_point and the decision',
                  read_only=True),
    ParameterSpec('diagnostics_period', 1.0, 'Period of the /diagnostics report [s]', 0.1,
                  60.0, read_only=True),
]


def area_config(values: dict[str, ParameterValue]) -> AreaConfig:
    """Return the AreaConfig described by parameter values."""
    return AreaConfig(
        workspace_min=(float(values['workspace.min_x']), float(values['workspace.min_y']),
                       float(values['workspace.min_z'])),
        workspace_max=(float(values['workspace.max_x']), float(values['workspace.max_y']),
                       float(values['workspace.max_z'])),
        surface_margin_m=float(values['surface_margin_m']),
        cluster_gap_m=float(values['cluster_gap_m']),
        keep_largest_cluster=bool(values['keep_largest_cluster']),
        top_band_m=float(values['top_band_m']),
        min_points=int(values['min_points']),  # type: ignore[arg-type]
    )


def stereo_rig(values: dict[str, ParameterValue]) -> StereoRig:
    """Return the StereoRig described by parameter values."""
    return StereoRig(
        baseline_m=float(values['rig.baseline_m']), alpha_deg=float(values['rig.alpha_deg']),
        theta_deg=float(values['rig.theta_deg']), x0_m=float(values['rig.x0_m']),
        y0_m=float(values['rig.y0_m']), z0_m=float(values['rig.z0_m']),
        vergence_deg=float(values['rig.vergence_deg']))
