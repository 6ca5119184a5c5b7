"""The randomized scene distribution: ranges, splits, solvable scenes, disparity search,
texture families, the depth-buffer ceiling and the OpenCV reference."""

import math
from dataclasses import replace

import numpy as np
import pytest
from stereo_fuzzy_perception.core.rig_geometry import StereoRig, transform_points
from stereo_fuzzy_perception.simulation.scene_distribution import (
    DEFAULT_SETTINGS,
    SCENE_SEED_BASE,
    SPLITS,
    DistributionError,
    bare_table,
    rig_pool,
    split_plan,
    split_rigs,
    top_width_px,
)
from stereo_fuzzy_perception.simulation.scene_model import OBJECT_TYPES, WORKSPACE, in_view
from stereo_fuzzy_perception.simulation.texture_families import (
    TEXTURE_FAMILIES,
    TextureError,
    family_shade,
    family_texture,
)

SETTINGS = DEFAULT_SETTINGS


def within(value: float, limits: tuple[float, float], slack: float = 1e-6) -> bool:
    return limits[0] - slack <= value <= limits[1] + slack


def test_every_rig_of_the_pool_lies_in_the_ranges_and_looks_at_the_workspace():
    for drawn in rig_pool():
        rig, camera = drawn.rig, drawn.camera
        assert within(rig.z0_m, SETTINGS.rig_height_m), drawn.describe()
        assert within(rig.baseline_m, SETTINGS.baseline_m), drawn.describe()
        assert within(rig.alpha_deg, SETTINGS.tilt_deg, 1e-3), drawn.describe()
        assert within(rig.theta_deg, SETTINGS.pan_deg, 1e-3), drawn.describe()
        assert within(rig.vergence_deg / 2.0, SETTINGS.toe_in_deg, 1e-3), drawn.describe()
        assert within(camera.vertical_fov_deg, SETTINGS.vertical_fov_deg, 1e-3)
        assert (camera.width, camera.height) == (SETTINGS.image_width, SETTINGS.image_height)
        axis = rig.rig_rotation()[:, 2]
        midpoint = np.array([rig.x0_m, rig.y0_m, rig.z0_m])
        aim = midpoint + (rig.z0_m / -axis[2]) * axis
        margin = SETTINGS.aim_margin_m - 1e-4
        assert WORKSPACE.x_min + margin <= aim[0] <= WORKSPACE.x_max - margin, drawn.describe()
        assert WORKSPACE.y_min + margin <= aim[1] <= WORKSPACE.y_max - margin, drawn.describe()


def test_the_pool_is_the_same_every_time_and_its_rigs_differ():
    first, second = rig_pool(), rig_pool()
    assert first == second
    assert len({drawn.rig for drawn in first}) == SETTINGS.rig_pool_size


def test_evaluation_rigs_and_seeds_never_occur_in_training_or_validation():
    held_out = {drawn.index for drawn in split_rigs('evaluation')}
    training = {drawn.index for drawn in split_rigs('train')}
    assert len(held_out) == SETTINGS.held_out_rigs
    assert not held_out & training
    assert {drawn.index for drawn in split_rigs('validation')} == training
    plans = {split: split_plan(split, 200) for split in SPLITS}
    seeds = {split: {planned.seed for planned in plan} for split, plan in plans.items()}
    for split, other in (('train', 'validation'), ('train', 'evaluation'),
                         ('validation', 'evaluation')):
        assert not seeds[split] & seeds[other], f'{split} and {other} share scene seeds'
    assert all(planned.rig.index in held_out for planned in plans['evaluation'])
    assert all(planned.rig.index in training for planned in plans['train'])


def test_every_held_out_rig_sees_every_object_type_in_a_50_per_type_evaluation():
    plan = split_plan('evaluation', 50)
    seen = {(planned.rig.index, planned.object_type) for planned in plan}
    assert len(seen) == SETTINGS.held_out_rigs * len(OBJECT_TYPES)
    assert plan[0].seed == SCENE_SEED_BASE['evaluation']


