"""benchmarks/outline_fit_probe.py: the shapes' distances, the fit's labels and the blend."""

import math

import numpy as np
import pytest

from benchmarks.outline_fit_probe import (
    PixelCosts,
    ShapeFit,
    blended,
    disc_distance,
    fit_top,
    principal_axes,
    rectangle_distance,
)


def test_a_disc_is_negative_inside_zero_on_its_rim_and_the_distance_outside():
    disc = np.array([0.1, 0.2, 0.03])
    points = np.array([[0.1, 0.2], [0.13, 0.2], [0.1, 0.25]])
    assert disc_distance(points, disc) == pytest.approx([-0.03, 0.0, 0.02])


def test_a_turned_rectangle_measures_along_its_own_sides():
    # 40 x 20 mm, its long side along the diagonal
    rectangle = np.array([0.0, 0.0, math.pi / 4, 0.04, 0.02])
    along = np.array([math.cos(math.pi / 4), math.sin(math.pi / 4)])
    across = np.array([-along[1], along[0]])
    points = np.array([0.0 * along, 0.03 * along, 0.02 * across, 0.03 * along + 0.02 * across])
    assert rectangle_distance(points, rectangle) == pytest.approx(
        [-0.01, 0.01, 0.01, math.hypot(0.01, 0.01)])


def _pixel_grid(metres_per_px: float, side: int) -> np.ndarray:
    columns, rows = np.meshgrid(np.arange(side), np.arange(side))
    return np.column_stack([columns.ravel(), rows.ravel()]) * metres_per_px


def test_the_fit_finds_the_disc_whose_pixels_match_the_top_and_the_rest_the_surface():
    metres_per_px = 0.001
    on_top = _pixel_grid(metres_per_px, 60)
    true_disc = np.array([0.031, 0.028, 0.012])
    inside = disc_distance(on_top, true_disc) < 0.0
    # no wall and nothing hidden from the right camera: the rays' points below the top and
    # the view lines to the right camera all run far outside the disc
    costs = PixelCosts(on_top=on_top, down_wall=on_top[None] + 1.0, to_right=on_top[None] + 1.0,
                       metres_per_px=np.full(len(on_top), metres_per_px),
                       top_cost=np.where(inside, 0.1, 1.2), wall_cost=np.ones((1, len(on_top))),
                       surface_cost=np.where(inside, 1.2, 0.1), mismatch=1.2)
    fit = fit_top(costs, np.array([0.027, 0.031]), (0.0, 0.02, 0.02), starts=1)
    assert fit.shape == 'disc'
    assert np.hypot(*(fit.centre - true_disc[:2])) < 0.5 * metres_per_px
    assert fit.drop_per_px > 0.0


def test_the_blend_moves_part_way_only_for_a_near_and_clear_fit():
    chain = np.array([0.1, 0.1, 0.05])
    near = ShapeFit('disc', np.array([0.102, 0.1]), drop_per_px=0.05)
    assert blended(chain, near, 0.5, 0.005, 0.02) == pytest.approx([0.101, 0.1, 0.05])
    far = ShapeFit('disc', np.array([0.11, 0.1]), drop_per_px=0.05)
    unclear = ShapeFit('disc', np.array([0.102, 0.1]), drop_per_px=0.01)
    for fit in (far, unclear, None):
        assert blended(chain, fit, 0.5, 0.005, 0.02) is chain


def test_the_principal_axes_of_a_uniform_strip_are_its_sides_and_direction():
    rng = np.random.default_rng(3)
    along, across = rng.uniform(-0.02, 0.02, 20000), rng.uniform(-0.005, 0.005, 20000)
    angle = 0.3
    xy = np.column_stack([along * math.cos(angle) - across * math.sin(angle),
                          along * math.sin(angle) + across * math.cos(angle)])
    found_angle, long_side, short_side = principal_axes(xy)
    assert long_side == pytest.approx(0.04, rel=0.02)
    assert short_side == pytest.approx(0.01, rel=0.02)
    assert math.sin(2 * (found_angle - angle)) == pytest.approx(0.0, abs=0.02)
