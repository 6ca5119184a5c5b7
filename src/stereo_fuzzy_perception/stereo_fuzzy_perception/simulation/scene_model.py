"""Scenes of the 3P robot's workspace: one object of the chapter's Table 1 on a textured surface.

A scene is a plain description (object type, size, pose, texture seeds) that the renderer turns
into a stereo pair. Random scenes are drawn from a seed, so the same seed always gives the same
scene, and every object is placed inside the workspace and fully in view of both cameras.

Object types (Table 1 of the chapter): `circle` a flat disc, `cylinder`, `cubic_rectangle` a
rectangular box, `cubic_square` a cube. Every object stands on the work surface (z = 0 in
`world`); its ground truth target is the centre of its top face.

ROS-free: numpy only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import StrEnum

import numpy as np

from stereo_fuzzy_perception.core.rig_geometry import StereoRig, rotation_z, transform_points


class SceneError(ValueError):
    """A scene that cannot be built or placed, with the reason in the message."""


class ObjectType(StrEnum):
    """The four object types of the chapter's Table 1."""

    CIRCLE = 'circle'
    CYLINDER = 'cylinder'
    CUBIC_RECTANGLE = 'cubic_rectangle'
    CUBIC_SQUARE = 'cubic_square'

    @property
    def is_round(self) -> bool:
        """Return True for the disc and the cylinder."""
        return self in (ObjectType.CIRCLE, ObjectType.CYLINDER)


OBJECT_TYPES: tuple[ObjectType, ...] = tuple(ObjectType)


def parse_object_type(name: str) -> ObjectType:
    """Return the ObjectType called `name` (e.g. 'cylinder').

    Raises:
        SceneError: When `name` is not one of the four types.
    """
    try:
        return ObjectType(name)
    except ValueError:
        raise SceneError(f'unknown object type {name!r}; expected one of '
                         + ', '.join(kind.value for kind in ObjectType)) from None


@dataclass(frozen=True)
class Workspace:
    """The box the gantry can reach, in `world` [m]."""

    x_min: float = 0.0
    x_max: float = 0.40
    y_min: float = 0.0
    y_max: float = 0.30
    z_min: float = 0.0
    z_max: float = 0.20


WORKSPACE = Workspace()


@dataclass(frozen=True)
class SimulatedCamera:
    """Pinhole camera of the simulator: image size and vertical field of view.

    The principal point is where pybullet's TinyRenderer puts it (checked by rendering markers):
    cx = W / 2, cy = H / 2 - 1, in OpenCV's convention (pixel centres at integer coordinates).

    Attributes:
        width: Image width [px].
        height: Image height [px].
        vertical_fov_deg: Vertical field of view [deg].
        near_m: Near clipping plane [m].
        far_m: Far clipping plane [m].
    """

    width: int = 640
    height: int = 480
    vertical_fov_deg: float = 45.0
    near_m: float = 0.02
    far_m: float = 3.0

    @property
    def focal_px(self) -> float:
        """Return fx = fy [px]."""
        return (self.height / 2.0) / math.tan(math.radians(self.vertical_fov_deg) / 2.0)

    def intrinsics(self) -> np.ndarray:
        """Return the 3x3 intrinsic matrix K [px]."""
        f = self.focal_px
        return np.array([[f, 0.0, self.width / 2.0],
                         [0.0, f, self.height / 2.0 - 1.0],
                         [0.0, 0.0, 1.0]])

    def project(self, world_from_camera: np.ndarray, points_world: np.ndarray) -> np.ndarray:
        """Project (N, 3) world points with the ideal pinhole (no distortion) to (N, 2) pixels.

        Points behind the camera come out as NaN.
        """
        camera_from_world = np.linalg.inv(world_from_camera)
        points = transform_points(camera_from_world, np.atleast_2d(points_world))
        pixels = (self.intrinsics() @ points.T).T
        with np.errstate(divide='ignore', invalid='ignore'):
            uv: np.ndarray = pixels[:, :2] / pixels[:, 2:3]
        uv[points[:, 2] <= self.near_m] = np.nan
        return uv