def test_unknown_split_is_refused():
    with pytest.raises(DistributionError, match='unknown split'):
        split_plan('test', 1)


@pytest.mark.parametrize('planned', split_plan('evaluation', 3) + split_plan('train', 2),
                         ids=lambda planned: f'{planned.split}-{planned.seed}')
def test_drawn_scenes_are_reproducible_solvable_and_inside_the_ranges(planned):
    scene = planned.draw()
    assert scene == planned.draw()
    rig, camera = scene.rig.rig, scene.rig.camera
    scene_object = scene.scene.scene_object
    assert scene.seed == planned.seed and scene.scene.seed == planned.seed
    assert scene.object_type == planned.object_type.value
    assert top_width_px(scene.scene, rig, camera) == scene.top_width_px >= SETTINGS.min_top_px
    assert in_view(scene_object.outline_points(), rig, camera, 0.0)
    assert scene_object.size_x_m <= SETTINGS.object_across_m[1] + 1e-9
    assert min(scene_object.size_x_m, scene_object.size_y_m) >= SETTINGS.object_across_m[0]
    assert scene.scene.surface_texture_family in TEXTURE_FAMILIES
    assert scene.scene.object_texture_family in TEXTURE_FAMILIES
    assert within(scene.noise_std, SETTINGS.noise_std, 1e-3)
    assert within(scene.right_gain, SETTINGS.right_gain, 1e-3)
    assert within(scene.right_offset, SETTINGS.right_offset, 1e-2)
    assert within(scene.lighting.ambient, SETTINGS.light_ambient, 1e-3)
    elevation = math.degrees(math.asin(scene.lighting.direction[2]))
    assert within(elevation, SETTINGS.light_elevation_deg, 1e-2)



@pytest.mark.parametrize('planned', split_plan('evaluation', 2),
                         ids=lambda planned: f'{planned.split}-{planned.seed}')
def test_a_bare_table_is_the_scene_with_its_object_out_of_every_view(planned):
    scene = planned.draw()
    bare = bare_table(scene)
    rig, camera = scene.rig.rig, scene.rig.camera
    moved = bare.scene.scene_object.outline_points()
    for pose in (rig.world_from_left_camera(), rig.world_from_right_camera()):
        uv = camera.project(pose, moved)
        seen = (np.isfinite(uv).all(axis=1) & (uv[:, 0] >= 0) & (uv[:, 1] >= 0)
                & (uv[:, 0] < camera.width) & (uv[:, 1] < camera.height))
        assert not seen.any(), 'expected the object out of both images'
    assert replace(bare.scene, scene_object=scene.scene.scene_object) == scene.scene
    assert replace(bare, scene=scene.scene) == scene

def test_the_distribution_draws_every_texture_family_and_a_spread_of_sensors():
    scenes = [planned.draw() for planned in split_plan('train', 12)]
    families = {scene.scene.object_texture_family for scene in scenes}
    families |= {scene.scene.surface_texture_family for scene in scenes}
    assert families == set(TEXTURE_FAMILIES)
    noise = [scene.noise_std for scene in scenes]
    assert min(noise) < 1.0 and max(noise) > 3.0


@pytest.mark.parametrize('planned', split_plan('evaluation', 2),
                         ids=lambda planned: f'{planned.seed}')
def test_the_default_disparity_search_covers_the_objects_top(planned):
    from stereo_fuzzy_perception.simulation.distribution_source import matcher_for
    from stereo_fuzzy_perception.simulation.scene_renderer import stereo_calibration

    scene = planned.draw()
    rig, camera = scene.rig.rig, scene.rig.camera
    calibration = stereo_calibration(camera, rig)
    config = matcher_for(calibration, scene)
    low, span = config.min_disparity, config.disparity_range
    top = scene.scene.scene_object.outline_points()[-4:]
    left = transform_points(np.linalg.inv(rig.world_from_left_camera()), top)
    rectified = left @ calibration.left.R.T
    homogeneous = np.column_stack([rectified, np.ones(len(rectified))])
    disparity = (homogeneous @ calibration.left.P[0] - homogeneous @ calibration.right.P[0]) \
        / rectified[:, 2]
    assert np.all(disparity > low) and np.all(disparity < low + span - 1), (disparity, low, span)


