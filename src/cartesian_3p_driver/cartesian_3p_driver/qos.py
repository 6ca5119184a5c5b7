"""QoS profiles of the gantry driver, by name, in one place (STYLE.md).

- Commands (best_point targets): reliable, keep last 10.
- Driver state (gantry/state): reliable, transient local, keep last 1, so a late subscriber
  gets the current state at once.
- Joint states: reliable, keep last 10 (what robot_state_publisher expects).
- Diagnostics: reliable, keep last 10, as diagnostic_updater publishes them.
- /tf: reliable, keep last 100, as tf2_ros' TransformBroadcaster.
"""

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

COMMANDS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=10, reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE)

DRIVER_STATE = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL)

JOINT_STATES = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=10, reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE)

TF = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=100, reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE)

DIAGNOSTICS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=10, reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE)
