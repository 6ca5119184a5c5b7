"""benchmarks/true_top.py: the best point the true top's outline gives at its matches' median
height (the evaluation's diagnosis row)."""

from dataclasses import replace

import numpy as np

from benchmarks.true_top import left_pixel_rays, top_face_pixels, true_outline_point


def _scene_matched_exactly(kind: str, seed: int, top_offset_m: float = 0.0,
                           rim_at_table_px: int = 0):
    """A geometric scene whose every left pixel is matched exactly on what it sees (the top or
    the table at z = 0), the top's matches `top_offset_m` too high, and the top pixels within
    `rim_at_table_px` of its outline matched on the table instead (a rim taken by the table)."""
    import cv2
    from stereo_fuzzy_perception.core.matched_points import MatchedPoints
    from stereo_fuzzy_perception.core.rig_geometry import StereoRig, transform_points
    from stereo_fuzzy_perception.simulation.synthetic_scenes import GeometricSceneSource

    scene = GeometricSceneSource(rig=StereoRig()).scene(np.random.default_rng(seed), kind)
    width, height = scene.left.width, scene.left.height
    columns, rows = np.meshgrid(np.arange(width, dtype=float), np.arange(height, dtype=float))
    u, v = columns.ravel(), rows.ravel()
    seen = top_face_pixels(scene, u, v)
    on_top = seen
    if rim_at_table_px:
        size = 2 * rim_at_table_px + 1
        inner = cv2.erode(seen.reshape(height, width).astype(np.uint8),
                          np.ones((size, size), np.uint8)) > 0
        on_top = inner.ravel()
    level = np.where(on_top, scene.prism.height + top_offset_m, 0.0)
    centre, rays = left_pixel_rays(scene, u, v)
    world = centre + rays * ((level - centre[2]) / rays[:, 2])[:, None]
    camera = transform_points(np.linalg.inv(scene.rig.world_from_left_camera()), world)
    points = MatchedPoints(camera.astype(np.float32), u, v, u - 10.0, np.ones(len(u)))
    return replace(scene, points=points), seen


def _error_mm(scene) -> np.ndarray:
    return 1000.0 * (true_outline_point(scene) - scene.target_world)


def test_exact_matches_give_the_top_centre():
    for kind, seed in (('cubic_square', 3), ('cylinder', 5), ('circle', 7)):
        scene, seen = _scene_matched_exactly(kind, seed)
        assert seen.sum() > 200, kind
        assert np.linalg.norm(_error_mm(scene)) < 0.5, kind


def test_the_matches_height_error_on_the_top_is_the_points_error():
    scene, _ = _scene_matched_exactly('cubic_square', 3, top_offset_m=0.004)
    error = _error_mm(scene)
    assert abs(error[2] - 4.0) < 0.1
    assert np.linalg.norm(error) >= 4.0


def test_a_rim_matched_on_the_table_is_left_out():
    # two pixels of rim at the table's height are 15-25 % of a small top's matches: inside the
    # outline by INNER_PX, the median does not see them at all
    scene, _ = _scene_matched_exactly('circle', 7, rim_at_table_px=2)
    assert np.linalg.norm(_error_mm(scene)) < 0.5


def test_no_match_on_the_top_gives_no_point():
    scene, seen = _scene_matched_exactly('cubic_square', 3)
    away = replace(scene.points, u_left=scene.points.u_left[~seen],
                   v_left=scene.points.v_left[~seen], u_right=scene.points.u_right[~seen],
                   xyz=scene.points.xyz[~seen], score=scene.points.score[~seen])
    assert np.isnan(true_outline_point(replace(scene, points=away))).all()


def test_the_rig_breakdown_reads_the_diagnosis_row_by_its_name():
    from benchmarks.rig_breakdown import ROWS
    from benchmarks.rig_generalisation_benchmark import ORACLE_ROW

    assert ROWS['true outline'] == ORACLE_ROW


def test_the_tuning_tool_splits_the_outcomes_by_what_the_true_outline_gives():
    from benchmarks.rig_tuning import held_by_true_outline, true_outline_outcomes

    exact, _ = _scene_matched_exactly('cubic_square', 3)
    high, _ = _scene_matched_exactly('cylinder', 5, top_offset_m=0.006)
    lines = true_outline_outcomes({'exact': 1.0, 'high': None},
                                  [('exact', exact), ('high', high)], 3.0)
    assert lines[0].endswith('within 3 mm on 1 of 2 scenes')
    assert lines[1] == '  fitted rules on those 1: within 1, <= 10 mm 0, > 10 mm 0, no point 0'
    assert lines[2] == ('  fitted rules on the other 1: within 0, <= 10 mm 0, > 10 mm 0, '
                        'no point 1')
    held = held_by_true_outline([('exact', exact), ('high', high)], 3.0)
    assert held == {'exact'}
    assert true_outline_outcomes({'exact': 1.0, 'high': None},
                                 [('exact', exact), ('high', high)], 3.0, held) == lines