@pytest.mark.parametrize('family', TEXTURE_FAMILIES)
def test_every_texture_family_is_reproducible_and_textured(family):
    texture = family_texture(family, 7, 128, 0.25, (0.6, 0.6, 0.6))
    assert texture.shape == (128, 128, 3) and texture.dtype == np.uint8
    assert np.array_equal(texture, family_texture(family, 7, 128, 0.25, (0.6, 0.6, 0.6)))
    assert not np.array_equal(texture, family_texture(family, 8, 128, 0.25, (0.6, 0.6, 0.6)))
    shade = family_shade(family, 7, 128, 0.25)
    assert shade.min() >= 0.0 and shade.max() <= 1.0
    assert shade.std() > 0.005, f'{family} is flat'


def test_low_texture_has_far_less_contrast_than_the_others():
    low = family_shade('low_texture', 3, 256, 0.25).std()
    for family in TEXTURE_FAMILIES:
        if family != 'low_texture':
            assert family_shade(family, 3, 256, 0.25).std() > 2.0 * low, family


def test_an_unknown_texture_family_is_refused():
    with pytest.raises(TextureError, match='unknown texture family'):
        family_shade('marble', 1, 16, 0.1)


@pytest.fixture(scope='module')
def matched_scene():
    """One evaluation scene at 320x240 (fast), matched with the ceiling and the reference."""
    from stereo_fuzzy_perception.simulation.distribution_source import match_scene

    small = replace(SETTINGS, image_width=320, image_height=240, min_top_px=20.0)
    planned = split_plan('evaluation', 1, small)[1]
    return match_scene(planned.draw(small), (1, 3), ceiling=True, opencv=True)


def test_perfect_points_lie_on_the_object_and_triangulate_back_to_themselves(matched_scene):
    perfect = matched_scene.perfect[1]
    assert len(perfect.points) > 100
    assert perfect.object_points > 100
    rig = perfect.rig
    world = transform_points(rig.world_from_left_camera(), perfect.points.xyz.astype(float))
    top = perfect.target_world[2]
    assert np.max(world[:, 2]) == pytest.approx(top, abs=5e-4)
    # u_left - u_right is the disparity the matcher would find; Eq. 1 gives the point back.
    points = perfect.points
    depth = (perfect.left.P[0, 3] - perfect.right.P[0, 3]) / (
        points.u_left - points.u_right - (perfect.left.P[0, 2] - perfect.right.P[0, 2]))
    rectified = points.xyz.astype(float) @ perfect.left.R.T
    assert np.allclose(depth, rectified[:, 2], rtol=1e-4)
    assert len(matched_scene.perfect[3].points) < len(perfect.points) / 4


def test_perfect_points_lie_on_the_matches_pixel_grid(matched_scene):
    # The ceiling's points are the pixels correlation_node would triangulate: the fuzzy stage
    # weights and groups points on that grid, so the ceiling must come on it too.
    for stride in (1, 3):
        perfect = matched_scene.perfect[stride].points
        matched = matched_scene.matched[stride].points
        for column in (perfect.u_left, perfect.v_left):
            assert np.all(column % stride == 0), f'stride {stride}: off the pixel grid'
        matched_cells = set(zip(matched.u_left.tolist(), matched.v_left.tolist(), strict=True))
        perfect_cells = set(zip(perfect.u_left.tolist(), perfect.v_left.tolist(), strict=True))
        # (the rectified image's border rows and columns see past the raw image)
        shared = len(matched_cells & perfect_cells) / len(matched_cells)
        assert shared > 0.97, f'stride {stride}: {100 * shared:.1f} % of the matched pixels'


