"""benchmarks/rig_tuning.py's --coverage: which pixels see the true top, and the shares."""

import math

import numpy as np

from benchmarks.rig_tuning import coverage_shares
from benchmarks.true_top import top_face_pixels


def _scene(kind: str, seed: int):
    from stereo_fuzzy_perception.core.rig_geometry import StereoRig
    from stereo_fuzzy_perception.simulation.synthetic_scenes import GeometricSceneSource

    return GeometricSceneSource(rig=StereoRig()).scene(np.random.default_rng(seed), kind)


def test_the_matches_on_the_top_face_see_it_and_the_surface_around_does_not():
    for kind, seed in (('cubic_square', 3), ('cylinder', 5), ('circle', 7)):
        scene = _scene(kind, seed)
        pose = scene.rig.world_from_left_camera()
        world = scene.points.xyz.astype(float) @ pose[:3, :3].T + pose[:3, 3]
        # the geometric scenes' matches are noisy: a point stands on the top when it lies over
        # the footprint at the top's height, on the surface when it lies well away from it
        on_top = (np.abs(world[:, 2] - scene.prism.height) < 1e-3) & (
            scene.prism.contains_xy(world[:, :2]))
        reach = np.max(np.linalg.norm(scene.prism.polygon - scene.prism.polygon.mean(axis=0),
                                      axis=1))
        away = np.linalg.norm(world[:, :2] - scene.prism.polygon.mean(axis=0), axis=1)
        on_surface = (np.abs(world[:, 2]) < 1e-3) & (away > 1.5 * reach)
        seen = top_face_pixels(scene, scene.points.u_left.astype(float),
                               scene.points.v_left.astype(float))
        assert on_top.sum() > 50 and on_surface.sum() > 50
        assert seen[on_top].mean() > 0.97, kind
        assert not seen[on_surface].any(), kind


def test_the_shares_count_what_the_area_misses_and_what_it_adds():
    top = {(0, 0), (0, 1), (1, 0), (1, 1)}
    assert coverage_shares({(0, 0), (0, 1), (5, 5)}, top) == (0.5, 1 / 3)
    assert coverage_shares(top, top) == (0.0, 0.0)
    missed, extra = coverage_shares(set(), top)
    assert missed == 1.0 and math.isnan(extra)
