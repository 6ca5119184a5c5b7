"""The rig pose and the workspace box: one definition for every node that needs them.

correlation_node derives its disparity search range from them, fuzzy_best_point_node maps the
matches to `world` and keeps the workspace with them. Both declare these same specs, so one
params file section `/**: ros__parameters:` gives them to both. ROS-free.
"""

from __future__ import annotations

from stereo_fuzzy_parameters.spec import ParameterSpec, ParameterValue

from stereo_fuzzy_perception.core.rig_geometry import StereoRig

_RIG = StereoRig()
WORKSPACE_MIN = (0.0, 0.0, 0.0)
"""Default lower corner of the workspace box in `world` [m] (the gantry's reach)."""
WORKSPACE_MAX = (0.40, 0.30, 0.20)
"""Default upper corner of the workspace box [m]."""

WORKSPACE_PARAMETERS = [
    ParameterSpec(f'workspace.{bound}_{axis}', corner[index],
                  f'Workspace box {"lower" if bound == "min" else "upper"} {axis} in world [m]',
                  -10.0, 10.0, read_only=True)
    for bound, corner in (('min', WORKSPACE_MIN), ('max', WORKSPACE_MAX))
    for index, axis in enumerate('xyz')
]

RIG_PARAMETERS = [
    ParameterSpec('rig.baseline_m', _RIG.baseline_m,
                  'Distance between the optical centres [m]', 0.001, 2.0, read_only=True),
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
]


def workspace_box(values: dict[str, ParameterValue]
                  ) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """Return (lower corner, upper corner) of the workspace box described by parameter values."""
    low = tuple(float(values[f'workspace.min_{axis}']) for axis in 'xyz')  # type: ignore[arg-type]
    high = tuple(float(values[f'workspace.max_{axis}']) for axis in 'xyz')  # type: ignore[arg-type]
    return (low[0], low[1], low[2]), (high[0], high[1], high[2])


def stereo_rig(values: dict[str, ParameterValue]) -> StereoRig:
    """Return the StereoRig described by parameter values."""
    return StereoRig(
        baseline_m=float(values['rig.baseline_m']), alpha_deg=float(values['rig.alpha_deg']),
        theta_deg=float(values['rig.theta_deg']), x0_m=float(values['rig.x0_m']),
        y0_m=float(values['rig.y0_m']), z0_m=float(values['rig.z0_m']),
        vergence_deg=float(values['rig.vergence_deg']))
