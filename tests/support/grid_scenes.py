"""Matches on the pixel grid of a rectified pair, ray-cast from a table and a box (tests only).

What correlation_node hands the fuzzy stage, without rendering: for every left-image pixel on the
grid of `stride`, the ray meets the work surface z = 0 or the top of the box; its disparity
gets noise that is correlated over a window (as window correlation's errors are), and the point
is triangulated back into the left optical frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage
from stereo_fuzzy_perception.core.camera_model import CameraCalibration
from stereo_fuzzy_perception.core.matched_points import MatchedPoints, RectifiedImage
from stereo_fuzzy_perception.core.rig_geometry import StereoRig
from stereo_fuzzy_perception.simulation.synthetic_scenes import (
    default_camera_matrix,
    rectified_calibration,
)

TILTED_RIG = StereoRig(baseline_m=0.08, alpha_deg=30.0, x0_m=0.2, y0_m=-0.2,
                       z0_m=0.6 * math.cos(math.radians(30.0)), vergence_deg=2.0)
"""A rig 0.6 m from the surface along its optical axis, looking down at 30 degrees: the rig
the outline, appearance and plain-top tests share."""


@dataclass(frozen=True)
class Box:
    """An upright box (or a disc when round) standing on the surface, [m] in `world`."""

    centre_xy: tuple[float, float]
    size: float
    height: float
    round: bool = False

    def covers(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        dx, dy = x - self.centre_xy[0], y - self.centre_xy[1]
        if self.round:
            return np.hypot(dx, dy) <= 0.5 * self.size
        return (np.abs(dx) <= 0.5 * self.size) & (np.abs(dy) <= 0.5 * self.size)


def grid_matches(rig: StereoRig, box: Box | None, noise_px: float, stride: int = 1,
                 seed: int = 0, fov_deg: float = 45.0, surface_z: float = 0.0,
                 surface_slope: tuple[float, float] = (0.0, 0.0), window: int = 9,
                 fatten_px: int = 0, image: bool = False, plain_rim_px: int = 0,
                 top_contrast: float = 1.0
                 ) -> tuple[MatchedPoints, CameraCalibration, CameraCalibration]:
    """Return (matches, left, right rectified calibrations) of a box on a (tilted) surface.

    The surface is z = surface_z + slope_x x + slope_y y; the box stands on z = surface_z with
    its top at surface_z + height. Side walls are not drawn. `fatten_px` gives the top's
    disparity to that many pixels right of its rim (as a window straddling a rim whose table
    side is plain would); `image` attaches the left rectified image: a textured table and a
    brighter textured top. `plain_rim_px` makes the top plain (a grey level of sensor noise in
    the image) and, as window correlation would, leaves it matches only within that many
    pixels of its rim. `top_contrast` scales the texture of a textured top in the image.
    """
    left, right = rectified_calibration(rig, default_camera_matrix(vertical_fov_deg=fov_deg))
    focal, cx, cy = left.P[0, 0], left.P[0, 2], left.P[1, 2]
    f_baseline = -right.P[0, 3]
    rows, columns = np.mgrid[0:left.height, 0:left.width].astype(float)
    rectified_rays = np.stack([(columns - cx) / focal, (rows - cy) / focal,
                               np.ones_like(columns)], axis=-1)
    pose = rig.world_from_left_camera()
    world_rays = rectified_rays @ (pose[:3, :3] @ np.asarray(left.R).T).T
    centre = pose[:3, 3]
    slope_x, slope_y = surface_slope
    # ray: centre + t * ray (t = rectified depth); surface z - sx x - sy y = surface_z
    along = world_rays[..., 2] - slope_x * world_rays[..., 0] - slope_y * world_rays[..., 1]
    with np.errstate(divide='ignore', invalid='ignore'):
        depth = (surface_z - centre[2] + slope_x * centre[0] + slope_y * centre[1]) / along
        if box is not None:
            top_depth = (surface_z + box.height - centre[2]) / world_rays[..., 2]
            top = centre + top_depth[..., None] * world_rays
            on_top = box.covers(top[..., 0], top[..., 1]) & (top_depth > 0)
            fattened = on_top.copy()
            for shift in range(1, fatten_px + 1):
                fattened[:, shift:] |= on_top[:, :-shift]
            depth = np.where(fattened, top_depth, depth)
    rng = np.random.default_rng(seed)
    picture = None
    plain = box is not None and plain_rim_px > 0
    if image:
        texture = ndimage.uniform_filter(rng.normal(size=depth.shape), 3)
        texture *= 25.0 / float(texture.std())
        if plain:
            texture = np.where(on_top, rng.normal(size=depth.shape), texture)
        elif box is not None:
            texture = np.where(on_top, top_contrast * texture, texture)
        brighter = 60.0 + (110.0 * on_top if box is not None else 0.0)
        picture = RectifiedImage(np.clip(brighter + texture, 0, 255).astype(np.uint8),
                                 window_size=window)
    noise = ndimage.uniform_filter(rng.normal(size=depth.shape), window)
    noise *= noise_px / max(float(noise.std()), 1e-12)
    disparity = f_baseline / depth + noise
    keep = (depth > 0) & (disparity > 0)
    keep[::, :] &= (rows % stride == 0) & (columns % stride == 0)
    if plain:
        keep &= ~on_top | (ndimage.distance_transform_edt(on_top) <= plain_rim_px)
    rectified = rectified_rays[keep] * (f_baseline / disparity[keep])[:, None]
    xyz = rectified @ np.asarray(left.R)  # R^T applied to row vectors
    u = columns[keep]
    points = MatchedPoints(xyz, u, rows[keep], u - disparity[keep], np.ones(int(keep.sum())),
                           picture)
    return points, left, right


def camera_distance(rig: StereoRig) -> float:
    """Return the distance [m] from the rig to the surface along its optical axis."""
    return rig.z0_m / math.cos(math.radians(rig.alpha_deg))


WALL_SAMPLES = 60
"""Heights a ray is followed at from a box's top down to the ground, for where it meets a wall."""


