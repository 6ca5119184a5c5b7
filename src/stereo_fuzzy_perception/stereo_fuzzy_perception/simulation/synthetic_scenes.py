"""Geometric stereo scenes: matched points of a known object, without rendering. ROS-free.

The training, evaluation and unit tests of the fuzzy best-point stage need many scenes with a
known answer. This module makes them from geometry alone: one of the chapter's four object types
(circle = flat disc, cylinder, cubic rectangle = box, cubic square = cube) stands on the work
surface; points are sampled on the surfaces that BOTH cameras of the rig see (convex objects, so
back-face culling is exact) and on the work surface around the object (minus what the object hides
from either camera), projected into the rectified stereo pair that cv2.stereoRectify makes for the
rig, disparity noise added, and triangulated back. What comes out is what correlation would hand
the fuzzy stage: MatchedPoints in the left camera's optical frame, with the rectified calibration
and the ground truth (the centre of the object's top face in `world`).

A scene source is anything with `scene(rng) -> SyntheticScene`; `SCENE_SOURCES` names them so the
training scripts can take `--source`: `geometric` (this module) and `rendered` (pybullet images
through the real correlation stage, rendered_scenes.py, imported only when asked for).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Protocol

import cv2
import numpy as np

from stereo_fuzzy_perception.core.camera_model import CameraCalibration
from stereo_fuzzy_perception.core.matched_points import MatchedPoints
from stereo_fuzzy_perception.core.rig_geometry import StereoRig, transform_points

OBJECT_TYPES = ('circle', 'cylinder', 'cubic_rectangle', 'cubic_square')

IMAGE_WIDTH = 640
IMAGE_HEIGHT = 480
VERTICAL_FOV_DEG = 45.0


def default_camera_matrix(width: int = IMAGE_WIDTH, height: int = IMAGE_HEIGHT,
                          vertical_fov_deg: float = VERTICAL_FOV_DEG) -> np.ndarray:
    """Return the project's default pinhole K (square pixels, cx = w/2, cy = h/2 - 1) [px]."""
    focal = 0.5 * height / math.tan(math.radians(0.5 * vertical_fov_deg))
    return np.array([[focal, 0.0, width / 2.0], [0.0, focal, height / 2.0 - 1.0],
                     [0.0, 0.0, 1.0]])


def rectified_calibration(rig: StereoRig, K: np.ndarray | None = None,
                          width: int = IMAGE_WIDTH, height: int = IMAGE_HEIGHT,
                          frame_id: str = 'left_camera_optical_frame',
                          distortion: np.ndarray | None = None,
                          ) -> tuple[CameraCalibration, CameraCalibration]:
    """Return the (left, right) rectified calibration of `rig` as cv2.stereoRectify makes it.

    Args:
        rig: The stereo rig; its relative pose gives R, T.
        K: Intrinsics of both cameras [px]; the default camera when None.
        width: Image width [px].
        height: Image height [px].
        frame_id: Optical frame name recorded in the left calibration.
        distortion: Plumb-bob coefficients of both cameras (k1, k2, p1, p2, k3); none when
            None.

    Returns:
        Left and right CameraCalibration with R, P from cv2.stereoRectify (zero disparity at
        infinity, so both rectified principal points coincide).
    """
    K = default_camera_matrix(width, height) if K is None else np.asarray(K, dtype=float)
    D = np.zeros(5) if distortion is None else np.asarray(distortion, dtype=float)
    R, T = rig.right_from_left()
    T = T.reshape(3, 1)
    R1, R2, P1, P2, _, _, _ = cv2.stereoRectify(K, D, K, D, (width, height), R, T,
                                                flags=cv2.CALIB_ZERO_DISPARITY, alpha=0)
    left = CameraCalibration(width, height, K, D, R1, P1, frame_id=frame_id)
    right = CameraCalibration(width, height, K.copy(), D.copy(), R2, P2,
                              frame_id=frame_id.replace('left', 'right'))
    return left, right


