"""Scene building blocks: random textures, the object's and the surface's meshes, poses.

Textures are random and non-repeating (multi-octave value noise): window correlation needs them.
Every face of a mesh gets explicit texture coordinates in metres, so texel density does not
depend on the object's size.

ROS-free: numpy and OpenCV only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from stereo_fuzzy_perception.simulation.scene_model import SceneObject


@dataclass(frozen=True)
class TextureSettings:
    """Random texture sizes.

    Attributes:
        surface_half_extent_m: Half side of the square work surface, centred under the workspace.
        surface_texture_px: Side of the surface texture [px]; it covers the whole surface.
        object_texture_span_m: Span of the object texture [m] (texture coordinates in metres).
        object_texture_px: Side of the object texture [px].
        finest_feature_m: Cell size of the finest noise octave [m].
        coarsest_feature_m: Cell size of the coarsest noise octave [m].
    """

    surface_half_extent_m: float = 0.6
    surface_texture_px: int = 1024
    object_texture_span_m: float = 0.25
    object_texture_px: int = 512
    finest_feature_m: float = 0.0024
    coarsest_feature_m: float = 0.05


def random_texture(seed: int, size_px: int, span_m: float, settings: TextureSettings,
                   tint: tuple[float, float, float]) -> np.ndarray:
    """Return a non-repeating RGB uint8 texture of multi-octave value noise.

    Args:
        seed: Seed of the noise.
        size_px: Side of the square texture [px].
        span_m: What the texture covers [m] (sets the octaves' cell sizes in pixels).
        settings: Finest and coarsest feature sizes.
        tint: Mean colour (r, g, b) in [0, 1].
    """
    rng = np.random.default_rng(seed)
    texel_m = span_m / size_px
    cell_px = max(2.0, settings.finest_feature_m / texel_m)
    noise = np.zeros((size_px, size_px), dtype=np.float32)
    while cell_px <= max(2.0, settings.coarsest_feature_m / texel_m):
        cells = int(math.ceil(size_px / cell_px)) + 3
        grid = rng.random((cells, cells), dtype=np.float32)
        grown = cv2.resize(grid, None, fx=cell_px, fy=cell_px, interpolation=cv2.INTER_CUBIC)
        offset = int(cell_px)
        noise += grown[offset:offset + size_px, offset:offset + size_px]
        cell_px *= 2.0
    low, high = np.percentile(noise, (1.0, 99.0))
    shade = np.clip((noise - low) / max(high - low, 1e-6), 0.0, 1.0)
    hue = rng.random((3,), dtype=np.float32) * 0.2 - 0.1
    channels = [np.clip((0.25 + 0.75 * shade) * (tint[k] + hue[k]), 0.0, 1.0) for k in range(3)]
    return np.round(np.stack(channels, axis=2) * 255.0).astype(np.uint8)


def _ring(scene_object: SceneObject, segments: int) -> tuple[np.ndarray, np.ndarray]:
    """Return the object's outline (counter-clockwise from above) and the outward normals."""
    hx, hy = 0.5 * scene_object.size_x_m, 0.5 * scene_object.size_y_m
    if scene_object.object_type.is_round:
        angles = np.linspace(0.0, 2.0 * math.pi, segments, endpoint=False)
        ring = np.stack([hx * np.cos(angles), hy * np.sin(angles)], axis=1)
        return ring, np.stack([np.cos(angles), np.sin(angles)], axis=1)
    ring = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
    return ring, np.zeros_like(ring)


def object_mesh(scene_object: SceneObject, span_m: float, segments: int = 96
                ) -> dict[str, Any]:
    """Return pybullet GEOM_MESH arguments for the object (top and sides, in its own frame).

    Texture coordinates are in metres divided by `span_m`, so a texture spans `span_m`.
    """
    ring, radial = _ring(scene_object, segments)
    height = scene_object.height_m
    vertices: list[list[float]] = []
    normals: list[list[float]] = []
    uvs: list[list[float]] = []
    indices: list[int] = []
    # Top: a fan around the centre, counter-clockwise seen from above.
    vertices.append([0.0, 0.0, height])
    for x, y in ring:
        vertices.append([float(x), float(y), height])
    normals.extend([[0.0, 0.0, 1.0]] * (len(ring) + 1))
    uvs.extend([[v[0] / span_m + 0.5, v[1] / span_m + 0.5] for v in vertices])
    for k in range(len(ring)):
        indices.extend([0, 1 + k, 1 + (k + 1) % len(ring)])
    # Sides: one quad per edge, counter-clockwise seen from outside.
    travelled = 0.0
    round_object = scene_object.object_type.is_round
    for k in range(len(ring)):
        a, b = ring[k], ring[(k + 1) % len(ring)]
        edge = b - a
        length = float(np.hypot(*edge))
        if round_object:
            na, nb = radial[k], radial[(k + 1) % len(ring)]
        else:
            na = nb = np.array([edge[1], -edge[0]]) / length
        first = len(vertices)
        for point, normal, z, s in ((a, na, 0.0, travelled), (b, nb, 0.0, travelled + length),
                                    (b, nb, height, travelled + length),
                                    (a, na, height, travelled)):
            vertices.append([float(point[0]), float(point[1]), z])
            normals.append([float(normal[0]), float(normal[1]), 0.0])
            uvs.append([(s / span_m) % 1.0 if not round_object else s / span_m, z / span_m])
        indices.extend([first, first + 1, first + 2, first, first + 2, first + 3])
        travelled += length
    # Keep side coordinates inside the texture (a round side is one strip around the object).
    side_uvs = np.array(uvs[len(ring) + 1:])
    if round_object and side_uvs[:, 0].max() > 1.0:
        side_uvs[:, 0] /= side_uvs[:, 0].max()
    uvs[len(ring) + 1:] = side_uvs.tolist()
    return {'vertices': vertices, 'indices': indices, 'uvs': uvs, 'normals': normals}


def surface_mesh(half_extent_m: float) -> dict[str, Any]:
    """Return pybullet GEOM_MESH arguments for the square work surface of `half_extent_m` [m]."""
    h = half_extent_m
    return {'vertices': [[-h, -h, 0.0], [h, -h, 0.0], [h, h, 0.0], [-h, h, 0.0]],
            'indices': [0, 1, 2, 0, 2, 3],
            'uvs': [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]],
            'normals': [[0.0, 0.0, 1.0]] * 4}


def yaw_quaternion(yaw_rad: float) -> tuple[float, float, float, float]:
    """Return the (x, y, z, w) quaternion of a rotation about z by `yaw_rad` [rad]."""
    return (0.0, 0.0, math.sin(yaw_rad / 2.0), math.cos(yaw_rad / 2.0))
