"""benchmarks/disc_rim_probe.py: the true top's outline and the band on its far side."""

import cv2
import numpy as np

from benchmarks.disc_rim_probe import BAND_PX, far_side_band, left_pixel, true_outline
from benchmarks.true_top import top_face_pixels


def _scene(kind: str, seed: int):
    from stereo_fuzzy_perception.core.rig_geometry import StereoRig
    from stereo_fuzzy_perception.simulation.synthetic_scenes import GeometricSceneSource

    return GeometricSceneSource(rig=StereoRig()).scene(np.random.default_rng(seed), kind)


def test_the_true_outline_bounds_the_pixels_that_see_the_top():
    for kind, seed in (('circle', 7), ('cubic_square', 3)):
        scene = _scene(kind, seed)
        outline = true_outline(scene)
        hull = cv2.convexHull(outline.astype(np.float32))
        low, high = np.floor(outline.min(axis=0)) - 3, np.ceil(outline.max(axis=0)) + 3
        columns, rows = (grid.ravel().astype(float) for grid in np.meshgrid(
            np.arange(low[0], high[0]), np.arange(low[1], high[1])))
        seen = top_face_pixels(scene, columns, rows)
        inside = np.array([cv2.pointPolygonTest(hull, (u, v), True) > 0.5
                           for u, v in zip(columns, rows, strict=True)])
        outside = np.array([cv2.pointPolygonTest(hull, (u, v), True) < -0.5
                            for u, v in zip(columns, rows, strict=True)])
        assert inside.sum() > 100, kind
        assert seen[inside].all() and not seen[outside].any(), kind


def test_the_band_straddles_the_rim_on_the_side_away_from_the_cameras():
    scene = _scene('circle', 7)
    outline = true_outline(scene)
    columns, rows, inside = far_side_band(scene, outline)
    hull = cv2.convexHull(outline.astype(np.float32))
    distance = np.array([cv2.pointPolygonTest(hull, (float(u), float(v)), True)
                         for u, v in zip(columns, rows, strict=True)])
    assert len(columns) > 50
    assert np.all(np.abs(distance) <= BAND_PX)
    assert np.array_equal(inside, distance > 0.0)
    assert 0.3 < inside.mean() < 0.7  # both sides of the rim
    # away from the cameras: a point sinking from the top toward the table moves the other way
    top = scene.target_world
    down = left_pixel(scene, top * np.array([1.0, 1.0, 0.0])) - left_pixel(scene, top)
    centre = outline.mean(axis=0)
    assert np.all((columns - centre[0]) * down[0] + (rows - centre[1]) * down[1] < 0.0)