@dataclass(frozen=True)
class SceneObject:
    """One object standing on the work surface.

    Attributes:
        object_type: Which of Table 1's objects it is.
        size_x_m: Extent along the object's own x axis [m] (the diameter for round objects).
        size_y_m: Extent along its own y axis [m] (equal to size_x_m for round objects and cubes).
        height_m: Height above the work surface [m].
        x_m: World x of the centre of its footprint [m].
        y_m: World y of that centre [m].
        yaw_rad: Rotation about world z [rad].
    """

    object_type: ObjectType
    size_x_m: float
    size_y_m: float
    height_m: float
    x_m: float
    y_m: float
    yaw_rad: float

    def top_centre(self) -> np.ndarray:
        """Return the centre of the top face in `world` [m] (where the gantry should go)."""
        return np.array([self.x_m, self.y_m, self.height_m])

    def centre(self) -> np.ndarray:
        """Return the centre of the object's volume in `world` [m]."""
        return np.array([self.x_m, self.y_m, self.height_m / 2.0])

    def world_from_object(self) -> np.ndarray:
        """Return the 4x4 pose of the object frame (footprint centre, z up) in `world`."""
        pose = np.eye(4)
        pose[:3, :3] = rotation_z(self.yaw_rad)
        pose[:3, 3] = (self.x_m, self.y_m, 0.0)
        return pose

    def footprint(self, segments: int = 32) -> np.ndarray:
        """Return (N, 2) corners of the outline in the object frame (box corners, or a
        `segments`-gon on the rim of a round object), counter-clockwise."""
        if self.object_type.is_round:
            angles = np.linspace(0.0, 2.0 * math.pi, segments, endpoint=False)
            return np.stack([0.5 * self.size_x_m * np.cos(angles),
                             0.5 * self.size_y_m * np.sin(angles)], axis=1)
        hx, hy = 0.5 * self.size_x_m, 0.5 * self.size_y_m
        return np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])

    def outline_points(self, segments: int = 32) -> np.ndarray:
        """Return (N, 3) world points on the bottom and top outlines (box corners or rims)."""
        ring = self.footprint(segments)
        bottom = np.column_stack([ring, np.zeros(len(ring))])
        top = np.column_stack([ring, np.full(len(ring), self.height_m)])
        return transform_points(self.world_from_object(), np.vstack([bottom, top]))

    def top_corners(self) -> np.ndarray:
        """Return the 4 top corners of a box, or 4 rim points of a round top, in `world` [m]."""
        hx, hy = 0.5 * self.size_x_m, 0.5 * self.size_y_m
        if self.object_type.is_round:
            local = np.array([[hx, 0.0], [0.0, hy], [-hx, 0.0], [0.0, -hy]])
        else:
            local = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
        points = np.column_stack([local, np.full(4, self.height_m)])
        return transform_points(self.world_from_object(), points)


@dataclass(frozen=True)
class Scene:
    """Everything needed to render one stereo pair, apart from the rig and the sensors.

    Attributes:
        seed: The seed the scene was drawn from (also seeds its sensor noise).
        scene_object: The object on the surface.
        surface_texture_seed: Seed of the work surface's random texture.
        object_texture_seed: Seed of the object's random texture.
        surface_texture_family: Texture family of the surface (texture_families.py).
        object_texture_family: Texture family of the object.
        surface_tint: Mean colour (r, g, b) of the surface, 0..1 each.
        object_tint: Mean colour of the object.
    """

    seed: int
    scene_object: SceneObject
    surface_texture_seed: int
    object_texture_seed: int
    surface_texture_family: str = 'value_noise'
    object_texture_family: str = 'value_noise'
    surface_tint: tuple[float, float, float] = (0.55, 0.6, 0.7)
    object_tint: tuple[float, float, float] = (0.85, 0.7, 0.45)


@dataclass(frozen=True)
class SizeRange:
    """Random size limits of the objects [m]."""

    across_min_m: float = 0.03
    across_max_m: float = 0.08
    height_min_m: float = 0.02
    height_max_m: float = 0.08
    disc_thickness_m: float = 0.005


SIZES = SizeRange()


