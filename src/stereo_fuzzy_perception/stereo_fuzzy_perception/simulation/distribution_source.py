"""Scenes of the randomized distribution through the real correlation stage, with references.

For each planned scene (scene_distribution.split_plan) this renders the pair with the scene's
rig, light, textures and sensor, matches it with the correlation stage the node runs (ZNCC,
default settings; with those the node derives the disparity search from the rig pose, the
calibration and the workspace box, disparity_range.workspace_disparity_range) and returns, per
point stride:

* `matched`: the matched points, as correlation_node publishes them;
* `perfect`: the same pixels' 3D points from the renderer's depth buffer (the ceiling: what the
  selectors make of perfect 3D points, so matcher loss and selector loss show separately);
* `opencv`: the best point of a plain OpenCV pipeline on the same pair (opencv_reference.py).

ROS-free; imports pybullet (through the renderer).
"""

from __future__ import annotations

import dataclasses
import multiprocessing
import os
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field

import cv2
import numpy as np

from stereo_fuzzy_perception.core.best_point.correlation_area import AreaConfig
from stereo_fuzzy_perception.core.camera_model import StereoCalibration
from stereo_fuzzy_perception.core.image_encoding import to_gray, to_rgb
from stereo_fuzzy_perception.core.matched_points import MatchedPoints
from stereo_fuzzy_perception.core.matching.disparity_range import workspace_disparity_range
from stereo_fuzzy_perception.core.matching.stereo_matching import StereoMatchingPipeline
from stereo_fuzzy_perception.core.matching.triangulation import triangulate
from stereo_fuzzy_perception.core.matching.window_matcher import MatcherConfig
from stereo_fuzzy_perception.core.rig_geometry import transform_points
from stereo_fuzzy_perception.simulation.opencv_reference import OpenCvReference
from stereo_fuzzy_perception.simulation.rendered_scenes import count_object_points, prism_of
from stereo_fuzzy_perception.simulation.scene_distribution import (
    DEFAULT_SETTINGS,
    DistributionScene,
    DistributionSettings,
    PlannedScene,
)
from stereo_fuzzy_perception.simulation.scene_renderer import SceneRenderer, StereoFrame
from stereo_fuzzy_perception.simulation.synthetic_scenes import SyntheticScene


def matcher_for(calibration: StereoCalibration, scene: DistributionScene,
                base: MatcherConfig | None = None,
                area: AreaConfig | None = None) -> MatcherConfig:
    """Return the matcher settings correlation_node uses for the scene's rig by default.

    `base` (MatcherConfig defaults) with the disparities the node derives when disparity_range
    is 0, its default: those of the workspace box (`area`'s, AreaConfig defaults) in view of
    both cameras (disparity_range.workspace_disparity_range).
    """
    area = area or AreaConfig()
    derived = workspace_disparity_range(calibration, scene.rig.rig.world_from_left_camera(),
                                        area.workspace_min, area.workspace_max)
    return dataclasses.replace(base or MatcherConfig(), min_disparity=derived.min_disparity,
                               disparity_range=derived.disparity_range)


SAME_SURFACE = 0.01
"""Four neighbouring depth-buffer pixels whose inverse depths differ by less than this share
lie on one surface (perfect_points interpolates between them)."""


