"""A randomized distribution of rigs, scenes, textures, lights and sensors, split for honest tests.

The simulator's first scenes all came from one rig, one texture family, one light and ideal
sensors, and the selectors were fitted and graded on them. Scenes rendered by someone else with
another rig told a different story. This module draws everything that differs between set-ups:

* Rigs (a seeded *rig pool*): height of the cameras' midpoint 0.30-0.80 m, baseline 40-120 mm,
  tilt (alpha) 0-50 deg, pan (theta) -45..45 deg, toe-in 0-4 deg per camera, vertical field of
  view 40-70 deg; the rig looks at a random point of the workspace's middle.
* Scenes: one of the four object types, 15-80 mm across, 15-80 mm high (discs 5 mm), placed in
  the workspace in view of both cameras; surface and object textures from seven procedural
  families (texture_families.py) with random colours; light direction (elevation 25-90 deg,
  any azimuth), ambient 0.30-0.70 and diffuse 0.15-0.60; Gaussian noise 0-4 grey levels per
  camera, right camera gain 0.7-1.3 and offset -30..+30 grey levels.
* One rule keeps the scenes solvable by a camera at all: the object's top must be at least
  `min_top_px` (24 px) wide in the left image (scenes rendered by others had 30-60 px). Draws
  that miss it are redrawn with the next attempt seed, so small objects appear with near rigs.

Splits (leave-rig-out): the rig pool is cut in two. `train` and `validation` scenes use the
training rigs, with different scene seed ranges; `evaluation` scenes use only the held-out rigs,
and a third seed range. Nothing fitted or tuned may look at `evaluation`.

Correlation settings follow from the rig alone: correlation_node's default derives the
disparity search from the rig pose, the calibration and the workspace box
(core/matching/disparity_range.py), and the benchmark does the same.

ROS-free: numpy, OpenCV (through the renderer's calibration) only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from stereo_fuzzy_perception.core.rig_geometry import StereoRig
from stereo_fuzzy_perception.simulation.scene_model import (
    OBJECT_TYPES,
    WORKSPACE,
    ObjectType,
    Scene,
    SceneError,
    SimulatedCamera,
    SizeRange,
    Workspace,
    random_scene,
)
from stereo_fuzzy_perception.simulation.scene_renderer import Lighting, SensorModel
from stereo_fuzzy_perception.simulation.texture_families import TEXTURE_FAMILIES

SPLITS = ('train', 'validation', 'evaluation')
SCENE_SEED_BASE = {'train': 1_000_000, 'validation': 2_000_000, 'evaluation': 3_000_000}
"""First scene seed of each split; a split's scene k of type t has seed base + 4 k + t."""


class DistributionError(ValueError):
    """A split, rig index or setting the distribution does not have."""


