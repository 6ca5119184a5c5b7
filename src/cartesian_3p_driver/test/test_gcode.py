"""G-code planning: transform, limits, approach, feed clamping and formatting (no ROS)."""

import math
import re

import pytest
from cartesian_3p_driver.gcode import (
    MachineTransform,
    MotionConfig,
    MotionConfigError,
    TargetRejectedError,
    WorkspaceLimits,
    check_feed,
    check_target,
    clamp_feed,
    format_number,
    plan_move,
)
from hypothesis import given, settings
from hypothesis import strategies as st

WORD_RE = re.compile(r'([A-Z])(-?\d+(?:\.\d+)?)')


def words(line: str) -> dict[str, float]:
    """Parse `G53 G1 X1.000 F100.0` into {'X': 1.0, 'F': 100.0} (G words dropped)."""
    return {letter: float(value) for letter, value in WORD_RE.findall(line) if letter != 'G'}


def test_transform_round_trips_and_flips_axes():
    transform = MachineTransform(offset_mm=(-400.0, 10.0, 0.0),
                                 scale_mm_per_m=(1000.0, -1000.0, 500.0))
    machine = transform.to_machine((0.1, 0.2, 0.3))
    assert machine == pytest.approx((-300.0, -190.0, 150.0))
    assert transform.to_world(machine) == pytest.approx((0.1, 0.2, 0.3))


def test_zero_scale_is_refused():
    with pytest.raises(MotionConfigError, match='scale for Y'):
        MachineTransform(scale_mm_per_m=(1000.0, 0.0, 1000.0))


def test_lift_xy_descend_plan_lines():
    config = MotionConfig(safe_z_m=0.15, default_feed_mm_min=1500.0,
                          max_rate_mm_min=(3000.0, 3000.0, 1000.0))
    plan = plan_move((0.1, 0.2, 0.05), (0.0, 0.0, 0.0), 0.0, config)
    assert plan.lines == (
        'G53 G1 Z150.000 F1000.0',
        'G53 G1 X100.000 Y200.000 F1500.0',
        'G53 G1 Z50.000 F1000.0',
    )
    assert plan.goal_machine_mm == (100.0, 200.0, 50.0)


def test_approach_offset_raises_the_goal_and_direct_is_one_line():
    config = MotionConfig(approach='direct', approach_offset_m=0.01)
    plan = plan_move((0.1, 0.1, 0.05), None, 500.0, config)
    assert plan.goal_world_m == pytest.approx((0.1, 0.1, 0.06))
    assert plan.lines == ('G53 G1 X100.000 Y100.000 Z60.000 F500.0',)


def test_goal_above_the_limits_after_offset_is_rejected():
    config = MotionConfig(approach_offset_m=0.05)
    with pytest.raises(TargetRejectedError, match='z=0.2200 m is outside'):
        plan_move((0.1, 0.1, 0.17), None, 0.0, config)


def test_feed_is_clamped_per_axis_along_the_direction():
    # 45 degrees in XY: each axis runs at feed / sqrt(2), so feed may reach 1000 * sqrt(2).
    feed = clamp_feed(5000.0, (0.0, 0.0, 0.0), (10.0, 10.0, 0.0),
                      (1000.0, 1000.0, 1000.0), (0, 1))
    assert feed == 1414.2  # 1000 * sqrt(2), rounded down to the 0.1 mm/min sent
    assert clamp_feed(5000.0, None, (10.0, 10.0, 0.0), (1000.0, 800.0, 50.0), (0, 1)) == 800.0
    assert clamp_feed(200.0, None, (10.0, 10.0, 0.0), (1000.0, 800.0, 50.0), (0, 1)) == 200.0


def test_format_number_refuses_non_finite_and_negative_zero():
    assert format_number(-0.0001) == '0.000'
    assert format_number(12.34567) == '12.346'
    with pytest.raises(ValueError, match='non-finite'):
        format_number(float('nan'))


@pytest.mark.parametrize(('point', 'frame', 'age', 'message'), [
    ((float('nan'), 0.1, 0.1), 'world', 0.0, 'x is not a finite number'),
    ((0.1, float('inf'), 0.1), 'world', 0.0, 'y is not a finite number'),
    ((0.1, 0.1, 0.1), 'map', 0.0, "frame_id 'map' is not 'world'"),
    ((0.1, 0.1, 0.1), 'world', 5.0, 'stale'),
    ((0.1, 0.1, 0.1), 'world', -5.0, 'future'),
    ((0.1, 0.1, 0.1), 'world', None, 'no time stamp'),
    ((0.5, 0.1, 0.1), 'world', 0.0, 'x=0.5000 m is outside the workspace'),
    ((0.1, -0.01, 0.1), 'world', 0.0, 'y=-0.0100 m is outside'),
])
def test_bad_targets_are_rejected_with_their_reason(point, frame, age, message):
    with pytest.raises(TargetRejectedError, match=re.escape(message)):
        check_target(point, frame, 'world', age, 1.0, WorkspaceLimits())


def test_good_target_passes_and_age_check_can_be_disabled():
    assert check_target([0.1, 0.2, 0.0], 'world', 'world', None, 0.0,
                        WorkspaceLimits()) == (0.1, 0.2, 0.0)


def test_safe_z_outside_limits_is_a_config_error():
    with pytest.raises(MotionConfigError, match='safe_z_m'):
        MotionConfig(safe_z_m=0.5)


