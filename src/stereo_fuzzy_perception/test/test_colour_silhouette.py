"""The top from the colour silhouette (core/best_point/colour_silhouette.py).

Rendered scenes of the training split with colour cameras: a far rig's 5 mm disc that the
grey looks refuse is found in colour, and the same pair tells nothing in colour where it has
no colour to tell (the table's own colour, a flat patch of another colour, a top whose matches
scatter, a patch of colour printed on the table): the grey looks then decide as before.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pytest
from stereo_fuzzy_perception.core.best_point.colour_silhouette import colour_top
from stereo_fuzzy_perception.core.best_point.correlation_area import (
    LOOK_COLOUR_SILHOUETTE,
    STATUS_OK,
    AreaConfig,
)
from stereo_fuzzy_perception.core.best_point.plain_top_height import plane_disparity
from stereo_fuzzy_perception.core.best_point.point_selectors import (
    BestPointChooser,
    decision_area,
)
from stereo_fuzzy_perception.core.best_point.work_surface import SurfacePlane
from stereo_fuzzy_perception.core.matched_points import RectifiedImage
from stereo_fuzzy_perception.core.rig_geometry import StereoRig, transform_points

# Training scene 20 (seed 1000020): a 5 mm disc 24 px across on rig 5 (0.72 m up), whose
# value-noise top stands out of no table noise in grey.
GREY_REFUSES = ('train', 50, 20)


@dataclass(frozen=True)
class Rendered:
    scene: object
    bare: object
    chooser: BestPointChooser


def _matched(split: str, per_type: int, index: int, bare: bool = False):
    from stereo_fuzzy_perception.simulation.distribution_source import match_scene
    from stereo_fuzzy_perception.simulation.scene_distribution import bare_table, split_plan

    drawn = split_plan(split, per_type)[index].draw()
    return match_scene(bare_table(drawn) if bare else drawn, (1,), encoding='rgb8').matched[1]


@pytest.fixture(scope='module')
def rendered() -> Rendered:
    scene = _matched(*GREY_REFUSES)
    chooser = replace(BestPointChooser.create('fuzzy_fitted', AreaConfig(), StereoRig()),
                      world_from_camera=scene.rig.world_from_left_camera())
    return Rendered(scene, _matched(*GREY_REFUSES, bare=True), chooser)


def _error_mm(decision, scene) -> float:
    return 1000.0 * float(np.linalg.norm(decision.best_point_world - scene.target_world))


def _colour_top(rendered, points):
    scene, config = rendered.scene, rendered.chooser.area_config
    surface = decision_area(points, scene.left, scene.right, rendered.chooser.world_from_camera,
                            config).surface
    return colour_top(points, scene.left, scene.right, rendered.chooser.world_from_camera,
                      surface, (config.workspace_min, config.workspace_max),
                      config.max_object_across_m, config.max_object_height_m)


def test_a_disc_the_grey_looks_refuse_is_found_in_colour(rendered):
    scene, chooser = rendered.scene, rendered.chooser
    assert scene.points.left_colour is not None, 'rgb8 cameras: the matches carry colour'
    assert scene.points.left_colour.pixels.shape == scene.points.left_image.pixels.shape + (3,)
    assert scene.points.right_colour.pixels.shape == (
        scene.points.right_image.pixels.shape + (3,))
    grey = chooser.decide(replace(scene.points, left_colour=None), scene.left, scene.right)
    assert grey.status != STATUS_OK, 'the grey looks refuse this disc (why it was chosen)'
    decision = chooser.decide(scene.points, scene.left, scene.right)
    assert decision.status == STATUS_OK, decision.status_text()
    assert decision.look == LOOK_COLOUR_SILHOUETTE
    assert _error_mm(decision, scene) <= 3.0
    assert decision.top_height == pytest.approx(0.005, abs=0.003)


def test_the_colour_look_can_be_turned_off(rendered):
    scene, chooser = rendered.scene, rendered.chooser
    off = replace(chooser, area_config=replace(chooser.area_config, colour_silhouette=False))
    decision = off.decide(scene.points, scene.left, scene.right)
    assert decision.look != LOOK_COLOUR_SILHOUETTE
    assert decision.status != STATUS_OK


def test_a_table_of_the_objects_colour_gives_no_silhouette(rendered):
    points = rendered.scene.points
    grey = points.left_image.pixels
    colourless = RectifiedImage(np.repeat(grey[..., None], 3, axis=2), points.left_image.x,
                                points.left_image.y, points.left_image.window_size)
    top, why = _colour_top(rendered, replace(points, left_colour=colourless))
    assert top is None
    assert 'no region of another colour' in why


def test_the_bare_table_gives_no_point(rendered):
    bare = rendered.bare
    top, why = _colour_top(rendered, bare.points)
    assert top is None, 'a table of one colour holds no silhouette'
    decision = rendered.chooser.decide(bare.points, bare.left, bare.right)
    assert decision.status != STATUS_OK


def _painted(image: RectifiedImage, inside: np.ndarray) -> RectifiedImage:
    pixels = image.pixels.copy()
    grey = pixels[inside].astype(float).mean(axis=1, keepdims=True)
    pixels[inside] = np.clip(grey * np.array([[1.3, 0.8, 0.6]]), 0, 255).astype(np.uint8)
    return replace(image, pixels=pixels)


def test_a_flat_patch_of_another_colour_is_the_tables_own(rendered):
    """A label printed on the table: another colour and no height, in both images (at the
    table's plane: z = 0, the rig's pose exact), on a far rig whose table's matches stand
    several millimetres above the plane there (the renderer's moire)."""
    bare, chooser = rendered.bare, rendered.chooser
    left_colour, right_colour = bare.points.left_colour, bare.points.right_colour
    centre = np.array([320.0, 240.0])  # where the table's matches stand highest
    rows, columns = np.mgrid[0:left_colour.pixels.shape[0], 0:left_colour.pixels.shape[1]]
    in_left = np.hypot(columns + left_colour.x - centre[0], rows + left_colour.y - centre[1]) < 30
    on_table = plane_disparity(bare.left, bare.right, chooser.world_from_camera,
                               SurfacePlane('measured', 0.0, 0.0, 0.0, 0.2, 100))
    shift = float(centre[0] - on_table(centre[:1], centre[1:], 0.0)[0])
    rows, columns = np.mgrid[0:right_colour.pixels.shape[0], 0:right_colour.pixels.shape[1]]
    in_right = np.hypot(columns + right_colour.x + shift - centre[0],
                        rows + right_colour.y - centre[1]) < 30
    points = replace(bare.points, left_colour=_painted(left_colour, in_left),
                     right_colour=_painted(right_colour, in_right))
    top, why = _colour_top(rendered, points)
    assert top is None
    assert 'a patch of colour on the table' in why
    decision = chooser.decide(points, bare.left, bare.right)
    assert decision.status != STATUS_OK


def test_a_top_whose_matches_scatter_is_not_measured(rendered):
    scene, chooser = rendered.scene, rendered.chooser
    points = scene.points
    world = transform_points(chooser.world_from_camera, points.xyz.astype(float))
    on_object = world[:, 2] > 0.002
    rng = np.random.default_rng(7)
    scale = np.ones(len(points))
    scale[on_object] = rng.uniform(0.9, 1.1, int(on_object.sum()))  # +-7 cm along the rays
    scattered = replace(points, xyz=(points.xyz * scale[:, None]).astype(np.float32))
    top, why = _colour_top(rendered, scattered)
    assert top is None
    assert 'scatter' in why or 'stand' in why
