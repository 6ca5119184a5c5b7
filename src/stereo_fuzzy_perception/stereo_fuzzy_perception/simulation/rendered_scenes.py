"""Rendered stereo scenes: pybullet images through the real correlation stage. ROS-free.

The geometric source (synthetic_scenes.py) hands the fuzzy stage perfect surface samples with
Gaussian disparity noise. The chapter's point is different: the fuzzy system is there to reduce
the systematic errors of the *correlation area* that window correlation really makes (fattened
edges, side faces matched as top, mismatches at the occlusion border). This source produces those:
it draws a scene (scene_model.random_scene), renders the stereo pair with pybullet's TinyRenderer
(scene_renderer.SceneRenderer), runs the correlation stage the node runs
(stereo_matching.StereoMatchingPipeline: rectify, ZNCC match, triangulate) and returns the same
SyntheticScene record as the geometric source: the matched points in the left camera's optical
frame, the rectified calibration and the ground truth (centre of the top face in `world`).

pybullet is only imported when this module is, and synthetic_scenes imports it lazily, so asking
for the geometric source never loads it. One source owns one pybullet connection; call close()
(or use it as a context manager) when done.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np

from stereo_fuzzy_perception.core.image_encoding import to_gray
from stereo_fuzzy_perception.core.matching.stereo_matching import (
    StereoMatchingPipeline,
    StereoMatchResult,
)
from stereo_fuzzy_perception.core.matching.window_matcher import MatcherConfig
from stereo_fuzzy_perception.core.rig_geometry import StereoRig, transform_points
from stereo_fuzzy_perception.simulation.scene_model import (
    SceneObject,
    SimulatedCamera,
    parse_object_type,
    random_scene,
)
from stereo_fuzzy_perception.simulation.scene_renderer import (
    SceneRenderer,
    SensorModel,
    StereoFrame,
)
from stereo_fuzzy_perception.simulation.synthetic_scenes import (
    OBJECT_TYPES,
    ConvexPrism,
    SyntheticScene,
)

DEFAULT_MIN_DISPARITY = 32
"""Smallest disparity searched [px]: the default rig sees the workspace at about 37-86 px."""
DEFAULT_DISPARITY_RANGE = 64
"""Disparities searched [px] (the demo's correlation_node settings)."""
DEFAULT_SENSOR = SensorModel(noise_std=1.0)
"""Sensor of the rendered scenes: 1 grey level of Gaussian noise per camera, no distortion."""
ROUND_SEGMENTS = 64


def prism_of(scene_object: SceneObject) -> ConvexPrism:
    """Return the object's footprint and height as a ConvexPrism in `world` (discs: 64-gon)."""
    pose = scene_object.world_from_object()
    xy = scene_object.footprint(ROUND_SEGMENTS) @ pose[:2, :2].T + pose[:2, 3]
    return ConvexPrism(xy, float(scene_object.height_m))


def count_object_points(world: np.ndarray, prism: ConvexPrism) -> int:
    """Return how many world points [m] lie over the footprint and above half the height."""
    if not len(world):
        return 0
    low, high = prism.polygon.min(axis=0), prism.polygon.max(axis=0)
    near = ((world[:, 2] > 0.5 * prism.height) & np.all(world[:, :2] >= low, axis=1)
            & np.all(world[:, :2] <= high, axis=1))
    return int(np.sum(prism.contains_xy(world[near, :2])))


@dataclass
class RenderedSceneSource:
    """Scenes from pybullet renders matched by the real correlation pipeline.

    Attributes:
        rig: Stereo rig; the default StereoRig when not given.
        camera: Image size and field of view of both cameras.
        sensor: Noise, gain/offset and lens distortion added to the rendered images.
        matcher: Correlation settings (ZNCC defaults, disparities 32..95 px for the default rig).
        point_stride: Keep every n-th valid match (1: all), as correlation_node's stride.
    """

    rig: StereoRig = field(default_factory=StereoRig)
    camera: SimulatedCamera = field(default_factory=SimulatedCamera)
    sensor: SensorModel = DEFAULT_SENSOR
    matcher: MatcherConfig = field(default_factory=lambda: MatcherConfig(
        min_disparity=DEFAULT_MIN_DISPARITY, disparity_range=DEFAULT_DISPARITY_RANGE))
    point_stride: int = 1
    _renderer: SceneRenderer | None = field(default=None, init=False, repr=False)
    _pipeline: StereoMatchingPipeline | None = field(default=None, init=False, repr=False)

    def __enter__(self) -> RenderedSceneSource:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def close(self) -> None:
        """Disconnect the renderer (a later scene() reconnects)."""
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    def renderer(self) -> SceneRenderer:
        """Return the source's renderer (connected on first use)."""
        if self._renderer is None:
            self._renderer = SceneRenderer(self.camera, self.rig, self.sensor, 'mono8')
        return self._renderer

    def pipeline(self) -> StereoMatchingPipeline:
        """Return the source's correlation pipeline (rectification maps cached)."""
        if self._pipeline is None:
            self._pipeline = StereoMatchingPipeline(self.matcher, self.point_stride)
        return self._pipeline

    def render(self, seed: int, object_type: str | None = None, with_maps: bool = False
               ) -> StereoFrame:
        """Draw the scene of `seed` (random_scene) and render its stereo pair (with its depth
        maps and object masks when with_maps)."""
        kind = None if object_type is None else parse_object_type(object_type)
        scene = random_scene(seed, kind, rig=self.rig, camera=self.camera)
        return self.renderer().render(scene, with_maps=with_maps)

    def match(self, frame: StereoFrame) -> StereoMatchResult:
        """Run the correlation stage on a rendered pair."""
        left = to_gray(frame.left, frame.encoding)
        right = to_gray(frame.right, frame.encoding)
        return self.pipeline().process(left, right, frame.calibration)

    def scene_of_seed(self, seed: int, object_type: str | None = None) -> SyntheticScene:
        """Return the matched scene of `seed`: render, correlate, record the ground truth.

        Raises:
            SceneError: When the scene cannot be placed in view of both cameras.
        """
        frame = self.render(seed, object_type)
        return self.scene_of_frame(frame, self.match(frame))

    def scene_of_frame(self, frame: StereoFrame, result: StereoMatchResult) -> SyntheticScene:
        """Return the scene of a rendered frame and its correlation result."""
        scene_object = frame.ground_truth.scene_object
        prism = prism_of(scene_object)
        world = transform_points(self.rig.world_from_left_camera(), result.points.xyz)
        return SyntheticScene(
            points=result.points, left=result.rectified.left, right=result.rectified.right,
            target_world=np.asarray(frame.ground_truth.target_world, dtype=float),
            object_type=scene_object.object_type.value, rig=self.rig,
            object_points=count_object_points(world, prism), prism=prism)

    def scene(self, rng: np.random.Generator, object_type: str | None = None
              ) -> SyntheticScene:
        """Return one random rendered scene (of `object_type`, or a random type).

        The scene seed is drawn from `rng`, so one generator gives a reproducible sequence.
        """
        kind = object_type or str(rng.choice(OBJECT_TYPES))
        return self.scene_of_seed(int(rng.integers(0, 2**31 - 1)), kind)

    def scenes(self, count: int, seed: int, object_type: str | None = None
               ) -> Iterator[SyntheticScene]:
        """Yield `count` scenes from one seed (the same seed gives the same scenes)."""
        rng = np.random.default_rng(seed)
        for _ in range(count):
            yield self.scene(rng, object_type)