@dataclass(frozen=True)
class ConvexPrism:
    """A convex polygon in the xy plane extruded from z = 0 to z = height, in `world`.

    Attributes:
        polygon: (K, 2) vertices counter-clockwise seen from above [m], world x, y.
        height: Height of the top face above the work surface [m].
    """

    polygon: np.ndarray
    height: float

    def planes(self) -> tuple[np.ndarray, np.ndarray]:
        """Return outward unit normals (F, 3) and offsets (F,): inside is n . x <= offset."""
        start = self.polygon
        end = np.roll(self.polygon, -1, axis=0)
        edge = end - start
        normals = np.stack([edge[:, 1], -edge[:, 0], np.zeros(len(edge))], axis=1)
        normals /= np.linalg.norm(normals, axis=1, keepdims=True)
        offsets = np.einsum('ij,ij->i', normals[:, :2], start)
        normals = np.vstack([normals, [0.0, 0.0, 1.0], [0.0, 0.0, -1.0]])
        offsets = np.concatenate([offsets, [self.height, 0.0]])
        return normals, offsets

    def top_centre(self) -> np.ndarray:
        """Return the centroid of the top face [m] (area centroid of the polygon)."""
        x, y = self.polygon[:, 0], self.polygon[:, 1]
        x1, y1 = np.roll(x, -1), np.roll(y, -1)
        cross = x * y1 - x1 * y
        area = 0.5 * cross.sum()
        cx = ((x + x1) * cross).sum() / (6.0 * area)
        cy = ((y + y1) * cross).sum() / (6.0 * area)
        return np.array([cx, cy, self.height])

    def contains_xy(self, xy: np.ndarray) -> np.ndarray:
        """Return which (N, 2) points lie inside the polygon (a boolean (N,))."""
        normals, offsets = self.planes()
        inside: np.ndarray = np.all(xy @ normals[:-2, :2].T <= offsets[:-2] + 1e-12, axis=1)
        return inside

    def segment_hits(self, points: np.ndarray, target: np.ndarray) -> np.ndarray:
        """Return which segments points[i] -> target pass through the prism (Cyrus-Beck)."""
        normals, offsets = self.planes()
        direction = target - points
        numerator = offsets[None, :] - points @ normals.T
        denominator = direction @ normals.T
        with np.errstate(divide='ignore', invalid='ignore'):
            t = numerator / denominator
        entering = denominator < 0.0
        leaving = denominator > 0.0
        t_enter = np.max(np.where(entering, t, 0.0), axis=1, initial=0.0)
        t_exit = np.min(np.where(leaving, t, 1.0), axis=1, initial=1.0)
        parallel_outside = np.any((denominator == 0.0) & (numerator < 0.0), axis=1)
        hits: np.ndarray = (t_enter < t_exit - 1e-9) & ~parallel_outside
        return hits


def make_object(object_type: str, rng: np.random.Generator, centre_xy: np.ndarray,
                yaw: float) -> ConvexPrism:
    """Return one of the chapter's object types with random size at `centre_xy`, turned by yaw.

    Sizes: 2-8 cm across; cylinders and boxes 0.5-8 cm high; the disc ~5 mm thick (4-6 mm);
    a cube as high as it is wide.

    Raises:
        ValueError: For an unknown object type.
    """
    if object_type in ('circle', 'cylinder'):
        radius = 0.5 * rng.uniform(0.02, 0.08)
        height = rng.uniform(0.004, 0.006) if object_type == 'circle' else rng.uniform(
            0.005, 0.08)
        angles = np.linspace(0.0, 2.0 * math.pi, 64, endpoint=False)
        corners = radius * np.stack([np.cos(angles), np.sin(angles)], axis=1)
    elif object_type in ('cubic_rectangle', 'cubic_square'):
        if object_type == 'cubic_square':
            side = rng.uniform(0.02, 0.08)
            length, width, height = side, side, side
        else:
            length, width = rng.uniform(0.02, 0.08, size=2)
            height = rng.uniform(0.005, 0.08)
        corners = 0.5 * np.array([[-length, -width], [length, -width], [length, width],
                                  [-length, width]])
    else:
        raise ValueError(f'object type {object_type!r} is not one of {", ".join(OBJECT_TYPES)}')
    c, s = math.cos(yaw), math.sin(yaw)
    rotation = np.array([[c, -s], [s, c]])
    return ConvexPrism(corners @ rotation.T + centre_xy, float(height))