finite = st.floats(min_value=-2.0, max_value=2.0, allow_nan=False)
anything = st.floats(allow_nan=True, allow_infinity=True)
scale = st.sampled_from([1000.0, -1000.0, 250.0, -40.0])


@settings(max_examples=400, deadline=None)
@given(target=st.tuples(st.one_of(finite, anything), st.one_of(finite, anything),
                        st.one_of(finite, anything)),
       current=st.one_of(st.none(), st.tuples(finite, finite, finite)),
       feed=st.one_of(anything, st.floats(min_value=0.0, max_value=1e6)),
       offset=st.tuples(finite, finite, finite).map(lambda p: tuple(v * 100 for v in p)),
       scales=st.tuples(scale, scale, scale),
       approach=st.sampled_from(['lift_xy_descend', 'direct']),
       approach_offset=st.floats(min_value=0.0, max_value=0.05))
def test_no_generated_line_ever_leaves_the_limits_or_exceeds_a_rate(
        target, current, feed, offset, scales, approach, approach_offset):
    limits = WorkspaceLimits((0.0, 0.0, 0.0), (0.40, 0.30, 0.20))
    max_rates = (3000.0, 2000.0, 500.0)
    config = MotionConfig(transform=MachineTransform(offset, scales), limits=limits,
                          approach=approach, approach_offset_m=approach_offset,
                          max_rate_mm_min=max_rates)
    try:
        point = check_target(target, 'world', 'world', 0.0, 1.0, limits)
        plan = plan_move(point, current, feed, config)
    except TargetRejectedError:
        return
    low, high = config.machine_limits_mm()
    position = list(config.transform.to_machine(current)) if current else [None, None, None]
    for line in plan.lines:
        assert line.startswith('G53 G1 '), line
        assert len(line) <= 80
        values = words(line)
        moving = [i for i, axis in enumerate('XYZ') if axis in values]
        assert moving, line
        feed = values['F']
        assert feed > 0.0, line
        if all(position[i] is not None for i in moving):
            deltas = [values['XYZ'[i]] - position[i] if i in moving else 0.0 for i in range(3)]
            length = math.sqrt(sum(d * d for d in deltas))
            for i in range(3):
                if length > 1e-3:
                    assert feed * abs(deltas[i]) / length <= max_rates[i] + 1e-6, (line, i)
        else:
            # Without the path start the feed is capped by the slowest moving axis.
            assert feed <= min(max_rates[i] for i in moving), line
        for i in moving:
            value = values['XYZ'[i]]
            assert low[i] - 1e-9 <= value <= high[i] + 1e-9, (line, low, high)
            world = (value - offset[i]) / scales[i]
            assert limits.minimum_m[i] - 1e-6 <= world <= limits.maximum_m[i] + 1e-6, line
            position[i] = value


@pytest.mark.parametrize(('kwargs', 'message'), [
    ({'scale_mm_per_m': (1e306, 1000.0, 1000.0)}, 'axis_scale_mm_per_m: the scale for X'),
    ({'scale_mm_per_m': (1000.0, 0.5, 1000.0)}, 'axis_scale_mm_per_m: the scale for Y'),
    ({'scale_mm_per_m': (1000.0, 1000.0, math.nan)}, 'axis_scale_mm_per_m: the scale for Z'),
    ({'offset_mm': (1e308, 0.0, 0.0)}, 'machine_offset_mm: the offset for X is 1e+308'),
    ({'offset_mm': (0.0, -math.inf, 0.0)}, 'machine_offset_mm: the offset for Y'),
])
def test_absurd_geometry_is_a_config_error_naming_the_parameter(kwargs, message):
    with pytest.raises(MotionConfigError, match=re.escape(message)):
        MachineTransform(**kwargs)


def test_a_workspace_mapping_to_over_long_lines_is_a_config_error():
    transform = MachineTransform(scale_mm_per_m=(100_000.0, 1000.0, 1000.0))
    with pytest.raises(MotionConfigError, match='workspace_max_m=.*within \\+-100000 mm'):
        MotionConfig(transform=transform, limits=WorkspaceLimits((0.0, 0.0, 0.0),
                                                                (2.0, 0.3, 0.2)))


def test_workspace_min_must_be_below_max():
    with pytest.raises(MotionConfigError, match='min < max'):
        WorkspaceLimits((0.0, 0.0, 0.2), (0.4, 0.3, 0.2))


@pytest.mark.parametrize(('kwargs', 'message'), [
    ({'min_feed_mm_min': 0.0}, 'min_feed_rate_mm_min'),
    ({'default_feed_mm_min': 5.0}, 'feed_rate_mm_min is 5.0'),
    ({'max_rate_mm_min': (3000.0, 1e30, 1000.0)}, 'max_rate_mm_min: the rate for Y'),
])
def test_feeds_and_rates_outside_their_range_are_config_errors(kwargs, message):
    with pytest.raises(MotionConfigError, match=re.escape(message)):
        MotionConfig(**kwargs)


def test_check_feed_keeps_zero_for_the_default_and_refuses_slow_feeds():
    config = MotionConfig(min_feed_mm_min=10.0, default_feed_mm_min=1500.0)
    assert check_feed(0.0, config) == 1500.0
    assert check_feed(10.0, config) == 10.0
    for feed in (9.99, 1e-12, -1.0, math.nan, math.inf):
        with pytest.raises(TargetRejectedError, match='min_feed_rate_mm_min'):
            check_feed(feed, config)
