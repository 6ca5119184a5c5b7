"""QoS profiles by name, in one place (STYLE.md): what each kind of topic needs.

- Camera inputs: sensor data (best effort, keep last 5), as camera drivers publish them.
- Results (pairs, matches, best points, decisions): reliable, keep last 10.
- Diagnostics: reliable, keep last 10, as diagnostic_updater publishes them.
- /tf_static: reliable, transient local (a late subscriber still gets the transforms); keep last
  1 to publish (every message holds all of a publisher's static transforms) and keep last 100
  to listen, as tf2_ros' StaticBroadcasterQoS and StaticListenerQoS.
- /tf: reliable, keep last 100, as tf2_ros' DynamicBroadcasterQoS.
"""

from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
    qos_profile_sensor_data,
)

CAMERA_INPUT = qos_profile_sensor_data

RESULTS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=10, reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE)

DIAGNOSTICS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=10, reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE)

TF_STATIC = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=100, reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL)

TF_STATIC_BROADCAST = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL)

TF = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=100, reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE)


def reliability_from_name(name: str) -> ReliabilityPolicy:
    """Map a parameter value ('reliable' or 'best_effort') to a ReliabilityPolicy."""
    return {'reliable': ReliabilityPolicy.RELIABLE,
            'best_effort': ReliabilityPolicy.BEST_EFFORT}[name]