def _random_object_shape(rng: np.random.Generator, object_type: ObjectType,
                         sizes: SizeRange) -> tuple[float, float, float]:
    across = float(rng.uniform(sizes.across_min_m, sizes.across_max_m))
    if object_type is ObjectType.CIRCLE:
        return across, across, sizes.disc_thickness_m
    if object_type is ObjectType.CYLINDER:
        return across, across, float(rng.uniform(sizes.height_min_m, sizes.height_max_m))
    if object_type is ObjectType.CUBIC_SQUARE:
        side = float(np.clip(across, sizes.height_min_m, sizes.height_max_m))
        return side, side, side
    # A rectangle clearly longer than wide: the short side is 45-75 % of the long one.
    short = max(sizes.across_min_m, across * float(rng.uniform(0.45, 0.75)))
    long_side = max(across, short / 0.75)
    return long_side, short, float(rng.uniform(sizes.height_min_m, sizes.height_max_m))


def in_view(points_world: np.ndarray, rig: StereoRig, camera: SimulatedCamera,
            margin_px: float) -> bool:
    """Return True when all points project inside both images, `margin_px` from the border."""
    for pose in (rig.world_from_left_camera(), rig.world_from_right_camera()):
        uv = camera.project(pose, points_world)
        if not np.all(np.isfinite(uv)):
            return False
        if (uv[:, 0].min() < margin_px or uv[:, 1].min() < margin_px
                or uv[:, 0].max() > camera.width - 1 - margin_px
                or uv[:, 1].max() > camera.height - 1 - margin_px):
            return False
    return True


def random_scene(
    seed: int,
    object_type: ObjectType | str | None = None,
    rig: StereoRig | None = None,
    camera: SimulatedCamera | None = None,
    workspace: Workspace = WORKSPACE,
    sizes: SizeRange = SIZES,
    margin_px: float = 16.0,
    max_attempts: int = 1000,
) -> Scene:
    """Draw a scene from `seed`: same arguments, same scene.

    Args:
        seed: Seed of numpy's default generator.
        object_type: The object's type; drawn from the four types when None.
        rig: Where the cameras are (StereoRig() when None).
        camera: The cameras' image size and field of view (SimulatedCamera() when None).
        workspace: The object lies fully inside its x-y footprint and below its top.
        sizes: Random size limits.
        margin_px: Every outline point lies this far inside both images [px].
        max_attempts: Placements tried before giving up.

    Returns:
        A scene whose object lies in the workspace and in view of both cameras.

    Raises:
        SceneError: When no placement in view was found (rig looking elsewhere, tiny images).
    """
    rig = rig or StereoRig()
    camera = camera or SimulatedCamera()
    rng = np.random.default_rng(seed)
    if object_type is None:
        kind = OBJECT_TYPES[int(rng.integers(len(OBJECT_TYPES)))]
    else:
        kind = parse_object_type(object_type) if isinstance(object_type, str) else object_type
    size_x, size_y, height = _random_object_shape(rng, kind, sizes)
    height = min(height, workspace.z_max - workspace.z_min)
    surface_seed, object_seed = (int(value) for value in rng.integers(0, 2**31 - 1, size=2))
    reach = 0.5 * math.hypot(size_x, size_y)
    for _ in range(max_attempts):
        candidate = SceneObject(
            object_type=kind, size_x_m=size_x, size_y_m=size_y, height_m=height,
            x_m=float(rng.uniform(workspace.x_min + reach, workspace.x_max - reach)),
            y_m=float(rng.uniform(workspace.y_min + reach, workspace.y_max - reach)),
            yaw_rad=0.0 if kind.is_round else float(rng.uniform(-math.pi / 2, math.pi / 2)))
        if in_view(candidate.outline_points(), rig, camera, margin_px):
            return Scene(seed=seed, scene_object=candidate, surface_texture_seed=surface_seed,
                         object_texture_seed=object_seed)
    raise SceneError(f'no placement of a {kind.value} in view of both cameras after '
                     f'{max_attempts} attempts (seed {seed}, rig {rig})')


@dataclass(frozen=True)
class GroundTruth:
    """What the chain should find in a scene.

    Attributes:
        target_world: Centre of the object's top face in `world` [m].
        scene_object: The object's type, size and pose.
    """

    target_world: np.ndarray
    scene_object: SceneObject

    @classmethod
    def of(cls, scene: Scene) -> GroundTruth:
        """Return the ground truth of `scene`."""
        return cls(target_world=scene.scene_object.top_centre(), scene_object=scene.scene_object)
