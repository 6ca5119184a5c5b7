"""Turn a target point in `world` into the G-code lines that move the gantry there.

ROS-free: the world -> machine transform, the workspace limits check, the approach plan, feed
clamping and number formatting. The driver formats every number itself; no text from outside
ever reaches the controller.

Conventions: world coordinates are metres; machine coordinates are the controller's MPos in
millimetres. Every motion line uses `G53` (machine coordinates for that line only), so a work
offset (G54/G92) set by someone else cannot shift a move outside the checked limits.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

Vector3 = tuple[float, float, float]
AXES = ('X', 'Y', 'Z')
APPROACH_STRATEGIES = ('lift_xy_descend', 'direct')
#: Resolution of coordinates sent to the controller [mm].
COORDINATE_DECIMALS = 3
#: Largest machine coordinate the driver sends [mm]: any line then fits Grbl's 80 characters.
MAX_MACHINE_COORDINATE_MM = 100_000.0
#: Accepted magnitudes of a world -> machine axis scale [mm/m].
AXIS_SCALE_RANGE_MM_PER_M = (1.0, 100_000.0)
#: Largest feed or axis rate the driver sends [mm/min].
MAX_FEED_MM_MIN = 100_000.0


class TargetRejectedError(ValueError):
    """A target the driver refuses to move to; `reason` says why, in words for an operator."""

    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason


class MotionConfigError(ValueError):
    """The motion parameters contradict each other (for example a safe Z outside the limits)."""


def as_vector3(values: Sequence[float], name: str) -> Vector3:
    """Return `values` as an (x, y, z) tuple of floats.

    Raises:
        MotionConfigError: When `values` does not hold exactly three numbers.
    """
    if len(values) != 3:
        raise MotionConfigError(f'{name} needs 3 values (x, y, z), got {list(values)!r}')
    return (float(values[0]), float(values[1]), float(values[2]))


@dataclass(frozen=True)
class MachineTransform:
    """Per-axis affine map between `world` [m] and machine coordinates [mm].

    machine_mm[i] = offset_mm[i] + scale_mm_per_m[i] * world_m[i]. A negative scale flips an
    axis (for example Grbl's negative machine space after homing).
    """

    offset_mm: Vector3 = (0.0, 0.0, 0.0)
    scale_mm_per_m: Vector3 = (1000.0, 1000.0, 1000.0)

    def __post_init__(self) -> None:
        low, high = AXIS_SCALE_RANGE_MM_PER_M
        for axis, scale in zip(AXES, self.scale_mm_per_m, strict=True):
            if not (math.isfinite(scale) and low <= abs(scale) <= high):
                raise MotionConfigError(
                    f'axis_scale_mm_per_m: the scale for {axis} is {scale}; allowed: '
                    f'{low:g} <= |scale| <= {high:g} mm/m, negative flips the axis')
        for axis, offset in zip(AXES, self.offset_mm, strict=True):
            if not (math.isfinite(offset) and abs(offset) <= MAX_MACHINE_COORDINATE_MM):
                raise MotionConfigError(
                    f'machine_offset_mm: the offset for {axis} is {offset}; allowed: '
                    f'|offset| <= {MAX_MACHINE_COORDINATE_MM:g} mm')

    def to_machine(self, world_m: Vector3) -> Vector3:
        """Map a world point [m] to machine coordinates [mm]."""
        return (self.offset_mm[0] + self.scale_mm_per_m[0] * world_m[0],
                self.offset_mm[1] + self.scale_mm_per_m[1] * world_m[1],
                self.offset_mm[2] + self.scale_mm_per_m[2] * world_m[2])

    def to_world(self, machine_mm: Vector3) -> Vector3:
        """Map machine coordinates [mm] to a world point [m]."""
        return ((machine_mm[0] - self.offset_mm[0]) / self.scale_mm_per_m[0],
                (machine_mm[1] - self.offset_mm[1]) / self.scale_mm_per_m[1],
                (machine_mm[2] - self.offset_mm[2]) / self.scale_mm_per_m[2])


@dataclass(frozen=True)
class WorkspaceLimits:
    """Inclusive per-axis [minimum, maximum] box in `world` [m]."""

    minimum_m: Vector3 = (0.0, 0.0, 0.0)
    maximum_m: Vector3 = (0.40, 0.30, 0.20)

    def __post_init__(self) -> None:
        for axis, low, high in zip(AXES, self.minimum_m, self.maximum_m, strict=True):
            if not (math.isfinite(low) and math.isfinite(high)) or low >= high:
                raise MotionConfigError(
                    f'workspace_min_m/workspace_max_m: the {axis} limits are [{low}, {high}] m; '
                    'allowed: finite numbers with min < max')

    def violation(self, point_m: Vector3) -> str | None:
        """Return which axis of `point_m` [m] lies outside the box and by how much, or None."""
        for axis, value, low, high in zip(AXES, point_m, self.minimum_m, self.maximum_m,
                                          strict=True):
            if value < low or value > high:
                return (f'{axis.lower()}={value:.4f} m is outside the workspace '
                        f'[{low:.4f}, {high:.4f}] m')
        return None


@dataclass(frozen=True)
class MotionConfig:
    """Everything needed to plan a move: geometry, limits, approach and feeds.

    Attributes:
        transform: world -> machine map.
        limits: Workspace box in world [m].
        approach: One of APPROACH_STRATEGIES.
        safe_z_m: Height the tool lifts to before moving in XY (lift_xy_descend) [m].
        approach_offset_m: The tool stops this far above the target's z [m].
        default_feed_mm_min: Feed when a request gives none [mm/min].
        max_rate_mm_min: Per-axis maximum rates (x, y, z) [mm/min].
        min_feed_mm_min: Slowest feed a request may ask for [mm/min].
    """

    transform: MachineTransform = field(default_factory=MachineTransform)
    limits: WorkspaceLimits = field(default_factory=WorkspaceLimits)
    approach: str = 'lift_xy_descend'
    safe_z_m: float = 0.15
    approach_offset_m: float = 0.0
    default_feed_mm_min: float = 1500.0
    max_rate_mm_min: Vector3 = (3000.0, 3000.0, 1000.0)
    min_feed_mm_min: float = 10.0

    def __post_init__(self) -> None:
        if self.approach not in APPROACH_STRATEGIES:
            raise MotionConfigError(f'approach {self.approach!r} is not one of '
                                    f'{", ".join(APPROACH_STRATEGIES)}')
        low, high = self.limits.minimum_m[2], self.limits.maximum_m[2]
        if self.approach == 'lift_xy_descend' and not low <= self.safe_z_m <= high:
            raise MotionConfigError(f'safe_z_m={self.safe_z_m} m is outside the z limits '
                                    f'[{low}, {high}] m')
        if not math.isfinite(self.approach_offset_m):
            raise MotionConfigError(f'approach_offset_m must be finite, got '
                                    f'{self.approach_offset_m}')
        low_feed = self.min_feed_mm_min
        if not (math.isfinite(low_feed) and 0.0 < low_feed <= MAX_FEED_MM_MIN):
            raise MotionConfigError(f'min_feed_rate_mm_min is {low_feed}; allowed: '
                                    f'0 < feed <= {MAX_FEED_MM_MIN:g} mm/min')
        if not (math.isfinite(self.default_feed_mm_min)
                and low_feed <= self.default_feed_mm_min <= MAX_FEED_MM_MIN):
            raise MotionConfigError(f'feed_rate_mm_min is {self.default_feed_mm_min}; allowed: '
                                    f'min_feed_rate_mm_min ({low_feed:g}) to '
                                    f'{MAX_FEED_MM_MIN:g} mm/min')
        for axis, rate in zip(AXES, self.max_rate_mm_min, strict=True):
            if not (math.isfinite(rate) and low_feed <= rate <= MAX_FEED_MM_MIN):
                raise MotionConfigError(f'max_rate_mm_min: the rate for {axis} is {rate}; '
                                        f'allowed: min_feed_rate_mm_min ({low_feed:g}) to '
                                        f'{MAX_FEED_MM_MIN:g} mm/min')
        for name, corner in (('workspace_min_m', self.limits.minimum_m),
                             ('workspace_max_m', self.limits.maximum_m)):
            machine = self.transform.to_machine(corner)
            if not all(math.isfinite(value) and abs(value) <= MAX_MACHINE_COORDINATE_MM
                       for value in machine):
                raise MotionConfigError(
                    f'{name}={list(corner)} m maps to machine {list(machine)} mm with '
                    'machine_offset_mm and axis_scale_mm_per_m; allowed: every machine '
                    f'coordinate within +-{MAX_MACHINE_COORDINATE_MM:g} mm')

    def machine_limits_mm(self) -> tuple[Vector3, Vector3]:
        """Return the workspace box in machine coordinates, (low, high) per axis [mm]."""
        corner_a = self.transform.to_machine(self.limits.minimum_m)
        corner_b = self.transform.to_machine(self.limits.maximum_m)
        low = tuple(min(a, b) for a, b in zip(corner_a, corner_b, strict=True))
        high = tuple(max(a, b) for a, b in zip(corner_a, corner_b, strict=True))
        return low, high  # type: ignore[return-value]


@dataclass(frozen=True)
class MovePlan:
    """The lines for one move and where the tool ends.

    Attributes:
        goal_world_m: Where the tool stops, in world [m] (target + approach offset).
        goal_machine_mm: The same point as sent to the controller [mm] (after rounding).
        lines: G-code lines without line ending, in order.
    """

    goal_world_m: Vector3
    goal_machine_mm: Vector3
    lines: tuple[str, ...]


def check_target(point_m: Sequence[float], frame_id: str, expected_frame: str,
                 age_s: float | None, max_age_s: float, limits: WorkspaceLimits) -> Vector3:
    """Validate a requested target and return it as a tuple.

    Args:
        point_m: Target (x, y, z) [m].
        frame_id: The frame the target is expressed in.
        expected_frame: The only frame accepted (`world`).
        age_s: Time since the target's stamp [s]; None when it carries no stamp.
        max_age_s: Oldest accepted target [s]; 0 disables the age check.
        limits: Workspace box [m].

    Returns:
        The target as (x, y, z) [m].

    Raises:
        TargetRejectedError: With the reason, for a wrong frame, a stale or unstamped target,
            a non-finite coordinate or a point outside the workspace.
    """
    if frame_id != expected_frame:
        raise TargetRejectedError(f'frame_id {frame_id!r} is not {expected_frame!r}')
    if max_age_s > 0.0:
        if age_s is None:
            raise TargetRejectedError('target has no time stamp (header.stamp is zero)')
        if not math.isfinite(age_s) or abs(age_s) > max_age_s:
            which = 'stale' if age_s > 0 else 'stamped in the future'
            raise TargetRejectedError(f'target is {which}: {age_s:.3f} s from now, limit '
                                 f'{max_age_s:.3f} s')
    if len(point_m) != 3:
        raise TargetRejectedError(f'target needs 3 coordinates, got {len(point_m)}')
    point = (float(point_m[0]), float(point_m[1]), float(point_m[2]))
    for axis, value in zip(AXES, point, strict=True):
        if not math.isfinite(value):
            raise TargetRejectedError(f'target {axis.lower()} is not a finite number ({value})')
    reason = limits.violation(point)
    if reason:
        raise TargetRejectedError(f'target outside workspace: {reason}')
    return point


def format_number(value: float, decimals: int = COORDINATE_DECIMALS) -> str:
    """Format a finite number for G-code: fixed point, no exponent, no negative zero.

    Raises:
        ValueError: For NaN or infinity, which must never reach the controller.
    """
    if not math.isfinite(value):
        raise ValueError(f'cannot send a non-finite number ({value}) to the controller')
    text = f'{value:.{decimals}f}'
    if float(text) == 0.0:
        text = f'{0.0:.{decimals}f}'
    return text


def clamp_feed(feed_mm_min: float, start_mm: Vector3 | None, end_mm: Vector3,
               max_rate_mm_min: Vector3, moving_axes: Sequence[int]) -> float:
    """Return the highest feed <= `feed_mm_min` that keeps every axis within its maximum rate.

    With a known start, an axis moving a fraction d of the path runs at feed * d, so the feed
    is capped at max_rate / d per axis. Without a start the cap is the smallest maximum of
    the moving axes, which is safe for any direction.

    Args:
        feed_mm_min: Requested path feed [mm/min].
        start_mm: Start point [mm], or None when unknown.
        end_mm: End point [mm].
        max_rate_mm_min: Per-axis maximum rates [mm/min].
        moving_axes: Indices of the axes the line commands.

    Returns:
        The clamped feed [mm/min], > 0.
    """
    caps = [feed_mm_min]
    if start_mm is None:
        caps.extend(max_rate_mm_min[i] for i in moving_axes)
    else:
        deltas = [end_mm[i] - start_mm[i] if i in moving_axes else 0.0 for i in range(3)]
        length = math.sqrt(sum(d * d for d in deltas))
        if length == 0.0:
            caps.extend(max_rate_mm_min[i] for i in moving_axes)
        else:
            caps.extend(max_rate_mm_min[i] * length / abs(deltas[i])
                        for i in range(3) if deltas[i] != 0.0)
    # Rounded down to the 0.1 mm/min that is sent, so formatting never raises the feed.
    return max(math.floor(min(caps) * 10.0) / 10.0, 0.1)


def check_feed(feed_mm_min: float, config: MotionConfig) -> float:
    """Return the feed a request gets: its own, or the default when it asks for 0 [mm/min].

    Raises:
        TargetRejectedError: For a feed that is not a finite number, negative, or below
            `config.min_feed_mm_min` (a feed so slow a move would run for hours).
    """
    if feed_mm_min == 0.0:
        return config.default_feed_mm_min
    if not math.isfinite(feed_mm_min) or feed_mm_min < config.min_feed_mm_min:
        raise TargetRejectedError(
            f'feed {feed_mm_min:g} mm/min refused: allowed are finite feeds from '
            f'min_feed_rate_mm_min ({config.min_feed_mm_min:g} mm/min) up, or 0 for the '
            'default feed')
    return feed_mm_min


def _quantize_inside(value_mm: float, low_mm: float, high_mm: float) -> float:
    """Round to the sent resolution, pulling the result back inside [low, high] [mm]."""
    scale: int = 10 ** COORDINATE_DECIMALS
    value = round(value_mm, COORDINATE_DECIMALS)
    low_q = math.ceil(round(low_mm * scale, 6)) / scale
    high_q = math.floor(round(high_mm * scale, 6)) / scale
    return min(max(value, low_q), high_q)


def _motion_line(words: dict[int, float], feed_mm_min: float) -> str:
    parts = ['G53', 'G1']
    parts.extend(f'{AXES[i]}{format_number(words[i])}' for i in sorted(words))
    parts.append(f'F{format_number(feed_mm_min, 1)}')
    return ' '.join(parts)


def plan_move(target_m: Vector3, current_m: Vector3 | None, feed_mm_min: float,
              config: MotionConfig) -> MovePlan:
    """Plan the G-code lines that take the tool from `current_m` to `target_m`.

    Strategies: `direct` is one straight G1 line; `lift_xy_descend` lifts Z to the safe
    height (or the goal height if that is higher), moves in XY, then descends. The goal is the
    target raised by the approach offset. Every waypoint is inside the workspace: the target
    and goal are checked, the safe height is validated with the config.

    Args:
        target_m: Target in world [m], already validated by check_target.
        current_m: Current tool position in world [m], or None when unknown.
        feed_mm_min: Requested feed [mm/min]; 0 uses the default feed.
        config: Motion configuration.

    Returns:
        The move plan.

    Raises:
        TargetRejectedError: When the goal (target + approach offset) is outside the
            workspace, or the feed is refused (see check_feed).
    """
    goal = (target_m[0], target_m[1], target_m[2] + config.approach_offset_m)
    reason = config.limits.violation(target_m) or config.limits.violation(goal)
    if reason:
        raise TargetRejectedError(f'target outside workspace: {reason}')
    feed_mm_min = check_feed(feed_mm_min, config)
    low, high = config.machine_limits_mm()

    def machine(point_m: Vector3) -> Vector3:
        raw = config.transform.to_machine(point_m)
        return (_quantize_inside(raw[0], low[0], high[0]),
                _quantize_inside(raw[1], low[1], high[1]),
                _quantize_inside(raw[2], low[2], high[2]))

    goal_mm = machine(goal)
    # The start is not clamped: a tool outside the box still sets the real direction.
    position = config.transform.to_machine(current_m) if current_m is not None else None
    lines: list[str] = []

    def move(axes: Sequence[int], end_mm: Vector3) -> None:
        nonlocal position
        feed = clamp_feed(feed_mm_min, position, end_mm, config.max_rate_mm_min, axes)
        lines.append(_motion_line({i: end_mm[i] for i in axes}, feed))
        if position is None:
            position = end_mm if len(axes) == 3 else None
        else:
            position = tuple(end_mm[i] if i in axes else position[i]  # type: ignore[assignment]
                             for i in range(3))

    if config.approach == 'direct':
        move((0, 1, 2), goal_mm)
    else:
        lift_z = max(config.safe_z_m, goal[2])
        lift_mm = machine((goal[0], goal[1], lift_z))
        move((2,), (0.0, 0.0, lift_mm[2]))
        move((0, 1), (goal_mm[0], goal_mm[1], lift_mm[2]))
        if lift_mm[2] != goal_mm[2]:
            move((2,), goal_mm)
    return MovePlan(goal_world_m=goal, goal_machine_mm=goal_mm, lines=tuple(lines))


#: Lines sent after every start-up banner: millimetres, absolute, feed in units per minute.
PREAMBLE = ('G21 G90 G94',)
