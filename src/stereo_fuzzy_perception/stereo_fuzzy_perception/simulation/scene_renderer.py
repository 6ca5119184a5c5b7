"""Render stereo pairs of a scene on the CPU with pybullet's TinyRenderer (headless, DIRECT).

What comes out is what two real cameras and a stereo calibration would give: a left and a right
image, the calibration (K, D, R, P of each camera from cv2.stereoRectify with the rig's R, T, as
a stereo calibration publishes it), and the ground truth (the centre of the object's top face).

The pieces live in their own modules and are importable from here too: render_camera (camera
conventions, calibration, distortion maps), sensor_effects (lighting, noise, gain and offset,
encodings) and scene_meshes (textures and meshes). The ideal image is rendered with a margin so
that barrel distortion pulls in real scene content, not a black border.

ROS-free: numpy, OpenCV and pybullet only.
"""

from __future__ import annotations

import math
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pybullet

from stereo_fuzzy_perception.core.camera_model import StereoCalibration
from stereo_fuzzy_perception.core.frame_transforms import quaternion_from_matrix
from stereo_fuzzy_perception.core.rig_geometry import StereoRig
from stereo_fuzzy_perception.simulation.render_camera import (
    LEFT_FRAME_ID,
    RIGHT_FRAME_ID,
    distortion_maps,
    stereo_calibration,
    view_matrix,
)
from stereo_fuzzy_perception.simulation.scene_meshes import (
    TextureSettings,
    object_mesh,
    random_texture,
    surface_mesh,
    yaw_quaternion,
)
from stereo_fuzzy_perception.simulation.scene_model import (
    GroundTruth,
    ObjectType,
    Scene,
    SimulatedCamera,
    random_scene,
)
from stereo_fuzzy_perception.simulation.sensor_effects import (
    Lighting,
    SensorModel,
    apply_sensor,
    to_encoding,
)
from stereo_fuzzy_perception.simulation.texture_families import NoiseScales, family_texture

RENDER_ENCODINGS = ('rgb8', 'bgr8', 'mono8')


class RenderError(ValueError):
    """Rendering settings that cannot work, with the reason in the message."""


@dataclass(frozen=True)
class StereoFrame:
    """One rendered stereo pair with its calibration and ground truth.

    Attributes:
        left: Left raw image (HxW for mono8, HxWx3 for rgb8/bgr8), uint8.
        right: Right raw image, same layout.
        encoding: sensor_msgs encoding of both images.
        calibration: K, D, R, P of both cameras as a stereo calibration publishes them.
        ground_truth: Target (top-face centre) and object.
        scene: The scene rendered.
        left_mask: Pixels showing the object in the left image (when asked for), else None.
        right_mask: The same for the right image.
        left_depth: Depth along the left optical axis [m] per pixel, infinite where the pixel
            sees nothing (when asked for), else None.
        right_depth: The same for the right image.
    """

    left: np.ndarray
    right: np.ndarray
    encoding: str
    calibration: StereoCalibration
    ground_truth: GroundTruth
    scene: Scene
    left_mask: np.ndarray | None = field(default=None, repr=False)
    right_mask: np.ndarray | None = field(default=None, repr=False)
    left_depth: np.ndarray | None = field(default=None, repr=False)
    right_depth: np.ndarray | None = field(default=None, repr=False)