@dataclass(frozen=True)
class DistributionSettings:
    """Ranges of everything the distribution draws (uniform unless said otherwise).

    Attributes:
        rig_height_m: Height of the midpoint between the optical centres [m].
        baseline_m: Distance between the optical centres [m].
        tilt_deg: The chapter's alpha [deg]: 0 looks straight down.
        pan_deg: The chapter's theta [deg].
        toe_in_deg: Toe-in of each camera [deg] (the rig's vergence is twice it).
        vertical_fov_deg: Vertical field of view of both cameras [deg].
        aim_margin_m: The rig looks at a point at least this far inside the workspace [m].
        image_width: Image width [px] (fixed for every rig: it sets the render cost).
        image_height: Image height [px].
        object_across_m: Object size across (diameter, long side) [m].
        object_height_m: Height of cylinders and boxes [m] (discs: 5 mm).
        min_top_px: Smallest width of the object's top in the left image [px].
        noise_std: Gaussian noise per camera [grey levels].
        right_gain: Right camera gain relative to the left [-].
        right_offset: Right camera offset [grey levels].
        light_elevation_deg: Elevation of the light direction above the table [deg].
        light_ambient: TinyRenderer ambient coefficient [-].
        light_diffuse: TinyRenderer diffuse coefficient [-].
        rig_pool_seed: Seed of the rig pool.
        rig_pool_size: Rigs in the pool.
        held_out_rigs: The last this many rigs of the pool are only used for evaluation.
        max_attempts: Redraws of a scene before giving up.
    """

    rig_height_m: tuple[float, float] = (0.30, 0.80)
    baseline_m: tuple[float, float] = (0.04, 0.12)
    tilt_deg: tuple[float, float] = (0.0, 50.0)
    pan_deg: tuple[float, float] = (-45.0, 45.0)
    toe_in_deg: tuple[float, float] = (0.0, 4.0)
    vertical_fov_deg: tuple[float, float] = (40.0, 70.0)
    aim_margin_m: float = 0.08
    image_width: int = 640
    image_height: int = 480
    object_across_m: tuple[float, float] = (0.015, 0.08)
    object_height_m: tuple[float, float] = (0.015, 0.08)
    min_top_px: float = 24.0
    noise_std: tuple[float, float] = (0.0, 4.0)
    right_gain: tuple[float, float] = (0.7, 1.3)
    right_offset: tuple[float, float] = (-30.0, 30.0)
    light_elevation_deg: tuple[float, float] = (25.0, 90.0)
    light_ambient: tuple[float, float] = (0.30, 0.70)
    light_diffuse: tuple[float, float] = (0.15, 0.60)
    rig_pool_seed: int = 14
    rig_pool_size: int = 40
    held_out_rigs: int = 10
    max_attempts: int = 200

    def sizes(self) -> SizeRange:
        """Return the object size limits as scene_model draws them."""
        return SizeRange(across_min_m=self.object_across_m[0],
                         across_max_m=self.object_across_m[1],
                         height_min_m=self.object_height_m[0],
                         height_max_m=self.object_height_m[1])


DEFAULT_SETTINGS = DistributionSettings()


@dataclass(frozen=True)
class DistributionRig:
    """One rig of the pool: its pose and its cameras.

    Attributes:
        index: Position in the pool.
        rig: Pose, baseline and toe-in.
        camera: Image size and field of view of both cameras.
    """

    index: int
    rig: StereoRig
    camera: SimulatedCamera

    def describe(self) -> str:
        """Return a one-line description (height, baseline, tilt, pan, toe-in, fov)."""
        rig = self.rig
        return (f'rig {self.index}: z0 {rig.z0_m:.3f} m, baseline {1000 * rig.baseline_m:.0f} mm,'
                f' tilt {rig.alpha_deg:.1f} deg, pan {rig.theta_deg:.1f} deg, toe-in '
                f'{rig.vergence_deg / 2:.2f} deg per camera, fov '
                f'{self.camera.vertical_fov_deg:.1f} deg')


def _uniform(rng: np.random.Generator, limits: tuple[float, float]) -> float:
    return float(rng.uniform(limits[0], limits[1]))


def draw_rig(index: int, settings: DistributionSettings = DEFAULT_SETTINGS) -> DistributionRig:
    """Return rig `index` of the pool (the same index and settings always give the same rig).

    The rig's optical axis (without toe-in) goes through a random aim point on the table at
    least `aim_margin_m` inside the workspace; its midpoint is where that axis reaches the drawn
    height.
    """
    rng = np.random.default_rng([settings.rig_pool_seed, index])
    height = _uniform(rng, settings.rig_height_m)
    shape = StereoRig(baseline_m=_uniform(rng, settings.baseline_m),
                      alpha_deg=_uniform(rng, settings.tilt_deg),
                      theta_deg=_uniform(rng, settings.pan_deg),
                      vergence_deg=2.0 * _uniform(rng, settings.toe_in_deg))
    camera = SimulatedCamera(width=settings.image_width, height=settings.image_height,
                             vertical_fov_deg=_uniform(rng, settings.vertical_fov_deg))
    margin = settings.aim_margin_m
    aim = np.array([float(rng.uniform(WORKSPACE.x_min + margin, WORKSPACE.x_max - margin)),
                    float(rng.uniform(WORKSPACE.y_min + margin, WORKSPACE.y_max - margin)),
                    0.0])
    axis = shape.rig_rotation()[:, 2]
    midpoint = aim - (height / -axis[2]) * axis
    rig = replace(shape, x0_m=round(float(midpoint[0]), 6), y0_m=round(float(midpoint[1]), 6),
                  z0_m=round(height, 6), baseline_m=round(shape.baseline_m, 6),
                  alpha_deg=round(shape.alpha_deg, 4), theta_deg=round(shape.theta_deg, 4),
                  vergence_deg=round(shape.vergence_deg, 4))
    camera = replace(camera, vertical_fov_deg=round(camera.vertical_fov_deg, 4))
    return DistributionRig(index, rig, camera)


