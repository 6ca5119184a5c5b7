"""Settings of gantry_driver_node: its parameters' names, defaults, ranges and docs, once.

`world_frame`, `workspace_min_m` and `workspace_max_m` are the shared WorldSettings
(stereo_fuzzy_parameters/world.py), declared by fuzzy_best_point_node too. Safety limits are
read-only: no peer may widen them at run time.
"""

from __future__ import annotations

from dataclasses import dataclass

from stereo_fuzzy_parameters.spec import parameter, parameter_group, parameter_specs
from stereo_fuzzy_parameters.world import WorldSettings

from .gcode import (
    APPROACH_STRATEGIES,
    MachineTransform,
    MotionConfig,
    MotionConfigError,
    Vector3,
    WorkspaceLimits,
)
from .line_streamer import STREAMING_MODES

NEW_TARGET_POLICIES = ('queue', 'replace')


@dataclass(frozen=True)
class GantryDriverSettings:
    """Parameters of gantry_driver_node, typed."""

    # --- wiring
    port: str = parameter(
        'socket://127.0.0.1:23000', 'Serial device path or pyserial URL (/dev/ttyUSB0, '
        'socket://host:port, a fake_gantry link_path)', read_only=True)
    baud: int = parameter(115200, 'Serial baud rate [bit/s]', 1200, 2000000, read_only=True)
    joint_names: tuple[str, str, str] = parameter(
        ('gantry_x_joint', 'gantry_y_joint', 'gantry_z_joint'),
        'Names of the three prismatic joints published on joint_states', read_only=True)
    sent_lines_log: str = parameter(
        '', "File every line written to the controller is appended to, in order ('' = off)",
        read_only=True)
    streaming_mode: str = parameter(
        'send_response', "send_response: one line in flight; character_counting: fill Grbl's "
        '127-byte receive buffer', choices=STREAMING_MODES, read_only=True)
    # --- status
    poll_rate_hz: float = parameter(5.0, 'Status report (?) polling rate [Hz]', 0.5, 5.0)
    diagnostics_period_s: float = parameter(
        1.0, 'Period of /diagnostics messages [s]', 0.1, 60.0)
    # --- targets
    max_target_age_s: float = parameter(
        1.0, 'Targets stamped longer ago (or later) than this are refused as stale; 0 disables '
        'the check [s]', 0.0, 3600.0)
    new_target_policy: str = parameter(
        'queue', 'A target arriving during a move: queue it, or replace the move (feed hold, '
        'Hold:0, soft reset, new move)', choices=NEW_TARGET_POLICIES)
    max_queued_moves: int = parameter(
        4, 'Most moves waiting behind the running one (queue policy); more are refused',
        0, 1000)
    # --- geometry: machine_mm = machine_offset_mm + axis_scale_mm_per_m * world_m, per axis
    world: WorldSettings = parameter_group(WorldSettings, prefix='')
    machine_offset_mm: Vector3 = parameter(
        (0.0, 0.0, 0.0), 'Machine coordinates of the world origin, x y z; |offset| <= 100000 '
        '[mm]', read_only=True)
    axis_scale_mm_per_m: Vector3 = parameter(
        (1000.0, 1000.0, 1000.0), 'Machine mm per world m, x y z; 1 <= |scale| <= 100000, '
        'negative flips an axis [mm/m]', read_only=True)
    approach_strategy: str = parameter(
        'lift_xy_descend', 'lift_xy_descend: lift Z to safe_z_m, move XY, descend; direct: one '
        'straight line', choices=APPROACH_STRATEGIES)
    safe_z_m: float = parameter(
        0.15, 'Height the tool lifts to before moving in XY (inside the z limits) [m]',
        -100.0, 100.0, read_only=True)
    approach_offset_m: float = parameter(
        0.0, 'The tool stops this far above the target z [m]', 0.0, 1.0)
    # --- feeds
    feed_rate_mm_min: float = parameter(
        1500.0, 'Feed when a request gives none [mm/min]', 1.0, 100000.0)
    max_rate_mm_min: Vector3 = parameter(
        (3000.0, 3000.0, 1000.0), 'Per-axis maximum rates x y z; every feed is clamped so no '
        "axis exceeds its own; at most the controller's $110-$112 [mm/min]", read_only=True)
    min_feed_rate_mm_min: float = parameter(
        10.0, 'Slowest feed a move_to goal may ask for; slower goals are refused (0 still '
        'means the default feed) [mm/min]', 1.0, 100000.0, read_only=True)
    position_tolerance_mm: float = parameter(
        0.02, 'Distance from the goal accepted as reached, with the controller Idle [mm]',
        0.001, 10.0)
    # --- safety and timing
    require_homing_at_start: bool = parameter(
        False, 'Refuse motion until gantry/home succeeded, even on the first connection '
        '(always required after a reconnection)')
    banner_timeout_s: float = parameter(
        2.5, 'Wait for the start-up banner before a soft reset, and as long again before '
        'reconnecting [s]', 0.1, 60.0)
    reply_timeout_s: float = parameter(
        5.0, 'Longest wait for the ok/error of a line; then streaming stops (nothing is '
        're-sent) [s]', 0.1, 600.0)
    homing_timeout_s: float = parameter(
        120.0, 'Longest wait for $H to finish [s]', 1.0, 3600.0)
    link_timeout_s: float = parameter(
        3.0, 'No data at all for this long means the controller is gone (must exceed the '
        'polling period) [s]', 0.5, 600.0)
    stop_timeout_s: float = parameter(
        10.0, 'Longest wait for Hold:0 and the banner when stopping [s]', 0.5, 600.0)
    reconnect_initial_s: float = parameter(
        0.5, 'First reconnection delay, doubled per failure [s]', 0.05, 60.0)
    reconnect_max_s: float = parameter(5.0, 'Longest reconnection delay [s]', 0.05, 600.0)

    def motion_config(self) -> MotionConfig:
        """Return the motion configuration these settings describe.

        Raises:
            MotionConfigError: When the values contradict each other.
        """
        return MotionConfig(
            transform=MachineTransform(self.machine_offset_mm, self.axis_scale_mm_per_m),
            limits=WorkspaceLimits(self.world.workspace_min_m, self.world.workspace_max_m),
            approach=self.approach_strategy, safe_z_m=self.safe_z_m,
            approach_offset_m=self.approach_offset_m,
            default_feed_mm_min=self.feed_rate_mm_min, max_rate_mm_min=self.max_rate_mm_min,
            min_feed_mm_min=self.min_feed_rate_mm_min)

    def problem(self) -> str | None:
        """Return why these settings cannot work together, or None."""
        try:
            self.motion_config()
        except MotionConfigError as error:
            return str(error)
        if self.link_timeout_s <= 1.0 / self.poll_rate_hz:
            return (f'link_timeout_s={self.link_timeout_s} s must exceed the polling period '
                    f'1/poll_rate_hz={1.0 / self.poll_rate_hz:.2f} s')
        return None


PARAMETERS = parameter_specs(GantryDriverSettings)