def plain_box_pair(rig: StereoRig, box: Box, top_grey: float = 140.0, wall_grey: float = 70.0,
                   noise_grey: float = 1.5, seed: int = 0, fov_deg: float = 45.0,
                   right_gain: float = 1.0, right_offset: float = 0.0,
                   top_texture: float = 0.0, walls_from_footprint: bool = False
                   ) -> tuple[RectifiedImage, RectifiedImage, CameraCalibration,
                              CameraCalibration, np.ndarray]:
    """Return both rectified images of a plain-topped box on a textured table, ray-cast.

    The table's texture is fixed on the table (a smooth random field in world x, y, 1 mm
    cells), so both cameras see the same texture where it lies; the top is `top_grey` and its
    walls `wall_grey`, both with sensor noise only; the right camera has its own gain and
    offset. `top_texture` gives the top a texture of its own, fixed on it as the table's is on
    the table (its standard deviation in grey levels). `walls_from_footprint` draws a wall only
    where the ray's ground point lies in the footprint, as these images were first drawn: the
    rays that clip a wall's corner then show the table. Returns (left image, right image, left
    and right rectified calibrations, the top's outline (K, 2) in the left image [px]).
    """
    left, right = rectified_calibration(rig, default_camera_matrix(vertical_fov_deg=fov_deg))
    focal, cx, cy = left.P[0, 0], left.P[0, 2], left.P[1, 2]
    baseline = -right.P[0, 3] / focal
    pose = rig.world_from_left_camera()
    to_world = pose[:3, :3] @ np.asarray(left.R).T  # rectified frame -> world (both cameras)
    rng = np.random.default_rng(seed)
    cells = ndimage.gaussian_filter(rng.normal(size=(1000, 1000)), 1.5)
    cells *= 30.0 / float(cells.std())
    rows, columns = np.mgrid[0:left.height, 0:left.width].astype(float)
    rays = np.stack([(columns - cx) / focal, (rows - cy) / focal, np.ones_like(columns)],
                    axis=-1) @ to_world.T
    images = []
    for offset_x, gain, offset in ((0.0, 1.0, 0.0), (baseline, right_gain, right_offset)):
        centre = pose[:3, 3] + to_world @ np.array([offset_x, 0.0, 0.0])
        with np.errstate(divide='ignore', invalid='ignore'):
            ground = centre + ((-centre[2]) / rays[..., 2])[..., None] * rays
            top = centre + ((box.height - centre[2]) / rays[..., 2])[..., None] * rays
        on_top = box.covers(top[..., 0], top[..., 1])
        # a wall where the ray, between the top's level and the ground, passes over the
        # footprint: it enters the box's side there (a ray clipping a corner too)
        on_wall = np.zeros_like(on_top)
        for share in [1.0] if walls_from_footprint else np.linspace(0.0, 1.0, WALL_SAMPLES):
            along = top + share * (ground - top)
            on_wall |= box.covers(along[..., 0], along[..., 1])
        on_wall &= ~on_top
        table = ndimage.map_coordinates(cells, [(ground[..., 1] + 0.2) * 1000.0,
                                                (ground[..., 0] + 0.2) * 1000.0],
                                        order=1, mode='wrap')
        # the top's texture: the table's field, turned and shifted so the two differ
        on_top_texture = ndimage.map_coordinates(cells, [(top[..., 0] + 0.3) * 1000.0,
                                                         (top[..., 1] + 0.1) * 1000.0],
                                                 order=1, mode='wrap')
        top_value = top_grey + (top_texture / 30.0) * on_top_texture
        grey = np.where(on_top, top_value, np.where(on_wall, wall_grey, 110.0 + table))
        grey = gain * (grey + rng.normal(0.0, noise_grey, grey.shape)) + offset
        images.append(RectifiedImage(np.clip(np.round(grey), 0, 255).astype(np.uint8)))
    half = 0.5 * box.size
    corners = np.array([[box.centre_xy[0] + dx, box.centre_xy[1] + dy, box.height]
                        for dx, dy in ((-half, -half), (half, -half), (half, half),
                                       (-half, half))])
    camera = (corners - pose[:3, 3]) @ to_world  # world -> rectified left frame
    outline = np.column_stack([focal * camera[:, 0] / camera[:, 2] + cx,
                               focal * camera[:, 1] / camera[:, 2] + cy])
    return images[0], images[1], left, right, outline