def perfect_points(frame: StereoFrame, rectified: StereoCalibration, stride: int = 1
                   ) -> MatchedPoints:
    """Return the 3D points of the left rectified image's pixels from the depth buffer.

    The pixels are those correlation_node would triangulate: every stride-th row and column of
    the left rectified image, so that the ceiling's points lie on the same grid as the
    matches (the fuzzy stage weights a point on the pixel grid by the patch of the face it
    sees, and finds regions on that grid). Each pixel's ray is taken back into the raw camera
    (no lens distortion: the renderer's pinhole). Where it crosses the raw image between
    pixels of one surface, the point is on the ray at the depth interpolated between them
    (exact for a plane); across an edge it is the nearest raw pixel's own point, so that no
    point floats off the scene. xyz is in the left optical frame (as the matcher gives it),
    u_left - u_right is the point's disparity, the score is 1. Every pixel that sees something
    is kept, the work surface too: the fuzzy stage measures the surface from its points.

    Raises:
        ValueError: When the frame was rendered without depth maps.
    """
    if frame.left_depth is None:
        raise ValueError('the frame has no depth map: render it with with_maps=True')
    raw_depth = np.asarray(frame.left_depth, dtype=float)
    height, width = raw_depth.shape
    K = np.asarray(frame.calibration.left.K, dtype=float)
    left_p = np.asarray(rectified.left.P, dtype=float)
    rotation = np.asarray(rectified.left.R, dtype=float)  # rectified <- raw optical frame
    rows, columns = np.mgrid[0:height:stride, 0:width:stride]
    u, v = columns.ravel().astype(float), rows.ravel().astype(float)
    rectified_rays = np.stack([(u - left_p[0, 2]) / left_p[0, 0],
                               (v - left_p[1, 2]) / left_p[1, 1], np.ones_like(u)], axis=1)
    rays = rectified_rays @ rotation  # R^T applied to row vectors: the raw optical frame
    with np.errstate(divide='ignore', invalid='ignore'):
        raw_u = K[0, 0] * rays[:, 0] / rays[:, 2] + K[0, 2]
        raw_v = K[1, 1] * rays[:, 1] / rays[:, 2] + K[1, 2]
    inside = ((rays[:, 2] > 0) & (raw_u >= 0) & (raw_u <= width - 1) & (raw_v >= 0)
              & (raw_v <= height - 1))
    u, v, rays, raw_u, raw_v = u[inside], v[inside], rays[inside], raw_u[inside], raw_v[inside]
    depth, one_surface = _depth_along(raw_depth, raw_u, raw_v)
    # across an edge: the nearest raw pixel's own ray
    own = ~one_surface
    rays[own] = np.column_stack([(np.rint(raw_u[own]) - K[0, 2]) / K[0, 0],
                                 (np.rint(raw_v[own]) - K[1, 2]) / K[1, 1],
                                 np.ones(int(own.sum()))])
    seen = np.isfinite(depth)
    xyz = rays[seen] * (depth[seen] / rays[seen, 2])[:, np.newaxis]
    homogeneous = np.column_stack([xyz @ rotation.T, np.ones(len(xyz))])
    left_uvw = homogeneous @ left_p.T
    right_uvw = homogeneous @ np.asarray(rectified.right.P, dtype=float).T
    disparity = left_uvw[:, 0] / left_uvw[:, 2] - right_uvw[:, 0] / right_uvw[:, 2]
    return MatchedPoints(xyz=xyz.astype(np.float32), u_left=u[seen].astype(np.float32),
                         v_left=v[seen].astype(np.float32),
                         u_right=(u[seen] - disparity).astype(np.float32),
                         score=np.ones(len(xyz), dtype=np.float32))