class SceneRenderer:
    """Renders scenes seen by a stereo rig; owns one pybullet DIRECT connection.

    Use as a context manager, or call close(). Rendering is deterministic: the same scene and
    settings give identical images.
    """

    def __init__(self, camera: SimulatedCamera | None = None, rig: StereoRig | None = None,
                 sensor: SensorModel | None = None, encoding: str = 'rgb8',
                 lighting: Lighting | None = None, textures: TextureSettings | None = None,
                 rectify_alpha: float = -1.0) -> None:
        """Connect to pybullet and fix the rig, cameras and sensors.

        Raises:
            RenderError: For an encoding other than rgb8, bgr8 or mono8.
        """
        if encoding not in RENDER_ENCODINGS:
            raise RenderError(f'cannot render encoding {encoding!r}; expected one of '
                              + ', '.join(RENDER_ENCODINGS))
        self.camera = camera or SimulatedCamera()
        self.rig = rig or StereoRig()
        self.sensor = sensor or SensorModel()
        self.encoding = encoding
        self.lighting = lighting or Lighting()
        self.textures = textures or TextureSettings()
        self.calibration = stereo_calibration(self.camera, self.rig, self.sensor.distortion,
                                              rectify_alpha)
        self._client = pybullet.connect(pybullet.DIRECT)
        self._texture_dir = tempfile.TemporaryDirectory(prefix='scene_textures_')
        self._margin_px = 0
        self._maps: tuple[np.ndarray, np.ndarray] | None = None
        if self.sensor.distorted:
            map_x, map_y = distortion_maps(self.camera, self.sensor.distortion)
            overflow = max(-map_x.min(), -map_y.min(), map_x.max() - (self.camera.width - 1),
                           map_y.max() - (self.camera.height - 1), 0.0)
            self._margin_px = int(math.ceil(overflow)) + 2
            self._maps = (map_x + self._margin_px, map_y + self._margin_px)

    def __enter__(self) -> SceneRenderer:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def close(self) -> None:
        """Disconnect from pybullet and delete the texture files."""
        if self._client >= 0:
            pybullet.disconnect(self._client)
            self._client = -1
            self._texture_dir.cleanup()

    # --- scene building ------------------------------------------------------------------

    def _load_texture(self, name: str, image: np.ndarray) -> int:
        path = Path(self._texture_dir.name) / f'{name}.bmp'
        cv2.imwrite(str(path), cv2.cvtColor(image, cv2.COLOR_RGB2BGR))
        texture: int = pybullet.loadTexture(str(path), physicsClientId=self._client)
        return texture

    def _add_mesh(self, mesh: dict[str, Any], position: tuple[float, float, float],
                  orientation: tuple[float, float, float, float], texture: int) -> int:
        shape = pybullet.createVisualShape(pybullet.GEOM_MESH, physicsClientId=self._client,
                                           **mesh)
        body: int = pybullet.createMultiBody(baseMass=0.0, baseVisualShapeIndex=shape,
                                             basePosition=position, baseOrientation=orientation,
                                             physicsClientId=self._client)
        pybullet.changeVisualShape(body, -1, textureUniqueId=texture, rgbaColor=[1, 1, 1, 1],
                                   physicsClientId=self._client)
        return body

    def _fresh_world(self) -> None:
        """Start from an empty world on a new connection.

        pybullet caches textures by file path for the life of a connection (resetSimulation
        keeps them): reloading 'surface.bmp' with new pixels returned the first scene's
        texture, so a scene looked different depending on what was rendered before it, and
        unique file names instead leak memory with every scene. A new DIRECT connection is
        cheap and frees everything.
        """
        pybullet.disconnect(self._client)
        self._client = pybullet.connect(pybullet.DIRECT)

    def _texture(self, family: str, seed: int, size_px: int, span_m: float,
                 tint: tuple[float, float, float]) -> np.ndarray:
        settings = self.textures
        if family == 'value_noise':
            return random_texture(seed, size_px, span_m, settings, tint=tint)
        return family_texture(family, seed, size_px, span_m, tint, NoiseScales(
            settings.finest_feature_m, settings.coarsest_feature_m))

    def _build(self, scene: Scene) -> int:
        """Reset the world and add the surface and the object; return the object's body id."""
        self._fresh_world()
        settings = self.textures
        surface_span = 2.0 * settings.surface_half_extent_m
        surface_texture = self._load_texture('surface', self._texture(
            scene.surface_texture_family, scene.surface_texture_seed,
            settings.surface_texture_px, surface_span, scene.surface_tint))
        self._add_mesh(surface_mesh(settings.surface_half_extent_m), (0.2, 0.15, 0.0),
                       (0.0, 0.0, 0.0, 1.0), surface_texture)
        scene_object = scene.scene_object
        object_texture = self._load_texture('object', self._texture(
            scene.object_texture_family, scene.object_texture_seed, settings.object_texture_px,
            settings.object_texture_span_m, scene.object_tint))
        return self._add_mesh(object_mesh(scene_object, settings.object_texture_span_m),
                              (scene_object.x_m, scene_object.y_m, 0.0),
                              yaw_quaternion(scene_object.yaw_rad), object_texture)

    # --- rendering -----------------------------------------------------------------------

    def _render_view(self, world_from_camera: np.ndarray, segmentation: bool,
                     lighting: Lighting | None = None
                     ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
        """Render the RGB image of one camera, distorted; with body ids and depth per pixel."""
        camera = self.camera
        margin = self._margin_px
        width, height = camera.width + 2 * margin, camera.height + 2 * margin
        fov_deg = math.degrees(2.0 * math.atan((height / 2.0) / camera.focal_px))
        projection = pybullet.computeProjectionMatrixFOV(
            fov_deg, width / height, camera.near_m, camera.far_m)
        light = lighting or self.lighting
        flags = 0 if segmentation else pybullet.ER_NO_SEGMENTATION_MASK
        _, _, rgba, buffer, seg = pybullet.getCameraImage(
            width, height, view_matrix(world_from_camera), projection,
            lightDirection=list(light.direction), lightAmbientCoeff=light.ambient,
            lightDiffuseCoeff=light.diffuse, lightSpecularCoeff=light.specular, shadow=0,
            renderer=pybullet.ER_TINY_RENDERER, flags=flags, physicsClientId=self._client)
        rgb: np.ndarray = np.reshape(np.asarray(rgba, dtype=np.uint8),
                                     (height, width, 4))[:, :, :3]
        ids: np.ndarray | None = None
        depth: np.ndarray | None = None
        if segmentation:
            ids = np.reshape(np.asarray(seg), (height, width))
            near, far = camera.near_m, camera.far_m
            depth = far * near / (far - (far - near) * np.reshape(
                np.asarray(buffer, dtype=np.float64), (height, width)))
            depth[ids < 0] = np.inf  # the ray met nothing (a view past the table's edge)
        if self._maps is not None:
            rgb = cv2.remap(rgb, *self._maps, interpolation=cv2.INTER_LINEAR,
                            borderMode=cv2.BORDER_REPLICATE)
            if ids is not None and depth is not None:
                ids = cv2.remap(ids.astype(np.float32), *self._maps,
                                interpolation=cv2.INTER_NEAREST).astype(np.int32)
                depth = cv2.remap(depth, *self._maps, interpolation=cv2.INTER_NEAREST)
        return np.ascontiguousarray(rgb), ids, depth

    def render(self, scene: Scene, with_maps: bool = False, lighting: Lighting | None = None,
               sensor: SensorModel | None = None, oversampling: int = 1) -> StereoFrame:
        """Render `scene` with both cameras.

        Args:
            scene: The scene to render.
            with_maps: Also return the object's pixel masks and the depth maps (slower).
            lighting: This scene's light (the renderer's when None).
            sensor: This scene's noise, gain and offset (the renderer's when None); its
                distortion must be the renderer's (the maps are built once).
            oversampling: Odd factor: each pixel of the images is the mean of
                oversampling^2 rendered ones, as a camera's sensor integrates light over its
                pixel. 1 renders as TinyRenderer does, without antialiasing: every texture
                edge falls on whole pixels, in each camera independently. The masks and
                depth maps are rendered at the image's own resolution either way.

        Returns:
            Images, calibration and ground truth of the scene.

        Raises:
            RenderError: For a sensor whose distortion differs from the renderer's, or an
                even or non-positive `oversampling`.
        """
        if sensor is not None and sensor.distortion != self.sensor.distortion:
            raise RenderError(f'a scene sensor cannot change the distortion '
                              f'{self.sensor.distortion} the renderer was built with')
        _check_oversampling(oversampling)
        sensor = sensor or self.sensor
        body = self._build(scene)
        rng = np.random.default_rng([scene.seed, 0x5E45])
        views = []
        for pose in (self.rig.world_from_left_camera(), self.rig.world_from_right_camera()):
            ids = depth = None
            if with_maps or oversampling == 1:
                rgb, ids, depth = self._render_view(pose, with_maps, lighting)
            if oversampling > 1:
                rgb = self._render_oversampled(pose, oversampling, lighting)
            views.append((rgb, ids, depth))
        (left_rgb, left_ids, left_depth), (right_rgb, right_ids, right_depth) = views
        left = apply_sensor(to_encoding(left_rgb, self.encoding), rng, 1.0, 0.0, sensor.noise_std)
        right = apply_sensor(to_encoding(right_rgb, self.encoding), rng, sensor.right_gain,
                             sensor.right_offset, sensor.noise_std)
        return StereoFrame(
            left=left, right=right, encoding=self.encoding, calibration=self.calibration,
            ground_truth=GroundTruth.of(scene), scene=scene,
            left_mask=None if left_ids is None else left_ids == body,
            right_mask=None if right_ids is None else right_ids == body,
            left_depth=left_depth, right_depth=right_depth)

    def render_markers(self, points_world: np.ndarray, radius_m: float = 0.002
                       ) -> tuple[list[np.ndarray], list[np.ndarray]]:
        """Render small spheres at `points_world` alone and return each one's pixel masks.

        Returns:
            (left_masks, right_masks): one boolean HxW mask per point and camera.
        """
        self._fresh_world()
        shape = pybullet.createVisualShape(pybullet.GEOM_SPHERE, radius=radius_m,
                                           physicsClientId=self._client)
        bodies = [pybullet.createMultiBody(baseMass=0.0, baseVisualShapeIndex=shape,
                                           basePosition=[float(c) for c in point],
                                           physicsClientId=self._client)
                  for point in np.atleast_2d(points_world)]
        masks = []
        for pose in (self.rig.world_from_left_camera(), self.rig.world_from_right_camera()):
            _, ids, _ = self._render_view(pose, segmentation=True)
            assert ids is not None
            masks.append([ids == body for body in bodies])
        return masks[0], masks[1]

    def render_plane(self, texture: np.ndarray, world_from_plane: np.ndarray,
                     extent_m: tuple[float, float, float, float], seed: int = 0,
                     oversampling: int = 3) -> tuple[np.ndarray, np.ndarray]:
        """Render a flat textured rectangle alone (e.g. a calibration board) with both cameras.

        Args:
            texture: RGB uint8 image; its top-left pixel lies at (x_min, y_min) of the
                rectangle, its rows along the rectangle's y axis.
            world_from_plane: 4x4 pose of the rectangle's frame (rectangle in its z = 0 plane).
            extent_m: (x_min, y_min, x_max, y_max) of the rectangle in its frame [m].
            seed: Seed of the sensor noise.
            oversampling: Odd factor: each pixel is the mean of oversampling^2 rendered ones,
                as a sensor integrates light over its pixel (TinyRenderer does not
                antialias, which puts edges on whole pixels); 1 renders as render() does.

        Returns:
            (left, right) images in the renderer's encoding, with its lenses and sensors.

        Raises:
            RenderError: For an even or non-positive `oversampling`.
        """
        _check_oversampling(oversampling)
        self._fresh_world()
        x0, y0, x1, y1 = extent_m
        # pybullet samples textures with v = 0 at the image's last row.
        mesh = {'vertices': [[x0, y0, 0.0], [x1, y0, 0.0], [x1, y1, 0.0], [x0, y1, 0.0]],
                'indices': [0, 1, 2, 0, 2, 3],
                'uvs': [[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]],
                'normals': [[0.0, 0.0, 1.0]] * 4}
        pose = np.asarray(world_from_plane, dtype=float)
        position = (float(pose[0, 3]), float(pose[1, 3]), float(pose[2, 3]))
        self._add_mesh(mesh, position, quaternion_from_matrix(pose[:3, :3]),
                       self._load_texture('plane', texture))
        rng = np.random.default_rng([seed, 0x9A7E])
        left_rgb = self._render_oversampled(self.rig.world_from_left_camera(), oversampling)
        right_rgb = self._render_oversampled(self.rig.world_from_right_camera(), oversampling)
        sensor = self.sensor
        left = apply_sensor(to_encoding(left_rgb, self.encoding), rng, 1.0, 0.0, sensor.noise_std)
        right = apply_sensor(to_encoding(right_rgb, self.encoding), rng, sensor.right_gain,
                             sensor.right_offset, sensor.noise_std)
        return left, right

    def _render_oversampled(self, world_from_camera: np.ndarray, factor: int,
                            lighting: Lighting | None = None) -> np.ndarray:
        """Render one camera's RGB image at `factor` x the resolution and average it down.

        Rendered pixel (u_k, v_k) sees the ray of image point (u_k / k, (v_k + 1) / k - 1) of
        this renderer's camera (principal point W / 2, H / 2 - 1 at both resolutions), so image
        pixel (u, v) averages the k x k block centred on (k u, k v + k - 1).
        """
        if factor == 1:
            return self._render_view(world_from_camera, False, lighting)[0]
        camera, margin, maps = self.camera, self._margin_px, self._maps
        width, height = camera.width + 2 * margin, camera.height + 2 * margin
        fov_deg = math.degrees(2.0 * math.atan((height / 2.0) / camera.focal_px))
        try:
            self.camera = SimulatedCamera(width=factor * width, height=factor * height,
                                          vertical_fov_deg=fov_deg, near_m=camera.near_m,
                                          far_m=camera.far_m)
            self._margin_px, self._maps = 0, None
            fine = self._render_view(world_from_camera, False, lighting)[0].astype(np.float32)
        finally:
            self.camera, self._margin_px, self._maps = camera, margin, maps
        half = (factor - 1) // 2
        fine = np.pad(fine, ((0, half), (half, 0), (0, 0)), mode='edge')[half:, :factor * width]
        rgb = fine.reshape(height, factor, width, factor, 3).mean(axis=(1, 3))
        ideal: np.ndarray = np.clip(np.round(rgb), 0, 255).astype(np.uint8)
        if maps is None:
            return ideal
        distorted: np.ndarray = cv2.remap(ideal, *maps, interpolation=cv2.INTER_LINEAR,
                                          borderMode=cv2.BORDER_REPLICATE)
        return distorted


def _check_oversampling(oversampling: int) -> None:
    """Raise RenderError unless `oversampling` is an odd factor >= 1 (a block has a centre)."""
    if oversampling < 1 or oversampling % 2 == 0:
        raise RenderError(f'oversampling must be an odd factor >= 1, got {oversampling}')


def render_scene(seed: int, object_type: ObjectType | str | None = None,
                 rig: StereoRig | None = None, camera: SimulatedCamera | None = None,
                 sensor: SensorModel | None = None, encoding: str = 'rgb8') -> StereoFrame:
    """Draw the scene of `seed` and render it once (opens and closes a renderer).

    For many scenes, keep one SceneRenderer and call random_scene + render instead.

    Returns:
        frame.left, frame.right, frame.calibration, frame.ground_truth (and the scene).
    """
    camera = camera or SimulatedCamera()
    rig = rig or StereoRig()
    scene = random_scene(seed, object_type, rig=rig, camera=camera)
    with SceneRenderer(camera=camera, rig=rig, sensor=sensor, encoding=encoding) as renderer:
        return renderer.render(scene)


__all__ = [
    'LEFT_FRAME_ID', 'RIGHT_FRAME_ID', 'Lighting', 'RenderError', 'SceneRenderer', 'SensorModel',
    'StereoFrame', 'TextureSettings', 'distortion_maps', 'object_mesh', 'random_texture',
    'render_scene', 'stereo_calibration', 'yaw_quaternion',
]
