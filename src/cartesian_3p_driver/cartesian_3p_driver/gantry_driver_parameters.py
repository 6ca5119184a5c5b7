"""Parameters of gantry_driver_node: the one place their names, defaults, ranges and docs live."""

from stereo_fuzzy_parameters.spec import ParameterSpec

from .gcode import APPROACH_STRATEGIES
from .line_streamer import STREAMING_MODES

NEW_TARGET_POLICIES = ('queue', 'replace')

PARAMETERS = [
    # Wiring
    ParameterSpec('port', 'socket://127.0.0.1:23000', 'Serial device path or pyserial URL '
                  '(/dev/ttyUSB0, socket://host:port, a fake_gantry link_path)', read_only=True),
    ParameterSpec('baud', 115200, 'Serial baud rate [bit/s]', minimum=1200, maximum=2000000,
                  read_only=True),
    ParameterSpec('world_frame', 'world', 'The only frame_id accepted for targets',
                  read_only=True),
    ParameterSpec('joint_names', ['gantry_x_joint', 'gantry_y_joint', 'gantry_z_joint'],
                  'Names of the three prismatic joints published on joint_states',
                  read_only=True),
    ParameterSpec('sent_lines_log', '', 'File every line written to the controller is appended '
                  "to, in order ('' = off)", read_only=True),
    ParameterSpec('streaming_mode', 'send_response', 'send_response: one line in flight; '
                  "character_counting: fill Grbl's 127-byte receive buffer",
                  choices=STREAMING_MODES, read_only=True),
    # Status
    ParameterSpec('poll_rate_hz', 5.0, 'Status report (?) polling rate [Hz]', minimum=0.5,
                  maximum=5.0),
    ParameterSpec('diagnostics_period_s', 1.0, 'Period of /diagnostics messages [s]',
                  minimum=0.1, maximum=60.0),
    # Targets
    ParameterSpec('max_target_age_s', 1.0, 'Targets stamped longer ago (or later) than this '
                  'are refused as stale; 0 disables the check [s]', minimum=0.0,
                  maximum=3600.0),
    ParameterSpec('new_target_policy', 'queue', 'A target arriving during a move: queue it, '
                  'or replace the move (feed hold, Hold:0, soft reset, new move)',
                  choices=NEW_TARGET_POLICIES),
    ParameterSpec('max_queued_moves', 4, 'Most moves waiting behind the running one (queue '
                  'policy); more are refused', minimum=0, maximum=1000),
    # Geometry: machine_mm = machine_offset_mm + axis_scale_mm_per_m * world_m, per axis
    # Safety limits are read-only: no peer may widen them at run time.
    ParameterSpec('machine_offset_mm', [0.0, 0.0, 0.0], 'Machine coordinates of the world '
                  'origin, x y z; |offset| <= 100000 [mm]', read_only=True),
    ParameterSpec('axis_scale_mm_per_m', [1000.0, 1000.0, 1000.0], 'Machine mm per world m, '
                  'x y z; 1 <= |scale| <= 100000, negative flips an axis [mm/m]',
                  read_only=True),
    ParameterSpec('workspace_min_m', [0.0, 0.0, 0.0], 'Lower workspace limits in world, x y z; '
                  'below workspace_max_m, within +-100000 mm once mapped to the machine [m]',
                  read_only=True),
    ParameterSpec('workspace_max_m', [0.40, 0.30, 0.20], 'Upper workspace limits in world, '
                  "x y z; must fit the controller's travel ($130-$132) [m]", read_only=True),
    ParameterSpec('approach_strategy', 'lift_xy_descend', 'lift_xy_descend: lift Z to '
                  'safe_z_m, move XY, descend; direct: one straight line',
                  choices=APPROACH_STRATEGIES),
    ParameterSpec('safe_z_m', 0.15, 'Height the tool lifts to before moving in XY (inside the '
                  'z limits) [m]', minimum=-100.0, maximum=100.0, read_only=True),
    ParameterSpec('approach_offset_m', 0.0, 'The tool stops this far above the target z [m]',
                  minimum=0.0, maximum=1.0),
    # Feeds
    ParameterSpec('feed_rate_mm_min', 1500.0, 'Feed when a request gives none [mm/min]',
                  minimum=1.0, maximum=100000.0),
    ParameterSpec('max_rate_mm_min', [3000.0, 3000.0, 1000.0], 'Per-axis maximum rates x y z; '
                  "every feed is clamped so no axis exceeds its own; at most the controller's "
                  '$110-$112 [mm/min]', read_only=True),
    ParameterSpec('min_feed_rate_mm_min', 10.0, 'Slowest feed a move_to goal may ask for; '
                  'slower goals are refused (0 still means the default feed) [mm/min]',
                  minimum=1.0, maximum=100000.0, read_only=True),
    ParameterSpec('position_tolerance_mm', 0.02, 'Distance from the goal accepted as reached, '
                  'with the controller Idle [mm]', minimum=0.001, maximum=10.0),
    # Safety and timing
    ParameterSpec('require_homing_at_start', False, 'Refuse motion until gantry/home succeeded, '
                  'even on the first connection (always required after a reconnection)'),
    ParameterSpec('banner_timeout_s', 2.5, 'Wait for the start-up banner before a soft reset, '
                  'and as long again before reconnecting [s]', minimum=0.1, maximum=60.0),
    ParameterSpec('reply_timeout_s', 5.0, 'Longest wait for the ok/error of a line; then '
                  'streaming stops (nothing is re-sent) [s]', minimum=0.1, maximum=600.0),
    ParameterSpec('homing_timeout_s', 120.0, 'Longest wait for $H to finish [s]', minimum=1.0,
                  maximum=3600.0),
    ParameterSpec('link_timeout_s', 3.0, 'No data at all for this long means the controller is '
                  'gone (must exceed the polling period) [s]', minimum=0.5, maximum=600.0),
    ParameterSpec('stop_timeout_s', 10.0, 'Longest wait for Hold:0 and the banner when '
                  'stopping [s]', minimum=0.5, maximum=600.0),
    ParameterSpec('reconnect_initial_s', 0.5, 'First reconnection delay, doubled per failure '
                  '[s]', minimum=0.05, maximum=60.0),
    ParameterSpec('reconnect_max_s', 5.0, 'Longest reconnection delay [s]', minimum=0.05,
                  maximum=600.0),
]
