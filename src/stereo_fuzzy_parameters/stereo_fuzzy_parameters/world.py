"""The world frame and the workspace box: one declaration for every node that needs them.

fuzzy_best_point_node keeps only points inside the box, gantry_driver_node moves only inside
it; both include `WorldSettings` with `parameter_group(WorldSettings, prefix='')`, so the
parameters are `world_frame`, `workspace_min_m` and `workspace_max_m` in both.
"""

from __future__ import annotations

from dataclasses import dataclass

from stereo_fuzzy_parameters.spec import parameter

Vector3 = tuple[float, float, float]


@dataclass(frozen=True)
class WorldSettings:
    """The world frame and the workspace box in it."""

    world_frame: str = parameter(
        'world', 'Frame of the workspace and of every world point: best_point is published in '
        'it, gantry targets are accepted in it only', read_only=True)
    workspace_min_m: Vector3 = parameter(
        (0.0, 0.0, 0.0), 'Lower corner of the workspace box in world_frame, x y z [m]',
        -10.0, 10.0, read_only=True)
    workspace_max_m: Vector3 = parameter(
        (0.4, 0.3, 0.2), 'Upper corner of the workspace box in world_frame, x y z; above '
        "workspace_min_m, and for the driver inside the controller's travel ($130-$132) [m]",
        -10.0, 10.0, read_only=True)

    def problem(self) -> str | None:
        """Return why the box is empty, or None."""
        if not self.world_frame:
            return "world_frame='' is not allowed: a frame id is needed"
        for axis, low, high in zip('xyz', self.workspace_min_m, self.workspace_max_m,
                                   strict=True):
            if low >= high:
                return (f'workspace_max_m={list(self.workspace_max_m)} must exceed '
                        f'workspace_min_m={list(self.workspace_min_m)} on every axis ({axis}: '
                        f'{high} <= {low})')
        return None