def rig_pool(settings: DistributionSettings = DEFAULT_SETTINGS) -> tuple[DistributionRig, ...]:
    """Return every rig of the pool."""
    return tuple(draw_rig(index, settings) for index in range(settings.rig_pool_size))


def split_rigs(split: str, settings: DistributionSettings = DEFAULT_SETTINGS
               ) -> tuple[DistributionRig, ...]:
    """Return the rigs a split uses: training rigs for train/validation, held-out ones else.

    Raises:
        DistributionError: For an unknown split.
    """
    if split not in SPLITS:
        raise DistributionError(f'unknown split {split!r}; expected one of {", ".join(SPLITS)}')
    pool = rig_pool(settings)
    cut = settings.rig_pool_size - settings.held_out_rigs
    return pool[cut:] if split == 'evaluation' else pool[:cut]


@dataclass(frozen=True)
class DistributionScene:
    """One scene of the distribution: rig, scene, light and sensor.

    Attributes:
        split: The split it was drawn for.
        seed: Its scene seed.
        rig: The rig that sees it.
        scene: Object, pose, textures (families, seeds, colours).
        lighting: Light direction and coefficients.
        noise_std: Gaussian noise per camera [grey levels].
        right_gain: Right camera gain [-].
        right_offset: Right camera offset [grey levels].
        attempts: Draws needed to satisfy min_top_px.
        top_width_px: Width of the object's top in the left image [px].
    """

    split: str
    seed: int
    rig: DistributionRig
    scene: Scene
    lighting: Lighting
    noise_std: float
    right_gain: float
    right_offset: float
    attempts: int
    top_width_px: float = field(default=0.0)

    @property
    def object_type(self) -> str:
        """Return the object's type name."""
        return self.scene.scene_object.object_type.value

    def sensor(self) -> SensorModel:
        """Return the scene's sensor model (no lens distortion)."""
        return SensorModel(noise_std=self.noise_std, right_gain=self.right_gain,
                           right_offset=self.right_offset)


