"""surface_lookalike: a low face that looks like the table around it is the table."""

import numpy as np
from scipy import ndimage
from stereo_fuzzy_perception.core.best_point.surface_lookalike import (
    LOW_FACE_SIGMAS,
    MAX_OVERLAP,
    looks_like_the_surface,
    overlap_with_surroundings,
)
from stereo_fuzzy_perception.core.matched_points import RectifiedImage


def _grain(shape, seed, period_px=5.0):
    """A wood-like texture: stripes that waver, with noise."""
    rng = np.random.default_rng(seed)
    rows, columns = np.mgrid[0:shape[0], 0:shape[1]].astype(float)
    waver = ndimage.gaussian_filter(rng.normal(size=shape), 8.0) * 40.0
    return 110.0 + 40.0 * np.sin(2.0 * np.pi * (columns + waver) / period_px) + rng.normal(
        0.0, 2.0, shape)


def _face(x0=60, y0=50, side=40):
    v, u = np.mgrid[y0:y0 + side, x0:x0 + side]
    return u.ravel().astype(float), v.ravel().astype(float)


def _image(pixels, x=0, y=0):
    return RectifiedImage(np.clip(np.round(pixels), 0, 255).astype(np.uint8), x, y)


def test_a_patch_of_the_table_looks_like_the_table_around_it():
    table = _image(_grain((160, 180), 1))
    u, v = _face()
    assert overlap_with_surroundings(u, v, table) > MAX_OVERLAP
    assert looks_like_the_surface(u, v, LOW_FACE_SIGMAS - 1.0, table) is not None
    # a face standing well out of the noise is not looked at, whatever it looks like
    assert looks_like_the_surface(u, v, LOW_FACE_SIGMAS + 1.0, table) is None


def test_a_top_of_its_own_texture_or_shade_does_not():
    pixels = _grain((160, 180), 1)
    u, v = _face()
    inside = (slice(50, 90), slice(60, 100))
    other_texture = pixels.copy()
    other_texture[inside] = _grain((160, 180), 2, period_px=9.0)[inside] * 0.6 + 20.0
    darker = pixels.copy()
    darker[inside] = pixels[inside] * 0.55
    for top in (other_texture, darker):
        image = _image(top)
        assert overlap_with_surroundings(u, v, image) < MAX_OVERLAP
        assert looks_like_the_surface(u, v, LOW_FACE_SIGMAS - 1.0, image) is None


def test_the_image_part_offset_is_taken_into_account():
    pixels = _grain((160, 180), 1)
    pixels[50:90, 60:100] *= 0.55  # a darker top at (60..100, 50..90) of the part
    u, v = _face()
    part = _image(pixels, x=200, y=100)
    assert overlap_with_surroundings(u + 200, v + 100, part) < MAX_OVERLAP
    # without the offset the face would lie outside the part: nothing to compare
    assert overlap_with_surroundings(u + 200, v + 100, _image(pixels)) == 1.0


def test_a_bare_wood_table_matched_a_repeat_off_gives_no_point():
    # Train scene 33 with the rigs of pool 17 (seed 1000033), its object out of view: a wood
    # table whose patch of matches a repeat off stood 5.5 sigmas out and was given a point
    # 8.0 mm above the table before the test.
    from dataclasses import replace

    from stereo_fuzzy_perception.core.best_point.correlation_area import NO_OBJECT, AreaConfig
    from stereo_fuzzy_perception.core.best_point.point_selectors import BestPointChooser
    from stereo_fuzzy_perception.core.rig_geometry import StereoRig
    from stereo_fuzzy_perception.simulation.distribution_source import match_scene
    from stereo_fuzzy_perception.simulation.scene_distribution import (
        DEFAULT_SETTINGS,
        bare_table,
        split_plan,
    )

    planned = split_plan('train', 50, replace(DEFAULT_SETTINGS, rig_pool_seed=17))[33]
    assert planned.seed == 1000033
    scene = match_scene(bare_table(planned.draw()), (1,)).matched[1]
    chooser = replace(BestPointChooser.create('fuzzy_fitted', AreaConfig(), StereoRig()),
                      world_from_camera=scene.rig.world_from_left_camera())
    decision = chooser.decide(scene.points, scene.left, scene.right)
    assert decision.best_point_world is None
    assert decision.status == NO_OBJECT and 'looks like the surface' in decision.reason