def project_rectified(world: np.ndarray, world_from_left: np.ndarray, left: CameraCalibration,
                      right: CameraCalibration
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Return u_left, v_left, u_right [px] of world points (N, 3) in the rectified pair, and
    which of them fall in front of the cameras and inside both images."""
    camera = transform_points(np.linalg.inv(world_from_left), world)
    rectified = camera @ left.R.T
    homogeneous = np.column_stack([rectified, np.ones(len(rectified))])
    left_image = homogeneous @ left.P.T
    right_image = homogeneous @ right.P.T
    u_left = left_image[:, 0] / left_image[:, 2]
    v_left = left_image[:, 1] / left_image[:, 2]
    u_right = right_image[:, 0] / right_image[:, 2]
    inside = ((rectified[:, 2] > 0.0) & (u_left >= 0.0) & (u_left <= left.width - 1)
              & (u_right >= 0.0) & (u_right <= right.width - 1)
              & (v_left >= 0.0) & (v_left <= left.height - 1))
    return u_left, v_left, u_right, inside


@dataclass(frozen=True)
class SyntheticScene:
    """One stereo view of one object with its ground truth.

    Attributes:
        points: Matched points (left camera optical frame, rectified image coordinates).
        left: Rectified calibration of the left camera.
        right: Rectified calibration of the right camera.
        target_world: Centre of the object's top face in `world` [m], shape (3,).
        object_type: One of OBJECT_TYPES.
        rig: The rig the scene was seen with.
        object_points: How many of the points lie on the object (the rest on the surface).
        prism: The object's geometry in `world`.
    """

    points: MatchedPoints
    left: CameraCalibration
    right: CameraCalibration
    target_world: np.ndarray
    object_type: str
    rig: StereoRig
    object_points: int
    prism: ConvexPrism


class SceneSource(Protocol):
    """Anything that makes scenes: GeometricSceneSource, RenderedSceneSource."""

    def scene(self, rng: np.random.Generator, object_type: str | None = None
              ) -> SyntheticScene:
        """Return one random scene (of `object_type`, or a random type)."""
        ...


@dataclass
class GeometricSceneSource:
    """Scenes from geometry: visible surfaces sampled, projected, noised, triangulated.

    Attributes:
        rig: Stereo rig; the default StereoRig when not given.
        workspace_min: Lower corner of the workspace box in `world` [m].
        workspace_max: Upper corner of the workspace box in `world` [m].
        point_spacing_m: Mean spacing of samples on a face seen head-on [m].
        disparity_noise_px: (low, high) range of the per-scene disparity noise sigma [px].
        surface_ring_m: How far around the object the work surface is sampled [m]; 0: none.
        score_range: Correlation scores are uniform in this range.
    """

    rig: StereoRig = field(default_factory=StereoRig)
    workspace_min: tuple[float, float, float] = (0.0, 0.0, 0.0)
    workspace_max: tuple[float, float, float] = (0.40, 0.30, 0.20)
    point_spacing_m: float = 0.001
    disparity_noise_px: tuple[float, float] = (0.1, 0.3)
    surface_ring_m: float = 0.03
    score_range: tuple[float, float] = (0.6, 1.0)
    _calibration: tuple[CameraCalibration, CameraCalibration] | None = field(
        default=None, init=False, repr=False)

    def calibration(self) -> tuple[CameraCalibration, CameraCalibration]:
        """Return the rig's rectified (left, right) calibration (computed once)."""
        if self._calibration is None:
            self._calibration = rectified_calibration(self.rig)
        return self._calibration

    def scene(self, rng: np.random.Generator, object_type: str | None = None
              ) -> SyntheticScene:
        """Return one random scene whose whole top face is in both images.

        Raises:
            ValueError: For an unknown object type.
        """
        kind = object_type or str(rng.choice(OBJECT_TYPES))
        for _ in range(100):
            margin = 0.045
            centre = np.array([
                rng.uniform(self.workspace_min[0] + margin, self.workspace_max[0] - margin),
                rng.uniform(self.workspace_min[1] + margin, self.workspace_max[1] - margin)])
            prism = make_object(kind, rng, centre, rng.uniform(0.0, math.pi))
            noise = rng.uniform(*self.disparity_noise_px)
            scene = self.scene_of(prism, kind, rng, noise)
            if scene is not None:
                return scene
        raise RuntimeError('could not place an object fully in view in 100 tries')

    def scene_of(self, prism: ConvexPrism, object_type: str, rng: np.random.Generator,
                 disparity_noise_px: float) -> SyntheticScene | None:
        """Return the scene of one given object, or None when its top face leaves an image."""
        left_cal, right_cal = self.calibration()
        world_from_left = self.rig.world_from_left_camera()
        cameras = (world_from_left[:3, 3], self.rig.world_from_right_camera()[:3, 3])
        object_world = self._object_samples(prism, rng, cameras)
        surface_world = self._surface_samples(prism, rng, cameras)
        top_corners = np.column_stack([prism.polygon, np.full(len(prism.polygon), prism.height)])
        corners_in = project_rectified(top_corners, world_from_left, left_cal, right_cal)[3]
        if not np.all(corners_in):
            return None
        world = np.vstack([object_world, surface_world])
        is_object = np.arange(len(world)) < len(object_world)
        u_left, v_left, u_right, inside = project_rectified(world, world_from_left, left_cal,
                                                            right_cal)
        u_left, v_left, u_right = u_left[inside], v_left[inside], u_right[inside]
        is_object = is_object[inside]
        u_right = u_right - rng.normal(0.0, disparity_noise_px, size=u_right.shape)
        xyz = self._triangulate(u_left, v_left, u_right, left_cal, right_cal)
        score = rng.uniform(*self.score_range, size=len(xyz))
        points = MatchedPoints(xyz, u_left, v_left, u_right, score)
        return SyntheticScene(points, left_cal, right_cal, prism.top_centre(), object_type,
                              self.rig, int(is_object.sum()), prism)

    def _sample_count(self, area: float, rng: np.random.Generator) -> int:
        return int(rng.poisson(area / self.point_spacing_m ** 2))

    def _keep_foreshortened(self, samples: np.ndarray, normal: np.ndarray,
                            camera: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Thin samples by the cosine of the viewing angle: pixel density, not area density."""
        view = camera - samples
        cosine = (view @ normal) / np.linalg.norm(view, axis=1)
        kept: np.ndarray = samples[rng.uniform(size=len(samples)) < np.clip(cosine, 0.0, 1.0)]
        return kept

    def _object_samples(self, prism: ConvexPrism, rng: np.random.Generator,
                        cameras: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
        normals, offsets = prism.planes()
        parts = []
        left_camera = cameras[0]
        for index, normal in enumerate(normals[:-1]):  # every face but the bottom
            if not all(normal @ camera > offsets[index] for camera in cameras):
                continue  # back face for one of the cameras
            if index == len(normals) - 2:  # top face
                low, high = prism.polygon.min(axis=0), prism.polygon.max(axis=0)
                count = self._sample_count(float(np.prod(high - low)), rng)
                xy = rng.uniform(low, high, size=(count, 2))
                xy = xy[prism.contains_xy(xy)]
                samples = np.column_stack([xy, np.full(len(xy), prism.height)])
            else:
                start = prism.polygon[index]
                end = prism.polygon[(index + 1) % len(prism.polygon)]
                count = self._sample_count(float(np.linalg.norm(end - start)) * prism.height,
                                           rng)
                s = rng.uniform(size=(count, 1))
                xy = start + s * (end - start)
                samples = np.column_stack([xy, rng.uniform(0.0, prism.height, size=count)])
            parts.append(self._keep_foreshortened(samples, normal, left_camera, rng))
        return np.vstack(parts) if parts else np.zeros((0, 3))

    def _surface_samples(self, prism: ConvexPrism, rng: np.random.Generator,
                         cameras: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
        if self.surface_ring_m <= 0.0:
            return np.zeros((0, 3))
        low = prism.polygon.min(axis=0) - self.surface_ring_m
        high = prism.polygon.max(axis=0) + self.surface_ring_m
        count = self._sample_count(float(np.prod(high - low)), rng)
        xy = rng.uniform(low, high, size=(count, 2))
        xy = xy[~prism.contains_xy(xy)]
        samples = np.column_stack([xy, np.zeros(len(xy))])
        for camera in cameras:
            samples = samples[~prism.segment_hits(samples, camera)]
        return self._keep_foreshortened(samples, np.array([0.0, 0.0, 1.0]), cameras[0], rng)

    @staticmethod
    def _triangulate(u_left: np.ndarray, v_left: np.ndarray, u_right: np.ndarray,
                     left: CameraCalibration, right: CameraCalibration) -> np.ndarray:
        """Return points [m] in the left camera optical frame from rectified coordinates."""
        fx, fy = left.P[0, 0], left.P[1, 1]
        cx, cy = left.P[0, 2], left.P[1, 2]
        disparity = u_left - u_right - (cx - right.P[0, 2])
        z = -right.P[0, 3] / disparity
        rectified = np.stack([(u_left - cx) * z / fx, (v_left - cy) * z / fy, z], axis=1)
        camera: np.ndarray = rectified @ left.R  # R maps camera -> rectified; R.T maps back
        return camera

    def scenes(self, count: int, seed: int, object_type: str | None = None
               ) -> Iterator[SyntheticScene]:
        """Yield `count` scenes from one seed (the same seed gives the same scenes)."""
        rng = np.random.default_rng(seed)
        for _ in range(count):
            yield self.scene(rng, object_type)


def rendered_scene_source() -> SceneSource:
    """Return a RenderedSceneSource (imports pybullet and the correlation stage on first use)."""
    from stereo_fuzzy_perception.simulation.rendered_scenes import RenderedSceneSource
    return RenderedSceneSource()


SCENE_SOURCES: dict[str, Callable[[], SceneSource]] = {
    'geometric': GeometricSceneSource,
    'rendered': rendered_scene_source,
}
"""Scene sources by name, for `--source` of the training and benchmark scripts."""