def _depth_along(depth: np.ndarray, u: np.ndarray, v: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Return the depth buffer at raw image positions (u, v) [px] inside the image, and where
    the four pixels around each lie on one surface.

    Inverse depth is linear across the image of a plane: on one surface (the four pixels'
    inverse depths within SAME_SURFACE of each other) it is interpolated bilinearly; across
    an edge the nearest pixel's depth is returned.
    """
    column, row = np.floor(u).astype(int), np.floor(v).astype(int)
    column1 = np.minimum(column + 1, depth.shape[1] - 1)
    row1 = np.minimum(row + 1, depth.shape[0] - 1)
    du, dv = u - column, v - row
    corners = np.stack([depth[row, column], depth[row, column1], depth[row1, column],
                        depth[row1, column1]])
    inverse = 1.0 / corners  # 0 where a pixel sees nothing: never one surface with the others
    weights = np.stack([(1 - du) * (1 - dv), du * (1 - dv), (1 - du) * dv, du * dv])
    with np.errstate(divide='ignore'):
        blended = 1.0 / np.sum(weights * inverse, axis=0)
    nearest = corners[np.argmax(weights, axis=0), np.arange(len(u))]
    one_surface = np.ptp(inverse, axis=0) <= SAME_SURFACE * np.min(inverse, axis=0)
    return np.where(one_surface, blended, nearest), one_surface


@dataclass
class MatchedDistributionScene:
    """One distribution scene, matched, with its references.

    Attributes:
        scene: What was drawn.
        matched: Per point stride, the matched scene (points as correlation_node gives them).
        perfect: Per point stride, the same scene with depth-buffer points (empty if not asked).
        opencv_point: The plain OpenCV pipeline's best point in `world` [m] (None: no point or
            not asked).
        matcher: The matcher settings used.
    """

    scene: DistributionScene
    matched: dict[int, SyntheticScene]
    perfect: dict[int, SyntheticScene] = field(default_factory=dict)
    opencv_point: np.ndarray | None = None
    matcher: MatcherConfig | None = None


def _synthetic(frame: StereoFrame, scene: DistributionScene, points: MatchedPoints,
               rectified: StereoCalibration) -> SyntheticScene:
    rig = scene.rig.rig
    scene_object = frame.ground_truth.scene_object
    prism = prism_of(scene_object)
    world = transform_points(rig.world_from_left_camera(), points.xyz.astype(float))
    return SyntheticScene(points=points, left=rectified.left, right=rectified.right,
                          target_world=np.asarray(frame.ground_truth.target_world, dtype=float),
                          object_type=scene_object.object_type.value, rig=rig,
                          object_points=count_object_points(world, prism), prism=prism)


def match_scene(scene: DistributionScene, strides: Iterable[int] = (1,), ceiling: bool = False,
                opencv: bool = False, base_matcher: MatcherConfig | None = None,
                oversampling: int = 1, encoding: str = 'mono8') -> MatchedDistributionScene:
    """Render, match and (if asked) build the ceiling and the OpenCV reference of one scene.

    `oversampling` > 1 renders the images antialiased, as a camera integrates light over a
    pixel (SceneRenderer.render); 1 renders them as TinyRenderer does. `encoding` 'rgb8'
    renders colour cameras: the grey images are matched as correlation_node matches them and
    the matches carry the left colour image too (colour_silhouette.py); 'mono8' grey ones.
    """
    strides = tuple(strides)
    rig = scene.rig
    with SceneRenderer(camera=rig.camera, rig=rig.rig, encoding=encoding) as renderer:
        frame = renderer.render(scene.scene, with_maps=ceiling, lighting=scene.lighting,
                                sensor=scene.sensor(), oversampling=oversampling)
    config = matcher_for(frame.calibration, scene, base_matcher)
    # One stride: match only its rows, as correlation_node does; several: match every row
    # once and take each stride's points from the same disparity map (the same points).
    single = len(set(strides)) == 1
    pipeline = StereoMatchingPipeline(config, point_stride=strides[0] if single else 1)
    left = to_gray(frame.left, frame.encoding)
    right = to_gray(frame.right, frame.encoding)
    result = pipeline.process(left, right, frame.calibration, full_disparity=not single)
    colour = to_rgb(frame.left, frame.encoding)
    if colour is not None:
        pipeline.colour_parts(colour, to_rgb(frame.right, frame.encoding), frame.calibration,
                              result.points)
    rectified = result.rectified
    disparity_map = result.disparity_map
    # the face's outline is taken from the left image (face_outline.py), a plain top's height
    # from both (plain_face.py)
    matched = {stride: _synthetic(frame, scene, result.points if single else dataclasses.replace(
        triangulate(disparity_map.disparity, disparity_map.score, rectified, stride),
        left_image=result.points.left_image, right_image=result.points.right_image,
        left_colour=result.points.left_colour, right_colour=result.points.right_colour),
        rectified) for stride in strides}
    # The ceiling: perfect depth, whose own outline is exact (no image to correct it with).
    perfect = ({stride: _synthetic(frame, scene, perfect_points(frame, rectified, stride),
                                   rectified) for stride in strides} if ceiling else {})
    opencv_point = None
    if opencv:
        reference = OpenCvReference(config.min_disparity, config.disparity_range)
        opencv_point = reference.best_point(left, right, frame.calibration,
                                            rig.rig.world_from_left_camera())
    return MatchedDistributionScene(scene, matched, perfect, opencv_point, config)


@dataclass(frozen=True)
class _Job:
    planned: PlannedScene
    strides: tuple[int, ...]
    ceiling: bool
    opencv: bool
    settings: DistributionSettings
    oversampling: int
    encoding: str = 'mono8'


def _single_threaded() -> None:
    cv2.setNumThreads(1)


def _run(job: _Job) -> MatchedDistributionScene:
    return match_scene(job.planned.draw(job.settings), job.strides, job.ceiling, job.opencv,
                       oversampling=job.oversampling, encoding=job.encoding)


def match_plan(plan: Iterable[PlannedScene], strides: Iterable[int] = (1,),
               ceiling: bool = False, opencv: bool = False, jobs: int = 1,
               settings: DistributionSettings = DEFAULT_SETTINGS, oversampling: int = 1,
               encoding: str = 'mono8'
               ) -> Iterator[MatchedDistributionScene]:
    """Yield match_scene of every planned scene, in plan order, on `jobs` processes.

    Each process gets its own pybullet connection; results are the same for any `jobs`.
    """
    work = [_Job(planned, tuple(strides), ceiling, opencv, settings, oversampling, encoding)
            for planned in plan]
    if jobs <= 1:
        yield from map(_run, work)
        return
    # One thread per process: the processes share the cores instead of oversubscribing them.
    for variable in ('NUMBA_NUM_THREADS', 'OMP_NUM_THREADS', 'OPENBLAS_NUM_THREADS'):
        os.environ[variable] = '1'
    context = multiprocessing.get_context('spawn')
    with context.Pool(jobs, initializer=_single_threaded) as pool:
        yield from pool.imap(_run, work)


def distribution_scenes(plan: Iterable[PlannedScene], stride: int = 1, jobs: int = 1,
                        settings: DistributionSettings = DEFAULT_SETTINGS
                        ) -> Iterator[SyntheticScene]:
    """Yield the matched scenes of a plan at one point stride (for training)."""
    for matched in match_plan(plan, (stride,), jobs=jobs, settings=settings):
        yield matched.matched[stride]


__all__ = ['MatchedDistributionScene', 'distribution_scenes', 'match_plan', 'match_scene',
           'matcher_for',
           'perfect_points']