def test_matched_points_at_stride_3_are_the_stride_1_map_sampled(matched_scene):
    one, three = matched_scene.matched[1].points, matched_scene.matched[3].points
    assert 0 < len(three) < len(one)
    assert np.all(three.u_left % 3 == 0) and np.all(three.v_left % 3 == 0)


def test_the_opencv_reference_finds_the_top_of_a_plain_scene():
    """On the simulator's own rig, ideal sensors, a textured box: SGBM + top band is close."""
    from stereo_fuzzy_perception.core.image_encoding import to_gray
    from stereo_fuzzy_perception.simulation.opencv_reference import OpenCvReference
    from stereo_fuzzy_perception.simulation.scene_renderer import render_scene

    frame = render_scene(11, 'cubic_square', encoding='mono8')
    reference = OpenCvReference(min_disparity=32, disparity_range=64)
    point = reference.best_point(to_gray(frame.left, 'mono8'), to_gray(frame.right, 'mono8'),
                                 frame.calibration, StereoRig().world_from_left_camera())
    assert point is not None
    error_mm = 1000.0 * np.linalg.norm(point - frame.ground_truth.target_world)
    assert error_mm < 5.0, f'OpenCV reference {error_mm:.2f} mm from the top-face centre'


def test_chain_parameters_give_the_nodes_the_rig_and_derive_the_disparity_search():
    from stereo_fuzzy_perception.simulation.scene_bag_writer import chain_parameters
    from stereo_fuzzy_perception.simulation.scene_distribution import draw_rig

    template = {'correlation_node': {'ros__parameters': {
                    'point_stride': 3, 'min_disparity': 32, 'disparity_range': 64}},
                'gantry_driver_node': {'ros__parameters': {'approach_offset_m': 0.0}}}
    parameters = chain_parameters(template, 31)
    drawn = draw_rig(31)
    correlation = parameters['correlation_node']['ros__parameters']
    assert correlation['point_stride'] == 3 and correlation['disparity_range'] == 0
    assert 'min_disparity' not in correlation
    assert StereoRig(**correlation['rig']) == drawn.rig
    assert StereoRig(**parameters['fuzzy_best_point_node']['ros__parameters']['rig']) \
        == drawn.rig
    assert parameters['gantry_driver_node'] == template['gantry_driver_node']
    assert template['correlation_node']['ros__parameters']['disparity_range'] == 64, (
        'the template was changed')


def test_render_scenes_from_a_distribution_rig_is_reproducible(tmp_path):
    import yaml
    from stereo_fuzzy_perception.bag.bag_io import read_info, read_messages
    from stereo_fuzzy_perception.simulation.scene_bag_writer import main

    template = tmp_path / 'template.yaml'
    template.write_text('correlation_node:\n  ros__parameters:\n    point_stride: 3\n')
    arguments = ['--distribution-rig', '32', '--types', 'circle', '--scenes-per-type', '1',
                 '--seed', '5', '--encoding', 'mono8', '--chain-params', str(template)]
    for name in ('a', 'b'):
        assert main(['-o', str(tmp_path / name), *arguments]) == 0
    first, second = (list(read_messages(tmp_path / name)) for name in ('a', 'b'))
    assert [m.data for m in first] == [m.data for m in second]
    info = read_info(tmp_path / 'a')
    assert info.message_count == 7, 'six messages for the scene and /tf_static with the rig'
    assert info.topic('/tf_static').message_count == 1
    parameters = yaml.safe_load((tmp_path / 'a' / 'chain_params.yaml').read_text())
    assert parameters['fuzzy_best_point_node']['ros__parameters']['rig']['z0_m'] == \
        pytest.approx(rig_pool()[32].rig.z0_m)


def test_render_scenes_refuses_chain_params_without_a_distribution_rig(tmp_path):
    from stereo_fuzzy_perception.simulation.scene_bag_writer import main

    with pytest.raises(SystemExit, match='--chain-params needs --distribution-rig'):
        main(['-o', str(tmp_path / 'bag'), '--chain-params', 'chain/demo_params.yaml'])
