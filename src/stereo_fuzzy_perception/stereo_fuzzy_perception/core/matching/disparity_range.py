"""The disparity search range a rig needs: from the calibration, the rig pose and the workspace.

A point (X, Y, Z) of the left rectified frame has the disparity d = (cx_l - cx_r) + f B / Z
(triangulation.py). The disparities the matcher must search are those of the workspace box (the
highest object at its ceiling) where both cameras see it, and those of the work surface
wherever the left image shows it: a pixel whose true disparity lies outside the range is matched
at a wrong one inside it, and the surface beyond the box would come out as points floating in
the box. The box is sampled on a grid, the surface along the image border (its nearest and
farthest points lie there), and the range spans their disparities with a margin for a rig pose
that is a little off.

ROS-free: numpy only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from stereo_fuzzy_perception.core.camera_model import StereoCalibration

SAMPLES_PER_AXIS = (25, 25, 9)
"""Grid samples of the workspace box along x, y, z."""

SURFACE_BELOW_M = 0.02
"""The box is extended this far below its floor: a work surface a little lower than the rig
pose says must still be matched (its plane is measured from these points) [m]."""

MARGIN_PX = 3
"""Disparities added on each side of the sampled span [px]."""

MAX_RANGE_PX = 512
"""The matcher's largest disparity_range (window_matcher.MAX_DISPARITY_RANGE)."""


class DisparityRangeError(ValueError):
    """No part of the workspace box is in view of both cameras (rig pose or box wrong)."""


@dataclass(frozen=True)
class DisparityRange:
    """Disparities to search [px].

    Attributes:
        min_disparity: Smallest disparity searched [px].
        disparity_range: Number of disparities searched [px].
        nearest_m: Smallest rectified depth of the box in view [m].
        farthest_m: Largest rectified depth of the box in view [m].
    """

    min_disparity: int
    disparity_range: int
    nearest_m: float
    farthest_m: float

    @property
    def max_disparity(self) -> int:
        """Return the largest disparity searched [px]."""
        return self.min_disparity + self.disparity_range - 1


def _surface_disparities(calibration: StereoCalibration, world_from_left_camera: np.ndarray,
                         surface_z: float) -> np.ndarray:
    """Return the disparities [px] of the plane z = surface_z along the left image's border."""
    left_p = np.asarray(calibration.left.P, dtype=float)
    width, height = calibration.left.width, calibration.left.height
    u = np.concatenate([np.linspace(0, width - 1, 64), np.full(48, width - 1.0),
                        np.linspace(0, width - 1, 64), np.zeros(48)])
    v = np.concatenate([np.zeros(64), np.linspace(0, height - 1, 48), np.full(64, height - 1.0),
                        np.linspace(0, height - 1, 48)])
    rays = np.column_stack([(u - left_p[0, 2]) / left_p[0, 0], (v - left_p[1, 2]) / left_p[1, 1],
                            np.ones(len(u))])  # rectified, unit depth
    pose = np.asarray(world_from_left_camera, dtype=float)
    world_rays = rays @ (pose[:3, :3] @ np.asarray(calibration.left.R, dtype=float).T).T
    with np.errstate(divide='ignore', invalid='ignore'):
        depth = (surface_z - pose[2, 3]) / world_rays[:, 2]
    depth = depth[np.isfinite(depth) & (depth > 0.0)]
    f_baseline = left_p[0, 3] - float(calibration.right.P[0, 3])
    shift = left_p[0, 2] - float(calibration.right.P[0, 2])
    surface: np.ndarray = shift + f_baseline / depth
    return surface


def workspace_disparity_range(calibration: StereoCalibration, world_from_left_camera: np.ndarray,
                              workspace_min: tuple[float, float, float],
                              workspace_max: tuple[float, float, float],
                              margin_px: int = MARGIN_PX) -> DisparityRange:
    """Return the disparities under which both cameras see the workspace box.

    Args:
        calibration: Rectified stereo calibration (R and P of both cameras).
        world_from_left_camera: 4x4 pose of the left camera's optical frame in `world`.
        workspace_min: Lower corner (x, y, z) of the workspace box in `world` [m].
        workspace_max: Upper corner of the box [m].
        margin_px: Disparities added on each side of the sampled span [px].

    Returns:
        The range, at most MAX_RANGE_PX wide (the nearest disparities are dropped first: the
        work surface and low objects lie far).

    Raises:
        DisparityRangeError: When no sample of the box is in view of both cameras.
    """
    left_p = np.asarray(calibration.left.P, dtype=float)
    right_p = np.asarray(calibration.right.P, dtype=float)
    axes = [np.linspace(low - (SURFACE_BELOW_M if axis == 2 else 0.0), high, count)
            for axis, (low, high, count) in enumerate(zip(workspace_min, workspace_max,
                                                          SAMPLES_PER_AXIS, strict=True))]
    world = np.stack(np.meshgrid(*axes, indexing='ij'), axis=-1).reshape(-1, 3)
    camera_from_world = np.linalg.inv(np.asarray(world_from_left_camera, dtype=float))
    camera = world @ camera_from_world[:3, :3].T + camera_from_world[:3, 3]
    rectified = camera @ np.asarray(calibration.left.R, dtype=float).T
    depth = rectified[:, 2]
    in_front = depth > 1e-6
    rectified, depth = rectified[in_front], depth[in_front]
    homogeneous = np.column_stack([rectified, np.ones(len(rectified))])
    left_uv = homogeneous @ left_p.T
    right_uv = homogeneous @ right_p.T
    width, height = calibration.left.width, calibration.left.height
    seen = np.ones(len(depth), dtype=bool)
    for projected in (left_uv, right_uv):
        u = projected[:, 0] / projected[:, 2]
        v = projected[:, 1] / projected[:, 2]
        seen &= (u >= 0.0) & (u <= width - 1) & (v >= 0.0) & (v <= height - 1)
    if not np.any(seen):
        raise DisparityRangeError(
            'no part of the workspace box '
            f'{tuple(workspace_min)}..{tuple(workspace_max)} m is in view of both cameras: '
            'check the rig pose and the workspace box')
    disparity = (left_uv[seen, 0] / left_uv[seen, 2]) - (right_uv[seen, 0] / right_uv[seen, 2])
    surface = _surface_disparities(calibration, world_from_left_camera,
                                   workspace_min[2] - SURFACE_BELOW_M)
    if len(surface):
        disparity = np.concatenate([disparity, surface])
    low = math.floor(max(float(disparity.min()), 1.0)) - margin_px
    high = math.ceil(float(disparity.max())) + margin_px
    high = min(high, low + MAX_RANGE_PX - 1)
    return DisparityRange(low, high - low + 1, float(depth[seen].min()),
                          float(depth[seen].max()))