def top_width_px(scene: Scene, rig: StereoRig, camera: SimulatedCamera) -> float:
    """Return the width (u extent) of the object's top outline in the left image [px]."""
    scene_object = scene.scene_object
    outline = scene_object.outline_points(48)
    top = outline[len(outline) // 2:]
    uv = camera.project(rig.world_from_left_camera(), top)
    return float(np.nanmax(uv[:, 0]) - np.nanmin(uv[:, 0]))


def _tint(rng: np.random.Generator) -> tuple[float, float, float]:
    base = rng.uniform(0.35, 0.9)
    colour = np.clip(base + rng.uniform(-0.2, 0.2, size=3), 0.15, 1.0)
    return (float(colour[0]), float(colour[1]), float(colour[2]))


def draw_scene(split: str, seed: int, rig: DistributionRig, object_type: ObjectType | str,
               settings: DistributionSettings = DEFAULT_SETTINGS,
               workspace: Workspace = WORKSPACE) -> DistributionScene:
    """Draw the scene of `seed` seen by `rig` (same arguments, same scene).

    Raises:
        SceneError: When no draw puts a wide enough object in view of both cameras.
    """
    rng = np.random.default_rng([seed, 0xD15])
    families = [TEXTURE_FAMILIES[int(k)] for k in rng.integers(len(TEXTURE_FAMILIES), size=2)]
    surface_tint, object_tint = _tint(rng), _tint(rng)
    elevation = math.radians(_uniform(rng, settings.light_elevation_deg))
    azimuth = float(rng.uniform(0.0, 2.0 * math.pi))
    lighting = Lighting(direction=(round(math.cos(elevation) * math.cos(azimuth), 6),
                                   round(math.cos(elevation) * math.sin(azimuth), 6),
                                   round(math.sin(elevation), 6)),
                        ambient=round(_uniform(rng, settings.light_ambient), 4),
                        diffuse=round(_uniform(rng, settings.light_diffuse), 4))
    noise = round(_uniform(rng, settings.noise_std), 3)
    gain = round(_uniform(rng, settings.right_gain), 4)
    offset = round(_uniform(rng, settings.right_offset), 2)
    sizes = settings.sizes()
    for attempt in range(settings.max_attempts):
        try:
            scene = random_scene(seed * settings.max_attempts + attempt, object_type,
                                 rig=rig.rig, camera=rig.camera, workspace=workspace,
                                 sizes=sizes, max_attempts=100)
        except SceneError:
            continue
        width = top_width_px(scene, rig.rig, rig.camera)
        if width >= settings.min_top_px:
            scene = replace(scene, seed=seed, surface_texture_family=families[0],
                            object_texture_family=families[1], surface_tint=surface_tint,
                            object_tint=object_tint)
            return DistributionScene(split, seed, rig, scene, lighting, noise, gain, offset,
                                     attempt + 1, width)
    raise SceneError(f'no {object_type} of seed {seed} at least {settings.min_top_px} px wide '
                     f'in view of {rig.describe()} after {settings.max_attempts} draws')


OUT_OF_VIEW_M = 20.0
"""How far bare_table moves the object along world x [m]: beyond any rig's view."""


def bare_table(scene: DistributionScene) -> DistributionScene:
    """Return the scene with its object moved out of every camera's view: the same table,
    textures, light, sensor and rig with nothing on the table (what no best point must come
    from; benchmarks/bare_table_benchmark.py)."""
    scene_object = replace(scene.scene.scene_object,
                           x_m=scene.scene.scene_object.x_m + OUT_OF_VIEW_M)
    return replace(scene, scene=replace(scene.scene, scene_object=scene_object))


@dataclass(frozen=True)
class PlannedScene:
    """Where a split's scene comes from: its seed, object type and rig."""

    split: str
    seed: int
    object_type: ObjectType
    rig: DistributionRig

    def draw(self, settings: DistributionSettings = DEFAULT_SETTINGS) -> DistributionScene:
        """Draw the scene (see draw_scene)."""
        return draw_scene(self.split, self.seed, self.rig, self.object_type, settings)


def split_plan(split: str, per_type: int, settings: DistributionSettings = DEFAULT_SETTINGS,
               first: int = 0) -> list[PlannedScene]:
    """Return the plan of `per_type` scenes of each type of a split, types interleaved.

    Scene k of type t has seed SCENE_SEED_BASE[split] + 4 k + t and rig k % (rigs in the
    split), so every rig of the split sees every type. `first` skips the first k's (to extend
    a set without repeating it).

    Raises:
        DistributionError: For an unknown split.
    """
    rigs = split_rigs(split, settings)
    return [PlannedScene(split, SCENE_SEED_BASE[split] + len(OBJECT_TYPES) * k + t, kind,
                         rigs[k % len(rigs)])
            for k in range(first, first + per_type) for t, kind in enumerate(OBJECT_TYPES)]


__all__ = ['DEFAULT_SETTINGS', 'OUT_OF_VIEW_M', 'SCENE_SEED_BASE', 'SPLITS',
           'DistributionError', 'DistributionRig', 'DistributionScene', 'DistributionSettings',
           'PlannedScene', 'bare_table', 'draw_rig', 'draw_scene', 'rig_pool',
           'split_plan', 'split_rigs', 'top_width_px']
